//! The crate's tests: a synthetic COLMAP model from known cameras, written as text and binary
//! and read back; a known similarity recovered from noisy control points; each bad input.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::{DMat3, DVec2, DVec3};
use igi_camera::{Camera, Distortion, Intrinsics, WorldToCamera};
use igi_formats::ControlObservation;

use crate::align::{align, AlignOptions, Similarity};
use crate::model::{
    matrix_to_quat, CameraModel, ColmapCamera, ColmapImage, ColmapModel, ColmapPoint,
};
use crate::{binary, import_colmap, read_model, text, write_binary, write_text, ColmapImport};

const W: u32 = 1200;
const H: u32 = 800;

/// One camera per supported model: (model, COLMAP params with the contract principal point).
fn models() -> Vec<(CameraModel, Vec<f64>)> {
    vec![
        (CameraModel::SimplePinhole, vec![1000.0, 600.25, 399.75]),
        (CameraModel::Pinhole, vec![1010.5, 990.25, 601.0, 402.5]),
        (CameraModel::SimpleRadial, vec![980.0, 598.5, 401.25, -0.05]),
        (CameraModel::Radial, vec![1005.0, 602.0, 398.0, -0.04, 0.01]),
        (
            CameraModel::OpenCv,
            vec![995.0, 1002.0, 599.0, 400.5, -0.06, 0.02, 1e-3, -5e-4],
        ),
        (
            CameraModel::FullOpenCv,
            vec![
                1001.0, 999.0, 600.0, 401.0, -0.03, 0.015, -2e-4, 3e-4, -0.002, 0.0, 0.0, 0.0,
            ],
        ),
    ]
}

/// The contract intrinsics a COLMAP camera's parameters mean (shifted by -0.5 px).
fn truth_intrinsics(model: CameraModel, p: &[f64]) -> Intrinsics {
    let (f, d) = match model {
        CameraModel::SimplePinhole => ([p[0], p[0], p[1], p[2]], [0.0; 5]),
        CameraModel::Pinhole => ([p[0], p[1], p[2], p[3]], [0.0; 5]),
        CameraModel::SimpleRadial => ([p[0], p[0], p[1], p[2]], [p[3], 0.0, 0.0, 0.0, 0.0]),
        CameraModel::Radial => ([p[0], p[0], p[1], p[2]], [p[3], p[4], 0.0, 0.0, 0.0]),
        CameraModel::OpenCv => ([p[0], p[1], p[2], p[3]], [p[4], p[5], p[6], p[7], 0.0]),
        _ => ([p[0], p[1], p[2], p[3]], [p[4], p[5], p[6], p[7], p[8]]),
    };
    Intrinsics {
        fx: f[0],
        fy: f[1],
        cx: f[2] - 0.5,
        cy: f[3] - 0.5,
        dist: Distortion::from_array(d),
    }
}

/// Six contract cameras on a ring 15 m from the origin, looking at it.
pub(crate) fn truth_cameras() -> Vec<Camera> {
    models()
        .iter()
        .enumerate()
        .map(|(i, (m, p))| {
            let a = i as f64 * std::f64::consts::TAU / 6.0 + 0.3;
            let eye = DVec3::new(15.0 * a.cos(), 15.0 * a.sin(), 4.0 + i as f64 * 0.5);
            let pose = WorldToCamera::look_at(eye, DVec3::new(0.2, -0.1, 1.0), DVec3::Z).unwrap();
            Camera {
                width: W,
                height: H,
                intrinsics: truth_intrinsics(*m, p),
                pose,
            }
        })
        .collect()
}

/// Known 3D points (scan frame) around the origin.
pub(crate) fn truth_points() -> Vec<DVec3> {
    vec![
        DVec3::new(-3.0, -2.0, 0.0),
        DVec3::new(3.5, -1.5, 0.2),
        DVec3::new(2.0, 3.0, 0.1),
        DVec3::new(-2.5, 2.5, 0.0),
        DVec3::new(0.5, 0.5, 3.0),
        DVec3::new(-1.0, 0.0, 1.5),
    ]
}

/// The COLMAP model of `cams` (world = their frame), with `points` projected into each image.
fn colmap_of(cams: &[Camera], points: &[DVec3]) -> ColmapModel {
    let mut model = ColmapModel::default();
    for (i, (c, (m, p))) in cams.iter().zip(models()).enumerate() {
        model.cameras.push(ColmapCamera {
            id: i as u32 + 1,
            model: m,
            width: W as u64,
            height: H as u64,
            params: p,
        });
        let points2d = points
            .iter()
            .enumerate()
            .filter_map(|(k, x)| {
                c.project(*x)
                    .map(|q| ([q.x + 0.5, q.y + 0.5], k as i64 + 1))
            })
            .collect();
        model.images.push(ColmapImage {
            id: i as u32 + 1,
            q: matrix_to_quat(c.pose.r),
            t: c.pose.t.to_array(),
            camera_id: i as u32 + 1,
            name: format!("IMG_{i:04}.JPG"),
            points2d,
        });
    }
    model.points = points
        .iter()
        .enumerate()
        .map(|(k, x)| ColmapPoint {
            id: k as u64 + 1,
            xyz: x.to_array(),
            rgb: [10, 20, k as u8],
            error: 0.25,
            track: (0..cams.len() as u32).map(|i| (i + 1, k as u32)).collect(),
        })
        .collect();
    model
}

fn assert_close(a: f64, b: f64, tol: f64, what: &str) {
    assert!((a - b).abs() <= tol, "{what}: {a} vs {b} (tolerance {tol})");
}

fn assert_cameras_equal(got: &Camera, want: &Camera, tol: f64) {
    assert_eq!((got.width, got.height), (want.width, want.height));
    let (g, w) = (got.intrinsics, want.intrinsics);
    for (a, b) in [(g.fx, w.fx), (g.fy, w.fy), (g.cx, w.cx), (g.cy, w.cy)] {
        assert_close(a, b, tol, "K");
    }
    assert_eq!(g.dist, w.dist);
    let r = (got.pose.r - want.pose.r).to_cols_array();
    assert!(r.iter().all(|e| e.abs() <= tol), "R differs by {r:?}");
    assert!(
        (got.pose.t - want.pose.t).abs().max_element() <= tol * 20.0,
        "t {:?} vs {:?}",
        got.pose.t,
        want.pose.t
    );
}

fn contract_cameras(model: &ColmapModel) -> Vec<Camera> {
    model
        .images
        .iter()
        .map(|i| crate::model::contract_camera(model, i).unwrap())
        .collect()
}

#[test]
fn text_and_binary_models_read_back_as_the_cameras_they_came_from() {
    let cams = truth_cameras();
    let model = colmap_of(&cams, &truth_points());
    for binary_files in [false, true] {
        let dir = tempfile::tempdir().unwrap();
        if binary_files {
            write_binary(&model, dir.path()).unwrap();
        } else {
            write_text(&model, dir.path()).unwrap();
        }
        let (back, read) = read_model(dir.path()).unwrap();
        assert_eq!(back, model, "binary: {binary_files}");
        let ext = if binary_files { "bin" } else { "txt" };
        assert!(
            read.iter().all(|p| p.extension().unwrap() == ext),
            "{read:?}"
        );
        for (got, want) in contract_cameras(&back).iter().zip(&cams) {
            assert_cameras_equal(got, want, 1e-12);
        }
    }
    // the 0.5 px shift: SIMPLE_PINHOLE's cx 600.25 is the contract's 599.75
    assert_eq!(contract_cameras(&model)[0].intrinsics.cx, 599.75);
}

#[test]
fn bin_is_preferred_over_txt_and_rigs_frames_are_ignored() {
    let model = colmap_of(&truth_cameras(), &truth_points());
    let dir = tempfile::tempdir().unwrap();
    write_binary(&model, dir.path()).unwrap();
    std::fs::write(
        dir.path().join("cameras.txt"),
        "garbage that is never read\n",
    )
    .unwrap();
    std::fs::write(dir.path().join("rigs.txt"), "# rigs\n1 2 3\n").unwrap();
    std::fs::write(dir.path().join("frames.bin"), [1u8, 2, 3]).unwrap();
    let (back, read) = read_model(dir.path()).unwrap();
    assert_eq!(back, model);
    assert!(read[0].ends_with("cameras.bin"));
}

/// The known similarity: scale 2.5, 30 degrees about a tilted axis, a translation.
fn truth_similarity() -> Similarity {
    Similarity {
        scale: 2.5,
        rotation: DMat3::from_axis_angle(
            DVec3::new(0.3, -0.5, 0.8).normalize(),
            30f64.to_radians(),
        ),
        translation: DVec3::new(12.0, -7.5, 3.25),
    }
}

/// A scan-frame camera moved into the model frame `x_model = Rs^T (x_scan - ts) / s`.
fn to_model_frame(c: &Camera, s: &Similarity) -> Camera {
    let r = c.pose.r * s.rotation;
    let t = (c.pose.t + c.pose.r * s.translation) / s.scale;
    Camera {
        pose: WorldToCamera { r, t },
        ..c.clone()
    }
}

/// A deterministic uniform number in [-1, 1).
fn noise(k: usize) -> f64 {
    let x = ((k as f64 + 1.0) * 12.9898).sin() * 43758.5453;
    2.0 * (x - x.floor()) - 1.0
}

/// Observations of `points` (scan frame) by every scan camera that sees them, `amp` px of noise.
fn observe(cams: &[Camera], points: &[DVec3], amp: f64) -> Vec<ControlObservation> {
    let mut out = Vec::new();
    for (k, p) in points.iter().enumerate() {
        for (i, c) in cams.iter().enumerate() {
            let Some(q) = c.project(*p).filter(|q| c.in_frame(*q)) else {
                continue;
            };
            let n = out.len();
            let q = q + DVec2::new(noise(2 * n), noise(2 * n + 1)) * amp;
            out.push(ControlObservation {
                name: format!("gcp-{k}"),
                world: p.to_array(),
                image: format!("IMG_{i:04}.JPG"),
                pixel: q.to_array(),
            });
        }
    }
    out
}

/// The model-frame cameras by image name.
fn by_name(cams: &[Camera]) -> HashMap<String, Camera> {
    cams.iter()
        .enumerate()
        .map(|(i, c)| (format!("IMG_{i:04}.JPG"), c.clone()))
        .collect()
}

fn rotation_angle_deg(r: DMat3) -> f64 {
    let tr = r.x_axis.x + r.y_axis.y + r.z_axis.z;
    ((tr - 1.0) / 2.0).clamp(-1.0, 1.0).acos().to_degrees()
}

#[test]
fn a_known_similarity_is_recovered_despite_noise_and_an_outlier() {
    let truth = truth_similarity();
    let scan = truth_cameras();
    let model: Vec<Camera> = scan.iter().map(|c| to_model_frame(c, &truth)).collect();
    let mut obs = observe(&scan, &truth_points(), 0.3);
    // gross outlier: gcp-5 surveyed 2 m away from where the photos see it
    obs.iter_mut()
        .filter(|o| o.name == "gcp-5")
        .for_each(|o| o.world[0] += 2.0);
    let a = align(
        Path::new("control.csv"),
        &obs,
        &by_name(&model),
        AlignOptions::default(),
    )
    .unwrap();
    let s = a.similarity;
    let rel = (s.scale / truth.scale - 1.0).abs();
    let angle = rotation_angle_deg(s.rotation * truth.rotation.transpose());
    let dt = s.translation.distance(truth.translation);
    eprintln!(
        "scale rel error {rel:.2e}, rotation {angle:.2e} deg, translation {dt:.2e} m, rms {:.2e} m",
        a.rms_m
    );
    for p in &a.points {
        eprintln!(
            "  {} views {} residual {:.4} m reprojection {:?} px inlier {}",
            p.name, p.views, p.residual_m, p.reprojection_px, p.inlier
        );
    }
    assert!(rel < 1e-3, "scale {}", s.scale);
    assert!(angle < 0.05, "rotation off by {angle} deg");
    assert!(dt < 0.01, "translation off by {dt} m");
    let outliers: Vec<&str> = a
        .points
        .iter()
        .filter(|p| !p.inlier)
        .map(|p| p.name.as_str())
        .collect();
    assert_eq!(outliers, ["gcp-5"]);
    assert!((a.points[5].residual_m - 2.0).abs() < 0.05);
    assert!(a.points[..5]
        .iter()
        .all(|p| p.reprojection_px.unwrap() < 1.0 && p.residual_m < 0.02));
    // the aligned cameras are the scan's
    for (m, c) in model.iter().zip(&scan) {
        let got = s.camera(m);
        let far = truth_points()[4];
        assert!(got.project(far).unwrap().distance(c.project(far).unwrap()) < 1.0);
    }
}

#[test]
fn exact_control_points_give_exact_cameras() {
    let truth = truth_similarity();
    let scan = truth_cameras();
    let model: Vec<Camera> = scan.iter().map(|c| to_model_frame(c, &truth)).collect();
    let obs = observe(&scan, &truth_points(), 0.0);
    let a = align(
        Path::new("c.csv"),
        &obs,
        &by_name(&model),
        AlignOptions::default(),
    )
    .unwrap();
    for (m, c) in model.iter().zip(&scan) {
        assert_cameras_equal(&a.similarity.camera(m), c, 1e-7);
    }
    assert!(a.rms_m < 1e-7, "{}", a.rms_m);
}

fn align_error(obs: &[ControlObservation], max_residual: Option<f64>) -> String {
    let model: Vec<Camera> = truth_cameras()
        .iter()
        .map(|c| to_model_frame(c, &truth_similarity()))
        .collect();
    let e = align(
        Path::new("control.csv"),
        obs,
        &by_name(&model),
        AlignOptions { max_residual },
    )
    .unwrap_err();
    let e = e.to_string();
    assert!(e.starts_with("control.csv: "), "{e}");
    e
}

#[test]
fn bad_control_points_are_refused_by_name() {
    let cams = truth_cameras();
    let pts = truth_points();
    let two = observe(&cams, &pts[..2], 0.0);
    assert!(align_error(&two, None).contains("2 usable control points; at least 3"));
    let mut once = observe(&cams, &pts[..4], 0.0);
    once.retain(|o| o.name != "gcp-3" || o.image == "IMG_0000.JPG");
    assert!(align_error(&once, None).contains("point `gcp-3` is seen in only one image"));
    let line: Vec<DVec3> = (0..4)
        .map(|k| DVec3::new(k as f64, 0.5 * k as f64, 0.0))
        .collect();
    assert!(align_error(&observe(&cams, &line, 0.0), None).contains("near a line"));
    let mut outside = observe(&cams, &pts, 0.0);
    outside[3].pixel = [1200.0, 10.0];
    let e = align_error(&outside, None);
    assert!(
        e.contains("row `gcp-") && e.contains("outside the 1200 x 800 image"),
        "{e}"
    );
    let mut unknown = observe(&cams, &pts, 0.0);
    unknown[2].image = "nope.jpg".into();
    assert!(align_error(&unknown, None).contains("image `nope.jpg` is not in the model"));
    let noisy = observe(&cams, &pts, 0.3);
    assert!(align_error(&noisy, Some(1e-7)).contains("--max-residual"));
}

/// Two rows of one point whose rays, as lines, meet behind both cameras (A looks left of its
/// axis, B right of its own, 2 m to A's right): refused, naming the point and an image.
#[test]
fn a_point_that_triangulates_behind_a_camera_is_refused() {
    let a = Camera::look_at(DVec3::ZERO, DVec3::new(0.0, 10.0, 0.0), 640, 480, 60.0).unwrap();
    let b = Camera::look_at(
        DVec3::new(2.0, 0.0, 0.0),
        DVec3::new(2.0, 10.0, 0.0),
        640,
        480,
        60.0,
    )
    .unwrap();
    let px = |c: &Camera, p: DVec3| c.project(p).unwrap().to_array();
    let group = |pa: DVec3, pb: DVec3| crate::align::Group {
        name: "gcp-7".into(),
        world: DVec3::ZERO,
        views: vec![(&a, px(&a, pa)), (&b, px(&b, pb))],
        images: vec!["A.JPG".into(), "B.JPG".into()],
    };
    let path = Path::new("control.csv");
    // crossing in front: (1, 5, 0)
    let ok = group(DVec3::new(1.0, 5.0, 0.0), DVec3::new(1.0, 5.0, 0.0));
    let x = crate::align::triangulate_all(path, &[ok]).unwrap();
    assert!((x[0] - DVec3::new(1.0, 5.0, 0.0)).length() < 1e-9, "{x:?}");
    // lines through (-1, 5, 0) and (3, 5, 0) meet at (1, -5, 0), behind both
    let bad = group(DVec3::new(-1.0, 5.0, 0.0), DVec3::new(3.0, 5.0, 0.0));
    let e = crate::align::triangulate_all(path, &[bad])
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("control.csv: ")
            && e.contains("point `gcp-7` triangulates behind the camera of image `A.JPG`"),
        "{e}"
    );
}

#[test]
fn unsupported_camera_models_are_refused_by_name() {
    let mut model = colmap_of(&truth_cameras(), &truth_points());
    model.cameras[5].params[10] = 0.01;
    let e = crate::model::contract_camera(&model, &model.images[5]).unwrap_err();
    assert!(
        e.contains("FULL_OPENCV with k4, k5, k6") && e.contains("no rational"),
        "{e}"
    );
    model.cameras[4].model = CameraModel::OpenCvFisheye;
    let e = crate::model::contract_camera(&model, &model.images[4]).unwrap_err();
    assert!(
        e.contains("camera model OPENCV_FISHEYE is not supported"),
        "{e}"
    );
    for m in ["FOV", "THIN_PRISM_FISHEYE", "RADIAL_FISHEYE"] {
        let cam = ColmapCamera {
            id: 1,
            model: CameraModel::from_name(m).unwrap(),
            width: 10,
            height: 10,
            params: vec![1.0; CameraModel::from_name(m).unwrap().num_params()],
        };
        let e = crate::model::contract_intrinsics(&cam).unwrap_err();
        assert!(
            e.contains(&format!("camera model {m} is not supported")),
            "{e}"
        );
    }
}

fn text_error(file: &str, body: &str) -> String {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(file);
    std::fs::write(&path, body).unwrap();
    let e = match file {
        "cameras.txt" => text::read_cameras(&path).map(|_| ()),
        "images.txt" => text::read_images(&path).map(|_| ()),
        _ => text::read_points(&path).map(|_| ()),
    };
    let e = e.unwrap_err().to_string();
    e.strip_prefix(&format!("{}", dir.path().display()))
        .unwrap()
        .to_string()
}

#[test]
fn text_errors_name_file_and_line() {
    assert_eq!(
        text_error("cameras.txt", "# c\n1 FISHEYE_X 10 10 1\n"),
        "/cameras.txt:2: unknown camera model `FISHEYE_X`"
    );
    assert_eq!(
        text_error("cameras.txt", "1 PINHOLE 10 10 1 2 3\n"),
        "/cameras.txt:1: PINHOLE takes 4 parameters, the line has 3"
    );
    assert_eq!(
        text_error("cameras.txt", "1 PINHOLE 10 ten 1 2 3 4\n"),
        "/cameras.txt:1: HEIGHT = `ten` is not a valid number"
    );
    let img = "# i\n1 1 0 0 0 0 0 0 1 a.jpg\n1.5 2.5 -1 3 4\n";
    assert_eq!(
        text_error("images.txt", img),
        "/images.txt:3: 5 fields: 2D points are X Y POINT3D_ID triples"
    );
    assert_eq!(
        text_error("images.txt", "1 1 0 0 0 0 0 1\n\n"),
        "/images.txt:1: missing NAME (field 10)"
    );
    assert_eq!(
        text_error("points3D.txt", "1 0 0 0 255 0 256 0.5\n"),
        "/points3D.txt:1: B = `256` is not a valid number"
    );
    // an empty second line is an image without 2D points
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("images.txt");
    std::fs::write(
        &p,
        "1 1 0 0 0 0 0 0 1 a b.jpg\n\n2 1 0 0 0 1 2 3 1 c.jpg\n1 2 -1\n",
    )
    .unwrap();
    let imgs = text::read_images(&p).unwrap();
    assert_eq!(
        (
            imgs[0].name.as_str(),
            imgs[0].points2d.len(),
            imgs[1].points2d.clone()
        ),
        ("a b.jpg", 0, vec![([1.0, 2.0], -1)])
    );
}

#[test]
fn truncated_and_absurd_binary_files_are_refused_before_allocating() {
    let model = colmap_of(&truth_cameras(), &truth_points());
    let [cams, imgs, pts] = binary::to_binary(&model);
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, bytes: &[u8]| -> PathBuf {
        let p = dir.path().join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    };
    let cut = cams.len() - 12;
    let e = binary::read_cameras(&write("cameras.bin", &cams[..cut]))
        .unwrap_err()
        .to_string();
    let want = format!(
        "cameras.bin: at byte {}: file truncated: params needs 8 bytes, 4 left",
        cut - 4
    );
    assert!(e.contains(&want), "{e}");
    let e = binary::read_images(&write("images.bin", &imgs[..imgs.len() - 5]))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("number of 2D points = 6, but 139 bytes left hold at most 5"),
        "{e}"
    );
    let e = binary::read_points(&write("points3D.bin", &pts[..pts.len() - 1]))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("points3D.bin: at byte")
            && (e.contains("truncated") || e.contains("bytes left")),
        "{e}"
    );
    // a count of 2^62 cameras in a 40-byte file: refused at byte 0 without allocating
    let mut huge = (1u64 << 62).to_le_bytes().to_vec();
    huge.extend_from_slice(&cams[8..40]);
    let e = binary::read_cameras(&write("cameras.bin", &huge))
        .unwrap_err()
        .to_string();
    assert!(e.contains("cameras.bin: at byte 0: number of cameras = 4611686018427387904, but 32 bytes left hold at most 1"), "{e}");
    // a huge 2D-point count inside an image record
    let mut img = imgs.clone();
    let at = 8 + 4 + 56 + 4 + "IMG_0000.JPG".len() + 1;
    img[at..at + 8].copy_from_slice(&u64::MAX.to_le_bytes());
    let e = binary::read_images(&write("images.bin", &img))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains(&format!("at byte {at}: number of 2D points = {}", u64::MAX)),
        "{e}"
    );
    let mut bad_model = cams.clone();
    bad_model[12..16].copy_from_slice(&99i32.to_le_bytes());
    let e = binary::read_cameras(&write("cameras.bin", &bad_model))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("at byte 12: camera 1: unknown camera model id 99"),
        "{e}"
    );
    let mut extra = cams.clone();
    extra.push(0);
    let e = binary::read_cameras(&write("cameras.bin", &extra))
        .unwrap_err()
        .to_string();
    assert!(e.contains("1 bytes after the last record"), "{e}");
}

/// A sparse folder, an images folder with every image, a mesh and a control file.
fn import_inputs(root: &Path) -> ColmapImport {
    let truth = truth_similarity();
    let scan = truth_cameras();
    let model_cams: Vec<Camera> = scan.iter().map(|c| to_model_frame(c, &truth)).collect();
    let model = colmap_of(&model_cams, &[]);
    let sparse = root.join("sparse");
    std::fs::create_dir_all(&sparse).unwrap();
    write_binary(&model, &sparse).unwrap();
    let images = root.join("photos");
    std::fs::create_dir_all(&images).unwrap();
    model
        .images
        .iter()
        .for_each(|i| std::fs::write(images.join(&i.name), b"jpeg").unwrap());
    std::fs::write(root.join("site.ply"), b"ply\n").unwrap();
    let control = root.join("control.csv");
    igi_formats::control::write_control_points(&control, &observe(&scan, &truth_points(), 0.0))
        .unwrap();
    ColmapImport {
        format: crate::ModelFormat::Colmap,
        sparse,
        images,
        control: Some(control),
        lighting: None,
        meshes: vec![root.join("site.ply")],
        output: root.join("survey"),
        align: AlignOptions::default(),
        icp: None,
    }
}

#[test]
fn import_writes_a_survey_of_aligned_cameras() {
    let dir = tempfile::tempdir().unwrap();
    let job = import_inputs(dir.path());
    let r = import_colmap(&job).unwrap();
    assert_eq!((r.images, r.frame, r.lighting), (6, "scan", false));
    assert_close(r.scale, 2.5, 1e-9, "scale");
    let survey: igi_formats::survey::SurveyFile =
        igi_formats::TomlFile::read(&job.output.join("survey.toml")).unwrap();
    assert_eq!(survey.site.mesh.as_deref(), Some(Path::new("../site.ply")));
    assert_eq!(survey.photo[2].image, Path::new("../photos/IMG_0002.JPG"));
    let cam = Camera::load(&job.output.join(&survey.photo[2].camera)).unwrap();
    assert_cameras_equal(&cam, &truth_cameras()[2], 1e-7);
    let a: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(job.output.join("alignment.json")).unwrap())
            .unwrap();
    assert_eq!(a["points"].as_array().unwrap().len(), 6);
    // an existing, non-empty output folder is refused
    let e = import_colmap(&job).unwrap_err().to_string();
    assert!(
        e.ends_with("output folder is not empty (choose a new or empty folder)"),
        "{e}"
    );
}

#[test]
fn a_failed_import_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let job = import_inputs(dir.path());
    std::fs::remove_file(job.images.join("IMG_0003.JPG")).unwrap();
    let e = import_colmap(&job).unwrap_err().to_string();
    assert!(
        e.contains("IMG_0003.JPG: image `IMG_0003.JPG` of the model (")
            && e.contains("images.bin) is not in --images"),
        "{e}"
    );
    assert!(!job.output.exists());
    std::fs::write(job.images.join("IMG_0003.JPG"), b"x").unwrap();
    let bad = ColmapImport {
        align: AlignOptions {
            max_residual: Some(-1.0),
        },
        ..job.clone()
    };
    let e = import_colmap(&bad).unwrap_err().to_string();
    assert!(
        e.ends_with("control.csv: --max-residual -1 m is not a positive distance"),
        "{e}"
    );
    assert!(!job.output.exists());
    let no_mesh = ColmapImport {
        meshes: vec![dir.path().join("none.ply")],
        ..job.clone()
    };
    assert!(import_colmap(&no_mesh)
        .unwrap_err()
        .to_string()
        .contains("none.ply: site mesh not found"));
    let no_model = ColmapImport {
        sparse: dir.path().join("photos"),
        ..job
    };
    assert!(import_colmap(&no_model)
        .unwrap_err()
        .to_string()
        .contains("no COLMAP cameras"));
}
