//! The albedo error of an existing result folder against a truth scene over the same
//! geometry: `cargo run --release -p igi-reflect --example truth_error -- RESULT_DIR
//! TRUTH_SCENE`. Prints the texel MAE and the surface MAE per channel (`igi_reflect::truth`:
//! texels, or area-uniform points of the surface, whose texel two photographs saw), as JSON. For
//! results of older builds, whose reports lack the surface MAE (docs/SOLVER.md, "Two errors").

use igi_reflect::truth::{surface_error, texel_error, truth_from_scene};
use igi_reflect::SolveResult;
use std::path::Path;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    assert_eq!(args.len(), 2, "usage: truth_error RESULT_DIR TRUTH_SCENE");
    let result = SolveResult::load(Path::new(&args[0])).unwrap_or_else(|e| panic!("{e}"));
    let (scene, _) = igi_render::Scene::load(Path::new(&args[1])).unwrap_or_else(|e| panic!("{e}"));
    let truth = truth_from_scene(&result.parts, &scene);
    let all = vec![true; result.parts.len()];
    let (texel, _) = texel_error(&result, &truth, &all);
    let (surface, _) = surface_error(&result, &truth, &all);
    let summary = serde_json::json!({
        "texel_mae": texel,
        "surface_mae": surface,
        "surface_points": truth.points.len(),
    });
    println!("{summary}");
}
