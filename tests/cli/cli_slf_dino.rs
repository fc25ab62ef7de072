//! `igi slf build` with its defaults on a real hull mesh: the Middlebury dino (../shared/data),
//! one view left out, the visual hull of the other 14 as the mesh, the field rendered at the
//! held-out camera against its photo (docs/LIGHTFIELD.md, "Real data"). With the six-axis
//! projected atlas the defaults failed ("54490 charts do not fit a 256x256 atlas"); with
//! uvunwrap's charts they build.

use igi_testkit::{s, Cli};

fn igi() -> Cli {
    Cli::new(env!("CARGO_BIN_EXE_igi"))
}

/// The rig without `view` (the `[[view]]` block whose id it is dropped).
fn without(rig: &str, view: &str) -> String {
    let mut blocks = rig.split("[[view]]");
    let head = blocks.next().unwrap().to_string();
    let keep: Vec<&str> = blocks
        .filter(|b| !b.contains(&format!("id = \"{view}\"")))
        .collect();
    assert_eq!(keep.len(), 14, "{view} is one of the 15 views");
    head + &keep
        .iter()
        .map(|b| format!("[[view]]{b}"))
        .collect::<String>()
}

/// Held-out PSNR of the field of the dino without dinoSR0004, every `igi slf build` option at
/// its default (PFA q = 2, atlas 256, the raw 810,844-triangle hull simplified to 16,384
/// triangles by the texel budget); the photo's maximum as the peak. Measured 15.62 dB over
/// 110,313 pixels on 2026-11-27 (dev build), 16.04 dB on 2026-11-29 before the view-angle gain
/// (the hulls of the opacity-hull work of 2026-11-28), 16.06 dB with it, and 15.66 dB on the
/// hull whose surface follows the mattes' contours (docs/OPACITY_HULL.md, "Sub-cell surface"),
/// 15.65 dB once that surface's values are computed once a cell (2026-11-29, thirtieth session).
/// PFA's training draw alone spreads it by up to 1 dB (seeds 0-4: 15.63-15.81 dB here,
/// docs/LIGHTFIELD.md). The
/// issue's goal (18.76 dB, 3 dB over the projected atlas's 15.76 dB) is not met: the hull, not
/// the atlas, limits it (docs/LIGHTFIELD.md, "Real data").
#[test]
fn dino_leave_one_out_with_the_default_atlas() {
    let t = tempfile::tempdir().unwrap();
    let set = igi_testkit::shared_data("multiview/dinoSparseRing");
    let rig_dir = t.path().join("rig");
    igi().ok(&["hull", "import-middlebury", s(&set), "-o", s(&rig_dir)]);
    let view = "dinoSR0004";
    let rig = rig_dir.join(format!("without_{view}.toml"));
    let text = std::fs::read_to_string(rig_dir.join("rig.toml")).unwrap();
    std::fs::write(&rig, without(&text, view)).unwrap();
    let hull = t.path().join("hull");
    igi().ok(&["hull", "build", s(&rig), "-o", s(&hull)]);
    let slf = t.path().join("slf");
    let o = igi().ok(&[
        "slf",
        "build",
        s(&rig),
        "--mesh",
        s(&hull.join("hull.ply")),
        "-o",
        s(&slf),
        "--json",
    ]);
    let r: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    eprintln!("{r}");
    let img = t.path().join("held_out.exr");
    let cam = rig_dir.join(format!("cameras/{view}.json"));
    igi().ok(&["slf", "render", s(&slf), "--camera", s(&cam), "-o", s(&img)]);
    let photo = rig_dir.join(format!("photos/{view}.png"));
    let o = igi().ok(&["compare", s(&img), s(&photo), "--json"]);
    let c: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let (psnr, pixels) = (
        c["psnr_db"].as_f64().unwrap(),
        c["pixels"].as_u64().unwrap(),
    );
    eprintln!("{view}: held-out PSNR {psnr:.2} dB over {pixels} pixels");
    // the dino covers about 108,000 pixels of the held-out view
    assert!(pixels > 90_000, "the field covers only {pixels} pixels");
    // with the projected atlas the defaults failed; at --atlas 1024 PFA reached 15.76 dB
    assert!(psnr >= 15.0, "held-out PSNR {psnr:.2} dB");
}
