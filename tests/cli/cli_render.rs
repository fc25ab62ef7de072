//! End-to-end tests of `igi render` and `igi compare`.

use std::path::Path;
use std::process::Command;

fn igi() -> Command {
    igi_testkit::Cli::new(env!("CARGO_BIN_EXE_igi")).command()
}

/// A 40 m ground quad (albedo 0.5 or a 2x1 texture), a sun at 30 degrees from the zenith and a
/// camera 10 m above looking straight down.
fn write_scene(dir: &Path, textured: bool) {
    std::fs::create_dir_all(dir.join("geometry")).unwrap();
    std::fs::create_dir_all(dir.join("lighting")).unwrap();
    let mesh = igi_geometry::TriMesh {
        positions: vec![
            [-20.0, -20.0, 0.0],
            [20.0, -20.0, 0.0],
            [20.0, 20.0, 0.0],
            [-20.0, 20.0, 0.0],
        ],
        normals: None,
        uvs: Some(vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]),
        colors: None,
        indices: vec![[0, 1, 2], [0, 2, 3]],
    };
    igi_geometry::write_ply(&dir.join("geometry/ground.ply"), &mesh).unwrap();
    let albedo = if textured {
        let mut t = igi_imaging::HdrImage::new(2, 1);
        t.set(0, 0, [0.2, 0.2, 0.2]);
        t.set(1, 0, [0.8, 0.8, 0.8]);
        igi_imaging::write_exr(&dir.join("geometry/albedo.exr"), &t).unwrap();
        "\"geometry/albedo.exr\"".to_string()
    } else {
        "[0.5, 0.5, 0.5]".to_string()
    };
    let a = 30f64.to_radians();
    std::fs::write(
        dir.join("lighting/sun.toml"),
        format!("[sun]\ndirection = [{}, 0.0, {}]\nradiance = [100000, 100000, 100000]\nangular_diameter_deg = 0.53\n", a.sin(), a.cos()),
    )
    .unwrap();
    std::fs::write(
        dir.join("scene.toml"),
        format!("lighting = \"lighting/sun.toml\"\n[[object]]\nmesh = \"geometry/ground.ply\"\nalbedo = {albedo}\n"),
    )
    .unwrap();
    std::fs::write(
        dir.join("camera.json"),
        r#"{ "width": 16, "height": 12, "K": [[20, 0, 7.5], [0, 20, 5.5], [0, 0, 1]],
             "R": [[1, 0, 0], [0, -1, 0], [0, 0, -1]], "t": [0, 0, 10] }"#,
    )
    .unwrap();
}

/// `igi render` of the scene in `dir` at its camera into `NAME.exr` with its standard error
/// in `NAME_se.exr`, plus `extra` arguments; returns the two paths.
fn render_cli(
    dir: &Path,
    spp: &str,
    seed: &str,
    name: &str,
    extra: &[&str],
) -> (std::path::PathBuf, std::path::PathBuf) {
    let out = dir.join(format!("{name}.exr"));
    let se = dir.join(format!("{name}_se.exr"));
    let st = igi()
        .args(["-q", "render"])
        .arg(dir.join("scene.toml"))
        .arg("--camera")
        .arg(dir.join("camera.json"))
        .args(["--spp", spp, "--seed", seed, "--stderr"])
        .arg(&se)
        .arg("-o")
        .arg(&out)
        .args(extra)
        .output()
        .unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    (out, se)
}

fn e_sun() -> f64 {
    let half = (0.53f64 / 2.0).to_radians();
    1e5 * 2.0 * std::f64::consts::PI * (1.0 - half.cos()) * 30f64.to_radians().cos()
}

#[test]
fn render_matches_analytic_sunlit_plane_and_writes_stderr() {
    let dir = tempfile::tempdir().unwrap();
    write_scene(dir.path(), false);
    let (out, se) = render_cli(dir.path(), "16", "3", "out", &["--indirect", "2"]);
    let img = igi_imaging::read_image(&out).unwrap();
    let se_img = igi_imaging::read_image(&se).unwrap();
    assert_eq!((img.width, img.height), (16, 12));
    let expect = 0.5 / std::f64::consts::PI * e_sun();
    for (p, s) in img.pixels.iter().zip(&se_img.pixels) {
        for c in 0..3 {
            assert!(
                ((p[c] as f64) - expect).abs() < 2e-3 * expect,
                "{p:?} vs {expect}"
            );
            assert!(s[c].is_finite() && (s[c] as f64) < 2e-3 * expect);
        }
    }
    // Same seed, same image; compare reports zero error.
    let out2 = dir.path().join("out2.exr");
    let st = igi()
        .args(["-q", "render"])
        .arg(dir.path().join("scene.toml"))
        .arg("--camera")
        .arg(dir.path().join("camera.json"))
        .args(["--spp", "16", "--seed", "3", "-o"])
        .arg(&out2)
        .output()
        .unwrap();
    assert!(st.status.success());
    assert_eq!(igi_imaging::read_image(&out2).unwrap().pixels, img.pixels);
    let diff = dir.path().join("diff.png");
    let c = igi()
        .arg("compare")
        .arg(&out)
        .arg(&out2)
        .arg("--json")
        .arg("--diff")
        .arg(&diff)
        .output()
        .unwrap();
    assert!(c.status.success(), "{}", String::from_utf8_lossy(&c.stderr));
    let v: serde_json::Value = serde_json::from_slice(&c.stdout).unwrap();
    assert_eq!(v["rmse"].as_f64().unwrap(), 0.0);
    assert!(diff.exists());
}

#[test]
fn textured_plane_and_compare_with_noise_rmse() {
    let dir = tempfile::tempdir().unwrap();
    write_scene(dir.path(), true);
    let render = |spp: &str, seed: &str, name: &str| render_cli(dir.path(), spp, seed, name, &[]);
    let (a, sa) = render("8", "1", "a");
    let (b, sb) = render("8", "2", "b");
    let img = igi_imaging::read_image(&a).unwrap();
    // The camera sees x in [-3.75, 3.75] m of the 40 m quad: u = (x + 20) / 40 in [0.41, 0.59],
    // between the two texel centres (0.25 and 0.75): bilinear albedo 0.2 + 0.6 (u - 0.25) / 0.5.
    let cam_x = |col: usize| (col as f64 - 7.5) / 20.0 * 10.0;
    for col in [0usize, 8, 15] {
        let u = (cam_x(col) + 20.0) / 40.0;
        let rho = 0.2 + 0.6 * (u - 0.25) / 0.5;
        let expect = rho / std::f64::consts::PI * e_sun();
        let got = img.get(col, 6)[1] as f64;
        // 2 % tolerance: the pixel box filter averages rho over 0.5 m (linear, so exact) and MC noise.
        assert!(
            (got - expect).abs() < 0.01 * expect,
            "col {col}: {got} vs {expect}"
        );
    }
    let c = igi()
        .arg("compare")
        .arg(&a)
        .arg(&b)
        .arg("--stderr-a")
        .arg(&sa)
        .arg("--stderr-b")
        .arg(&sb)
        .output()
        .unwrap();
    assert!(c.status.success(), "{}", String::from_utf8_lossy(&c.stderr));
    let text = String::from_utf8_lossy(&c.stdout);
    assert!(
        text.contains("RMSE") && text.contains("explained by noise") && text.contains("PSNR"),
        "{text}"
    );
}

#[test]
fn bad_inputs_give_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    write_scene(dir.path(), false);
    let run = |args: &[&std::ffi::OsStr]| {
        let o = igi().arg("render").args(args).output().unwrap();
        assert!(!o.status.success());
        String::from_utf8_lossy(&o.stderr).to_string()
    };
    let cam = dir.path().join("camera.json");
    let out = dir.path().join("o.exr");
    let e = run(&[
        dir.path().as_os_str(),
        "--camera".as_ref(),
        cam.as_os_str(),
        "-o".as_ref(),
        out.as_os_str(),
    ]);
    // A folder is taken as a solve result, which needs --lighting.
    assert!(
        e.contains(&dir.path().display().to_string()) && e.contains("--lighting"),
        "{e}"
    );
    let missing = dir.path().join("nocam.json");
    let scene = dir.path().join("scene.toml");
    let e = run(&[
        scene.as_os_str(),
        "--camera".as_ref(),
        missing.as_os_str(),
        "-o".as_ref(),
        out.as_os_str(),
    ]);
    assert!(e.contains("nocam.json"), "{e}");
    std::fs::write(
        dir.path().join("broken.toml"),
        "[[object]]\nmesh = \"geometry/ground.ply\"\n",
    )
    .unwrap();
    let broken = dir.path().join("broken.toml");
    let e = run(&[
        broken.as_os_str(),
        "--camera".as_ref(),
        cam.as_os_str(),
        "-o".as_ref(),
        out.as_os_str(),
    ]);
    assert!(e.contains("broken.toml") && e.contains("albedo"), "{e}");
    let o = igi().arg("compare").arg(&cam).arg(&cam).output().unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("camera.json"));
}

/// The scene of [`write_scene`] (with its occluder) lit by the sun and a graded sky.
fn write_sky_scene(dir: &Path) {
    write_scene(dir, true);
    let mut sky = igi_imaging::HdrImage::new(16, 8);
    for y in 0..8 {
        for x in 0..16 {
            let l = if y < 4 {
                0.5 + 3.0 * x as f32 / 16.0
            } else {
                0.0
            };
            sky.set(x, y, [l, l, l]);
        }
    }
    igi_imaging::write_exr(&dir.join("lighting/sky.exr"), &sky).unwrap();
    let sun = std::fs::read_to_string(dir.join("lighting/sun.toml")).unwrap();
    std::fs::write(
        dir.join("lighting/sun.toml"),
        format!("[environment]\nmap = \"sky.exr\"\n\n{sun}"),
    )
    .unwrap();
}

/// `igi render --stratified` under a graded sky and the sun: the same image on average, with far
/// less noise between seeds than independent samples at the same `spp`, and a standard error
/// that bounds that noise from above.
#[test]
fn stratified_render_is_the_same_image_with_less_noise() {
    let dir = tempfile::tempdir().unwrap();
    write_sky_scene(dir.path());
    let render = |seed: &str, spp: &str, stratified: bool| {
        let extra: &[&str] = if stratified { &["--stratified"] } else { &[] };
        let (out, se) = render_cli(
            dir.path(),
            spp,
            seed,
            &format!("r{seed}_{stratified}"),
            extra,
        );
        (
            igi_imaging::read_image(&out).unwrap(),
            igi_imaging::read_image(&se).unwrap(),
        )
    };
    let spread = |a: &igi_imaging::HdrImage, b: &igi_imaging::HdrImage| {
        a.pixels
            .iter()
            .zip(&b.pixels)
            .map(|(p, q)| ((p[1] - q[1]) as f64).powi(2))
            .sum::<f64>()
            / a.pixels.len() as f64
    };
    let mean = |a: &igi_imaging::HdrImage| {
        a.pixels.iter().map(|p| p[1] as f64).sum::<f64>() / a.pixels.len() as f64
    };
    let mean_square = |a: &igi_imaging::HdrImage| {
        a.pixels.iter().map(|p| (p[1] as f64).powi(2)).sum::<f64>() / a.pixels.len() as f64
    };
    let (s1, se1) = render("1", "16", true);
    let (s2, se2) = render("2", "16", true);
    let (r1, _) = render("3", "16", false);
    let (r2, _) = render("4", "16", false);
    let (noise_s, noise_r) = (spread(&s1, &s2), spread(&r1, &r2));
    assert!(
        noise_s < 0.25 * noise_r,
        "seed-to-seed squared difference: stratified {noise_s}, independent {noise_r}"
    );
    let reported = mean_square(&se1) + mean_square(&se2);
    assert!(noise_s <= reported, "noise {noise_s}, reported {reported}");
    let (reference, _) = render("5", "1024", false);
    let (m, m_ref) = (0.5 * (mean(&s1) + mean(&s2)), mean(&reference));
    assert!(
        (m - m_ref).abs() < 2e-3 * m_ref,
        "image mean stratified {m}, reference {m_ref}"
    );
}

/// `igi render --adaptive`: the same image on average (against 1024 independent samples a
/// pixel); too few samples for its pilot is an error that writes nothing.
#[test]
fn adaptive_render_is_the_same_image_and_needs_samples_for_its_pilot() {
    let dir = tempfile::tempdir().unwrap();
    write_sky_scene(dir.path());
    // the image mean (green) and its standard error from the per-pixel standard errors
    let mean = |p: &Path, se: &Path| {
        let (a, s) = (
            igi_imaging::read_image(p).unwrap(),
            igi_imaging::read_image(se).unwrap(),
        );
        let n = a.pixels.len() as f64;
        let var = s.pixels.iter().map(|p| (p[1] as f64).powi(2)).sum::<f64>();
        (
            a.pixels.iter().map(|p| p[1] as f64).sum::<f64>() / n,
            var.sqrt() / n,
        )
    };
    let (a, a_se) = render_cli(dir.path(), "32", "1", "adaptive", &["--adaptive"]);
    let (reference, r_se) = render_cli(dir.path(), "1024", "2", "reference", &[]);
    let ((m, se), (m_ref, se_ref)) = (mean(&a, &a_se), mean(&reference, &r_se));
    // within 4 standard errors of the difference (about 0.0055, 0.3 % of the mean: a bound of
    // 0.4 % was 1.4 of them, and seed 1 of the packet tracer sits 1.9 away, seeds 3 and 4 0.3)
    assert!(
        (m - m_ref).abs() < 4.0 * (se * se + se_ref * se_ref).sqrt(),
        "image mean adaptive {m} +- {se}, reference {m_ref} +- {se_ref}"
    );
    assert!(se < 0.005 * m, "adaptive standard error {se} of {m}");
    let out = dir.path().join("few.exr");
    let st = igi()
        .args(["-q", "render"])
        .arg(dir.path().join("scene.toml"))
        .arg("--camera")
        .arg(dir.path().join("camera.json"))
        .args(["--spp", "8", "--adaptive", "-o"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(!st.status.success());
    let e = String::from_utf8_lossy(&st.stderr);
    assert!(e.contains("--adaptive needs --spp 16"), "{e}");
    assert!(!out.exists());
}
