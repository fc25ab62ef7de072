//! Planar fiducial targets: the pose of a photographed rig from its fiducials.
//!
//! Two paths give the target-to-camera transform:
//!
//! - marked points ([`pose_from_marked_points`]): the pixels of known points of the target's
//!   plane, given by the user, through the pure-Rust homography pose
//!   [`igi_camera::planar::pose_from_plane`] (no OpenCV);
//! - ArUco markers ([`match_markers`], then [`igi_camera::cv::solve_pnp_matched`]): the
//!   detected markers' corners matched by id to their target-frame corners, solved by SQPnP and
//!   Levenberg-Marquardt refinement with outlier rejection. The detection and the solve are
//!   OpenCV calls (feature `opencv`, all in `igi_camera::cv`); without the feature they return
//!   [`igi_camera::CameraError::NoOpenCv`].
//!
//! The lighting board (igi-probe) and the sample frame ([`crate::sample_frame`]) are both such
//! targets.

use glam::{DVec2, DVec3};
use igi_camera::cv::ArucoMarker;
use igi_camera::{planar, Intrinsics};

/// One fiducial of a target: its ArUco id and its corners in the target frame, in OpenCV's
/// order (the printed marker's top-left, top-right, bottom-right, bottom-left corner).
#[derive(Clone, Debug, PartialEq)]
pub struct FiducialMarker {
    pub id: i32,
    pub corners: [DVec3; 4],
}

/// A target's markers matched to the markers detected in a photograph.
#[derive(Clone, Debug, Default)]
pub struct MarkerMatches {
    /// Target-frame corners and their pixels, four per found marker, in the target's order.
    pub target: Vec<DVec3>,
    pub pixels: Vec<DVec2>,
    /// Ids of the target's markers found (once) in the photograph, and of those not found.
    pub found: Vec<i32>,
    pub missing: Vec<i32>,
}

/// Match the target's `markers` to the `detected` ones by id. A marker detected exactly once
/// contributes its four corners; one detected twice is ambiguous and counts as missing.
pub fn match_markers(markers: &[FiducialMarker], detected: &[ArucoMarker]) -> MarkerMatches {
    let mut m = MarkerMatches::default();
    for marker in markers {
        let mut hits = detected.iter().filter(|d| d.id == marker.id);
        match (hits.next(), hits.next()) {
            (Some(d), None) => {
                m.found.push(marker.id);
                m.target.extend_from_slice(&marker.corners);
                m.pixels.extend_from_slice(&d.corners);
            }
            _ => m.missing.push(marker.id),
        }
    }
    m
}

/// The pose of a plane target (z = 0) from the pixels of its points `plane` (at least four,
/// no three collinear) marked in a `width` x `height` photograph. Errors are messages for the
/// caller to put beside the photograph's name.
pub fn pose_from_marked_points(
    intrinsics: &Intrinsics,
    plane: &[DVec2],
    pixels: &[DVec2],
    (width, height): (usize, usize),
) -> Result<planar::PlanarPose, String> {
    if pixels.len() != plane.len() {
        return Err(format!(
            "{} corner pixels given, the frame has {} fiducials",
            pixels.len(),
            plane.len()
        ));
    }
    for (i, p) in pixels.iter().enumerate() {
        if !p.is_finite()
            || p.x < 0.0
            || p.y < 0.0
            || p.x > (width - 1) as f64
            || p.y > (height - 1) as f64
        {
            return Err(format!(
                "corner {i} ({:.1}, {:.1}) lies outside the {width}x{height} photo",
                p.x, p.y
            ));
        }
    }
    planar::pose_from_plane(intrinsics, plane, pixels)
        .map_err(|e| format!("corners: {e} (wrong order, or the wrong frame file?)"))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn marker(id: i32, x: f64) -> FiducialMarker {
        FiducialMarker {
            id,
            corners: [0.0, 1.0, 2.0, 3.0].map(|k| DVec3::new(x + k, 0.0, 0.0)),
        }
    }

    fn seen(id: i32, u: f64) -> ArucoMarker {
        ArucoMarker {
            id,
            corners: [0.0, 1.0, 2.0, 3.0].map(|k| DVec2::new(u + k, 5.0)),
        }
    }

    #[test]
    fn matching_keeps_target_order_and_drops_ambiguous_ids() {
        let markers = [marker(3, 0.0), marker(7, 10.0), marker(9, 20.0)];
        // 9 seen before 3; 7 seen twice (ambiguous); 42 is not the target's
        let det = [
            seen(9, 200.0),
            seen(7, 100.0),
            seen(3, 0.0),
            seen(7, 150.0),
            seen(42, 9.0),
        ];
        let m = match_markers(&markers, &det);
        assert_eq!(m.found, vec![3, 9]);
        assert_eq!(m.missing, vec![7]);
        assert_eq!(m.target.len(), 8);
        assert_eq!(m.target[4], DVec3::new(20.0, 0.0, 0.0));
        assert_eq!(m.pixels[0], DVec2::new(0.0, 5.0));
        assert_eq!(m.pixels[7], DVec2::new(203.0, 5.0));
    }

    #[test]
    fn marked_points_outside_the_photo_or_miscounted_are_refused() {
        let intr = igi_camera::Camera::pinhole(100, 80, 90.0, 90.0, 49.5, 39.5).intrinsics;
        let plane = [DVec2::ZERO, DVec2::X, DVec2::ONE, DVec2::Y];
        let px = [DVec2::new(10.0, 10.0); 3];
        let e = pose_from_marked_points(&intr, &plane, &px, (100, 80)).unwrap_err();
        assert!(e.contains("3 corner pixels given, the frame has 4"), "{e}");
        let px = [
            DVec2::new(10.0, 10.0),
            DVec2::new(50.0, 10.0),
            DVec2::new(50.0, 79.5),
            DVec2::new(10.0, 50.0),
        ];
        let e = pose_from_marked_points(&intr, &plane, &px, (100, 80)).unwrap_err();
        assert!(
            e.contains("corner 2 (50.0, 79.5) lies outside the 100x80 photo"),
            "{e}"
        );
    }
}
