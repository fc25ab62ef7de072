//! End-to-end tests of `igi hdr merge` and `igi camera ...`: the real Memorial Church
//! brackets, and clear errors (non-zero exit, stderr naming the file and the problem, no
//! output file left behind) on bad input.

use igi_camera::{Camera, Distortion};
use igi_imaging::{read_image, write_exr, write_png_tonemapped, HdrImage};
use igi_testkit::{assert_failed, s, Cli};
use std::path::Path;
use std::process::Output;

fn igi(args: &[&str]) -> Output {
    Cli::new(env!("CARGO_BIN_EXE_igi")).run(args)
}

fn gray_png(path: &Path, w: usize, h: usize, v: f32) {
    let mut im = HdrImage::new(w, h);
    for (i, p) in im.pixels.iter_mut().enumerate() {
        let x = v * (0.5 + 0.5 * (i % w) as f32 / w as f32);
        *p = [x, x, x];
    }
    write_png_tonemapped(path, &im, 1.0).unwrap();
}

#[test]
fn merge_memorial_brackets_writes_readable_exr() {
    let dir = igi_testkit::shared_data("hdr_bracketed/memorial");
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("memorial.exr");
    let resp = tmp.path().join("resp.csv");
    let imgs: Vec<String> = (61..=76)
        .map(|k| {
            dir.join(format!("memorial{k:04}.png"))
                .to_string_lossy()
                .into_owned()
        })
        .collect();
    let mut args = vec!["hdr", "merge"];
    args.extend(imgs.iter().map(|s| s.as_str()));
    let tf = dir.join("shutter_times.txt");
    args.extend([
        "--times-file",
        s(&tf),
        "--response-out",
        s(&resp),
        "--json",
        "-o",
        s(&out),
    ]);
    let o = igi(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["exposures"], 16);
    assert_eq!(j["response_monotonic"], true);
    assert!(j["valid_fraction"].as_f64().unwrap() > 0.99, "{j}");
    let im = read_image(&out).unwrap();
    assert_eq!((im.width, im.height), (512, 768));
    assert!(im
        .pixels
        .iter()
        .all(|p| p.iter().all(|v| v.is_finite() && *v > 0.0)));
    // huge dynamic range: the stained-glass windows vs the dark interior
    let mut lum: Vec<f32> = im.pixels.iter().map(|p| p[1]).collect();
    lum.sort_by(|a, b| a.partial_cmp(b).unwrap());
    let range = lum[lum.len() * 999 / 1000] / lum[lum.len() / 1000];
    assert!(range > 1000.0, "dynamic range {range}");
    let csv = std::fs::read_to_string(&resp).unwrap();
    assert_eq!(csv.lines().count(), 257);
    assert!(csv.starts_with("z,g_r,g_g,g_b"));
    // times as arguments (fractions) give the same result
    let out2 = tmp.path().join("m2.exr");
    let times = [
        "32", "16", "8", "4", "2", "1", "1/2", "1/4", "1/8", "1/16", "1/32", "1/64", "1/128",
        "1/256", "1/512", "1/1024",
    ];
    let mut args = vec!["hdr", "merge"];
    args.extend(imgs.iter().map(|s| s.as_str()));
    args.push("--times");
    args.extend(times);
    args.extend(["-o", s(&out2)]);
    let o = igi(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(read_image(&out2).unwrap(), im);
}

#[test]
fn merge_errors_missing_file_and_unknown_format() {
    let tmp = tempfile::tempdir().unwrap();
    let a = tmp.path().join("a.png");
    gray_png(&a, 8, 6, 0.5);
    let out = tmp.path().join("out.exr");
    let missing = tmp.path().join("nothere.png");
    let o = igi(&[
        "hdr",
        "merge",
        s(&a),
        s(&missing),
        "--times",
        "1",
        "2",
        "-o",
        s(&out),
    ]);
    assert_failed(
        &o,
        "nothere.png",
        "not found",
        tmp.path(),
        std::slice::from_ref(&a),
    );
    let bmp = tmp.path().join("b.bmp");
    std::fs::write(&bmp, b"BM....").unwrap();
    let o = igi(&[
        "hdr",
        "merge",
        s(&a),
        s(&bmp),
        "--times",
        "1",
        "2",
        "-o",
        s(&out),
    ]);
    assert_failed(
        &o,
        "b.bmp",
        "unknown image format",
        tmp.path(),
        &[a.clone(), bmp.clone()],
    );
}

#[test]
fn merge_errors_sizes_times_and_missing_times() {
    let tmp = tempfile::tempdir().unwrap();
    let a = tmp.path().join("a.png");
    let b = tmp.path().join("b.png");
    let c = tmp.path().join("c.png");
    gray_png(&a, 8, 6, 0.3);
    gray_png(&b, 8, 6, 0.6);
    gray_png(&c, 9, 6, 0.9);
    let keep = [a.clone(), b.clone(), c.clone()];
    let out = tmp.path().join("out.exr");
    let o = igi(&[
        "hdr",
        "merge",
        s(&a),
        s(&b),
        s(&c),
        "--times",
        "1",
        "2",
        "4",
        "-o",
        s(&out),
    ]);
    assert_failed(&o, "c.png", "different sizes", tmp.path(), &keep);
    let o = igi(&[
        "hdr",
        "merge",
        s(&a),
        s(&b),
        "--times",
        "2",
        "2",
        "-o",
        s(&out),
    ]);
    assert_failed(&o, "b.png", "strictly monotonic", tmp.path(), &keep);
    let o = igi(&[
        "hdr",
        "merge",
        s(&a),
        s(&b),
        "--times",
        "1",
        "0",
        "-o",
        s(&out),
    ]);
    assert_failed(&o, "\"0\"", "positive", tmp.path(), &keep);
    let o = igi(&["hdr", "merge", s(&a), s(&b), "--times", "1", "-o", s(&out)]);
    assert_failed(
        &o,
        "2 image(s) but 1 time(s)",
        "missing exposure times",
        tmp.path(),
        &keep,
    );
    // no times and no EXIF in the PNGs
    let o = igi(&["hdr", "merge", s(&a), s(&b), "-o", s(&out)]);
    assert_failed(&o, "a.png", "missing exposure times", tmp.path(), &keep);
    // a response asked of the linear merge, which recovers none: refused before any output
    let curve = tmp.path().join("curve.csv");
    let o = igi(&[
        "hdr",
        "merge",
        s(&a),
        s(&b),
        "--times",
        "1",
        "0.5",
        "--linear",
        "--response-out",
        s(&curve),
        "-o",
        s(&out),
    ]);
    assert_failed(&o, "--response-out", "--linear", tmp.path(), &keep);
    // a good merge of the same files works (sanity check of the fixture)
    let o = igi(&[
        "hdr",
        "merge",
        s(&a),
        s(&b),
        "--times",
        "1",
        "2",
        "-o",
        s(&out),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.exists());
}

#[test]
fn merge_rejects_nan_and_inf_in_float_input() {
    let tmp = tempfile::tempdir().unwrap();
    let good = tmp.path().join("good.exr");
    write_exr(&good, &HdrImage::new(4, 4)).unwrap();
    let out = tmp.path().join("out.exr");
    for (name, bad) in [("nan.exr", f32::NAN), ("inf.exr", f32::INFINITY)] {
        let p = tmp.path().join(name);
        exr::prelude::write_rgb_file(&p, 4, 4, |x, y| {
            if (x, y) == (1, 2) {
                (0.5, bad, 0.5)
            } else {
                (0.5, 0.5, 0.5)
            }
        })
        .unwrap();
        let o = igi(&[
            "hdr",
            "merge",
            "--linear",
            s(&good),
            s(&p),
            "--times",
            "1",
            "2",
            "-o",
            s(&out),
        ]);
        assert_failed(
            &o,
            name,
            "NaN or infinite",
            tmp.path(),
            &[
                good.clone(),
                tmp.path().join("nan.exr"),
                tmp.path().join("inf.exr"),
            ],
        );
    }
}

fn test_camera(dist: Distortion) -> Camera {
    let mut c = Camera::pinhole(64, 48, 60.0, 60.0, 31.5, 23.5);
    c.intrinsics.dist = dist;
    c
}

#[test]
fn camera_undistort_and_bad_rotation() {
    let tmp = tempfile::tempdir().unwrap();
    let img = tmp.path().join("img.exr");
    let mut im = HdrImage::new(64, 48);
    for y in 0..48 {
        for x in 0..64 {
            im.set(x, y, [x as f32 / 64.0, y as f32 / 48.0, 0.25]);
        }
    }
    write_exr(&img, &im).unwrap();
    let cam = tmp.path().join("cam.json");
    test_camera(Distortion {
        k1: 0.15,
        ..Default::default()
    })
    .save(&cam)
    .unwrap();
    let out = tmp.path().join("und.exr");
    let cout = tmp.path().join("und.json");
    let o = igi(&[
        "camera",
        "undistort",
        s(&img),
        "--camera",
        s(&cam),
        "--camera-out",
        s(&cout),
        "-o",
        s(&out),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let u = read_image(&out).unwrap();
    assert_eq!((u.width, u.height), (64, 48));
    // centre pixel is unchanged by radial distortion
    let d = u.get(31, 23);
    let e = im.bilinear(31.0, 23.0).unwrap();
    assert!((d[0] - e[0]).abs() < 1e-3 && (d[1] - e[1]).abs() < 1e-3);
    // pincushion k1 > 0: output corners map outside the input
    assert!(!u.valid[0]);
    assert!(Camera::load(&cout).unwrap().intrinsics.dist.is_zero());

    let bad = tmp.path().join("bad_r.json");
    let mut j: serde_json::Value =
        serde_json::from_str(&test_camera(Distortion::default()).to_json_string()).unwrap();
    j["R"][0][0] = serde_json::json!(1.01);
    std::fs::write(&bad, j.to_string()).unwrap();
    let out2 = tmp.path().join("und2.exr");
    let o = igi(&[
        "camera",
        "undistort",
        s(&img),
        "--camera",
        s(&bad),
        "-o",
        s(&out2),
    ]);
    let keep = [
        img.clone(),
        cam.clone(),
        out.clone(),
        cout.clone(),
        bad.clone(),
    ];
    assert_failed(&o, "bad_r.json", "not orthonormal", tmp.path(), &keep);
}

#[test]
fn camera_pose_from_correspondences() {
    let tmp = tempfile::tempdir().unwrap();
    let mut truth = Camera::pinhole(640, 480, 500.0, 500.0, 320.0, 240.0);
    truth.pose.r = glam::DMat3::from_rotation_x(0.3) * glam::DMat3::from_rotation_z(-0.4);
    truth.pose.t = glam::DVec3::new(0.1, 0.2, 5.0);
    let cam = tmp.path().join("cam.json");
    Camera::pinhole(640, 480, 500.0, 500.0, 320.0, 240.0)
        .save(&cam)
        .unwrap();
    let mut csv = String::from("u,v,x,y,z\n");
    for k in 0..20 {
        let p = glam::DVec3::new(
            (k % 5) as f64 * 0.5 - 1.0,
            (k / 5) as f64 * 0.5 - 0.8,
            ((k * 7) % 5) as f64 * 0.3 - 0.6,
        );
        let q = truth.project(p).unwrap();
        csv.push_str(&format!("{},{},{},{},{}\n", q.x, q.y, p.x, p.y, p.z));
    }
    let pts = tmp.path().join("corr.csv");
    std::fs::write(&pts, csv).unwrap();
    let out = tmp.path().join("posed.json");
    let o = igi(&[
        "camera",
        "pose",
        "--camera",
        s(&cam),
        "--points",
        s(&pts),
        "--json",
        "-o",
        s(&out),
    ]);
    if cfg!(feature = "opencv") {
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let c = Camera::load(&out).unwrap();
        assert!((c.center_world() - truth.center_world()).length() < 1e-3);
    } else {
        assert_failed(
            &o,
            "corr.csv",
            "built without opencv",
            tmp.path(),
            &[cam.clone(), pts.clone()],
        );
    }
    // malformed CSV names the file and line
    std::fs::write(&pts, "u,v,x,y,z\n1,2,3,4\n").unwrap();
    let o = igi(&[
        "camera",
        "pose",
        "--camera",
        s(&cam),
        "--points",
        s(&pts),
        "-o",
        s(&out),
    ]);
    assert_failed(
        &o,
        "corr.csv:2",
        "expected 5 finite numbers",
        tmp.path(),
        &[cam.clone(), pts.clone(), out.clone()],
    );
}

#[test]
fn merge_linear_exr_brackets_recovers_radiance() {
    let tmp = tempfile::tempdir().unwrap();
    let times = [0.01, 0.1, 1.0];
    let field = |x: usize| 10f32.powf(-2.0 + 3.5 * x as f32 / 31.0); // 0.01 .. 31.6
    let mut paths = Vec::new();
    for (k, t) in times.iter().enumerate() {
        let mut im = HdrImage::new(32, 2);
        for y in 0..2 {
            for x in 0..32 {
                let v = (field(x) * *t as f32).min(1.0);
                im.set(x, y, [v, v, v]);
            }
        }
        let p = tmp.path().join(format!("b{k}.exr"));
        write_exr(&p, &im).unwrap();
        paths.push(p.to_string_lossy().into_owned());
    }
    let out = tmp.path().join("m.exr");
    let mut args = vec!["hdr", "merge", "--linear", "--json"];
    args.extend(paths.iter().map(|s| s.as_str()));
    args.extend(["--times", "0.01", "0.1", "1", "-o", s(&out)]);
    let o = igi(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["method"], "linear");
    assert_eq!(j["valid_fraction"], 1.0);
    let m = read_image(&out).unwrap();
    for x in 0..32 {
        let got = m.get(x, 0)[0];
        assert!(
            (got / field(x) - 1.0).abs() < 1e-5,
            "x={x}: {got} vs {}",
            field(x)
        );
    }
}
