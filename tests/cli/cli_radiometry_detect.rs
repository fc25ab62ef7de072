//! `igi camera radiometry --checker CHART.exr` without `--corners`: the chart is found by
//! OpenCV's mcc detector (feature `opencv`), its corners reported; a photo without a chart is
//! an error naming the file.
#![cfg(feature = "opencv")]

use glam::{DMat3, DVec2};
use igi_camera::radiometry::{apply_color_matrix, render_checker, CameraRadiometry};
use igi_imaging::{write_exr, HdrImage};
use igi_testkit::{assert_failed, s, Cli};

const MIX: [[f64; 3]; 3] = [[0.8, 0.15, 0.05], [0.1, 0.75, 0.15], [0.05, 0.2, 0.75]];

#[test]
fn checker_without_corners_is_detected_and_its_corners_reported() {
    let cli = Cli::new(env!("CARGO_BIN_EXE_igi"));
    let tmp = tempfile::tempdir().unwrap();
    let truth = [
        DVec2::new(150.0, 118.0),
        DVec2::new(492.0, 135.0),
        DVec2::new(480.0, 372.0),
        DVec2::new(138.0, 350.0),
    ];
    let mut img = render_checker(640, 480, &truth, 1.5, 0.2).unwrap();
    apply_color_matrix(&mut img, &MIX);
    let chart = tmp.path().join("chart.exr");
    write_exr(&chart, &img).unwrap();
    let out = tmp.path().join("radiometry.json");
    let o = cli.ok(&[
        "camera",
        "radiometry",
        "--checker",
        s(&chart),
        "--white",
        "1.5",
        "--json",
        "-o",
        s(&out),
    ]);
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(report["checker_corners_detected"], true, "{report}");
    for (k, t) in truth.iter().enumerate() {
        let c = &report["checker_corners"][k];
        let p = DVec2::new(c[0].as_f64().unwrap(), c[1].as_f64().unwrap());
        assert!((p - *t).length() < 3.0, "corner {k}: {p} vs {t}");
    }
    let m = CameraRadiometry::load(&out).unwrap().color_matrix.unwrap();
    let inv = DMat3::from_cols_array_2d(&MIX)
        .transpose()
        .inverse()
        .transpose()
        .to_cols_array_2d();
    for r in 0..3 {
        for k in 0..3 {
            assert!((m[r][k] - inv[r][k]).abs() < 0.01, "{m:?} vs {inv:?}");
        }
    }
    // a photo without a chart: the file named, --corners suggested, nothing written
    let blank = tmp.path().join("blank.exr");
    let mut b = HdrImage::new(320, 240);
    b.pixels.iter_mut().for_each(|p| *p = [0.3, 0.25, 0.2]);
    write_exr(&blank, &b).unwrap();
    let o = cli.run(&[
        "camera",
        "radiometry",
        "--checker",
        s(&blank),
        "-o",
        s(&tmp.path().join("r2.json")),
    ]);
    let keep = vec![chart, out, blank];
    assert_failed(&o, "blank.exr", "--corners", tmp.path(), &keep);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("no ColorChecker Classic"), "{err}");
}
