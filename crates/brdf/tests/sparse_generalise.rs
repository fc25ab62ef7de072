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
//! `cargo test -p igi-brdf --test sparse_generalise -- --nocapture` prints the table of
//! docs/BRDF.md; `... -- --ignored --nocapture` also sweeps 1 to 8 light positions and draws
//! `target/brdf_error_vs_lights.png`.

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

fn study(lights: usize, dense: &[(f64, f64)], opts: &FitOptions) -> Vec<Row> {
    let train = load("lights8.csv");
    let held = load("heldout.csv");
    let mut rows = Vec::new();
    for (i, ((name, s), (hname, h))) in train.iter().zip(&held).enumerate() {
        assert_eq!(name, hname);
        assert_eq!(s.len(), 8 * VIEWS, "{name}: 8 lights x 20 views");
        let fit = fit_material(name, &s[..lights * VIEWS], opts).unwrap();
        eprintln!(
            "{name} lights {lights}: lobes {} cv {:?}\n  {:?}",
            fit.lobes_used, fit.cv, fit.brdf
        );
        rows.push(Row {
            name: name.clone(),
            sparse: errors(&fit.brdf, h),
            dense: dense[i],
        });
    }
    rows
}

/// The fits to the dense held-out pairs themselves (plain weighted least squares).
fn dense_fits() -> Vec<(f64, f64)> {
    load("heldout.csv")
        .iter()
        .map(|(name, h)| {
            let b = errors(
                &fit_material(name, h, &FitOptions::plain()).unwrap().brdf,
                h,
            );
            eprintln!("{name} dense: plain log {:.3} relRMS {:.3}", b.0, b.1);
            b
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

/// Plain fits from the 4 light positions of the hand-held frame against the dense fit. Measured
/// (docs/BRDF.md): ratios of mean |log ratio| 1.34 / 1.15 / 1.03 and of relative RMS
/// 1.13 / 1.03 / 0.99 (`plastic_a010`, `plastic_a030`, `dark_grazing`): the relative RMS is
/// within 1.2x for every material, the log ratio of `plastic_a010` is not.
#[test]
fn four_lights_against_the_dense_fit() {
    let dense = dense_fits();
    let rows = study(4, &dense, &FitOptions::plain());
    print(4, &rows);
    let log_bound = [
        ("plastic_a010", 1.45),
        ("plastic_a030", 1.2),
        ("dark_grazing", 1.2),
    ];
    for (r, (name, lb)) in rows.iter().zip(log_bound) {
        assert_eq!(r.name, name);
        let ratio = (r.sparse.0 / r.dense.0, r.sparse.1 / r.dense.1);
        assert!(
            ratio.0 <= lb,
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

/// Error against the number of light positions (1 to 8), plain and regularised fits, and the
/// plot `target/brdf_error_vs_lights.png`. About 10 minutes.
#[test]
#[ignore]
fn error_against_number_of_lights() {
    use plotters::prelude::*;
    let dense = dense_fits();
    let mut curves: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    for (label, opts) in [
        ("plain", FitOptions::plain()),
        ("regularised", FitOptions::regularised()),
    ] {
        let mut per: Vec<Vec<(f64, f64)>> = vec![Vec::new(); 3];
        for lights in 1..=8 {
            let rows = study(lights, &dense, &opts);
            print(lights, &rows);
            for (k, r) in rows.iter().enumerate() {
                per[k].push((lights as f64, r.sparse.0 / r.dense.0));
            }
        }
        let names = ["plastic_a010", "plastic_a030", "dark_grazing"];
        for (k, p) in per.into_iter().enumerate() {
            curves.push((format!("{} {label}", names[k]), p));
        }
    }
    igi_imaging::plot::register_fonts();
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../target/brdf_error_vs_lights.png");
    let root = BitMapBackend::new(&path, (900, 600)).into_drawing_area();
    root.fill(&WHITE).unwrap();
    let ymax = curves
        .iter()
        .flat_map(|c| c.1.iter().map(|p| p.1))
        .fold(1.5, f64::max)
        .min(5.0);
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "held-out mean |log ratio| / dense fit's, against light positions",
            ("sans-serif", 20),
        )
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(1.0..8.0, 0.8..ymax)
        .unwrap();
    chart
        .configure_mesh()
        .x_desc("light positions")
        .y_desc("ratio to the dense fit")
        .draw()
        .unwrap();
    for (i, (label, pts)) in curves.iter().enumerate() {
        let col = Palette99::pick(i).to_rgba();
        chart
            .draw_series(LineSeries::new(
                pts.iter().map(|p| (p.0, p.1.min(ymax))),
                col.stroke_width(2),
            ))
            .unwrap()
            .label(label.clone())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], col));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .unwrap();
    root.present().unwrap();
    eprintln!("wrote {}", path.display());
}
