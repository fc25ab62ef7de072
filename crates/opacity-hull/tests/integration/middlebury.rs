//! Real data: the Middlebury dinoSparseRing (15 good views, 640 x 480), imported with the
//! README's mask recipe and carved at 256 cells per axis.

use glam::DVec3;
use igi_camera::Rig;
use igi_opacity_hull::carve::{carve, CellGrid, KEPT};
use igi_opacity_hull::hull::{
    carve_hull, leave_one_out, plot_volume_curves, reproject, volume_curves,
};
use igi_opacity_hull::views::{load_views, MatteOptions, View};
use igi_opacity_hull::warp::{nearest_view, warp_view};

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

/// The dino's foot runs out of the frames (band votes keep it): the votes by boxes carve what
/// the rule cell by cell carves.
#[test]
fn dino_band_votes_by_boxes_equal_the_votes_cell_by_cell() {
    let (_dir, rig, views) = dino();
    let refs: Vec<&View> = views.iter().collect();
    let (min, max) = bbox(&rig);
    for resolution in [64, 96] {
        let voted = crate::thin_parts::assert_votes_by_boxes_equal_votes_by_cells(
            &refs, min, max, resolution,
        );
        assert!(voted > 10, "the dino exercises the votes: {voted}");
    }
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

/// Fig. 12 at a CI-sized 64 cells per axis: 30 seeded random orders. Every curve falls
/// monotonically to 1 (the hull of all views); its first value is the volume one silhouette
/// keeps; the final cell count agrees with the octree carver's.
#[test]
fn dino_volume_against_views() {
    let (_d, rig, views) = dino();
    let (lo, hi) = bbox(&rig);
    let refs: Vec<&View> = views.iter().collect();
    let curves = volume_curves(&refs, lo, hi, 64, 30, 7);
    assert_eq!(curves, volume_curves(&refs, lo, hi, 64, 30, 7), "seeded");
    let grid = CellGrid::new(lo, hi, 64);
    let kept = |vs: &[&View]| carve(&grid, vs).iter().filter(|&&c| c == KEPT).count();
    let all = kept(&refs) as f64;
    let singles: Vec<f64> = refs.iter().map(|v| kept(&[*v]) as f64 / all).collect();
    assert_eq!(curves.len(), 30);
    for c in &curves {
        assert_eq!(c.len(), 15);
        assert!(c.windows(2).all(|w| w[1] <= w[0]), "{c:?}");
        assert_eq!(c[14], 1.0);
        assert!(singles.contains(&c[0]), "{} not a one-view volume", c[0]);
    }
    let mean: Vec<f64> = (0..15)
        .map(|k| curves.iter().map(|c| c[k]).sum::<f64>() / 30.0)
        .collect();
    eprintln!("mean volume / final after 1..15 views: {mean:.3?}");
    // measured: 2.617 after one view, 1.372 after five, 1.014 after fourteen; the mean falls
    // with every view added and the last view changes it by less than 2 %
    assert!(mean.windows(2).all(|w| w[1] < w[0]), "{mean:?}");
    assert!(mean[0] > 2.0 && mean[13] < 1.02, "{mean:?}");
}

/// The Fig. 12 plot at the carving resolution (256 cells per axis), written to
/// `target/hull_fig12_dino_volume.png` (`cargo test -p igi-opacity-hull --test integration middlebury:: --
/// --ignored --nocapture`).
#[test]
#[ignore = "writes the Fig. 12 plot at 256 cells per axis into target/"]
fn dino_fig12_plot() {
    let (_d, rig, views) = dino();
    let (lo, hi) = bbox(&rig);
    let refs: Vec<&View> = views.iter().collect();
    let curves = volume_curves(&refs, lo, hi, 256, 30, 1);
    let path = igi_testkit::repo_root().join("target/hull_fig12_dino_volume.png");
    plot_volume_curves(&path, &curves).unwrap();
    let mean: Vec<f64> = (0..curves[0].len())
        .map(|k| curves.iter().map(|c| c[k]).sum::<f64>() / curves.len() as f64)
        .collect();
    let spread: Vec<f64> = (0..curves[0].len())
        .map(|k| {
            let v = curves.iter().map(|c| c[k]);
            v.clone().fold(0.0, f64::max) - v.fold(f64::INFINITY, f64::min)
        })
        .collect();
    eprintln!(
        "mean volume / final: {mean:.3?}\nmax - min over orders: {spread:.3?}\n-> {}",
        path.display()
    );
    assert!(std::fs::metadata(&path).unwrap().len() > 1000);
}

/// One held-out view: the hull built from the other 14 views rendered at its camera, and the
/// nearest of those 14 photos warped to it through the same hull, each against its photo
/// (PSNR, peak 1, inside its silhouette; pixels either leaves empty count as black).
struct HeldOut {
    view: String,
    render_db: f64,
    warp_db: f64,
    nearest: String,
    /// Fractions of the silhouette the render covers (alpha > 0.5) and the warp fills.
    render_cover: f64,
    warp_cover: f64,
}

fn held_out(dir: &std::path::Path, rig: &Rig, views: &[View], held: &str) -> HeldOut {
    use igi_opacity_hull::build::{build, load_model, BuildOptions};
    use igi_opacity_hull::render::{render, RenderOptions};
    let mut others = rig.clone();
    others.views.retain(|v| v.id != held);
    let rig_path = dir.join(format!("rig-without-{held}.toml"));
    others.save(&rig_path).unwrap();
    let out = dir.join(format!("hull-without-{held}"));
    let opts = BuildOptions {
        volume_orders: 1,
        volume_resolution: 16,
        ..BuildOptions::default()
    };
    build(&Rig::load(&rig_path).unwrap(), &out, opts, &mut |_| {}).unwrap();
    let target = views.iter().find(|v| v.id == held).unwrap();
    let (image, alpha) = render(
        &load_model(&out).unwrap(),
        &target.camera,
        RenderOptions::default(),
    );
    let mesh = igi_geometry::read_ply(&out.join("hull.ply")).unwrap();
    let (lo, hi) = bbox(rig);
    let refs: Vec<&View> = views.iter().filter(|v| v.id != held).collect();
    let near = nearest_view(&refs, &target.camera, (lo + hi) / 2.0).unwrap();
    let cell = ((hi - lo) / 256.0).max_element();
    let warped = warp_view(&mesh, near, &target.camera, 1.5 * cell);
    let inside = &target.silhouette.data;
    let n = target.silhouette.count() as f64;
    let count = |f: &dyn Fn(usize) -> bool| {
        (0..inside.len()).filter(|&i| inside[i] && f(i)).count() as f64 / n
    };
    HeldOut {
        render_cover: count(&|i| alpha[i] > 0.5),
        warp_cover: count(&|i| warped.valid.data[i]),
        view: held.to_string(),
        render_db: image.psnr_inside(&target.photo, inside, 1.0).unwrap(),
        warp_db: warped
            .image
            .psnr_inside(&target.photo, inside, 1.0)
            .unwrap(),
        nearest: near.id.clone(),
    }
}

fn held_out_views(ids: &[&str]) -> Vec<HeldOut> {
    let (d, rig, views) = dino();
    let res: Vec<HeldOut> = ids
        .iter()
        .map(|id| held_out(d.path(), &rig, &views, id))
        .collect();
    for r in &res {
        eprintln!(
            "held out {}: render {:.2} dB (covers {:.3}), nearest photo {} warped {:.2} dB (covers {:.3})",
            r.view, r.render_db, r.render_cover, r.nearest, r.warp_db, r.warp_cover
        );
    }
    res
}

/// Issue 12: from a held-out view, `igi hull render`'s blending beats the nearest input photo
/// warped to it. Three views spread over the ring (CI-sized); every view in the ignored test.
#[test]
fn dino_held_out_views_beat_the_nearest_photo_warped() {
    for r in held_out_views(&["dinoSR0003", "dinoSR0008", "dinoSR0013"]) {
        assert!(
            r.render_db > r.warp_db,
            "{}: render {:.2} dB, warped {} {:.2} dB",
            r.view,
            r.render_db,
            r.nearest,
            r.warp_db
        );
    }
}

/// Every one of the 15 views held out in turn (`cargo test -p igi-opacity-hull --test
/// middlebury -- --ignored --nocapture`; numbers in docs/OPACITY_HULL.md).
#[test]
#[ignore = "about 15 hull builds; run by hand for the docs table"]
fn dino_every_view_held_out() {
    let (_d, rig, _views) = dino();
    let ids: Vec<String> = rig.views.iter().map(|v| v.id.clone()).collect();
    let refs: Vec<&str> = ids.iter().map(String::as_str).collect();
    let res = held_out_views(&refs);
    let wins = res.iter().filter(|r| r.render_db > r.warp_db).count();
    let mean = |f: fn(&HeldOut) -> f64| res.iter().map(f).sum::<f64>() / res.len() as f64;
    eprintln!(
        "render beats the warped nearest photo in {wins} of {}; mean render {:.2} dB, mean warp {:.2} dB",
        res.len(),
        mean(|r| r.render_db),
        mean(|r| r.warp_db)
    );
    assert_eq!(wins, res.len());
}
