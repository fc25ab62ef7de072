//! Independent ground truth (issue 5): Lafortune fits of Mitsuba 3 `roughplastic` samples
//! (`datasets/fixtures/brdf/samples.csv`, written by `datasets/mitsuba/brdf_samples.py`) against
//! 500 noise-free held-out light/view pairs per material (`heldout.csv`).
//!
//! Metrics, per channel, over a material's held-out pairs (values are `pi f`):
//! - relative RMS `sqrt(sum (model - truth)^2) / sqrt(sum truth^2)` (energy-weighted: dominated by
//!   the brightest pairs, i.e. highlights near grazing);
//! - median relative error `median |model - truth| / truth` (the typical pair);
//!
//! Both over all 500 pairs and over the pairs with both directions within 75 degrees of the normal
//! (the elevations the training lights cover; the held-out pairs reach 89 degrees).
//! The "bound" fits Lafortune to the held-out pairs themselves: no fit from training data can beat
//! it (up to local minima), so it measures what the model can represent at all.
//!
//! `cargo test -p igi-brdf --test integration mitsuba_fixtures:: -- --nocapture` prints the table of docs/BRDF.md.

use std::path::{Path, PathBuf};

use igi_brdf::samples::group_by_material;
use igi_brdf::{fit_material, read_samples, BrdfSample, FitOptions, FitReport, Lafortune};

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../datasets/fixtures/brdf")
}

fn load(file: &str) -> Vec<(String, Vec<BrdfSample>)> {
    let path = fixtures().join(file);
    group_by_material(&read_samples(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display())))
}

#[derive(Clone, Copy, Debug)]
struct Metrics {
    rel_rms: [f64; 3],
    median_rel: [f64; 3],
    pairs: usize,
}

impl Metrics {
    fn worst_rms(&self) -> f64 {
        self.rel_rms.iter().copied().fold(0.0, f64::max)
    }
    fn worst_median(&self) -> f64 {
        self.median_rel.iter().copied().fold(0.0, f64::max)
    }
}

fn metrics(m: &Lafortune, pairs: &[BrdfSample]) -> Metrics {
    let mut num = [0.0f64; 3];
    let mut den = [0.0f64; 3];
    let mut rel: [Vec<f64>; 3] = Default::default();
    for s in pairs {
        let f = m.as_ref().eval(s.light, s.view) * std::f32::consts::PI;
        for c in 0..3 {
            let (a, t) = (f[c] as f64, s.value[c] as f64);
            assert!(a.is_finite(), "model value {a} at {s:?}");
            num[c] += (a - t).powi(2);
            den[c] += t * t;
            rel[c].push((a - t).abs() / t.max(1e-12));
        }
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(|a, b| a.total_cmp(b));
        let n = v.len();
        if n % 2 == 1 {
            v[n / 2]
        } else {
            0.5 * (v[n / 2 - 1] + v[n / 2])
        }
    };
    Metrics {
        rel_rms: [0, 1, 2].map(|c| (num[c] / den[c]).sqrt()),
        median_rel: [0, 1, 2].map(|c| median(&mut rel[c])),
        pairs: pairs.len(),
    }
}

/// Held-out pairs with both directions within 75 degrees of the normal.
fn inside_75(pairs: &[BrdfSample]) -> Vec<BrdfSample> {
    let c75 = 75f32.to_radians().cos();
    pairs
        .iter()
        .filter(|s| s.light.z >= c75 && s.view.z >= c75)
        .cloned()
        .collect()
}

fn fmt3(v: [f64; 3]) -> String {
    format!("{:.3} {:.3} {:.3}", v[0], v[1], v[2])
}

struct Row {
    name: String,
    fit: FitReport,
    all: Metrics,
    inside: Metrics,
}

fn fit_all() -> Vec<Row> {
    let train = load("samples.csv");
    let held = load("heldout.csv");
    assert_eq!(train.len(), 3, "three materials in samples.csv");
    let mut rows = Vec::new();
    for ((name, s), (hname, h)) in train.iter().zip(&held) {
        assert_eq!(name, hname, "materials in the same order in both files");
        assert_eq!(h.len(), 500, "{name}: 500 held-out pairs");
        let fit = fit_material(name, s, &FitOptions::default()).unwrap();
        let all = metrics(&fit.brdf, h);
        let inside = metrics(&fit.brdf, &inside_75(h));
        let b = &fit.brdf;
        let (re, sp) = (&b.lobes[0], &b.lobes[1]);
        eprintln!(
            "{name}: {} samples, training rms {:.3} (relative), rms_abs {:.4}\n  rho_d [{:.3} {:.3} {:.3}]  retro rho [{:.3} {:.3} {:.3}] cxy {:.3} n {:.2}  spec rho [{:.3} {:.3} {:.3}] cxy {:.4} n {:.1} +- {:.1}\n  held-out all ({}): rel RMS {}  median rel {}\n  held-out <=75 deg ({}): rel RMS {}  median rel {}",
            s.len(), fit.rms, fit.rms_abs,
            b.rho_d.x, b.rho_d.y, b.rho_d.z, re.rho.x, re.rho.y, re.rho.z, re.cxy, re.n,
            sp.rho.x, sp.rho.y, sp.rho.z, sp.cxy, sp.n, fit.stderr.lobes[1].n,
            all.pairs, fmt3(all.rel_rms), fmt3(all.median_rel), inside.pairs, fmt3(inside.rel_rms), fmt3(inside.median_rel),
        );
        rows.push(Row {
            name: name.clone(),
            fit,
            all,
            inside,
        });
    }
    rows
}

/// Achieved numbers (worst channel), with about 10% margin: training rms (coverage-weighted, the
/// default fit), held-out relative RMS (all pairs, <= 75 degrees), held-out median relative error
/// (all pairs, <= 75 degrees).
#[test]
fn fits_of_mitsuba_samples_predict_heldout_pairs() {
    let expect: [(&str, f64, [f64; 2], [f64; 2]); 3] = [
        ("plastic_a010", 0.24, [0.85, 0.78], [0.066, 0.052]),
        ("plastic_a030", 0.23, [0.88, 0.41], [0.038, 0.030]),
        ("dark_grazing", 0.29, [0.97, 0.85], [0.148, 0.125]),
    ];
    let rows = fit_all();
    for (row, (name, rms, rel_rms, median)) in rows.iter().zip(expect) {
        assert_eq!(row.name, name);
        let f = &row.fit;
        assert!(f.rms < rms * 1.1, "{name}: training rms {}", f.rms);
        assert!(
            f.rms > 0.05,
            "{name}: training rms {} cannot be below the misfit of GGX/Fresnel shapes",
            f.rms
        );
        assert!(
            row.all.worst_rms() < rel_rms[0] * 1.1,
            "{name}: held-out relative RMS {:?}",
            row.all.rel_rms
        );
        assert!(
            row.inside.worst_rms() < rel_rms[1] * 1.1,
            "{name}: held-out <=75 relative RMS {:?}",
            row.inside.rel_rms
        );
        assert!(
            row.all.worst_median() < median[0] * 1.1,
            "{name}: held-out median {:?}",
            row.all.median_rel
        );
        assert!(
            row.inside.worst_median() < median[1] * 1.1,
            "{name}: held-out <=75 median {:?}",
            row.inside.median_rel
        );
        assert!(
            row.fit.brdf.is_energy_conserving(),
            "{name}: {:?}",
            row.fit.brdf
        );
    }
    // the typical pair of the rough plastics is predicted within 10%
    for row in &rows[..2] {
        assert!(
            row.all.worst_median() < 0.10,
            "{}: {:?}",
            row.name,
            row.all.median_rel
        );
    }
}

/// What Lafortune can represent at all: fits to the held-out pairs themselves, with the default
/// relative residuals and with near-absolute ones (`rel_floor` 20, which minimises the
/// relative-RMS metric). Neither reaches 10% relative RMS on the rough plastics.
#[test]
fn representability_bound_from_fitting_the_heldout_pairs() {
    let held = load("heldout.csv");
    let expect_best_rms = [0.67, 0.23, 0.76];
    for ((name, h), bound) in held.iter().zip(expect_best_rms) {
        let mut best = (f64::INFINITY, f64::INFINITY);
        for floor in [0.05, 20.0] {
            let fit = fit_material(
                name,
                h,
                &FitOptions {
                    rel_floor: floor,
                    ..FitOptions::plain()
                },
            )
            .unwrap();
            let all = metrics(&fit.brdf, h);
            let inside = metrics(&fit.brdf, &inside_75(h));
            eprintln!(
                "{name} bound, rel_floor {floor}: all rel RMS {} median {} | <=75 deg rel RMS {} median {}",
                fmt3(all.rel_rms), fmt3(all.median_rel), fmt3(inside.rel_rms), fmt3(inside.median_rel)
            );
            best = (best.0.min(all.worst_rms()), best.1.min(all.worst_median()));
        }
        assert!(best.0 < bound * 1.1, "{name}: best relative RMS {}", best.0);
        assert!(
            best.0 > 0.10,
            "{name}: a Lafortune fit reaches relative RMS {} (update docs/BRDF.md)",
            best.0
        );
        eprintln!(
            "{name}: best relative RMS any fit reached {:.3}, best median {:.3}",
            best.0, best.1
        );
    }
}
