//! `igi hull render` speed and the carving resolution's error against run time, on the
//! Middlebury dino (docs/BENCHMARKS.md, docs/OPACITY_HULL.md).
//!
//!     cargo bench -p igi-opacity-hull --bench hull_render
//!
//! Set-up imports the dino, builds its hull folder at 256 cells per axis and loads it; the
//! frame is a 512 x 512 camera at input view dinoSR0008's pose (its focal length, the object
//! centred). Before the timed part it prints, per carving resolution, the carve time and the
//! hull's reprojection IoU against the 15 silhouettes.

use criterion::{criterion_group, criterion_main, Criterion};
use glam::DVec3;
use igi_camera::Rig;
use igi_opacity_hull::build::{build, load_model, BuildOptions};
use igi_opacity_hull::hull::{carve_hull, reproject};
use igi_opacity_hull::render::{render, RenderOptions};
use igi_opacity_hull::views::{load_views, MatteOptions, View};
use std::time::Instant;

fn carving_table(rig: &Rig, views: &[View]) {
    let (lo, hi) = (
        DVec3::from_array(rig.object.bbox_min),
        DVec3::from_array(rig.object.bbox_max),
    );
    let refs: Vec<&View> = views.iter().collect();
    eprintln!("| cells per axis | carve + mesh (s) | triangles | min IoU | mean IoU |");
    for res in [64, 128, 256, 384, 512] {
        let t = Instant::now();
        let hull = carve_hull(&rig.path, &refs, lo, hi, res).unwrap();
        let secs = t.elapsed().as_secs_f64();
        let ious: Vec<f64> = views.iter().map(|v| reproject(&hull.mesh, v).iou).collect();
        let min = ious.iter().cloned().fold(1.0, f64::min);
        let mean = ious.iter().sum::<f64>() / ious.len() as f64;
        eprintln!(
            "| {res} | {secs:.2} | {} | {min:.4} | {mean:.4} |",
            hull.mesh.triangle_count()
        );
    }
}

fn bench(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let rig_dir = dir.path().join("rig");
    igi_opacity_hull::middlebury::import(
        &igi_testkit::shared_data("multiview/dinoSparseRing"),
        &rig_dir,
    )
    .unwrap();
    let rig = Rig::load(&rig_dir.join("rig.toml")).unwrap();
    let views = load_views(&rig, MatteOptions::default()).unwrap();
    carving_table(&rig, &views);
    let out = dir.path().join("hull");
    build(&rig, &out, BuildOptions::default(), &mut |_| {}).unwrap();
    let model = load_model(&out).unwrap();
    let mut cam = views
        .iter()
        .find(|v| v.id == "dinoSR0008")
        .unwrap()
        .camera
        .clone();
    let centre =
        (DVec3::from_array(rig.object.bbox_min) + DVec3::from_array(rig.object.bbox_max)) / 2.0;
    let at = cam.project(centre).unwrap();
    cam.intrinsics.cx += 255.5 - at.x;
    cam.intrinsics.cy += 255.5 - at.y;
    (cam.width, cam.height) = (512, 512);
    let (_, alpha) = render(&model, &cam, RenderOptions::default());
    eprintln!(
        "{} surfels; the frame covers {} pixels",
        model.surfels.len(),
        alpha.iter().filter(|a| **a > 0.5).count()
    );
    let mut g = c.benchmark_group("hull_render");
    g.sample_size(20);
    g.bench_function("dino_512x512", |b| {
        b.iter(|| render(&model, &cam, RenderOptions::default()))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
