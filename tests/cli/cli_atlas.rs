//! `igi solve --atlas auto` on the Mitsuba survey fixture (`datasets/fixtures/survey`): each
//! part's atlas resolution follows from the resolving pixel footprint of the photographs on it,
//! it is reported, recorded in run.json (a resume with another choice is refused), and bad
//! values are refused before any work.

use igi_testkit::run_ok;
use std::path::{Path, PathBuf};
use std::process::Command;

fn igi() -> Command {
    igi_testkit::Cli::new(env!("CARGO_BIN_EXE_igi")).command()
}

fn fixture() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("datasets/fixtures/survey")
}

/// `igi solve` of the fixture into `out` with one quick iteration and `extra` options.
fn solve(out: &Path, extra: &[&str]) -> Command {
    let mut c = igi();
    c.arg("solve")
        .arg(fixture())
        .arg("-o")
        .arg(out)
        .args(["--iterations", "1", "--spp", "4", "--json"])
        .args(extra);
    c
}

/// (name, resolution, texel size, footprint) per part of a JSON report.
fn parts(report: &str) -> Vec<(String, u64, f64, Option<f64>)> {
    let r: serde_json::Value = serde_json::from_str(report).expect("JSON report");
    r["parts"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| {
            (
                p["name"].as_str().unwrap().to_string(),
                p["resolution"].as_u64().unwrap(),
                p["texel_size_m"].as_f64().unwrap(),
                p["footprint_m"].as_f64(),
            )
        })
        .collect()
}

#[test]
fn atlas_auto_sizes_each_part_from_the_photographs() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("auto");
    let auto = parts(&run_ok(solve(&out, &["--atlas", "auto"]).arg("--restart")));
    assert_eq!(auto.len(), 3);
    for (name, res, texel, fp) in &auto {
        let fp = fp.unwrap_or_else(|| panic!("{name}: no footprint reported"));
        // the fixture's photos are 160 x 120 of a site some 10 m across: centimetres per pixel
        assert!((0.01..0.5).contains(&fp), "{name}: footprint {fp}");
        assert!((64..=2048).contains(res) && res % 16 == 0, "{name}: {res}");
        // one texel per pixel: the atlas is at least as fine as the finest footprint
        assert!(
            *texel <= fp * 1.0001,
            "{name}: texel {texel} > footprint {fp}"
        );
    }
    let get = |n: &str| auto.iter().find(|p| p.0 == n).unwrap().clone();
    let (ground, block) = (get("ground"), get("block"));
    // the block is smaller and seen no finer (its footprint is at least the ground's): a
    // smaller atlas
    assert!(block.3.unwrap() >= ground.3.unwrap(), "{auto:?}");
    assert!(block.1 < ground.1, "{auto:?}");
    let run_json = std::fs::read_to_string(out.join("run.json")).unwrap();
    assert!(run_json.contains("\"--atlas\": \"auto\""), "{run_json}");
    // auto is the default
    let default = parts(&run_ok(&mut solve(&tmp.path().join("default"), &[])));
    assert_eq!(default, auto);
    assert!(run_json.contains("\"--atlas-max\": \"2048\""), "{run_json}");

    // a resume with another atlas choice is refused
    for other in [
        &["--atlas", "512"][..],
        &["--atlas", "auto", "--atlas-max", "1024"],
    ] {
        let o = solve(&out, other).output().unwrap();
        assert!(!o.status.success(), "{other:?} resumed an auto run");
        assert!(
            String::from_utf8_lossy(&o.stderr).contains("--atlas"),
            "{}",
            String::from_utf8_lossy(&o.stderr)
        );
    }

    // a numeric atlas stays what it was: the same resolution everywhere, no footprint
    let fixed = parts(&run_ok(&mut solve(
        &tmp.path().join("fixed"),
        &["--atlas", "64"],
    )));
    assert!(
        fixed.iter().all(|p| p.1 == 64 && p.3.is_none()),
        "{fixed:?}"
    );
}

#[test]
fn bad_atlas_values_are_refused_before_any_work() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    for (args, says) in [
        (&["--atlas", "0"][..], "--atlas 0"),
        (&["--atlas", "banana"], "banana"),
        (&["--atlas", "-3"], "-3"),
        (&["--atlas", "auto", "--atlas-max", "16"], "--atlas-max 16"),
    ] {
        let o = solve(&out, args).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?} was accepted");
        assert!(err.contains(says), "{args:?}: {err}");
        assert!(!out.exists(), "{args:?} left an output folder");
    }
}

/// A photograph taken at another exposure, with its `exposure` in the survey, solves to the
/// same albedo: the fixture's photos at 4 times their values with `exposure = 4.0` give the
/// same bytes as the fixture itself (dividing by 4 is exact in floating point).
#[test]
fn a_photos_exposure_puts_it_on_the_surveys_scale() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("survey");
    std::fs::create_dir_all(dir.join("scaled")).unwrap();
    let text = std::fs::read_to_string(fixture().join("survey.toml"))
        .unwrap()
        .replace(
            "\"geometry/",
            &format!("\"{}/geometry/", fixture().display()),
        );
    let mut out = String::new();
    for line in text.lines() {
        let Some((key, value)) = line.split_once(" = \"") else {
            out += &format!("{line}\n");
            continue;
        };
        let rel = value.trim_end_matches('"');
        if key == "image" {
            // every photo is read from its scaled copy
            let mut img = igi_imaging::read_image(&fixture().join(rel)).unwrap();
            img.pixels.iter_mut().for_each(|p| *p = p.map(|c| 4.0 * c));
            let scaled = dir.join("scaled").join(Path::new(rel).file_name().unwrap());
            igi_imaging::write_exr(&scaled, &img).unwrap();
            out += &format!("image = {:?}\nexposure = 4.0\n", scaled.to_str().unwrap());
        } else {
            let abs = fixture().join(rel);
            out += &format!("{key} = {:?}\n", abs.to_str().unwrap());
        }
    }
    assert_eq!(out.matches("exposure = 4.0").count(), 8, "{out}");
    std::fs::write(dir.join("survey.toml"), out).unwrap();
    let rho = |survey: &Path, name: &str| {
        let res = tmp.path().join(name);
        let mut c = igi();
        c.arg("solve").arg(survey).arg("-o").arg(&res).args([
            "--iterations",
            "1",
            "--spp",
            "4",
            "--atlas",
            "64",
            "--quiet",
        ]);
        run_ok(&mut c);
        std::fs::read(res.join("parts/ground_rho_d.exr")).unwrap()
    };
    assert!(rho(&dir, "scaled") == rho(&fixture(), "plain"));
    // without the exposure the same photographs give a brighter albedo
    let text = std::fs::read_to_string(dir.join("survey.toml")).unwrap();
    std::fs::write(
        dir.join("survey.toml"),
        text.replace("exposure = 4.0\n", ""),
    )
    .unwrap();
    assert!(rho(&dir, "unscaled") != rho(&fixture(), "plain2"));
}

/// Per iteration of a JSON report: (coarse, texel MAE against the truth).
fn iterations(report: &str) -> Vec<(bool, [f64; 3])> {
    let r: serde_json::Value = serde_json::from_str(report).expect("JSON report");
    r["iterations"]
        .as_array()
        .unwrap()
        .iter()
        .map(|i| {
            let mae = i["truth_mae"].as_array().expect("truth_mae");
            let mae: Vec<f64> = mae.iter().map(|m| m.as_f64().unwrap()).collect();
            (
                i["coarse"].as_bool().unwrap_or(false),
                [mae[0], mae[1], mae[2]],
            )
        })
        .collect()
}

#[test]
fn the_fine_iteration_reads_its_shading_from_a_lattice_unless_told_not_to() {
    let tmp = tempfile::tempdir().unwrap();
    let truth = fixture().join("truth/scene.toml");
    let run = |name: &str, lattice: &str| {
        let mut c = igi();
        c.arg("solve")
            .arg(fixture())
            .arg("-o")
            .arg(tmp.path().join(name))
            .args(["--iterations", "2", "--spp", "16", "--json", "--truth"])
            .arg(&truth)
            .args(["--shading-lattice", lattice]);
        c
    };
    let on = iterations(&run_ok(&mut run("on", "true")));
    let off = iterations(&run_ok(&mut run("off", "false")));
    // one coarse iteration, then the fine one; the coarse stage is the same solve both ways
    assert_eq!(on.iter().map(|i| i.0).collect::<Vec<_>>(), [true, false]);
    assert_eq!(off.iter().map(|i| i.0).collect::<Vec<_>>(), [true, false]);
    assert_eq!(on[0], off[0]);
    // measured 2026-11-28: coarse 0.0066 / 0.0125 / 0.0110; fine on the lattice 0.0055 /
    // 0.0045 / 0.0068 (every third texel), 0.0060 / 0.0050 / 0.0073 (every fifth, since
    // 2026-11-29); traced at every texel 0.0042 / 0.0037 / 0.0057
    for c in 0..3 {
        assert!(on[1].1[c] < 0.008 && off[1].1[c] < 0.0065, "{on:?} {off:?}");
        assert!(off[1].1[c] <= on[1].1[c], "{on:?} {off:?}");
    }
    assert!(on[1].1[1] < 0.5 * on[0].1[1], "{on:?}");
    // recorded when off: a resume with the default is refused, naming the option
    let o = igi()
        .arg("solve")
        .arg(fixture())
        .arg("-o")
        .arg(tmp.path().join("off"))
        .args(["--iterations", "2", "--spp", "16"])
        .output()
        .unwrap();
    assert!(
        !o.status.success(),
        "resumed a run without the lattice on it"
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("--shading-lattice"), "{err}");
}
