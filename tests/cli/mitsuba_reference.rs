//! igi's path tracer against Mitsuba 3 on the outdoor reference scene
//! (`datasets/fixtures/outdoor`, written by `datasets/mitsuba/outdoor_reference.py`): a diffuse
//! ground, colonnade and textured wall under a lat-long sky and a 0.53 degree sun, max_depth 4
//! (igi `--indirect 2`), box filter, 128 x 128.
//!
//! Pass criteria: mean radiance within 1 %, and per-pixel RMSE at most 1.2 times the RMSE that
//! the two images' Monte-Carlo noise explains, sqrt(mean(se_igi^2 + se_mitsuba^2)).

use igi_render::{compare_images, render_image, RenderOptions, Scene};
use std::path::Path;

#[test]
fn igi_matches_mitsuba_on_the_outdoor_reference() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("datasets/fixtures/outdoor");
    let reference = dir.join("reference.exr");
    assert!(
        reference.exists(),
        "{} is missing (run datasets/mitsuba/outdoor_reference.py)",
        reference.display()
    );
    let (scene, lighting) = Scene::load(&dir.join("scene.toml")).unwrap();
    let camera = igi_camera::Camera::load(&dir.join("camera.json")).unwrap();
    let ref_img = igi_imaging::read_image(&reference).unwrap();
    let ref_se = igi_imaging::read_image(&dir.join("reference_stderr.exr")).unwrap();
    let opts = RenderOptions {
        spp: 256,
        seed: 2024,
        indirect: 2,
        russian_roulette: false,
        stratified: false,
        adaptive: false,
    };
    let t = std::time::Instant::now();
    let out = render_image(&scene, &lighting, &camera, &opts, &|_| {}).unwrap();
    let secs = t.elapsed().as_secs_f64();
    assert_eq!(out.bad_samples, 0);
    let c = compare_images(&out.mean, &ref_img, Some(&out.stderr), Some(&ref_se)).unwrap();
    let noise = c.noise_rmse.unwrap();
    println!(
        "igi {} spp in {secs:.1} s vs Mitsuba: mean {:.6} vs {:.6} ({:+.3} %), RMSE {:.5e} vs noise-explained {:.5e} (ratio {:.3}), PSNR {:.2} dB",
        opts.spp,
        c.mean_a,
        c.mean_b,
        100.0 * c.relative_mean_difference,
        c.rmse,
        noise,
        c.rmse / noise,
        c.psnr_db
    );
    assert!(
        c.relative_mean_difference.abs() < 0.01,
        "mean differs by {:.3} %",
        100.0 * c.relative_mean_difference
    );
    assert!(
        c.rmse <= 1.2 * noise,
        "RMSE {} > 1.2 x noise-explained {}",
        c.rmse,
        noise
    );
    // Per channel means too (a colour bias would hide in the grey mean).
    for ch in 0..3 {
        let m = |img: &igi_imaging::HdrImage| {
            img.pixels.iter().map(|p| p[ch] as f64).sum::<f64>() / img.pixels.len() as f64
        };
        let (a, b) = (m(&out.mean), m(&ref_img));
        assert!(((a - b) / b).abs() < 0.01, "channel {ch}: {a} vs {b}");
    }
}
