//! Matusik et al.'s rig size: 6 cameras x 36 turntable positions = 216 views, of a sphere whose
//! silhouettes are exact (each pixel's ray tested against the sphere), at 40 x 30 pixels.

use glam::DVec3;
use igi_camera::{Camera, Rig};
use igi_imaging::Mask;
use igi_opacity_hull::build::{build, load_model, BuildOptions};
use igi_opacity_hull::carve::MAX_VIEWS;
use igi_opacity_hull::hull::volume_curves;
use igi_opacity_hull::views::{load_views, MatteOptions, View};
use igi_opacity_hull::HullError;
use std::fmt::Write as _;
use std::path::Path;

const RADIUS: f64 = 0.05;

/// A turntable rig of `cameras` elevations x `positions` turns around a sphere at the origin;
/// with `images`, every view's photo and exact mask are written too.
fn sphere_rig(dir: &Path, cameras: usize, positions: usize, images: bool) -> Rig {
    let mut toml =
        String::from("[object]\nbbox_min = [-0.08, -0.08, -0.08]\nbbox_max = [0.08, 0.08, 0.08]\n");
    for c in 0..cameras {
        let elevation = (-10.0 + 60.0 * c as f64 / (cameras.max(2) - 1) as f64).to_radians();
        for p in 0..positions {
            let azimuth = (360.0 * p as f64 / positions as f64).to_radians();
            let eye = 0.4
                * DVec3::new(
                    elevation.cos() * azimuth.cos(),
                    elevation.cos() * azimuth.sin(),
                    elevation.sin(),
                );
            let cam = Camera::look_at(eye, DVec3::ZERO, 40, 30, 30.0).unwrap();
            let id = format!("cam{c}-pos{p:02}");
            if images {
                std::fs::create_dir_all(dir.join("cameras")).unwrap();
                cam.save(&dir.join(format!("cameras/{id}.json"))).unwrap();
                sphere_mask(&cam)
                    .save_png(&dir.join(format!("{id}.png")))
                    .unwrap();
            }
            write!(
                toml,
                "[[view]]\nid = \"{id}\"\ncamera = \"cameras/{id}.json\"\nphoto = \"{id}.png\"\nmask = \"{id}.png\"\n"
            )
            .unwrap();
        }
    }
    let path = dir.join("rig.toml");
    std::fs::write(&path, toml).unwrap();
    Rig::from_toml_str(&std::fs::read_to_string(&path).unwrap(), &path).unwrap()
}

/// Set where the pixel's ray meets the sphere.
fn sphere_mask(cam: &Camera) -> Mask {
    let (w, h) = (cam.width as usize, cam.height as usize);
    let mut img = Mask::new(w, h);
    for y in 0..h {
        for x in 0..w {
            let (o, d) = cam.pixel_ray(x as f64, y as f64);
            let b = o.dot(d);
            if b * b - (o.length_squared() - RADIUS * RADIUS) > 0.0 {
                img.set(x, y, true);
            }
        }
    }
    img
}

#[test]
fn the_papers_216_view_rig_builds() {
    let dir = tempfile::tempdir().unwrap();
    let rig = sphere_rig(dir.path(), 6, 36, true);
    assert_eq!(rig.views.len(), 216);
    let out = dir.path().join("hull");
    let opts = BuildOptions {
        volume_orders: 3,
        volume_resolution: 32,
        ..BuildOptions::default()
    };
    let report = build(&rig, &out, opts, &mut |_| {}).unwrap();
    assert_eq!(report.views.len(), 216);
    // Exact silhouettes: the hull reprojects onto every one of them, and its volume is the
    // sphere's up to the pixels' quantisation: a cell is carved by the nearest pixel, so the
    // radius can move by half a pixel's footprint (0.4 m / 74.6 px / 2 = 2.7 mm of 50 mm).
    assert!(report.iou_min > 0.9, "IoU min {}", report.iou_min);
    let sphere = 4.0 / 3.0 * std::f64::consts::PI * RADIUS.powi(3);
    let half_pixel = 0.5 * 0.4 * (15.0f64.to_radians().tan() / 20.0);
    let (lo, hi) = (1.0 - half_pixel / RADIUS, 1.0 + half_pixel / RADIUS);
    let ratio = report.volume_m3 / sphere;
    assert!(
        (lo.powi(3)..hi.powi(3)).contains(&ratio),
        "hull / sphere volume {ratio} outside [{}, {}]",
        lo.powi(3),
        hi.powi(3)
    );
    // Fig. 12's curves over all 216 views (more than a 64-bit view set): one value per view,
    // never growing, ending at the final volume.
    let views = load_views(&rig, MatteOptions::default()).unwrap();
    let refs: Vec<&View> = views.iter().collect();
    let (min, max) = (DVec3::splat(-0.08), DVec3::splat(0.08));
    for curve in volume_curves(&refs, min, max, 32, 2, 7) {
        assert_eq!(curve.len(), 216);
        assert!(curve.windows(2).all(|w| w[1] <= w[0]), "{curve:?}");
        assert_eq!(curve[215], 1.0);
        assert!(curve[0] > 1.5, "one view leaves a cylinder: {}", curve[0]);
    }
}

#[test]
fn a_rig_of_more_views_than_a_hull_takes_is_refused_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    // No image is written: the refusal must come before any view is read.
    let rig = sphere_rig(dir.path(), 1, MAX_VIEWS + 1, false);
    let out = dir.path().join("hull");
    match build(&rig, &out, BuildOptions::default(), &mut |_| {}) {
        Err(HullError::TooManyViews { views, max, .. }) => {
            assert_eq!((views, max), (MAX_VIEWS + 1, MAX_VIEWS));
        }
        other => panic!("expected TooManyViews, got {other:?}"),
    }
    assert!(!out.exists());
}

/// A capture folder holding its rig and the hull built from it moves as one: `hull.json` names
/// the rig relative to the hull folder, and the moved hull renders the same bytes. A folder
/// naming its rig absolutely (as before) still loads.
#[test]
fn a_capture_folder_moved_as_one_still_renders() {
    let dir = tempfile::tempdir().unwrap();
    let capture = dir.path().join("capture");
    std::fs::create_dir(&capture).unwrap();
    let rig = sphere_rig(&capture, 2, 4, true);
    let opts = BuildOptions {
        volume_orders: 1,
        volume_resolution: 16,
        ..BuildOptions::default()
    };
    build(&rig, &capture.join("hull"), opts, &mut |_| {}).unwrap();
    let manifest = |hull: &Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(hull.join("hull.json")).unwrap()).unwrap()
    };
    assert_eq!(manifest(&capture.join("hull"))["rig"], "../rig.toml");
    let camera = Camera::look_at(DVec3::new(0.3, -0.2, 0.1), DVec3::ZERO, 32, 24, 30.0).unwrap();
    let render = |hull: &Path| {
        let model = load_model(hull).unwrap();
        let (image, alpha) = igi_opacity_hull::render::render(&model, &camera, Default::default());
        assert!(alpha.iter().any(|&a| a > 0.5), "the sphere is in view");
        (image.pixels, alpha)
    };
    let before = render(&capture.join("hull"));
    let moved = dir.path().join("elsewhere/capture");
    std::fs::create_dir(dir.path().join("elsewhere")).unwrap();
    std::fs::rename(&capture, &moved).unwrap();
    assert_eq!(render(&moved.join("hull")), before);
    // a manifest naming the rig by its absolute path, as folders written before did
    let mut m = manifest(&moved.join("hull"));
    m["rig"] = moved.join("rig.toml").to_str().unwrap().into();
    std::fs::write(moved.join("hull/hull.json"), m.to_string()).unwrap();
    assert_eq!(render(&moved.join("hull")), before);
}
