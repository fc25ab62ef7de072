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

/// Empty photos named `names` in `dir/photos`, and a mesh file.
fn photo_folder(dir: &Path, names: &[&str]) {
    let photos = dir.join("photos");
    std::fs::create_dir_all(&photos).unwrap();
    for n in names {
        std::fs::write(photos.join(n), b"jpeg").unwrap();
    }
    std::fs::write(dir.join("site.ply"), b"ply\n").unwrap();
}

fn import_args(format: &str, model: &Path, dir: &Path, out: &Path) -> Vec<String> {
    [
        "import",
        "colmap",
        "--format",
        format,
        s(model),
        "--images",
        s(&dir.join("photos")),
        "--mesh",
        s(&dir.join("site.ply")),
        "-o",
        s(out),
    ]
    .map(String::from)
    .to_vec()
}

fn run_ok(a: &[String]) -> String {
    let o = igi().ok(&a.iter().map(String::as_str).collect::<Vec<_>>());
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// The committed Metashape fixture: its chunk and component transforms put camera DSC01001
/// at (506, 1200.125, 36.875) and the point every camera looks at at (499.75, 1200.125,
/// 36.875) (worked by hand in the fixture's comment), which must land on the principal point
/// w/2 + cx - 0.5, h/2 + cy - 0.5 of each camera.
#[test]
fn import_metashape_fixture() {
    let dir = tempfile::tempdir().unwrap();
    photo_folder(
        dir.path(),
        &["DSC01001.JPG", "DSC01002.JPG", "DSC01003.JPG", "other.JPG"],
    );
    let xml = igi_testkit::fixture("import/metashape/cameras.xml");
    let out = dir.path().join("survey");
    let stdout = run_ok(&import_args("metashape", &xml, dir.path(), &out));
    assert!(
        stdout.contains("metashape: 1 cameras, 3 images")
            && stdout.contains("1 images without a pose: DSC01004"),
        "{stdout}"
    );
    let target = DVec3::new(499.75, 1200.125, 36.875);
    for n in ["DSC01001", "DSC01002", "DSC01003"] {
        let cam = Camera::load(&out.join(format!("cameras/{n}.json"))).unwrap();
        let k = cam.intrinsics;
        assert_eq!((k.fx, k.fy), (4480.8, 4480.0));
        assert!(
            (k.cx - 3011.8).abs() < 1e-9 && (k.cy - 1990.8).abs() < 1e-9,
            "{k:?}"
        );
        // Metashape's P1, P2 are OpenCV's p2, p1
        assert_eq!((k.dist.p1, k.dist.p2), (-0.0002, 0.0004));
        let q = cam.project(target).unwrap();
        assert!(
            (q.x - 3011.8).abs() < 1e-6 && (q.y - 1990.8).abs() < 1e-6,
            "{n}: {q}"
        );
    }
    let c = Camera::load(&out.join("cameras/DSC01001.json")).unwrap();
    let centre = c.center_world();
    assert!(
        (centre - DVec3::new(506.0, 1200.125, 36.875)).length() < 1e-9,
        "{centre}"
    );
    let survey = std::fs::read_to_string(out.join("survey.toml")).unwrap();
    assert!(survey.contains("../photos/DSC01002.JPG"), "{survey}");
}

/// The committed nerfstudio fixture (as ns-process-data writes from COLMAP, applied_transform
/// included): undone, the cameras sit where they were made in COLMAP's frame, looking at its
/// origin with the scene's up (-y there) up in the image.
#[test]
fn import_nerfstudio_fixture() {
    let dir = tempfile::tempdir().unwrap();
    photo_folder(
        dir.path(),
        &["frame_00001.jpg", "frame_00002.jpg", "frame_00003.jpg"],
    );
    let ns = igi_testkit::fixture("import/nerfstudio");
    let out = dir.path().join("survey");
    let stdout = run_ok(&import_args("nerfstudio", &ns, dir.path(), &out));
    assert!(
        stdout.contains("nerfstudio: 1 cameras, 3 images"),
        "{stdout}"
    );
    let made = [[4.0, -1.0, -3.0], [0.5, -1.2, -5.0], [-3.5, -0.8, -3.5]];
    for (i, p) in made.iter().enumerate() {
        let cam = Camera::load(&out.join(format!("cameras/frame_{:05}.json", i + 1))).unwrap();
        assert!(
            (cam.center_world() - DVec3::from_array(*p)).length() < 1e-9,
            "{}",
            cam.center_world()
        );
        let o = cam.project(DVec3::ZERO).unwrap();
        assert!(
            (o.x - 958.75).abs() < 1e-6 && (o.y - 541.25).abs() < 1e-6,
            "{o}"
        );
        let up = cam.project(DVec3::new(0.0, -0.5, 0.0)).unwrap();
        assert!(up.y < o.y - 50.0, "up is up: {up} vs {o}");
    }
}

#[test]
fn import_refuses_a_fisheye_sensor_and_a_fisheye_nerfstudio_model_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    photo_folder(dir.path(), &["DSC01001.JPG", "frame_00001.jpg"]);
    let xml = std::fs::read_to_string(igi_testkit::fixture("import/metashape/cameras.xml"))
        .unwrap()
        .replace(
            "label=\"ILCE-7RM3 (35mm)\" type=\"frame\"",
            "type=\"fisheye\"",
        );
    let bad = dir.path().join("fisheye.xml");
    std::fs::write(&bad, xml).unwrap();
    let out = dir.path().join("survey");
    let a = import_args("metashape", &bad, dir.path(), &out);
    let o = igi().run(&a.iter().map(String::as_str).collect::<Vec<_>>());
    let keep: Vec<_> = ["photos", "site.ply", "fisheye.xml"]
        .map(|n| dir.path().join(n))
        .to_vec();
    assert_failed(
        &o,
        "fisheye.xml:9",
        "camera type `fisheye` is not supported",
        dir.path(),
        &keep,
    );
    let json = std::fs::read_to_string(igi_testkit::fixture("import/nerfstudio/transforms.json"))
        .unwrap()
        .replace("\"OPENCV\"", "\"OPENCV_FISHEYE\"");
    std::fs::write(dir.path().join("transforms.json"), json).unwrap();
    let a = import_args(
        "nerfstudio",
        &dir.path().join("transforms.json"),
        dir.path(),
        &out,
    );
    let o = igi().run(&a.iter().map(String::as_str).collect::<Vec<_>>());
    let mut keep = keep;
    keep.push(dir.path().join("transforms.json"));
    assert_failed(
        &o,
        "transforms.json",
        "camera model OPENCV_FISHEYE is not supported",
        dir.path(),
        &keep,
    );
}
