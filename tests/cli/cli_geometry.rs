//! End-to-end tests of `igi prepare` and `igi info`.

use std::path::{Path, PathBuf};
use std::process::Command;

fn igi() -> Command {
    igi_testkit::Cli::new(env!("CARGO_BIN_EXE_igi")).command()
}

fn bunny() -> PathBuf {
    PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../shared/data/meshes/stanford_bunny/reconstruction/bun_zipper_res4.ply"
    ))
}

#[test]
fn prepare_bunny_then_info_and_load() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("bunny.igi");
    // the bunny is 0.15 m across: voxels of 4 cm split it into several
    let o = igi()
        .args(["-q", "prepare"])
        .arg(bunny())
        .args([
            "--voxel",
            "0.04",
            "--origin",
            "0.001,0.002,0.003",
            "--atlas",
            "128",
            "--json",
            "-o",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let man: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let voxels = man["voxels"].as_array().unwrap();
    assert!(voxels.len() >= 8, "{}", voxels.len());
    let t = man["triangles_per_level"].as_array().unwrap();
    // clipping adds triangles: level 0 has at least the 948 input triangles
    assert!(t[0].as_u64().unwrap() >= 948);
    assert!(t[2].as_u64().unwrap() < t[0].as_u64().unwrap());
    assert!(man["coverage_mean"].as_f64().unwrap() > 0.0);
    assert!(out.join("manifest.json").exists());
    let o = igi()
        .args(["info"])
        .arg(&out)
        .args(["--json", "--load-voxel", "middle"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let info: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let loaded = info["load"]["triangles_loaded"].as_u64().unwrap();
    let full = info["load"]["triangles_full"].as_u64().unwrap();
    assert!(
        loaded < full && full == t[0].as_u64().unwrap(),
        "{loaded} {full}"
    );
    let o = igi().args(["info"]).arg(&out).output().unwrap();
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("level 2") && text.contains("coverage"),
        "{text}"
    );
}

fn expect_failure(dir: &Path, name: &str, content: &[u8], needle: &str) {
    let mesh = dir.join(name);
    std::fs::write(&mesh, content).unwrap();
    let out = dir.join(format!("{name}.igi"));
    let o = igi()
        .args(["-q", "prepare"])
        .arg(&mesh)
        .arg("-o")
        .arg(&out)
        .output()
        .unwrap();
    assert!(!o.status.success(), "{name} was accepted");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains(name) && err.contains(needle), "{name}: {err}");
    assert!(!out.exists(), "{name}: a partial site folder was left");
}

#[test]
fn bad_meshes_fail_clearly_without_a_site_folder() {
    let d = tempfile::tempdir().unwrap();
    let head = |nv: usize, nf: usize| {
        format!(
            "ply\nformat ascii 1.0\nelement vertex {nv}\nproperty float x\nproperty float y\nproperty float z\n\
element face {nf}\nproperty list uchar int vertex_indices\nend_header\n"
        )
    };
    let body = "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    expect_failure(
        d.path(),
        "truncated.ply",
        format!("{}0 0 0\n1 0", head(3, 1)).as_bytes(),
        "truncated",
    );
    expect_failure(
        d.path(),
        "count.ply",
        format!("{}{body}", head(3, 2)).as_bytes(),
        "truncated",
    );
    expect_failure(
        d.path(),
        "extra.ply",
        format!("{}{body}3 0 2 1\n", head(3, 1)).as_bytes(),
        "counts do not match",
    );
    expect_failure(
        d.path(),
        "nan.ply",
        format!("{}0 0 0\n1 nan 0\n0 1 0\n3 0 1 2\n", head(3, 1)).as_bytes(),
        "non-finite",
    );
    expect_failure(d.path(), "empty.ply", head(0, 0).as_bytes(), "empty mesh");
    expect_failure(
        d.path(),
        "range.ply",
        format!("{}0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n", head(3, 1)).as_bytes(),
        "index 7",
    );
    expect_failure(d.path(), "site.stl", b"solid x\n", "unknown mesh format");
    // binary truncated in the middle of the faces
    let mut b = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n".to_vec();
    for v in [0f32, 0., 0., 1., 0., 0., 0., 1., 0.] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    b.extend_from_slice(&[3, 0, 0, 0, 0, 1, 0]);
    expect_failure(d.path(), "binary.ply", &b, "truncated");
    // a bad option is refused before anything is written
    let out = d.path().join("opt.igi");
    let o = igi()
        .args(["-q", "prepare"])
        .arg(bunny())
        .args(["--levels", "1.0,0.5,0.7", "-o"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("levels"));
    assert!(!out.exists());
}
