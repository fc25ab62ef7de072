//! End-to-end tests of `igi camera radiometry` (flat fields + colour checker -> camera
//! radiometry file) and `igi camera refine` (pose refinement against a photo of the model).

use glam::{DMat3, DVec2, DVec3, Vec3};
use igi_camera::camera::reprojection_rms;
use igi_camera::radiometry::{apply_color_matrix, render_checker, CameraRadiometry, Falloff};
use igi_camera::{Camera, WorldToCamera};
use igi_imaging::{write_exr, HdrImage};
use igi_testkit::{assert_failed, s, Cli};
use std::path::{Path, PathBuf};

const MIX: [[f64; 3]; 3] = [[0.8, 0.15, 0.05], [0.1, 0.75, 0.15], [0.05, 0.2, 0.75]];
const FALLOFF: Falloff = Falloff {
    a2: -0.4,
    a4: 0.1,
    a6: -0.05,
};

fn through_camera(img: &mut HdrImage) {
    FALLOFF.vignette(img);
    apply_color_matrix(img, &MIX);
}

/// The corners of the test chart, and the same as the `--corners` argument.
const CHART_CORNERS: [DVec2; 4] = [
    DVec2::new(10.0, 12.0),
    DVec2::new(110.0, 10.0),
    DVec2::new(108.0, 80.0),
    DVec2::new(12.0, 78.0),
];
const CORNER_ARG: &str = "10,12,110,10,108,80,12,78";

/// A flat field and a chart (white radiance 2) photographed through the test camera.
fn flat_and_chart(dir: &Path, w: usize, h: usize) -> (PathBuf, PathBuf) {
    let flat = dir.join("flat.exr");
    let mut f = HdrImage::new(w, h);
    f.pixels.iter_mut().for_each(|p| *p = [0.8; 3]);
    through_camera(&mut f);
    write_exr(&flat, &f).unwrap();
    let chart = dir.join("chart.exr");
    let mut c = render_checker(w, h, &CHART_CORNERS, 2.0, 0.2).unwrap();
    through_camera(&mut c);
    write_exr(&chart, &c).unwrap();
    (flat, chart)
}

/// The calibration file against the test camera's falloff and inverse crosstalk.
fn check_calibration(out: &Path) {
    let cal = CameraRadiometry::load(out).unwrap();
    assert!((cal.falloff.unwrap().eval(1.0) - FALLOFF.eval(1.0)).abs() < 2e-3);
    let m = cal.color_matrix.unwrap();
    let inv = nalgebra_free_inverse(&MIX);
    for r in 0..3 {
        for k in 0..3 {
            assert!((m[r][k] - inv[r][k]).abs() < 0.01, "{m:?} vs {inv:?}");
        }
    }
}

/// A checker without corners: found by OpenCV's mcc detector with the `opencv` feature (even
/// this small one, 16 px patch pitch), else an error naming the file and --corners.
fn check_checker_without_corners(cli: &Cli, dir: &Path, chart: &Path, keep: &[PathBuf]) {
    let out2 = dir.join("r2.json");
    let o = cli.run(&[
        "camera",
        "radiometry",
        "--checker",
        s(chart),
        "--json",
        "-o",
        s(&out2),
    ]);
    if cfg!(feature = "opencv") {
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{err}");
        let r: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        for (k, t) in CHART_CORNERS.iter().enumerate() {
            let c = &r["checker_corners"][k];
            let p = DVec2::new(c[0].as_f64().unwrap(), c[1].as_f64().unwrap());
            assert!((p - *t).length() < 1.0, "corner {k}: {p} vs {t}");
        }
        std::fs::remove_file(&out2).unwrap();
    } else {
        assert_failed(&o, "chart.exr", "--corners", dir, keep);
    }
}

/// A flat of another size and malformed corners: errors naming the file or the flag, nothing
/// written.
fn check_bad_inputs(cli: &Cli, dir: &Path, flat: &Path, chart: &Path, keep: &[PathBuf]) {
    let out2 = dir.join("r2.json");
    let small = dir.join("small.exr");
    write_exr(&small, &HdrImage::new(60, 45)).unwrap();
    let mut keep2 = keep.to_vec();
    keep2.push(small.clone());
    let o = cli.run(&[
        "camera",
        "radiometry",
        "--flat",
        s(flat),
        s(&small),
        "-o",
        s(&out2),
    ]);
    assert_failed(&o, "small.exr", "60x45", dir, &keep2);
    let o = cli.run(&[
        "camera",
        "radiometry",
        "--flat",
        s(flat),
        "--checker",
        s(chart),
        "--corners",
        "1,2,3",
        "-o",
        s(&out2),
    ]);
    assert_failed(&o, "--corners", "8 finite numbers", dir, &keep2);
}

#[test]
fn radiometry_from_flats_and_checker_and_its_errors() {
    let cli = Cli::new(env!("CARGO_BIN_EXE_igi"));
    let tmp = tempfile::tempdir().unwrap();
    let (flat, chart) = flat_and_chart(tmp.path(), 120, 90);
    let out = tmp.path().join("radiometry.json");
    let o = cli.ok(&[
        "camera",
        "radiometry",
        "--flat",
        s(&flat),
        "--checker",
        s(&chart),
        "--corners",
        CORNER_ARG,
        "--white",
        "2",
        "--json",
        "-o",
        s(&out),
    ]);
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(
        report["fit"]["color_rms"].as_f64().unwrap() < 0.01,
        "{report}"
    );
    check_calibration(&out);
    let keep = vec![flat.clone(), chart.clone(), out.clone()];
    check_checker_without_corners(&cli, tmp.path(), &chart, &keep);
    check_bad_inputs(&cli, tmp.path(), &flat, &chart, &keep);
}

fn nalgebra_free_inverse(m: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let a = DMat3::from_cols_array_2d(m).transpose(); // rows -> glam's column-major
    let inv = a.inverse().transpose();
    inv.to_cols_array_2d()
}

#[test]
fn refine_recovers_a_perturbed_pose_from_a_photo_of_the_model() {
    use igi_reflect::parts::build_parts;
    use igi_synth::survey::ground_and_block;
    let cli = Cli::new(env!("CARGO_BIN_EXE_igi"));
    let tmp = tempfile::tempdir().unwrap();
    let parts = build_parts(ground_and_block(), 32).unwrap();
    let (truth, photo) = photograph_of_the_model(&parts);
    let photo_path = tmp.path().join("photo.exr");
    write_exr(&photo_path, &photo).unwrap();
    let mut mesh_args = Vec::new();
    for (name, m) in ground_and_block() {
        let p = tmp.path().join(format!("{name}.ply"));
        igi_geometry::write_ply(&p, &m).unwrap();
        mesh_args.push(p);
    }
    let points: Vec<DVec3> = parts
        .iter()
        .flat_map(|p| p.cache.texels.iter().map(|t| t.position.as_dvec3()))
        .collect();
    let rough = perturbed_by_3_px(&truth, &points);
    let before = reprojection_rms(&truth, &rough, &points).unwrap();
    let rough_path = tmp.path().join("rough.json");
    rough.save(&rough_path).unwrap();
    let out = tmp.path().join("refined.json");
    let mut args = vec![
        "camera",
        "refine",
        s(&photo_path),
        "--camera",
        s(&rough_path),
        "--json",
        "-o",
        s(&out),
    ];
    for m in &mesh_args {
        args.extend(["--mesh", s(m)]);
    }
    let o = cli.ok(&args);
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let refined = Camera::load(&out).unwrap();
    let after = reprojection_rms(&truth, &refined, &points).unwrap();
    let seen = igi_camera::camera::points_in_frame(&truth, &points);
    let (before_seen, after_seen) = (
        reprojection_rms(&truth, &rough, &seen).unwrap(),
        reprojection_rms(&truth, &refined, &seen).unwrap(),
    );
    eprintln!(
        "refine: {before:.2} px -> {after:.3} px over {} texels in front, \
         {before_seen:.2} px -> {after_seen:.3} px over {} in frame; {report}",
        points.len(),
        seen.len()
    );
    assert!((before - 3.0).abs() < 0.05, "perturbation {before} px");
    assert!(
        after <= 0.5,
        "refined pose is {after:.3} px off (from {before:.2})"
    );
    let paths = [photo_path, rough_path, out];
    wrong_camera_size_is_refused(tmp.path(), &paths, &rough, &mesh_args);
}

/// The true camera and its photograph of the ground and block (`parts`) under an overcast sky.
fn photograph_of_the_model(parts: &[igi_reflect::Part]) -> (Camera, igi_imaging::HdrImage) {
    use igi_reflect::truth::{scene_with_albedo, truth_atlas};
    let atlases: Vec<Vec<Vec3>> = parts
        .iter()
        .map(|p| truth_atlas(p, |x| Vec3::new(0.5, 0.45, 0.3 + 0.05 * x.z)))
        .collect();
    let scene = scene_with_albedo(parts, &atlases).unwrap();
    let sky = igi_render::sky::overcast_sky(32, 16, 2.0, Vec3::splat(0.15));
    let lighting = igi_render::Lighting {
        environment: Some(igi_render::Environment::from_image(&sky, 1.0).unwrap()),
        sun: None,
    };
    let truth = Camera::look_at(
        DVec3::new(5.5, 3.0, 3.0),
        DVec3::new(0.0, 0.0, 0.5),
        128,
        96,
        70.0,
    )
    .unwrap();
    let opts = igi_render::RenderOptions {
        spp: 32,
        seed: 3,
        indirect: 1,
        russian_roulette: false,
        stratified: false,
        adaptive: false,
    };
    let photo = igi_render::render_image(&scene, &lighting, &truth, &opts, &|_| {})
        .unwrap()
        .mean;
    (truth, photo)
}

/// `truth` moved by a rigid motion scaled to 3 px of reprojection error of `points`.
fn perturbed_by_3_px(truth: &Camera, points: &[DVec3]) -> Camera {
    let at = |k: f64| {
        let r = DMat3::from_axis_angle(DVec3::new(0.3, 1.0, 0.2).normalize(), 0.01 * k);
        Camera {
            pose: WorldToCamera {
                r: r * truth.pose.r,
                t: r * truth.pose.t + DVec3::new(0.03, -0.02, 0.05) * k,
            },
            ..truth.clone()
        }
    };
    let mut k = 1.0;
    for _ in 0..4 {
        k *= 3.0 / reprojection_rms(truth, &at(k), points).unwrap();
    }
    at(k)
}

/// A camera of another size: error naming the photo, nothing written (`paths`: the photo, the
/// rough camera and the refined one).
fn wrong_camera_size_is_refused(
    tmp: &Path,
    [photo_path, rough_path, out]: &[PathBuf; 3],
    rough: &Camera,
    mesh_args: &[PathBuf],
) {
    let cli = Cli::new(env!("CARGO_BIN_EXE_igi"));
    let wrong = tmp.join("wrong.json");
    Camera {
        width: 64,
        ..rough.clone()
    }
    .save(&wrong)
    .unwrap();
    let out2 = tmp.join("r2.json");
    let mut args = vec![
        "camera",
        "refine",
        s(photo_path),
        "--camera",
        s(&wrong),
        "-o",
        s(&out2),
    ];
    for m in mesh_args {
        args.extend(["--mesh", s(m)]);
    }
    let o = cli.run(&args);
    let mut keep = vec![
        photo_path.clone(),
        rough_path.clone(),
        out.clone(),
        wrong.clone(),
    ];
    keep.extend(mesh_args.iter().cloned());
    assert_failed(&o, "photo.exr", "128x96", tmp, &keep);
}
