//! The board's pose from its four ArUco fiducials (feature `opencv`): a synthetic board
//! photograph with printed markers, spheres given in the board frame, a known pose. Without
//! the feature, a board given only in its own frame is a clear error.

// the helpers serve the OpenCV tests; without the feature only the error test runs
#![cfg_attr(not(feature = "opencv"), allow(unused_imports, dead_code))]

use glam::{DMat3, DVec3};
use igi_camera::{Camera, WorldToCamera};
use igi_imaging::read_image;
use igi_probe::fiducial::place_board;
use igi_probe::BoardSpec;
use std::path::{Path, PathBuf};

fn fixture(rel: &str) -> PathBuf {
    PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../datasets/fixtures/board"
    ))
    .join(rel)
}

/// Camera at the world origin looking along +X (x right = world -Y, y down = world -Z).
fn camera() -> Camera {
    let mut c = Camera::pinhole(960, 720, 900.0, 900.0, 479.5, 359.5);
    c.pose = WorldToCamera {
        r: DMat3::from_cols_array_2d(&[[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
            .transpose(),
        t: DVec3::ZERO,
    };
    c
}

/// Board to camera: board x right, y up, z toward the camera, turned 25 degrees about the
/// camera's y axis and 12 degrees about its x axis, centre 1.0 m ahead.
fn true_pose() -> WorldToCamera {
    let base = DMat3::from_cols(DVec3::X, -DVec3::Y, -DVec3::Z);
    let tilt =
        DMat3::from_rotation_y(25f64.to_radians()) * DMat3::from_rotation_x(-12f64.to_radians());
    WorldToCamera {
        r: tilt * base,
        t: DVec3::new(0.02, 0.03, 1.0),
    }
}

const MARKER: f64 = 0.09;
/// Lower-left corners (board frame) of markers 0..3 at the corners of a 0.8 x 0.54 m panel.
const MARKERS: [(f64, f64); 4] = [(-0.38, 0.16), (0.29, 0.16), (-0.38, -0.25), (0.29, -0.25)];

fn marker_corners(i: usize) -> [DVec3; 4] {
    let (x, y) = MARKERS[i];
    // the printed image's top-left, top-right, bottom-right, bottom-left (board y up)
    [
        DVec3::new(x, y + MARKER, 0.0),
        DVec3::new(x + MARKER, y + MARKER, 0.0),
        DVec3::new(x + MARKER, y, 0.0),
        DVec3::new(x, y, 0.0),
    ]
}

/// The board file: fiducials and board-frame centres only (no camera-frame centres).
fn board_json() -> String {
    let markers: Vec<String> = (0..4)
        .map(|i| {
            let c = marker_corners(i).map(|p| format!("[{}, {}, {}]", p.x, p.y, p.z));
            format!(r#"{{ "id": {i}, "corners": [{}] }}"#, c.join(", "))
        })
        .collect();
    format!(
        r#"{{ "spheres": [
            {{ "kind": "mirror", "center_board": [-0.13, 0.05, 0.06], "radius": 0.06 }},
            {{ "kind": "black", "center_board": [0.13, 0.05, 0.06], "radius": 0.06 }},
            {{ "kind": "diffuse", "center_board": [0.0, -0.12, 0.06], "radius": 0.06 }} ],
          "fiducials": {{ "dictionary": "DICT_4X4_50", "markers": [{}] }} }}"#,
        markers.join(", ")
    )
}

#[cfg(feature = "opencv")]
#[test]
fn fiducials_give_the_board_pose_and_the_same_lighting() {
    use igi_probe::{process, ProbeOptions};
    use igi_synth::board::{direction_from_angles, SynthSun};
    let spec = BoardSpec::from_json_str(&board_json(), Path::new("board.json")).unwrap();
    let cam = camera();
    let pose = true_pose();
    let board_true = spec.with_pose(&pose).unwrap();
    let sun = SynthSun {
        direction: direction_from_angles(35.0, 200.0),
        radiance: [3.0e4, 2.9e4, 2.7e4],
        diameter_deg: 3.0,
    };
    let img = photograph(&spec, &cam, &pose, &board_true, sun);
    let placed = place_board(&spec, &img, &cam).unwrap();
    let centre_err = check_pose(&placed, &pose, &board_true);
    // the lighting from the fiducial placement against the lighting from the known pose
    // a 3 degree sun: the 0.53 degree disk would cover a tenth of a pixel of the 54 px black sphere
    let opt = ProbeOptions {
        sun_diameter_deg: 3.0,
        ..ProbeOptions::default()
    };
    let a = process(&img, &cam, &board_true, &opt).unwrap();
    let b = process(&img, &cam, &placed.board, &opt).unwrap();
    let (sa, sb) = (
        a.diagnostics.sun.as_ref().unwrap(),
        b.diagnostics.sun.as_ref().unwrap(),
    );
    let (da, db) = (
        DVec3::from_array(sa.direction),
        DVec3::from_array(sb.direction),
    );
    let sun_angle = da.angle_between(db).to_degrees();
    let truth_angle = da.angle_between(sun.direction).to_degrees();
    let (ra, rb) = (sa.radiance.unwrap(), sb.radiance.unwrap());
    let rad_rel: Vec<f64> = (0..3).map(|c| (rb[c] / ra[c] - 1.0) as f64).collect();
    let sky_rel = sky_relative_rms(&a.sky_measured, &b.sky_measured);
    eprintln!(
        "lighting, fiducial vs known pose: sun {sun_angle:.4} deg apart (vs truth: known pose {truth_angle:.3} deg, \
         fiducials {:.3} deg), radiance {rad_rel:?}, sky relative RMS {sky_rel:.5}",
        db.angle_between(sun.direction).to_degrees()
    );
    // a black-sphere centre off by dc tilts the normal at the sun's spot by about dc / r and
    // the reflected sun direction by twice that (0.33 deg for 0.17 mm on a 60 mm sphere)
    let bound = (1.5 * 2.0 * centre_err[1] / 0.06).to_degrees();
    assert!(
        sun_angle < bound.min(0.5),
        "sun directions {sun_angle} deg apart (bound {bound})"
    );
    assert!(rad_rel.iter().all(|r| r.abs() < 0.01), "{rad_rel:?}");
    assert!(sky_rel < 0.02, "sky maps differ by {sky_rel}");
    check_refined(
        &img,
        &cam,
        &placed,
        &board_true,
        &opt,
        (da, sun_angle),
        sun.direction,
    );
}

/// The synthetic photograph: the board at `pose` on its printed panel (the four markers),
/// under the sunny fixture sky and `sun`.
#[cfg(feature = "opencv")]
fn photograph(
    spec: &BoardSpec,
    cam: &Camera,
    pose: &WorldToCamera,
    board_true: &igi_probe::Board,
    sun: igi_synth::board::SynthSun,
) -> igi_imaging::HdrImage {
    use igi_synth::board::{render_board_with_panel, SynthPanel};
    let markers = (0..4)
        .map(|i| {
            (
                marker_corners(i),
                120,
                igi_camera::cv::aruco_marker_image(
                    spec.fiducials.as_ref().unwrap().dictionary,
                    i as i32,
                    120,
                )
                .unwrap(),
            )
        })
        .collect();
    let panel = SynthPanel {
        board_to_camera: *pose,
        extent: [-0.4, -0.27, 0.4, 0.27],
        white: 0.8,
        black: 0.04,
        markers,
    };
    let sky = read_image(&fixture("sunny/sky_truth.exr")).unwrap();
    render_board_with_panel(cam, board_true, &sky, Some(sun), 3, Some(&panel))
}

/// The pose from the fiducials against the true one: rotation, translation, sphere centres
/// and the corners' RMS; returns the centres' errors (mirror, black, diffuse) in metres.
#[cfg(feature = "opencv")]
fn check_pose(
    placed: &igi_probe::fiducial::Placement,
    pose: &WorldToCamera,
    board_true: &igi_probe::Board,
) -> [f64; 3] {
    let est = placed.pose.as_ref().expect("pose from the fiducials");
    assert_eq!(est.markers_found, vec![0, 1, 2, 3]);
    let p = est.board_to_camera();
    let rot_err = igi_camera::cv::rotation_angle_between(&p.r, &pose.r).to_degrees();
    let t_err = (p.t - pose.t).length();
    let centre_err = [
        placed
            .board
            .mirror
            .center_cam
            .distance(board_true.mirror.center_cam),
        placed
            .board
            .black
            .unwrap()
            .center_cam
            .distance(board_true.black.unwrap().center_cam),
        placed
            .board
            .diffuse
            .unwrap()
            .center_cam
            .distance(board_true.diffuse.unwrap().center_cam),
    ];
    eprintln!(
        "board pose: rotation error {rot_err:.4} deg, translation error {:.3} mm, sphere centres {:.3} / {:.3} / {:.3} mm, \
         {} of {} corners, RMS {:.3} px",
        1e3 * t_err,
        1e3 * centre_err[0],
        1e3 * centre_err[1],
        1e3 * centre_err[2],
        est.corners_inliers,
        est.corners_matched,
        est.rms_px
    );
    assert!(rot_err < 0.1, "rotation error {rot_err} deg");
    assert!(t_err < 1e-3, "translation error {t_err} m");
    assert!(centre_err.iter().all(|e| *e < 1e-3), "{centre_err:?}");
    assert!(est.rms_px < 0.3, "{}", est.rms_px);
    centre_err
}

/// The relative RMS difference of two lat-long sky maps where both are valid (solid-angle
/// weighted).
fn sky_relative_rms(a: &igi_imaging::HdrImage, b: &igi_imaging::HdrImage) -> f64 {
    let (mut se, mut st) = (0.0f64, 0.0f64);
    for k in 0..a.pixels.len() {
        if a.valid[k] && b.valid[k] {
            let i = k / a.width;
            let w = igi_imaging::latlong::pixel_solid_angle(i, a.width, a.height) as f64;
            for c in 0..3 {
                se += w * (a.pixels[k][c] - b.pixels[k][c]).powi(2) as f64;
                st += w * (a.pixels[k][c] as f64).powi(2);
            }
        }
    }
    (se / st).sqrt()
}

/// The fiducial placement with the mirror and black centres refined from their outlines
/// (igi probe --refine-spheres): `(da, sun_angle)` are the known pose's sun direction and the
/// fiducial placement's angle from it.
#[cfg(feature = "opencv")]
fn check_refined(
    img: &igi_imaging::HdrImage,
    cam: &Camera,
    placed: &igi_probe::fiducial::Placement,
    board_true: &igi_probe::Board,
    opt: &igi_probe::ProbeOptions,
    (da, sun_angle): (DVec3, f64),
    sun_direction: DVec3,
) {
    use igi_probe::{process, ProbeOptions};
    let opt_r = ProbeOptions {
        refine_centers: true,
        ..opt.clone()
    };
    let c = process(img, cam, &placed.board, &opt_r).unwrap();
    let dc = DVec3::from_array(c.diagnostics.sun.as_ref().unwrap().direction);
    let refined_angle = dc.angle_between(da).to_degrees();
    let across = |a: DVec3, t: DVec3| {
        let (los, d) = (t.normalize(), a - t);
        1e3 * (d - d.dot(los) * los).length()
    };
    let black_t = board_true.black.unwrap().center_cam;
    let black_fid = placed.board.black.unwrap().center_cam;
    let black_ref = DVec3::from_array(c.diagnostics.outline_fits[1].center_after);
    eprintln!(
        "refined from the outlines: sun {refined_angle:.4} deg from the known pose's (fiducials \
         {sun_angle:.4}), {:.4} deg from the truth; black centre across the line of sight {:.3} mm (fiducials {:.3} mm); fits {:?}",
        dc.angle_between(sun_direction).to_degrees(),
        across(black_ref, black_t),
        across(black_fid, black_t),
        c.diagnostics.outline_fits
    );
    // the silhouettes against the panel (which the glossy rims reflect) pin the centres better
    // than the fiducials do
    assert!(
        across(black_ref, black_t) < 0.5 * across(black_fid, black_t),
        "black centre not improved"
    );
    assert!(
        refined_angle < 0.1 && refined_angle < 0.5 * sun_angle,
        "refined sun {refined_angle} deg from the known pose's (fiducials {sun_angle})"
    );
}

#[cfg(not(feature = "opencv"))]
#[test]
fn without_opencv_a_board_frame_board_says_the_feature_is_needed() {
    let spec = BoardSpec::from_json_str(&board_json(), Path::new("board.json")).unwrap();
    let img = igi_imaging::HdrImage::new(960, 720);
    let e = place_board(&spec, &img, &camera()).unwrap_err().to_string();
    assert!(
        e.contains("board.json") && e.contains("opencv feature") && e.contains("center_board"),
        "{e}"
    );
    // with camera-frame centres too, the board falls back to them with a warning
    let both = board_json()
        .replace(
            r#""center_board": [-0.13, 0.05, 0.06]"#,
            r#""center": [-0.1, 0.0, 1.0], "center_board": [-0.13, 0.05, 0.06]"#,
        )
        .replace(
            r#""center_board": [0.13, 0.05, 0.06]"#,
            r#""center": [0.1, 0.0, 1.0], "center_board": [0.13, 0.05, 0.06]"#,
        )
        .replace(
            r#""center_board": [0.0, -0.12, 0.06]"#,
            r#""center": [0.0, 0.1, 1.0], "center_board": [0.0, -0.12, 0.06]"#,
        );
    let spec = BoardSpec::from_json_str(&both, Path::new("board.json")).unwrap();
    let placed = place_board(&spec, &img, &camera()).unwrap();
    assert!(
        placed.pose.is_none() && placed.warnings[0].contains("without the opencv feature"),
        "{:?}",
        placed.warnings
    );
    assert_eq!(placed.board.mirror.center_cam, DVec3::new(-0.1, 0.0, 1.0));
}
