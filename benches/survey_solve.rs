//! The default solve against `--atlas 512` on a large survey rendered by Mitsuba 3: albedo error
//! against run time (issue 37 item 1; docs/BENCHMARKS.md, "The default solve on a large
//! survey").
//!
//! The survey is made by `python3 datasets/mitsuba/large_survey.py --fine-contrast 0.25 --out
//! DIR` (one mesh of 36,375 triangles over 44 x 44 m, 32 photographs of 512 x 384, the true
//! albedo beside them) and named by `IGI_SURVEY` (default `/tmp/survey_large_c25`; the survey
//! whose photographs are about as noisy as a camera's adds `--fine-contrast 0.1 --spp 256`,
//! where the default reaches MAE <= 0.01 within 60 s). Each run is
//! `igi solve SURVEY --truth SURVEY/truth/scene.toml` with the defaults (4 iterations, adaptive
//! samples), once with `--atlas auto` (the default: a coarse stage, then one iteration on the
//! chosen atlases) and once with `--atlas 512`; `IGI_BENCH_RUNS=auto` or `=512` runs one, and
//! `IGI_BENCH_RUNS=lattice` runs only the default with `--shading-lattice false` (its fine
//! iteration traced at every texel: about 20 minutes).
//! Prints per iteration the cumulative time and the albedo MAE per texel and over the surface,
//! and the whole run's wall time (loading, atlases, truth and writing included); writes
//! `target/survey_solve.json` and the error-against-time plot `target/survey_solve.png`.
//!
//! Run: `cargo bench --bench survey_solve`.
use igi_reflect::solver::NoProgress;
use igi_reflect::{SolveOptions, SolveReport};
use igi_workflow::solve::{AtlasRequest, SolveRequest};
use std::path::PathBuf;
use std::time::Instant;

fn main() {
    let survey = PathBuf::from(
        std::env::var("IGI_SURVEY").unwrap_or_else(|_| "/tmp/survey_large_c25".into()),
    );
    assert!(
        survey.join("survey.toml").is_file(),
        "no survey at {} (make it with `python3 datasets/mitsuba/large_survey.py --fine-contrast 0.25 --out {}`, or set IGI_SURVEY)",
        survey.display(),
        survey.display()
    );
    let which = std::env::var("IGI_BENCH_RUNS").unwrap_or_default();
    // the third (the fine iteration traced at every texel) runs only when IGI_BENCH_RUNS names it
    let runs: Vec<(&str, AtlasRequest, bool)> = [
        (
            "--atlas auto (default)",
            AtlasRequest::Auto { max: 2048 },
            true,
        ),
        ("--atlas 512", AtlasRequest::Fixed(512), true),
        (
            "--shading-lattice false",
            AtlasRequest::Auto { max: 2048 },
            false,
        ),
    ]
    .into_iter()
    .filter(|(name, _, lattice)| {
        if which.is_empty() {
            *lattice
        } else {
            name.contains(which.as_str())
        }
    })
    .collect();
    let mut reports: Vec<(String, SolveReport, f64)> = Vec::new();
    for (name, atlas, lattice_shading) in runs {
        let out = tempfile::tempdir().expect("a temporary folder");
        let request = SolveRequest {
            survey: survey.clone(),
            output: out.path().join("result"),
            atlas,
            options: SolveOptions {
                adaptive_spp: true,
                smooth_shading: true,
                lattice_shading,
                ..SolveOptions::default()
            },
            truth: Some(survey.join("truth").join("scene.toml")),
            restart: false,
        };
        let t0 = Instant::now();
        let result = igi_workflow::solve::solve(&request, &NoProgress).expect("the solve");
        let wall = t0.elapsed().as_secs_f64();
        print_run(name, &result.report, wall);
        reports.push((name.to_string(), result.report, wall));
    }
    write_outputs(&reports);
}

/// One line per iteration and the run's wall time.
fn print_run(name: &str, report: &SolveReport, wall: f64) {
    let f = |m: Option<[f32; 3]>| {
        m.map(|m| format!("{:.4} {:.4} {:.4}", m[0], m[1], m[2]))
            .unwrap_or_else(|| "-".into())
    };
    println!("{name}:");
    for r in &report.iterations {
        println!(
            "  iteration {}{}: {} spp, {:.1} s, rho_d MAE {} (over the surface {})",
            r.iteration,
            if r.coarse { " (coarse atlases)" } else { "" },
            r.spp,
            r.cumulative_s,
            f(r.truth_mae),
            f(r.truth_surface_mae)
        );
    }
    for p in &report.parts {
        println!(
            "  part {}: {} texels per side, {} covered, texel {:.4} m",
            p.name, p.resolution, p.covered_texels, p.texel_size_m
        );
    }
    println!("  whole run {wall:.1} s");
}

/// `target/survey_solve.json` and `target/survey_solve.png`.
fn write_outputs(reports: &[(String, SolveReport, f64)]) {
    let target = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target");
    let json: Vec<serde_json::Value> = reports
        .iter()
        .map(|(name, r, wall)| {
            serde_json::json!({ "run": name, "wall_s": wall, "iterations": r.iterations, "parts": r.parts })
        })
        .collect();
    let text = serde_json::to_string_pretty(&json).expect("json");
    std::fs::write(target.join("survey_solve.json"), text).expect("target/survey_solve.json");
    let runs: Vec<(String, &SolveReport)> =
        reports.iter().map(|(n, r, _)| (n.clone(), r)).collect();
    igi_reflect::plot::plot_runs(&runs, &target.join("survey_solve.png")).expect("the plot");
    println!("wrote target/survey_solve.json and target/survey_solve.png");
}
