//! `igi_capture::sample_frame` with the pose from ArUco markers (`PoseInput::Aruco`, feature `opencv`):
//! the synthetic frame (`igi_synth::sample_frame`) rendered with the real 4x4_50 marker patterns
//! of OpenCV's `drawMarker` at its fiducials, measured end to end, checked against the known
//! pose, light and BRDFs.
#![cfg(feature = "opencv")]

use igi_synth::sample_frame as synth;

use std::path::Path;

use glam::{DVec2, DVec3, Vec3};
use igi_camera::cv::{aruco_marker_image, rotation_angle_between, ArucoDict};
use igi_capture::{measure_photo, MeasureOptions, PoseInput};
use synth::{camera, dir, Synth};

const TARGET: DVec3 = DVec3::new(-0.02, 0.02, 0.0);
/// Marker bitmap side, pixels (6 cells of 10 px: ample for a marker about 60 px in the photo).
const SIDE: usize = 60;

/// The synthetic frame with fiducial `i` printed as ArUco marker `aruco_id` of the frame's
/// dictionary: black 0.03, white 0.8 albedo. Bitmap row 0 is the marker's top (frame +y), as
/// `SampleFrame::aruco_corners` expects.
fn aruco_synth(light: DVec3) -> Synth {
    let mut s = Synth::new(light);
    let bitmaps: Vec<Vec<u8>> = s
        .frame
        .fiducials
        .iter()
        .map(|f| aruco_marker_image(ArucoDict::Dict4x4_50, f.aruco_id.unwrap(), SIDE).unwrap())
        .collect();
    s.marker = Box::new(move |i, p: DVec2| {
        let col = (((p.x + 0.5) * SIDE as f64) as usize).min(SIDE - 1);
        let row = (((0.5 - p.y) * SIDE as f64) as usize).min(SIDE - 1);
        if bitmaps[i][row * SIDE + col] > 127 {
            0.8
        } else {
            0.03
        }
    });
    s
}

/// End to end through `measure_photo` with the pose from the ArUco markers (`frame_pose`:
/// `detect_aruco` and the matched PnP solver; the RANSAC `solve_pnp` was 1.15 degrees off on
/// these coplanar points and failed the light's closest-approach check).
#[test]
fn aruco_pose_recovers_pose_light_and_brdf() {
    assert_eq!(synth::frame().aruco_dictionary, "4x4_50");
    // light at 30 and 50 degrees, views on the far side and out of the light's plane
    let (mut worst_ang, mut worst_pos, mut worst_light, mut worst_val) =
        (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for &(tv, pv, tl) in &[(40.0, 0.0, 30.0), (35.0, 90.0, 50.0)] {
        let s = aruco_synth(DVec3::new(-0.04, 0.0, 0.0) + dir(tl, 180.0) * 0.6);
        let cam = camera(TARGET + dir(tv, pv) * 0.5);
        let img = s.render(&cam);
        let m = measure_photo(
            &s.frame,
            &cam,
            &img,
            Path::new("aruco.exr"),
            &PoseInput::Aruco,
            &MeasureOptions::default(),
        )
        .unwrap_or_else(|e| panic!("theta_v {tv}, phi_v {pv}, theta_l {tl}: {e}"));
        // three or four of the markers (id 1 is missed on this rendering: jagged edges)
        assert!(
            m.pose_source.starts_with("aruco ids [0"),
            "{}",
            m.pose_source
        );
        let ang = rotation_angle_between(&m.pose().r, &cam.pose.r).to_degrees();
        let pos = (DVec3::from_array(m.camera_center) - cam.center_world()).length();
        let lerr = (m.light_position() - s.light).length() / (s.light - TARGET).length();
        let mut val = 0.0f64;
        for r in &m.regions {
            let mat = &s
                .materials
                .iter()
                .find(|(n, _)| *n == r.material)
                .unwrap()
                .1;
            let truth = mat
                .as_ref()
                .eval(Vec3::from_array(r.light), Vec3::from_array(r.view))
                * std::f32::consts::PI;
            let e = ((Vec3::from_array(r.value) - truth).abs() / truth).max_element() as f64;
            val = val.max(e);
        }
        eprintln!(
            "aruco (theta_v {tv}, phi_v {pv}, theta_l {tl}): pose {ang:.3} deg / {:.2} mm (rms {:.2} px), light {:.2}% of distance, gap {:.1e} m, pi f {:.2}% off",
            pos * 1e3,
            m.pose_rms_px,
            lerr * 100.0,
            m.gap,
            val * 100.0
        );
        worst_ang = worst_ang.max(ang);
        worst_pos = worst_pos.max(pos);
        worst_light = worst_light.max(lerr);
        worst_val = worst_val.max(val);
    }
    eprintln!(
        "aruco worst: pose {worst_ang:.3} deg / {:.2} mm, light {:.2}%, pi f {:.2}%",
        worst_pos * 1e3,
        worst_light * 100.0,
        worst_val * 100.0
    );
    // measured 0.16 deg / 1.7 mm, light 3.9 %, pi f 7.3 % (a lobe of exponent 25 amplifies the
    // light's direction error; with 0.5 px corner noise the four-corner path gives 0.22 deg and
    // up to 11 %)
    assert!(
        worst_ang < 0.3 && worst_pos < 3e-3,
        "pose {worst_ang} deg / {worst_pos} m"
    );
    assert!(worst_light < 0.06, "light {worst_light}");
    assert!(worst_val < 0.12, "pi f {worst_val}");
}

/// The markers rendered from `aruco_marker_image` are found by `detect_aruco_subpix` at their
/// true corners, and `solve_pnp_matched` recovers the pose from them.
#[test]
fn aruco_markers_give_the_pose_to_a_quarter_degree() {
    use igi_camera::cv::{detect_aruco_subpix, solve_pnp_matched};
    let s = aruco_synth(DVec3::new(-0.04, 0.0, 0.0) + dir(30.0, 180.0) * 0.6);
    let cam = camera(TARGET + dir(40.0, 0.0) * 0.5);
    let img = s.render(&cam);
    let found = detect_aruco_subpix(&img, ArucoDict::Dict4x4_50).unwrap();
    let (mut world, mut px, mut errs) = (Vec::new(), Vec::new(), Vec::new());
    for m in &found {
        let i = s
            .frame
            .fiducials
            .iter()
            .position(|f| f.aruco_id == Some(m.id))
            .unwrap_or_else(|| panic!("found marker {} the frame does not have", m.id));
        let wc = s.frame.aruco_corners(i).unwrap();
        for (c, w) in m.corners.iter().zip(wc) {
            errs.push((*c - cam.project(w).unwrap()).length());
        }
        world.extend(wc);
        px.extend(m.corners);
    }
    errs.sort_by(f64::total_cmp);
    let (median, worst) = (errs[errs.len() / 2], errs[errs.len() - 1]);
    let r = solve_pnp_matched(&cam.intrinsics, &world, &px, 3.0).unwrap();
    let ang = rotation_angle_between(&r.pose.r, &cam.pose.r).to_degrees();
    let pos = (r.pose.inverse().t - cam.center_world()).length();
    eprintln!(
        "{} of 4 markers, corners median {median:.2} px worst {worst:.2} px; pose {ang:.3} deg / {:.2} mm, rms {:.2} px",
        found.len(),
        pos * 1e3,
        r.rms_px
    );
    // measured: 3 of 4 (marker 1 is missed), median 0.50 px, worst 2.3 px (the synthetic photo
    // samples the plane once per pixel, so the marker edges are aliased), 0.24 deg
    assert!(found.len() >= 3, "{} markers", found.len());
    assert!(median < 1.0 && worst < 3.0, "corners {errs:?}");
    assert!(
        ang < 0.4 && r.rms_px < 1.0,
        "pose {ang} deg, rms {}",
        r.rms_px
    );
}
