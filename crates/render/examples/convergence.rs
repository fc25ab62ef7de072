//! Error against run time: renders the outdoor reference scene at 1, 2, 4, ..., 256 spp and
//! prints the RMSE to the Mitsuba reference with the wall time of each render.
//!
//! `cargo run --release -p igi-render --example convergence [-- FIXTURE_DIR [REFERENCE.exr]]`
//! (default: `datasets/fixtures/outdoor` and its `reference.exr`).

use igi_render::{compare_images, render_image, RenderOptions, Scene};
use std::path::PathBuf;
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let dir = args.get(1).map(PathBuf::from).unwrap_or_else(|| {
        PathBuf::from(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../datasets/fixtures/outdoor"
        ))
    });
    let reference = args
        .get(2)
        .map(PathBuf::from)
        .unwrap_or_else(|| dir.join("reference.exr"));
    let (scene, lighting) = Scene::load(&dir.join("scene.toml")).unwrap_or_else(|e| panic!("{e}"));
    let camera =
        igi_camera::Camera::load(&dir.join("camera.json")).unwrap_or_else(|e| panic!("{e}"));
    let ref_img = igi_imaging::read_image(&reference).unwrap_or_else(|e| panic!("{e}"));
    let ref_se = igi_imaging::read_image(&reference.with_file_name("reference_stderr.exr")).ok();
    println!("threads: {}", rayon::current_num_threads());
    println!("| spp | wall s | Mrays/s | RMSE | noise-explained RMSE | ratio | rel. mean diff | PSNR dB |");
    println!("|---:|---:|---:|---:|---:|---:|---:|---:|");
    let mut spp = 1;
    while spp <= 256 {
        let opts = RenderOptions {
            spp,
            seed: 7,
            indirect: 2,
            russian_roulette: false,
            stratified: false,
            adaptive: false,
        };
        let t = Instant::now();
        let out = render_image(&scene, &lighting, &camera, &opts, &|_| {}).unwrap();
        let secs = t.elapsed().as_secs_f64();
        let c = compare_images(&out.mean, &ref_img, Some(&out.stderr), ref_se.as_ref()).unwrap();
        let noise = c.noise_rmse.unwrap_or(f64::NAN);
        println!(
            "| {spp} | {secs:.3} | {:.2} | {:.4e} | {:.4e} | {:.3} | {:+.3}% | {:.2} |",
            out.rays as f64 / secs / 1e6,
            c.rmse,
            noise,
            c.rmse / noise,
            100.0 * c.relative_mean_difference,
            c.psnr_db
        );
        spp *= 2;
    }
}
