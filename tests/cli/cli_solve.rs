//! End-to-end tests of `igi demo`, `igi solve`, `igi render RESULT_DIR`, `igi export` and
//! `igi sample` on the embedded default (quick size).

use igi_testkit::run_ok;
use std::path::{Path, PathBuf};
use std::process::Command;

fn igi() -> Command {
    igi_testkit::Cli::new(env!("CARGO_BIN_EXE_igi")).command()
}

fn json(s: &str) -> serde_json::Value {
    serde_json::from_str(s).expect("JSON on stdout")
}

#[test]
fn demo_then_solve_resume_relight_export_and_sample() {
    let tmp = tempfile::tempdir().unwrap();
    let tmp = tmp.path();
    let demo = tmp.join("demo");
    run_demo(&demo);
    let survey = demo.join("survey");
    let res = solve_and_resume(tmp, &survey);
    let img = relight(tmp, &res, &survey);
    for fmt in ["ply", "obj", "mitsuba"] {
        check_export(tmp, &res, &survey, &img, fmt);
    }
    check_sample(tmp, &res);
    let (prepared_survey, man) = prepare_site(tmp, &survey);
    solve_one_voxel(tmp, &prepared_survey, &man);
    jacobi_voxels_are_independent(tmp, &prepared_survey, &man);
}

/// `igi demo --quick` into `demo`: its report and files.
fn run_demo(demo: &Path) {
    let d = json(&run_ok(
        igi()
            .args(["demo", "--quick", "--quiet", "--json", "-o"])
            .arg(demo),
    ));
    assert_eq!(d["photos"], 8);
    // the albedo error per texel and over the surface
    for key in ["albedo_mae", "albedo_surface_mae"] {
        let mae = d[key].as_array().expect("demo reports the albedo error");
        assert!(
            mae.iter().all(|m| m.as_f64().unwrap() < 0.15),
            "quick demo {key} {mae:?}"
        );
    }
    for f in [
        "demo.json",
        "pictures/relit.png",
        "pictures/convergence.png",
        "result/report.json",
        "survey/survey.toml",
    ] {
        assert!(demo.join(f).is_file(), "{f}");
    }
}

/// Solves the demo's survey from the CLI: one iteration, then resume for a second; returns
/// the result folder.
fn solve_and_resume(tmp: &Path, survey: &Path) -> PathBuf {
    let res = tmp.join("res");
    let solve = |iters: &str| {
        json(&run_ok(
            igi()
                .arg("solve")
                .arg(survey)
                .arg("-o")
                .arg(&res)
                .args([
                    "--atlas",
                    "32",
                    "--spp",
                    "8,32",
                    "--iterations",
                    iters,
                    "--quiet",
                    "--json",
                    "--truth",
                ])
                .arg(survey.join("truth/scene.toml")),
        ))
    };
    let r1 = solve("1");
    assert_eq!(r1["iterations"].as_array().unwrap().len(), 1);
    let r2 = solve("3");
    let its = r2["iterations"].as_array().unwrap();
    assert!(
        its.len() >= 2,
        "resumed and continued: {} iterations",
        its.len()
    );
    assert_eq!(
        its[0]["observations"], r1["iterations"][0]["observations"],
        "iteration 1 was kept, not redone"
    );
    let err = |i: &serde_json::Value| i["truth_rms"].as_f64().unwrap();
    assert!(
        err(its.last().unwrap()) < err(&its[0]),
        "rho_d error falls: {} -> {}",
        err(&its[0]),
        err(its.last().unwrap())
    );

    res
}

/// Re-lights the result under the held-out lighting; returns the image.
fn relight(tmp: &Path, res: &Path, survey: &Path) -> igi_imaging::HdrImage {
    let relit = tmp.join("relit.exr");
    run_ok(
        igi()
            .arg("render")
            .arg(res)
            .arg("--lighting")
            .arg(survey.join("lighting/held-out.toml"))
            .arg("--camera")
            .arg(survey.join("cameras/held-out.json"))
            .args(["--spp", "4", "--quiet", "-o"])
            .arg(&relit),
    );
    let img = igi_imaging::read_image(&relit).unwrap();
    assert!(img
        .pixels
        .iter()
        .all(|p| p.iter().all(|c| c.is_finite() && *c >= 0.0)));
    let mean: f64 = img
        .pixels
        .iter()
        .map(|p| (p[0] + p[1] + p[2]) as f64)
        .sum::<f64>()
        / (3 * img.pixels.len()) as f64;
    assert!(mean > 0.0);
    // without --lighting a result folder is refused clearly
    let out = igi()
        .arg("render")
        .arg(res)
        .arg("--camera")
        .arg(survey.join("cameras/held-out.json"))
        .arg("-o")
        .arg(tmp.join("x.exr"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--lighting"));
    assert!(!tmp.join("x.exr").exists());

    img
}

/// Export in `fmt`: every file the Mitsuba scene names exists, and the export renders as the
/// result does.
fn check_export(tmp: &Path, res: &Path, survey: &Path, img: &igi_imaging::HdrImage, fmt: &str) {
    let dir = tmp.join(format!("export-{fmt}"));
    run_ok(
        igi()
            .arg("export")
            .arg(res)
            .args(["--format", fmt, "-o"])
            .arg(&dir),
    );
    assert!(dir.join("terrain_albedo.exr").is_file(), "{fmt}");
    let png = igi_imaging::read_image(&dir.join("terrain_stderr.png")).unwrap();
    assert_eq!(png.width, result_res(res, "terrain"), "{fmt}");
    // grey where known (a standard error below 0.05 is darker than white), magenta where not
    assert!(
        png.pixels
            .iter()
            .all(|p| p[0] == p[2] && (p[1] == p[0] || (p[0] == 1.0 && p[1] == 0.0))),
        "{fmt}"
    );
    assert!(
        png.pixels.iter().any(|p| p[1] < 1.0 && p[1] == p[0]),
        "{fmt}"
    );
    // the export's scene.toml (albedo and lobe maps) renders exactly as the result does
    let scene = std::fs::read_to_string(dir.join("scene.toml")).unwrap();
    let result_scene = std::fs::read_to_string(res.join("scene.toml")).unwrap();
    assert_eq!(
        scene.matches("lobe_maps").count(),
        result_scene.matches("lobe_maps").count(),
        "{fmt}: {scene}"
    );
    let again = tmp.join(format!("export-{fmt}.exr"));
    run_ok(
        igi()
            .arg("render")
            .arg(dir.join("scene.toml"))
            .arg("--lighting")
            .arg(survey.join("lighting/held-out.toml"))
            .arg("--camera")
            .arg(survey.join("cameras/held-out.json"))
            .args(["--spp", "4", "--quiet", "-o"])
            .arg(&again),
    );
    assert!(
        igi_imaging::read_image(&again).unwrap().pixels == img.pixels,
        "{fmt}: the export renders differently from the result"
    );
    if fmt == "mitsuba" {
        let xml = std::fs::read_to_string(dir.join("scene.xml")).unwrap();
        assert_eq!(
            xml.contains("APPROXIMATION"),
            result_scene.contains("lobe"),
            "{xml}"
        );
        for name in xml
            .split("value=\"")
            .skip(1)
            .map(|s| s.split('"').next().unwrap())
        {
            if name.ends_with(".ply") || name.ends_with(".exr") {
                assert!(dir.join(name).is_file(), "scene.xml names {name}");
            }
        }
    }
}

/// `igi sample`: points on the surface get the albedo of the texel under them, a point off
/// it the nearest covered texel's.
fn check_sample(tmp: &Path, res: &Path) {
    let result = igi_reflect::SolveResult::load(res).unwrap();
    let part = result
        .parts
        .iter()
        .position(|p| p.name() == "wall")
        .unwrap();
    let texels: Vec<_> = result.parts[part]
        .part
        .cache
        .texels
        .iter()
        .step_by(37)
        .take(5)
        .copied()
        .collect();
    let mut csv = points_csv(&texels);
    // and one 20 cm in front of the wall with a normal along it, so no short ray finds a
    // surface: the nearest covered texel of any part (k-d tree), checked against brute force
    let off = texels[2].position + texels[2].normal * 0.2;
    let along = texels[2].normal.cross(glam::Vec3::Z).normalize();
    csv.push_str(&format!(
        "{},{},{},{},{},{}\n",
        off.x, off.y, off.z, along.x, along.y, along.z
    ));
    let nearest = nearest_texel(&result, off);
    let pts = tmp.join("points.csv");
    std::fs::write(&pts, csv).unwrap();
    let vals = tmp.join("values.csv");
    run_ok(
        igi()
            .arg("sample")
            .arg(res)
            .arg("--points")
            .arg(&pts)
            .arg("-o")
            .arg(&vals),
    );
    let text = std::fs::read_to_string(&vals).unwrap();
    assert_eq!(text.lines().next(), Some("x,y,z,nx,ny,nz,r,g,b,sr,sg,sb"));
    let last: Vec<f32> = text
        .lines()
        .last()
        .unwrap()
        .split(',')
        .take(9)
        .map(|v| v.parse().unwrap())
        .collect();
    assert_eq!(
        &last[6..9],
        &nearest.1.to_array(),
        "the nearest texel off the surface ({} m away): {text}",
        nearest.0.sqrt()
    );
    let mut known = 0;
    for (line, t) in text.lines().skip(1).zip(&texels) {
        let v: Vec<Option<f32>> = line.split(',').map(|s| s.parse().ok()).collect();
        assert_eq!(v.len(), 12, "{line}");
        let se = result.parts[part].stderr[t.index as usize];
        // the standard error of the texel under the point, or empty where unknown
        if se.min_element() >= 0.0 {
            known += 1;
            for ch in 0..3 {
                assert_eq!(v[9 + ch], Some(se[ch]), "{line} vs {se}");
            }
        } else {
            assert!(v[9..].iter().all(|x| x.is_none()), "{line}");
        }
        let v: Vec<f32> = v[..9].iter().map(|x| x.unwrap()).collect();
        let want = result.parts[part].rho[t.index as usize];
        // bilinear lookup at the texel centre returns the texel itself
        assert!(
            (v[6] - want.x).abs() < 2e-3
                && (v[7] - want.y).abs() < 2e-3
                && (v[8] - want.z).abs() < 2e-3,
            "{line} vs {want}"
        );
    }

    assert!(known > 0, "no sampled point has a standard error");
}

/// The CSV of `igi sample --points`: the texels' positions and normals.
fn points_csv(texels: &[igi_geometry::texels::Texel]) -> String {
    let mut csv = String::from("x,y,z,nx,ny,nz\n");
    for t in texels {
        csv.push_str(&format!(
            "{},{},{},{},{},{}\n",
            t.position.x, t.position.y, t.position.z, t.normal.x, t.normal.y, t.normal.z
        ));
    }
    csv
}

/// The squared distance to `off` of the nearest covered texel of any part, and its albedo
/// (by brute force).
fn nearest_texel(result: &igi_reflect::SolveResult, off: glam::Vec3) -> (f32, glam::Vec3) {
    let mut nearest = (f32::INFINITY, glam::Vec3::ZERO);
    for p in &result.parts {
        for t in &p.part.cache.texels {
            let d = t.position.distance_squared(off);
            if d < nearest.0 {
                nearest = (d, p.rho[t.index as usize]);
            }
        }
    }
    nearest
}

/// `igi prepare` the stylobate (with the terrain) and name it in a copy of the survey;
/// returns that survey and the site's manifest.
fn prepare_site(tmp: &Path, survey: &Path) -> (PathBuf, serde_json::Value) {
    // a prepared site: `igi prepare` the stylobate (with the terrain), name it in a copy of
    // the survey, and solve one voxel of it (--voxels); the others are not touched
    let site = tmp.join("site.igi");
    run_ok(
        igi()
            .arg("-q")
            .arg("prepare")
            .arg(survey.join("geometry/stylobate.ply"))
            .arg("--terrain")
            .arg(survey.join("geometry/terrain.ply"))
            .args(["--atlas", "32", "-o"])
            .arg(&site),
    );
    let text = std::fs::read_to_string(survey.join("survey.toml")).unwrap();
    let photos = &text[text.find("[[photo]]").unwrap()..];
    let prepared_survey = survey.join("prepared.toml");
    std::fs::write(
        &prepared_survey,
        format!(
            "[site]\nprepared = {:?}\n\n{photos}",
            site.display().to_string()
        ),
    )
    .unwrap();
    let man: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(site.join("manifest.json")).unwrap())
            .unwrap();
    (prepared_survey, man)
}

/// Solves one voxel of the prepared site (--voxels); the others are not touched.
fn solve_one_voxel(tmp: &Path, prepared_survey: &Path, man: &serde_json::Value) {
    let v = &man["voxels"][0]["voxel"];
    let name = format!("{}_{}_{}", v[0], v[1], v[2]);
    let pres = tmp.join("prepared-result");
    let r = json(&run_ok(
        igi()
            .arg("solve")
            .arg(prepared_survey)
            .arg("-o")
            .arg(&pres)
            .args([
                "--spp",
                "4",
                "--iterations",
                "1",
                "--quiet",
                "--json",
                "--voxels",
                &name,
            ]),
    ));
    let parts = r["parts"].as_array().unwrap();
    assert_eq!(
        parts.len(),
        man["voxels"].as_array().unwrap().len() + 1,
        "every voxel and the terrain"
    );
    for p in parts {
        let solved = p["name"] == name.as_str();
        assert_eq!(
            p["scene_triangles"].as_u64().unwrap() > 0,
            solved,
            "{}",
            p["name"]
        );
        if !solved {
            assert_eq!(p["seen_texels"], 0, "{}", p["name"]);
        }
    }
    assert!(r["site"].as_str().unwrap().ends_with("site.igi"));
    assert!(pres.join(format!("parts/{name}_rho_d.exr")).is_file());
}

/// The Jacobi schedule makes the voxels of an iteration independent; an unknown voxel is
/// refused.
fn jacobi_voxels_are_independent(tmp: &Path, prepared_survey: &Path, man: &serde_json::Value) {
    // the Jacobi schedule makes the voxels of an iteration independent (what a cluster needs):
    // each voxel solved alone equals, byte for byte, that voxel in a solve of the whole site;
    // Gauss-Seidel, where later voxels see earlier ones' new albedo, does not
    let solve_voxels = |out: &str, schedule: &str, voxels: Option<&str>| {
        let mut cmd = igi();
        cmd.arg("-q")
            .arg("solve")
            .arg(prepared_survey)
            .arg("-o")
            .arg(tmp.join(out))
            .args(["--spp", "4", "--iterations", "1", "--schedule", schedule]);
        if let Some(v) = voxels {
            cmd.args(["--voxels", v]);
        }
        run_ok(&mut cmd);
        let dir = tmp.join(out).join("parts");
        move |voxel: &str| std::fs::read(dir.join(format!("{voxel}_rho_d.exr"))).unwrap()
    };
    let names: Vec<String> = man["voxels"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| {
            let v = &v["voxel"];
            format!("{}_{}_{}", v[0], v[1], v[2])
        })
        .collect();
    assert!(names.len() >= 8, "{} voxels", names.len());
    let whole = solve_voxels("jacobi-all", "jacobi", None);
    let gauss = solve_voxels("gauss-all", "gauss-seidel", None);
    let mut gauss_differs = false;
    let terrain = "terrain".to_string();
    for v in [&names[1], &names[names.len() - 1], &terrain] {
        let alone = solve_voxels(&format!("jacobi-{v}"), "jacobi", Some(v));
        assert!(
            alone(v) == whole(v),
            "{v}: Jacobi alone differs from Jacobi whole"
        );
        gauss_differs |= gauss(v) != whole(v);
    }
    assert!(
        gauss_differs,
        "Gauss-Seidel should see earlier voxels' new albedo"
    );
    // an unknown voxel is refused
    let out = igi()
        .arg("solve")
        .arg(prepared_survey)
        .arg("-o")
        .arg(tmp.join("x"))
        .args(["--voxels", "99_99_99", "--restart"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("99_99_99"));
}

fn write(path: &Path, text: &str) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(path, text).unwrap();
}

#[test]
fn bad_surveys_fail_clearly_without_output() {
    let tmp = tempfile::tempdir().unwrap();
    let s = tmp.path().join("s");
    write(&s.join("survey.toml"), "[site]\nmesh = \"geometry/site.ply\"\n[[photo]]\nid = \"a\"\nimage = \"photos/a.exr\"\ncamera = \"c.json\"\nlighting = \"l.toml\"\n");
    let out_dir = tmp.path().join("out");
    let out = igi()
        .arg("solve")
        .arg(&s)
        .arg("-o")
        .arg(&out_dir)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("survey.toml") && err.contains("site.ply") && err.contains("does not exist"),
        "{err}"
    );
    assert!(!out_dir.exists(), "no output folder for a bad survey");

    write(&s.join("survey.toml"), "[site]\nmesh = 3\n");
    let out = igi()
        .arg("solve")
        .arg(&s)
        .arg("-o")
        .arg(&out_dir)
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("not a valid survey file"));
    assert!(!out_dir.exists());
}

/// The atlas resolution of part `name` of a result folder.
fn result_res(res: &std::path::Path, name: &str) -> usize {
    let r = igi_reflect::SolveResult::load(res).unwrap();
    let i = r.parts.iter().position(|p| p.name() == name).unwrap();
    r.parts[i].resolution()
}
