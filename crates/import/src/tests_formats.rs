//! Metashape camera XML and nerfstudio `transforms.json` written by these tests from known
//! cameras, with each format's own conventions (Metashape: principal point as an offset from
//! the image centre, pixel centres at +0.5, P1/P2 swapped from OpenCV, affinity b1, chunk and
//! component similarity transforms; nerfstudio: OpenGL camera axes, pixel centres at +0.5,
//! per-frame intrinsics, `applied_transform`), imported and compared with the cameras they came
//! from; and each bad input refused by name.

use std::fmt::Write as _;
use std::path::Path;

use glam::{DMat3, DVec3};
use igi_camera::Camera;

use crate::source::{Affine, ModelFormat};
use crate::tests::{truth_cameras, truth_points};
use crate::{import_colmap, read_metashape, read_nerfstudio, AlignOptions, ColmapImport};

/// A camera's camera-to-world map (OpenCV axes).
fn camera_to_world(c: &Camera) -> Affine {
    let a = c.pose.r.transpose();
    Affine {
        m: a,
        t: -(a * c.pose.t),
    }
}

fn similarity(scale: f64, axis: DVec3, angle: f64, t: DVec3) -> Affine {
    Affine {
        m: DMat3::from_axis_angle(axis.normalize(), angle) * scale,
        t,
    }
}

/// Row-major numbers of a 4x4 affine map, each written to round-trip exactly.
fn rows16(a: &Affine) -> String {
    let mut out = Vec::new();
    for i in 0..3 {
        for j in 0..3 {
            out.push(a.m.col(j)[i]);
        }
        out.push(a.t[i]);
    }
    out.extend([0.0, 0.0, 0.0, 1.0]);
    out.iter()
        .map(|x| format!("{x:?}"))
        .collect::<Vec<_>>()
        .join(" ")
}

/// `<transform>` as rotation (row-major), translation and scale parts.
fn parts(a: &Affine, indent: &str) -> String {
    let s = a.m.determinant().cbrt();
    let r = a.m * (1.0 / s);
    let rot: Vec<String> = (0..3)
        .flat_map(|i| (0..3).map(move |j| (i, j)))
        .map(|(i, j)| format!("{:?}", r.col(j)[i]))
        .collect();
    format!(
        "{indent}<transform>\n{indent}  <rotation locked=\"false\">{}</rotation>\n{indent}  <translation locked=\"false\">{:?} {:?} {:?}</translation>\n{indent}  <scale locked=\"false\">{s:?}</scale>\n{indent}</transform>\n",
        rot.join(" "),
        a.t.x,
        a.t.y,
        a.t.z
    )
}

/// The Metashape cameras XML of `cams` (world frame), one sensor per camera, the cameras
/// stored in a component frame under the given component and chunk transforms.
fn metashape_xml(cams: &[Camera], labels: &[String], chunk: Affine, comp: Affine) -> String {
    let mut x = String::from(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<document version=\"2.0.0\">\n  <chunk label=\"Chunk 1\" enabled=\"true\">\n    <sensors next_id=\"9\">\n",
    );
    for (i, c) in cams.iter().enumerate() {
        let k = c.intrinsics;
        let (w, h) = (f64::from(c.width), f64::from(c.height));
        let _ = write!(
            x,
            "      <sensor id=\"{i}\" label=\"unknown\" type=\"frame\">\n        <resolution width=\"{}\" height=\"{}\"/>\n        <property name=\"fixed\" value=\"false\"/>\n        <calibration type=\"frame\" class=\"initial\">\n          <resolution width=\"{}\" height=\"{}\"/>\n          <f>5000</f>\n        </calibration>\n        <calibration type=\"frame\" class=\"adjusted\">\n          <resolution width=\"{}\" height=\"{}\"/>\n          <f>{:?}</f>\n          <cx>{:?}</cx>\n          <cy>{:?}</cy>\n          <b1>{:?}</b1>\n          <k1>{:?}</k1>\n          <k2>{:?}</k2>\n          <k3>{:?}</k3>\n          <p1>{:?}</p1>\n          <p2>{:?}</p2>\n        </calibration>\n      </sensor>\n",
            c.width, c.height, c.width, c.height, c.width, c.height,
            k.fy,
            k.cx + 0.5 - w / 2.0,
            k.cy + 0.5 - h / 2.0,
            k.fx - k.fy,
            k.dist.k1,
            k.dist.k2,
            k.dist.k3,
            // Metashape's P1 is OpenCV's p2 and its P2 OpenCV's p1
            k.dist.p2,
            k.dist.p1,
        );
    }
    x.push_str("    </sensors>\n    <components next_id=\"1\" active_id=\"0\">\n      <component id=\"0\" label=\"Component 1\">\n");
    x.push_str(&parts(&comp, "        "));
    let ids: Vec<String> = (0..cams.len()).map(|i| i.to_string()).collect();
    let _ = write!(
        x,
        "        <partition>\n          <camera_ids>{}</camera_ids>\n        </partition>\n      </component>\n    </components>\n    <cameras next_id=\"9\" next_group_id=\"1\">\n      <group id=\"0\" label=\"Folder\" type=\"folder\">\n",
        ids.join(" ")
    );
    let to_comp = chunk.then_inner(comp).inverse().unwrap();
    for (i, (c, l)) in cams.iter().zip(labels).enumerate() {
        let t = to_comp.then_inner(camera_to_world(c));
        let _ = writeln!(
            x,
            "        <camera id=\"{i}\" sensor_id=\"{i}\" label=\"{l}\">\n          <transform>{}</transform>\n          <orientation>1</orientation>\n        </camera>",
            rows16(&t)
        );
    }
    x.push_str("        <camera id=\"99\" sensor_id=\"0\" label=\"NOT_ALIGNED\"/>\n      </group>\n    </cameras>\n");
    x.push_str(&parts(&chunk, "    "));
    x.push_str("  </chunk>\n</document>\n");
    x
}

/// nerfstudio's transforms.json of `cams`: per-frame intrinsics, OpenGL camera-to-world
/// matrices in the frame `applied` maps the cameras' world to.
fn transforms_json(cams: &[Camera], paths: &[String], applied: Affine) -> String {
    let gl = DMat3::from_diagonal(DVec3::new(1.0, -1.0, -1.0));
    let rows = |a: &Affine, n: usize| -> Vec<Vec<f64>> {
        let mut r: Vec<Vec<f64>> = (0..3)
            .map(|i| vec![a.m.col(0)[i], a.m.col(1)[i], a.m.col(2)[i], a.t[i]])
            .collect();
        if n == 4 {
            r.push(vec![0.0, 0.0, 0.0, 1.0]);
        }
        r
    };
    let frames: Vec<serde_json::Value> = cams
        .iter()
        .zip(paths)
        .map(|(c, p)| {
            let k = c.intrinsics;
            let cv = camera_to_world(c);
            let m = applied.then_inner(Affine {
                m: cv.m * gl,
                t: cv.t,
            });
            serde_json::json!({
                "file_path": p,
                "fl_x": k.fx, "fl_y": k.fy, "cx": k.cx + 0.5, "cy": k.cy + 0.5,
                "k1": k.dist.k1, "k2": k.dist.k2, "k3": k.dist.k3,
                "p1": k.dist.p1, "p2": k.dist.p2,
                "transform_matrix": rows(&m, 4),
            })
        })
        .collect();
    let v = serde_json::json!({
        "w": cams[0].width,
        "h": cams[0].height,
        "camera_model": "OPENCV",
        "frames": frames,
        "applied_transform": rows(&applied, 3),
    });
    serde_json::to_string_pretty(&v).unwrap()
}

/// Each imported camera against the truth: intrinsics to 1e-9 relative, pose to 1e-9, and
/// the truth's scene points reprojected within 1e-6 px. Returns the worst reprojection.
fn compare(got: &[Camera], want: &[Camera]) -> f64 {
    assert_eq!(got.len(), want.len());
    let mut worst = 0.0f64;
    for (g, w) in got.iter().zip(want) {
        assert_eq!((g.width, g.height), (w.width, w.height));
        let (a, b) = (g.intrinsics, w.intrinsics);
        for (x, y) in [(a.fx, b.fx), (a.fy, b.fy), (a.cx, b.cx), (a.cy, b.cy)] {
            assert!((x - y).abs() <= 1e-9 * y.abs(), "K {x} vs {y}");
        }
        for (x, y) in a.dist.to_array().iter().zip(b.dist.to_array()) {
            assert!((x - y).abs() <= 1e-9 * y.abs(), "distortion {x} vs {y}");
        }
        let dr = (g.pose.r - w.pose.r).to_cols_array();
        assert!(dr.iter().all(|e| e.abs() <= 1e-9), "R differs by {dr:?}");
        let dc = (g.center_world() - w.center_world()).abs().max_element();
        assert!(dc <= 1e-9, "centre differs by {dc} m");
        for p in truth_points() {
            let (x, y) = (g.project(p).unwrap(), w.project(p).unwrap());
            worst = worst.max(x.distance(y));
        }
    }
    assert!(worst <= 1e-6, "reprojection differs by {worst} px");
    worst
}

fn labels(n: usize) -> Vec<String> {
    (0..n).map(|i| format!("DSC{:05}", 100 + i)).collect()
}

#[test]
fn metashape_xml_round_trips_to_the_same_cameras() {
    let dir = tempfile::tempdir().unwrap();
    let truth = truth_cameras();
    let chunk = similarity(
        3.7,
        DVec3::new(0.3, -1.0, 2.0),
        2.1,
        DVec3::new(-120.0, 45.0, 8.0),
    );
    let comp = similarity(
        0.2,
        DVec3::new(1.0, 1.0, 0.0),
        -0.6,
        DVec3::new(2.0, -3.0, 0.5),
    );
    let path = dir.path().join("cameras.xml");
    std::fs::write(
        &path,
        metashape_xml(&truth, &labels(truth.len()), chunk, comp),
    )
    .unwrap();
    let set = read_metashape(&path).unwrap();
    assert_eq!(set.unposed, vec!["NOT_ALIGNED".to_string()]);
    assert_eq!(set.cameras, truth.len());
    let names: Vec<&str> = set.images.iter().map(|i| i.name.as_str()).collect();
    assert_eq!(names[0], "DSC00100");
    let got: Vec<Camera> = set.images.into_iter().map(|i| i.camera).collect();
    let worst = compare(&got, &truth);
    eprintln!("Metashape XML: worst reprojection against the truth {worst:.2e} px");
}

#[test]
fn nerfstudio_transforms_round_trip_to_the_same_cameras() {
    let dir = tempfile::tempdir().unwrap();
    let truth = truth_cameras();
    // what ns-process-data applies to a COLMAP world (swap y and z, flip the new z), and a
    // general similarity
    let colmap_like = Affine {
        m: DMat3::from_cols_array_2d(&[[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]),
        t: DVec3::ZERO,
    };
    for applied in [
        colmap_like,
        similarity(
            0.25,
            DVec3::new(2.0, 1.0, -1.0),
            0.9,
            DVec3::new(3.0, 0.5, -7.0),
        ),
    ] {
        let paths: Vec<String> = labels(truth.len())
            .iter()
            .map(|l| format!("./images/{l}.png"))
            .collect();
        std::fs::write(
            dir.path().join("transforms.json"),
            transforms_json(&truth, &paths, applied),
        )
        .unwrap();
        // the folder is enough
        let set = read_nerfstudio(dir.path()).unwrap();
        assert_eq!(set.images[1].name, "images/DSC00101.png");
        assert_eq!(set.cameras, truth.len());
        let got: Vec<Camera> = set.images.into_iter().map(|i| i.camera).collect();
        let worst = compare(&got, &truth);
        eprintln!("transforms.json: worst reprojection against the truth {worst:.2e} px");
    }
}

/// The inputs of an import of `format` in `root` (model file, photos/, site.ply), no control.
fn job(root: &Path, format: ModelFormat, model: &Path) -> ColmapImport {
    std::fs::write(root.join("site.ply"), b"ply\n").unwrap();
    ColmapImport {
        format,
        sparse: model.to_path_buf(),
        images: root.join("photos"),
        control: None,
        lighting: None,
        meshes: vec![root.join("site.ply")],
        output: root.join("survey"),
        align: AlignOptions::default(),
        icp: None,
    }
}

#[test]
fn metashape_and_nerfstudio_import_as_surveys_and_a_missing_photo_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let truth = truth_cameras();
    let names = labels(truth.len());
    let photos = dir.path().join("photos");
    std::fs::create_dir_all(&photos).unwrap();
    for l in &names {
        std::fs::write(photos.join(format!("{l}.JPG")), b"jpeg").unwrap();
    }
    let xml = dir.path().join("cameras.xml");
    std::fs::write(
        &xml,
        metashape_xml(&truth, &names, Affine::IDENTITY, Affine::IDENTITY),
    )
    .unwrap();
    let j = job(dir.path(), ModelFormat::Metashape, &xml);
    let r = import_colmap(&j).unwrap();
    assert_eq!((r.images, r.frame, r.unposed.len()), (6, "model", 1));
    let survey: igi_formats::survey::SurveyFile =
        igi_formats::TomlFile::read(&j.output.join("survey.toml")).unwrap();
    // a label without extension finds its photo by stem
    assert_eq!(survey.photo[3].image, Path::new("../photos/DSC00103.JPG"));
    let cam = Camera::load(&j.output.join(&survey.photo[3].camera)).unwrap();
    compare(&[cam], &truth[3..4]);

    let ns = dir.path().join("ns");
    std::fs::create_dir_all(&ns).unwrap();
    let paths: Vec<String> = names.iter().map(|l| format!("images/{l}.JPG")).collect();
    std::fs::write(
        ns.join("transforms.json"),
        transforms_json(&truth, &paths, Affine::IDENTITY),
    )
    .unwrap();
    let mut j = job(dir.path(), ModelFormat::Nerfstudio, &ns);
    j.output = dir.path().join("survey_ns");
    // file_path is relative to the dataset folder: found by file name in --images
    let r = import_colmap(&j).unwrap();
    assert_eq!(r.images, 6);
    let cam = Camera::load(&j.output.join("cameras/DSC00104.json")).unwrap();
    compare(&[cam], &truth[4..5]);

    std::fs::remove_file(photos.join("DSC00102.JPG")).unwrap();
    j.output = dir.path().join("survey_missing");
    let e = import_colmap(&j).unwrap_err().to_string();
    assert!(
        e.contains("image `images/DSC00102.JPG` of the model (")
            && e.contains("transforms.json) is not in --images"),
        "{e}"
    );
    assert!(!j.output.exists());
}

fn metashape_error(body: &str) -> String {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cams.xml");
    std::fs::write(&path, body).unwrap();
    read_metashape(&path).unwrap_err().to_string()
}

fn nerfstudio_error(body: &str) -> String {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("transforms.json");
    std::fs::write(&path, body).unwrap();
    read_nerfstudio(&path).unwrap_err().to_string()
}

const XML_HEAD: &str = "<document>\n<chunk>\n<sensors>\n";
const XML_TAIL: &str = "</sensors>\n<cameras>\n<camera id=\"0\" sensor_id=\"0\" label=\"a\">\n<transform>1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1</transform>\n</camera>\n</cameras>\n</chunk>\n</document>\n";

#[test]
fn bad_metashape_files_are_refused_naming_file_line_and_problem() {
    let sensor = |kind: &str, calib: &str| {
        format!(
            "{XML_HEAD}<sensor id=\"0\" type=\"{kind}\">\n<calibration type=\"{kind}\" class=\"adjusted\">\n<resolution width=\"100\" height=\"80\"/>\n{calib}\n</calibration>\n</sensor>\n{XML_TAIL}"
        )
    };
    let e = metashape_error(&sensor("fisheye", "<f>90</f>"));
    assert!(
        e.contains("cams.xml:4: sensor 0: camera type `fisheye` is not supported"),
        "{e}"
    );
    let e = metashape_error(&sensor("frame", "<f>90</f>\n<b2>0.5</b2>"));
    assert!(
        e.contains("cams.xml:8: sensor 0: b2 = 0.5 is skew (the contract camera has none)"),
        "{e}"
    );
    let e = metashape_error(&sensor("frame", "<f>90</f>\n<k4>0.01</k4>"));
    assert!(e.contains("cams.xml:8: sensor 0: k4 = 0.01"), "{e}");
    let e = metashape_error(&sensor("frame", "<f>ninety</f>"));
    assert!(e.contains("cams.xml:7: <f> `ninety` is not numbers"), "{e}");
    let e = metashape_error("<document>\n<chunk>\n<sensors>\n</chunk>\n");
    assert!(e.contains("cams.xml:4: not XML"), "{e}");
    let e = metashape_error(&sensor("frame", "<f>90</f>").replace(
        "1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1",
        "1 0 0 0 0 1 0 0 0 0 2 0 0 0 0 1",
    ));
    assert!(
        e.contains("cams.xml:13: camera `a`: its transform") && e.contains("not a rotation"),
        "{e}"
    );
    let e = metashape_error(
        &sensor("frame", "<f>90</f>").replace("sensor_id=\"0\"", "sensor_id=\"3\""),
    );
    assert!(e.contains("cams.xml:12: camera `a` names sensor 3"), "{e}");
    // a good one of the same shape reads: principal point w/2 + cx - 0.5
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cams.xml");
    std::fs::write(
        &path,
        sensor("frame", "<f>90</f>\n<cx>1.5</cx><cy>-2</cy><b1>3</b1>"),
    )
    .unwrap();
    let k = read_metashape(&path).unwrap().images[0].camera.intrinsics;
    assert_eq!((k.fx, k.fy, k.cx, k.cy), (93.0, 90.0, 51.0, 37.5));
}

#[test]
fn bad_transforms_json_is_refused_naming_file_and_problem() {
    let frame =
        r#"{"file_path": "a.png", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}"#;
    let file = |model: &str| {
        format!(
            "{{\"camera_model\": \"{model}\", \"w\": 100, \"h\": 80, \"fl_x\": 90, \"fl_y\": 91, \"cx\": 50, \"cy\": 40,\n \"frames\": [{frame}]}}"
        )
    };
    let e = nerfstudio_error(&file("OPENCV_FISHEYE"));
    assert!(
        e.contains("transforms.json: frames[0]: camera model OPENCV_FISHEYE is not supported"),
        "{e}"
    );
    let e = nerfstudio_error(&file("EQUIRECTANGULAR"));
    assert!(
        e.contains("camera model EQUIRECTANGULAR is not supported"),
        "{e}"
    );
    let e = nerfstudio_error("{\"frames\": [\n{\"file_path\": \"a.png\",,}]}");
    assert!(e.contains("transforms.json:2: not JSON"), "{e}");
    let e = nerfstudio_error(&file("OPENCV").replace("\"fl_y\": 91, ", ""));
    assert!(
        e.contains("transforms.json: frames[0]: no `fl_y` (neither the frame's nor the file's)"),
        "{e}"
    );
    let e = nerfstudio_error(&file("OPENCV").replace("[0,0,1,0],[0,0,0,1]", "[0,0,1,0],[0,0,1,1]"));
    assert!(e.contains("frames[0]: `transform_matrix`: last row"), "{e}");
    let e = nerfstudio_error(&file("OPENCV").replace("\"w\": 100", "\"w\": 100, \"k4\": 0.1"));
    assert!(e.contains("frames[0]: k4 = 0.1"), "{e}");
    // the same file with a pinhole model reads, principal point moved by -0.5 px, y and z
    // flipped into OpenCV's axes
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("transforms.json");
    std::fs::write(&path, file("PINHOLE")).unwrap();
    let c = &read_nerfstudio(&path).unwrap().images[0].camera;
    assert_eq!((c.intrinsics.cx, c.intrinsics.cy), (49.5, 39.5));
    assert_eq!(c.pose.r, DMat3::from_diagonal(DVec3::new(1.0, -1.0, -1.0)));
}
