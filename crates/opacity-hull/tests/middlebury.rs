//! Real data: the Middlebury dinoSparseRing (15 good views, 640 x 480), imported with the
//! README's mask recipe and carved at 256 cells per axis.

use glam::DVec3;
use igi_imaging::Rig;
use igi_opacity_hull::hull::{carve_hull, leave_one_out, reproject};
use igi_opacity_hull::views::{load_views, MatteOptions, View};

fn dino() -> (tempfile::TempDir, Rig, Vec<View>) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("rig");
    let report = igi_opacity_hull::middlebury::import(
        &igi_testkit::shared_data("multiview/dinoSparseRing"),
        &out,
    )
    .unwrap();
    assert_eq!(report.views, 15);
    assert_eq!(report.skipped, vec!["dinoSR0006.png".to_string()]);
    assert!(
        report.max_rotation_correction > 0.0 && report.max_rotation_correction < 1e-4,
        "{}",
        report.max_rotation_correction
    );
    let rig = Rig::load(&out.join("rig.toml")).unwrap();
    let views = load_views(&rig, MatteOptions::default()).unwrap();
    (dir, rig, views)
}

fn bbox(rig: &Rig) -> (DVec3, DVec3) {
    (
        DVec3::from_array(rig.object.bbox_min),
        DVec3::from_array(rig.object.bbox_max),
    )
}

#[test]
fn dino_hull_reprojects_onto_every_silhouette() {
    let (_d, rig, views) = dino();
    let (lo, hi) = bbox(&rig);
    let refs: Vec<&View> = views.iter().collect();
    let hull = carve_hull(&rig.path, &refs, lo, hi, 256).unwrap();
    let reps: Vec<_> = views.iter().map(|v| reproject(&hull.mesh, v)).collect();
    for r in &reps {
        eprintln!("{}: IoU {:.4} uncovered {:.4}", r.view, r.iou, r.uncovered);
    }
    let min = reps.iter().map(|r| r.iou).fold(1.0, f64::min);
    let mean = reps.iter().map(|r| r.iou).sum::<f64>() / reps.len() as f64;
    eprintln!(
        "IoU min {min:.4} mean {mean:.4}, {} triangles, volume {:.3e}",
        hull.mesh.triangle_count(),
        hull.volume()
    );
    assert!(min >= 0.97, "min IoU {min}");
    assert!(mean >= 0.98, "mean IoU {mean}");
}

#[test]
fn dino_leave_one_out() {
    let (_d, rig, views) = dino();
    let (lo, hi) = bbox(&rig);
    let reps = leave_one_out(&rig.path, &views, lo, hi, 256).unwrap();
    for r in &reps {
        eprintln!(
            "held out {}: IoU {:.4} uncovered {:.4}",
            r.view, r.iou, r.uncovered
        );
    }
    let worst = reps.iter().map(|r| r.uncovered).fold(0.0, f64::max);
    let mean = reps.iter().map(|r| r.iou).sum::<f64>() / reps.len() as f64;
    eprintln!("leave-one-out: worst uncovered {worst:.4}, mean IoU {mean:.4}");
    assert!(worst <= 0.02, "worst uncovered {worst}");
    assert!(mean >= 0.93, "mean IoU {mean}");
}
