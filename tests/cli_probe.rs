//! End-to-end `igi probe` on the Mitsuba board fixtures: the FORMATS.md invocation (HDR image)
//! and the bracket form, outputs, diagnostics, and clear errors for bad input.

use std::path::{Path, PathBuf};
use std::process::Command;

fn fixture(case: &str) -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/datasets/fixtures/board")).join(case)
}

fn igi(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_igi")).args(args).arg("--quiet").output().unwrap()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn angle_deg(a: &[f64], b: &[f64]) -> f64 {
    let d: f64 = a.iter().zip(b).map(|(x, y)| x * y).sum();
    d.clamp(-1.0, 1.0).acos().to_degrees()
}

fn truth(case: &str) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(fixture(case).join("truth.json")).unwrap()).unwrap()
}

#[test]
fn probe_hdr_image_writes_lighting_sky_diagnostics_and_pictures() {
    let f = fixture("sunny");
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("noon.toml");
    let o = igi(&["probe", s(&f.join("board.exr")), "--camera", s(&f.join("camera.json")), "--board", s(&f.join("board.json")), "-o", s(&out)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(text.contains("map = \"noon_sky.exr\""), "{text}");
    // the renderer's own loader accepts the lighting file
    let lighting = igi_render::Lighting::load(&out).unwrap();
    let sun = lighting.sun.as_ref().expect("sun section");
    let env = lighting.environment.as_ref().expect("environment section");
    assert_eq!((env.width(), env.height()), (256, 128));
    let dir: Vec<f64> = sun.direction.to_array().iter().map(|v| *v as f64).collect();
    let rad: Vec<f64> = sun.radiance.to_array().iter().map(|v| *v as f64).collect();
    assert!((sun.angular_diameter.to_degrees() - 0.53).abs() < 1e-4 || (sun.angular_diameter - 0.53).abs() < 1e-4);
    let t = truth("sunny");
    let dir_t: Vec<f64> = serde_json::from_value(t["sun"]["direction"].clone()).unwrap();
    let rad_t: Vec<f64> = serde_json::from_value(t["sun"]["radiance"].clone()).unwrap();
    assert!(angle_deg(&dir, &dir_t) < 0.25);
    for c in 0..3 {
        assert!((rad[c] / rad_t[c] - 1.0).abs() < 0.02, "{rad:?}");
    }
    let sky = igi_imaging::read_image(&tmp.path().join("noon_sky.exr")).unwrap();
    assert_eq!((sky.width, sky.height), (256, 128));
    assert!(sky.valid.iter().all(|v| *v) && sky.pixels.iter().flatten().all(|v| v.is_finite() && *v >= 0.0));
    let diag: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(tmp.path().join("noon_diagnostics.json")).unwrap()).unwrap();
    assert_eq!(diag["sun_found"], true);
    assert!(diag["check_rms_percent"].as_f64().unwrap() < 2.0);
    assert!(diag["sun"]["residual_rms_percent"].as_f64().unwrap() < 2.0);
    for p in ["mirror_hemi.png", "black_hemi.png", "diffuse_hemi.png", "sky.png", "diffuse_check.png", "mirror_hemi.exr", "sky_measured.exr"] {
        assert!(tmp.path().join(format!("noon_{p}")).is_file(), "{p}");
    }
    let hemi = igi_imaging::read_image(&tmp.path().join("noon_mirror_hemi.exr")).unwrap();
    assert_eq!((hemi.width, hemi.height), (512, 512));
}

#[test]
fn probe_brackets_cloudy_skips_the_sun() {
    let f = fixture("cloudy");
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("cloudy.toml");
    let b: Vec<PathBuf> = (0..3).map(|i| f.join(format!("bracket_{i}.png"))).collect();
    let o = igi(&[
        "probe", "--brackets", s(&b[0]), s(&b[1]), s(&b[2]), "--times", "0.25", "1/32", "1/256",
        "--camera", s(&f.join("camera.json")), "--board", s(&f.join("board.json")), "-o", s(&out),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let lighting = igi_render::Lighting::load(&out).unwrap();
    assert!(lighting.sun.is_none());
    assert!(lighting.environment.is_some());
    let diag: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(tmp.path().join("cloudy_diagnostics.json")).unwrap()).unwrap();
    assert_eq!(diag["sun_found"], false);
    assert!(diag["sun"].is_null());
    assert!(diag["check_rms_percent"].as_f64().unwrap() < 2.0);
    assert!(String::from_utf8_lossy(&o.stderr).contains("sun solve skipped"));
}

#[test]
fn probe_bad_input_is_a_clear_error() {
    let f = fixture("sunny");
    let tmp = tempfile::tempdir().unwrap();
    // board partly outside the image
    let board = tmp.path().join("board.json");
    std::fs::write(
        &board,
        r#"{"spheres":[{"kind":"mirror","center":[-0.3,-0.08,0.6],"radius":0.07},{"kind":"diffuse","center":[0,0.1,0.6],"radius":0.07}]}"#,
    )
    .unwrap();
    let o = igi(&["probe", s(&f.join("board.exr")), "--camera", s(&f.join("camera.json")), "--board", s(&board), "-o", s(&tmp.path().join("x.toml"))]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("mirror sphere is partly outside the 256x256 image"), "{e}");
    assert!(!tmp.path().join("x.toml").exists());
    // malformed board names the file
    std::fs::write(&board, r#"{"spheres":[{"kind":"mirror","center":[0,0,1]}]}"#).unwrap();
    let o = igi(&["probe", s(&f.join("board.exr")), "--camera", s(&f.join("camera.json")), "--board", s(&board), "-o", s(&tmp.path().join("x.toml"))]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && e.contains("board.json") && e.contains("radius"), "{e}");
    // brackets and times must pair up
    let o = igi(&[
        "probe", "--brackets", s(&f.join("bracket_0.png")), s(&f.join("bracket_1.png")), "--times", "0.25",
        "--camera", s(&f.join("camera.json")), "--board", s(&f.join("board.json")), "-o", s(&tmp.path().join("x.toml")),
    ]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && e.contains("2 brackets but 1 exposure times"), "{e}");
}
