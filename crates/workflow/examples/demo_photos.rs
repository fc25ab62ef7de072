//! `igi demo` with other survey photographs: `cargo run --release -p igi-workflow --example
//! demo_photos -- OUT WIDTH HEIGHT SPP` runs the embedded default with photographs of
//! WIDTH x HEIGHT at SPP samples per pixel (the defaults are 480 320 48) and prints the rho_d
//! MAE per channel (per texel and over the surface), the photograph, solve and total seconds and the re-lighting RMSE as JSON.
//! From the environment, `DEBLUR=N` sets the rounds of footprint deblurring (the demo's default: 4) and
//! `SOLVE_SPP=a,b,c` the solve's samples per iteration (one iteration per entry).
//! docs/SOLVER.md ("Error against run time") reports the runs.

use igi_reflect::solver::NoProgress;
use igi_workflow::demo::{run_demo, DemoOptions};
use std::path::PathBuf;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: demo_photos OUT WIDTH HEIGHT SPP";
    assert_eq!(args.len(), 4, "{usage}");
    let number = |s: &str| -> u32 { s.parse().unwrap_or_else(|_| panic!("{usage}: `{s}`")) };
    let mut opts = DemoOptions {
        photo_width: number(&args[1]),
        photo_height: number(&args[2]),
        photo_spp: number(&args[3]),
        ..DemoOptions::default()
    };
    if let Ok(v) = std::env::var("DEBLUR") {
        opts.deblur = v.parse().expect("DEBLUR takes a number of rounds");
    }
    if let Ok(v) = std::env::var("SOLVE_SPP") {
        opts.solve_spp = v
            .split(',')
            .map(|x| x.parse().expect("SOLVE_SPP takes numbers a,b,c"))
            .collect();
        opts.iterations = opts.solve_spp.len() as u32;
    }
    let out = PathBuf::from(&args[0]);
    let r =
        run_demo(&out, &opts, &NoProgress, &|s| eprintln!("{s}")).unwrap_or_else(|e| panic!("{e}"));
    let summary = serde_json::json!({
        "albedo_mae": r.albedo_mae,
        "albedo_surface_mae": r.albedo_surface_mae,
        "photo_seconds": r.photo_seconds,
        "solve_seconds": r.solve_seconds,
        "total_seconds": r.total_seconds,
        "relight_rmse": r.relight.rmse,
    });
    println!("{summary}");
}
