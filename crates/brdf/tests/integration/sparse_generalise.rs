//! Issue 16, item 1: fits from sparse hand-held samples must generalise. Each Mitsuba 3
//! `roughplastic` material of `datasets/fixtures/brdf/lights8.csv` is sampled like the hand-held
//! frame (20 views per light position, 1% noise); the fit from the first `k` light positions is
//! evaluated at the 500 held-out random pairs of `heldout.csv` and compared with the fit to those
//! 500 dense pairs themselves (the best the model can do there):
//!
//! - mean |log ratio| = mean over pairs and channels of `|ln(model / truth)|` (values floored at
//!   1e-6 of the channel's mean truth, so a zero prediction is a large, finite error);
//! - relative RMS = `sqrt(sum (model - truth)^2 / sum truth^2)` per channel (energy-weighted),
//!   the mean over the channels.
//!
//! `cargo test -p igi-brdf --test integration sparse_generalise:: -- --nocapture` prints the table of
//! docs/BRDF.md; `... -- --ignored --nocapture` also sweeps 1 to 8 light positions and draws
//! `docs/img/brdf_error_vs_lights.png`.

use std::path::{Path, PathBuf};

use igi_brdf::samples::group_by_material;
use igi_brdf::{fit_material, read_samples, BrdfSample, FitOptions, Lafortune};

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../datasets/fixtures/brdf")
}

fn load(file: &str) -> Vec<(String, Vec<BrdfSample>)> {
    let path = fixtures().join(file);
    group_by_material(&read_samples(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display())))
}

/// (mean |log ratio|, relative RMS) of `m` over `pairs`.
fn errors(m: &Lafortune, pairs: &[BrdfSample]) -> (f64, f64) {
    let n = pairs.len() as f64;
    let mean: [f64; 3] =
        [0, 1, 2].map(|c| pairs.iter().map(|s| s.value[c] as f64).sum::<f64>() / n);
    let (mut log, mut num, mut den) = (0.0, [0.0f64; 3], [0.0f64; 3]);
    for s in pairs {
        let f = m.as_ref().eval(s.light, s.view) * std::f32::consts::PI;
        for c in 0..3 {
            let (a, t) = (f[c] as f64, s.value[c] as f64);
            assert!(a.is_finite(), "model value {a} at {s:?}");
            let eps = 1e-6 * mean[c];
            log += ((a.max(eps)) / t.max(eps)).ln().abs();
            num[c] += (a - t).powi(2);
            den[c] += t * t;
        }
    }
    let rms = (0..3).map(|c| (num[c] / den[c]).sqrt()).sum::<f64>() / 3.0;
    (log / (3.0 * n), rms)
}

const VIEWS: usize = 20;

struct Row {
    name: String,
    sparse: (f64, f64),
    dense: (f64, f64),
}

/// The fixtures: `lights8.csv` and `heldout.csv`.
const FIXTURES: (&str, &str) = ("lights8.csv", "heldout.csv");
/// Four other Mitsuba materials, never used to choose the fit's options.
const VALIDATION: (&str, &str) = ("validation_lights8.csv", "validation_heldout.csv");

fn study(lights: usize, dense: &[(f64, f64)], opts: &FitOptions) -> Vec<Row> {
    study_on(FIXTURES, lights, dense, opts)
}

fn study_on(
    files: (&str, &str),
    lights: usize,
    dense: &[(f64, f64)],
    opts: &FitOptions,
) -> Vec<Row> {
    let train = load(files.0);
    let held = load(files.1);
    let mut rows = Vec::new();
    for (i, ((name, s), (hname, h))) in train.iter().zip(&held).enumerate() {
        assert_eq!(name, hname);
        assert_eq!(s.len(), 8 * VIEWS, "{name}: 8 lights x 20 views");
        let t0 = std::time::Instant::now();
        let fit = fit_material(name, &s[..lights * VIEWS], opts).unwrap();
        eprintln!(
            "{name} lights {lights}: fit {:.2} s, lobes {} cv {:?}\n  {:?}",
            t0.elapsed().as_secs_f64(),
            fit.lobes_used,
            fit.cv,
            fit.brdf
        );
        rows.push(Row {
            name: name.clone(),
            sparse: errors(&fit.brdf, h),
            dense: dense[i],
        });
    }
    rows
}

/// The fits to the dense held-out pairs themselves, per metric the better of the plain weighted
/// least squares and the default fit (the stricter reference).
fn dense_fits() -> Vec<(f64, f64)> {
    dense_fits_on(FIXTURES.1)
}

fn dense_fits_on(held: &str) -> Vec<(f64, f64)> {
    load(held)
        .iter()
        .map(|(name, h)| {
            let p = errors(
                &fit_material(name, h, &FitOptions::plain()).unwrap().brdf,
                h,
            );
            let d = errors(
                &fit_material(name, h, &FitOptions::default()).unwrap().brdf,
                h,
            );
            eprintln!(
                "{name} dense: plain log {:.3} relRMS {:.3} | default log {:.3} relRMS {:.3}",
                p.0, p.1, d.0, d.1
            );
            (p.0.min(d.0), p.1.min(d.1))
        })
        .collect()
}

fn print(lights: usize, rows: &[Row]) {
    for r in rows {
        eprintln!(
            "{} lights {lights}: sparse log {:.3} relRMS {:.3} | dense log {:.3} relRMS {:.3} | ratio {:.2} {:.2}",
            r.name,
            r.sparse.0,
            r.sparse.1,
            r.dense.0,
            r.dense.1,
            r.sparse.0 / r.dense.0,
            r.sparse.1 / r.dense.1
        );
    }
}

/// The goal of issue 16: default fits (`igi brdf fit`) from the 4 light positions of the
/// hand-held frame within 1.2x of the dense fit in both metrics, for every material. Measured
/// (docs/BRDF.md): mean |log ratio| 1.11 / 1.03 / 1.05 and relative RMS 1.17 / 1.07 / 1.01
/// (`plastic_a010`, `plastic_a030`, `dark_grazing`); the plain fit reaches 1.34 for
/// `plastic_a010`'s log ratio (`plain_fit_misses_the_goal_for_plastic_a010`).
#[test]
fn four_lights_against_the_dense_fit() {
    let dense = dense_fits();
    let rows = study(4, &dense, &FitOptions::default());
    print(4, &rows);
    let names = ["plastic_a010", "plastic_a030", "dark_grazing"];
    for (r, name) in rows.iter().zip(names) {
        assert_eq!(r.name, name);
        let ratio = (r.sparse.0 / r.dense.0, r.sparse.1 / r.dense.1);
        assert!(
            ratio.0 <= 1.2,
            "{name}: |log ratio| {:.3} vs dense {:.3}",
            r.sparse.0,
            r.dense.0
        );
        assert!(
            ratio.1 <= 1.2,
            "{name}: relative RMS {:.3} vs dense {:.3}",
            r.sparse.1,
            r.dense.1
        );
    }
}

/// The same at 4 lights on four other Mitsuba materials (`validation_*.csv`: GGX alpha 0.05,
/// 0.15 with IOR 1.6, Beckmann alpha 0.2, GGX alpha 0.4) that played no part in choosing the
/// default. Measured (docs/BRDF.md), default / plain: log ratio 1.07 / 1.80, 1.05 / 1.11,
/// 0.91 / 0.97, 1.04 / 1.10; relative RMS 0.97 / 489, 0.98 / 0.98, 2.34 / 2.50, 0.99 / 0.96.
/// The Beckmann material's grazing highlight (a lobe gain of about 400 in the dense fit) is
/// beyond every sample (lights <= 75 degrees): no fit from these samples sees it.
#[test]
fn four_lights_on_the_validation_materials() {
    let dense = dense_fits_on(VALIDATION.1);
    let rows = study_on(VALIDATION, 4, &dense, &FitOptions::default());
    print(4, &rows);
    let plain = study_on(VALIDATION, 4, &dense, &FitOptions::plain());
    print(4, &plain);
    for (r, p) in rows.iter().zip(&plain) {
        let ratio = (r.sparse.0 / r.dense.0, r.sparse.1 / r.dense.1);
        let plain_rms = p.sparse.1 / p.dense.1;
        assert!(ratio.0 <= 1.2, "{}: log ratio {ratio:?}", r.name);
        if r.name == "val_beckmann_a020" {
            assert!(ratio.1 <= plain_rms, "{}: {ratio:?}", r.name);
        } else {
            assert!(ratio.1 <= 1.2, "{}: relative RMS {ratio:?}", r.name);
        }
    }
}

/// What the coverage weights and the gain bound fix: the plain fit from 4 lights extrapolates
/// the diffuse falloff badly at grazing pairs (`plastic_a010` mean |log ratio| 1.34x the dense
/// fit's), and coverage weights without the gain bound let the specular lobe blow up toward
/// grazing (relative RMS about 14x); `FitOptions::regularised()` misses too (1.81x).
#[test]
fn plain_fit_and_unbounded_weights_miss_the_goal_for_plastic_a010() {
    let dense = dense_fits();
    let plain = &study(4, &dense, &FitOptions::plain())[0];
    print(4, std::slice::from_ref(plain));
    assert!(plain.sparse.0 / plain.dense.0 > 1.25, "plain log ratio");
    let unbounded = FitOptions {
        max_gain: f64::INFINITY,
        ..FitOptions::default()
    };
    let weighted = &study(4, &dense, &unbounded)[0];
    print(4, std::slice::from_ref(weighted));
    assert!(
        weighted.sparse.1 / weighted.dense.1 > 3.0,
        "unbounded rel RMS"
    );
    // the default plus the energy bound, smoothness and one/two-lobe cross-validation: the CV
    // keeps one lobe, and the retro lobe it drops is what bends the diffuse term at grazing
    let reg = study(4, &dense, &FitOptions::regularised());
    print(4, &reg);
    assert_eq!(reg[0].name, "plastic_a010");
    assert!(
        reg[0].sparse.0 / reg[0].dense.0 > 1.25,
        "regularised log ratio"
    );
}

/// The fit's reported uncertainty grows away from the samples: the standard error of `pi f`
/// (relative to the value) at held-out pairs out of the lights' plane and near grazing exceeds
/// the one at the training pairs themselves.
#[test]
fn value_stderr_grows_away_from_the_samples() {
    let train = load("lights8.csv");
    let held = load("heldout.csv");
    let (name, s) = &train[1];
    let fit = fit_material(name, &s[..4 * VIEWS], &FitOptions::plain()).unwrap();
    let rel = |pairs: &mut dyn Iterator<Item = &BrdfSample>| {
        let v: Vec<f64> = pairs
            .map(|p| {
                let f = fit.brdf.as_ref().eval(p.light, p.view) * std::f32::consts::PI;
                (fit.value_stderr(p.light, p.view).y / f.y.max(1e-9)) as f64
            })
            .collect();
        v.iter().sum::<f64>() / v.len() as f64
    };
    let at_samples = rel(&mut s[..4 * VIEWS].iter());
    let far = rel(&mut held[1]
        .1
        .iter()
        .filter(|p| p.light.y.abs() > 0.5 && p.view.z < 0.3));
    eprintln!(
        "{name}: mean relative stderr at the samples {at_samples:.4}, far from them {far:.4}"
    );
    assert!(at_samples.is_finite() && far.is_finite());
    // measured 0.0429 vs 0.0361 (x1.19): it grows, but modestly (the covariance is local)
    assert!(far > 1.1 * at_samples, "{far} vs {at_samples}");
}

/// One material's points: (light positions, mean |log ratio| ratio, relative RMS ratio).
type Curve = Vec<(f64, f64, f64)>;

/// Error against the number of light positions (1 to 8) of the default and the plain fit, both
/// metrics as ratios to the dense fit: prints the table of docs/BRDF.md and draws
/// `docs/img/brdf_error_vs_lights.png`. About 2 minutes.
#[test]
#[ignore]
fn error_against_number_of_lights() {
    let dense = dense_fits();
    let names = ["plastic_a010", "plastic_a030", "dark_grazing"];
    // curves[option][material] = [(lights, log ratio, rel RMS ratio)]
    let mut curves: Vec<(&str, Vec<Curve>)> = Vec::new();
    for (label, opts) in [
        ("default", FitOptions::default()),
        ("plain", FitOptions::plain()),
    ] {
        let mut per = vec![Vec::new(); 3];
        for lights in 1..=8 {
            let rows = study(lights, &dense, &opts);
            print(lights, &rows);
            for (k, r) in rows.iter().enumerate() {
                let q = (r.sparse.0 / r.dense.0, r.sparse.1 / r.dense.1);
                per[k].push((lights as f64, q.0, q.1));
            }
        }
        curves.push((label, per));
    }
    eprintln!("| lights | fit | {} |", names.join(" (log, rel. RMS) | "));
    for l in 0..8 {
        for (label, per) in &curves {
            let cells: Vec<String> = per
                .iter()
                .map(|c| format!("{:.2}, {:.2}", c[l].1, c[l].2))
                .collect();
            eprintln!("| {} | {label} | {} |", l + 1, cells.join(" | "));
        }
    }
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/img/brdf_error_vs_lights.png");
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    plot_curves(&path, &names, &curves);
    eprintln!("wrote {}", path.display());
}

/// Two panels (mean |log ratio|, relative RMS; each over the dense fit's) against light positions.
fn plot_curves(path: &Path, names: &[&str], curves: &[(&str, Vec<Curve>)]) {
    use igi_plot::{write_chart_grid, Axis, Chart, Series, PALETTE};
    let ymax = 3.0;
    let panels: Vec<Chart> = ["mean |log ratio|", "relative RMS"]
        .iter()
        .enumerate()
        .map(|(p, title)| {
            let goal = Series {
                opacity: 0.5,
                ..Series::line(vec![(1.0, 1.2), (8.0, 1.2)], [0, 0, 0], 1)
            };
            let mut series = vec![goal];
            for (o, (label, per)) in curves.iter().enumerate() {
                for (k, pts) in per.iter().enumerate() {
                    let y = |q: &(f64, f64, f64)| if p == 0 { q.1 } else { q.2 };
                    let pts = pts.iter().map(|q| (q.0, y(q).min(ymax))).collect();
                    let colour = PALETTE[k % PALETTE.len()];
                    series.push(Series {
                        opacity: if o == 0 { 1.0 } else { 0.6 },
                        legend: Some(format!("{} {label}", names[k])),
                        ..Series::line(pts, colour, if o == 0 { 3 } else { 1 })
                    });
                }
            }
            Chart {
                title: format!("held-out {title} / dense fit's"),
                x: Axis::linear("light positions (20 views each)", 1.0..8.0),
                y: Axis::linear("ratio to the dense fit (goal <= 1.2)", 0.8..ymax),
                series,
            }
        })
        .collect();
    write_chart_grid(path, (1200, 520), (1, 2), &panels).unwrap();
}
