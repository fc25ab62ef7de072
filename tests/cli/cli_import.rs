//! `igi import colmap` end to end: a synthetic COLMAP model (text) in a frame scaled, turned and
//! moved from the scan's, control points seen by its cameras, and the survey folder it writes.

use glam::{DMat3, DVec3};
use igi_camera::{Camera, Distortion, Intrinsics, WorldToCamera};
use igi_formats::ControlObservation;
use igi_import::model::{matrix_to_quat, CameraModel, ColmapCamera, ColmapImage};
use igi_import::ColmapModel;
use igi_testkit::{assert_failed, s, Cli};
use std::path::Path;

fn igi() -> Cli {
    Cli::new(env!("CARGO_BIN_EXE_igi"))
}

/// Four OPENCV cameras 12 m from the origin (scan frame), looking at it.
fn scan_cameras() -> Vec<Camera> {
    (0..4)
        .map(|i| {
            let a = i as f64 * 1.4 + 0.2;
            let eye = DVec3::new(12.0 * a.cos(), 12.0 * a.sin(), 3.0 + i as f64);
            let pose = WorldToCamera::look_at(eye, DVec3::new(0.0, 0.0, 1.0), DVec3::Z).unwrap();
            let dist = Distortion::from_array([-0.05, 0.01, 2e-4, -1e-4, 0.0]);
            let intrinsics = Intrinsics {
                fx: 900.0 + i as f64,
                fy: 905.0,
                cx: 639.5,
                cy: 479.5,
                dist,
            };
            Camera {
                width: 1280,
                height: 960,
                intrinsics,
                pose,
            }
        })
        .collect()
}

fn points() -> Vec<DVec3> {
    [
        [-2.0, -2.0, 0.0],
        [2.5, -1.0, 0.3],
        [1.0, 2.5, 0.0],
        [-1.5, 1.5, 2.0],
        [0.0, 0.0, 1.0],
    ]
    .map(DVec3::from_array)
    .to_vec()
}

/// The COLMAP model of the scan cameras seen in the frame `x_model = R^T (x_scan - t) / s`.
fn colmap_model(scan: &[Camera]) -> ColmapModel {
    let rs = DMat3::from_axis_angle(DVec3::new(1.0, 2.0, 0.5).normalize(), 0.7);
    let (scale, ts) = (0.37, DVec3::new(-4.0, 9.0, 1.5));
    let mut m = ColmapModel::default();
    for (i, c) in scan.iter().enumerate() {
        let (r, t) = (c.pose.r * rs, (c.pose.t + c.pose.r * ts) / scale);
        let k = c.intrinsics;
        let d = k.dist.to_array();
        let params = vec![k.fx, k.fy, k.cx + 0.5, k.cy + 0.5, d[0], d[1], d[2], d[3]];
        let id = i as u32 + 1;
        m.cameras.push(ColmapCamera {
            id,
            model: CameraModel::OpenCv,
            width: 1280,
            height: 960,
            params,
        });
        let name = format!("DSC{i:03}.jpg");
        m.images.push(ColmapImage {
            id,
            q: matrix_to_quat(r),
            t: t.to_array(),
            camera_id: id,
            name,
            points2d: vec![],
        });
    }
    m
}

fn control(scan: &[Camera]) -> Vec<ControlObservation> {
    let mut out = Vec::new();
    for (k, p) in points().iter().enumerate() {
        for (i, c) in scan.iter().enumerate() {
            let q = c.project(*p).unwrap();
            assert!(c.in_frame(q));
            out.push(ControlObservation {
                name: format!("gcp{k}"),
                world: p.to_array(),
                image: format!("DSC{i:03}.jpg"),
                pixel: q.to_array(),
            });
        }
    }
    out
}

/// The inputs in `dir`: sparse/, photos/, site.ply, control.csv, noon.toml.
fn inputs(dir: &Path, scan: &[Camera]) {
    let model = colmap_model(scan);
    std::fs::create_dir_all(dir.join("sparse")).unwrap();
    igi_import::write_text(&model, &dir.join("sparse")).unwrap();
    std::fs::create_dir_all(dir.join("photos")).unwrap();
    for i in &model.images {
        std::fs::write(dir.join("photos").join(&i.name), b"jpeg").unwrap();
    }
    std::fs::write(dir.join("site.ply"), b"ply\n").unwrap();
    std::fs::write(dir.join("noon.toml"), "[sun]\ndirection = [0.0, 0.0, 1.0]\nradiance = [1.0, 1.0, 1.0]\nangular_diameter_deg = 0.53\n").unwrap();
    igi_formats::control::write_control_points(&dir.join("control.csv"), &control(scan)).unwrap();
}

fn args<'a>(dir: &'a Path, control: &'a Path, out: &'a Path) -> Vec<String> {
    let p = |x: &str| s(&dir.join(x)).to_string();
    [
        "import",
        "colmap",
        &p("sparse"),
        "--images",
        &p("photos"),
        "--control",
        s(control),
        "--mesh",
        &p("site.ply"),
        "--lighting",
        &p("noon.toml"),
        "-o",
        s(out),
    ]
    .map(String::from)
    .to_vec()
}

#[test]
fn import_colmap_writes_cameras_that_reproject_the_truth() {
    let dir = tempfile::tempdir().unwrap();
    let scan = scan_cameras();
    inputs(dir.path(), &scan);
    let out = dir.path().join("survey");
    let a = args(dir.path(), &dir.path().join("control.csv"), &out);
    let o = igi().ok(&a.iter().map(String::as_str).collect::<Vec<_>>());
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains("cameras.txt") && stdout.contains("frame                 scan"),
        "{stdout}"
    );
    let mut worst = 0.0f64;
    for (i, truth) in scan.iter().enumerate() {
        let cam = Camera::load(&out.join(format!("cameras/DSC{i:03}.json"))).unwrap();
        for p in points().iter().chain([DVec3::new(0.3, -0.7, 0.4)].iter()) {
            worst = worst.max(
                cam.project(*p)
                    .unwrap()
                    .distance(truth.project(*p).unwrap()),
            );
        }
    }
    eprintln!("worst reprojection against the truth: {worst:.3e} px");
    assert!(worst < 1e-6, "{worst} px");
    let survey = std::fs::read_to_string(out.join("survey.toml")).unwrap();
    assert!(
        survey.contains("mesh = \"../site.ply\"") && survey.contains("lighting = \"../noon.toml\""),
        "{survey}"
    );
    let a: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("alignment.json")).unwrap())
            .unwrap();
    assert!((a["scale"].as_f64().unwrap() - 0.37).abs() < 1e-9, "{a}");
}

#[test]
fn import_colmap_refuses_a_control_image_not_in_the_model_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let scan = scan_cameras();
    inputs(dir.path(), &scan);
    let mut obs = control(&scan);
    obs[3].image = "other.jpg".into();
    let bad = dir.path().join("bad.csv");
    igi_formats::control::write_control_points(&bad, &obs).unwrap();
    let out = dir.path().join("survey");
    let a = args(dir.path(), &bad, &out);
    let o = igi().run(&a.iter().map(String::as_str).collect::<Vec<_>>());
    let keep: Vec<_> = [
        "sparse",
        "photos",
        "site.ply",
        "noon.toml",
        "control.csv",
        "bad.csv",
    ]
    .map(|n| dir.path().join(n))
    .to_vec();
    assert_failed(
        &o,
        "bad.csv",
        "image `other.jpg` is not in the model",
        dir.path(),
        &keep,
    );
}
