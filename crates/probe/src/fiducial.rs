//! The board's pose from its fiducials (ArUco markers, OpenCV via `igi_camera::cv`): the
//! markers' corners, detected to sub-pixel and matched by id to their board-frame positions
//! ([`igi_capture::fiducial::match_markers`]),
//! give the board-to-camera transform by SQPnP and Levenberg-Marquardt refinement; the
//! spheres' board-frame centres then go to the camera frame. Without the `opencv` feature of
//! `igi-imaging` the detection is unavailable and a board given only in its own frame is an
//! error that says so.

use crate::board::{Board, BoardSpec, Fiducials};
use crate::ProbeError;
use glam::DVec3;
use igi_camera::{cv, Camera, WorldToCamera};
use igi_capture::fiducial::match_markers;
use igi_imaging::HdrImage;

/// Corners reprojecting farther than this (pixels) are dropped from the PnP solve.
pub const PNP_THRESHOLD_PX: f64 = 2.0;

/// The board's pose found from its fiducials.
#[derive(Clone, Debug, serde::Serialize)]
pub struct BoardPose {
    /// Board to camera: `x_cam = r x_board + t` (row-major `r`).
    pub r: [[f64; 3]; 3],
    pub t: [f64; 3],
    /// Ids of the board's markers found in the image, and of those not found.
    pub markers_found: Vec<i32>,
    pub markers_missing: Vec<i32>,
    /// Corners used by the PnP solve (inliers) of all matched corners.
    pub corners_inliers: usize,
    pub corners_matched: usize,
    /// RMS reprojection error of the inlier corners, pixels.
    pub rms_px: f64,
}

impl BoardPose {
    pub fn board_to_camera(&self) -> WorldToCamera {
        WorldToCamera {
            r: glam::DMat3::from_cols_array_2d(&self.r).transpose(),
            t: DVec3::from_array(self.t),
        }
    }
}

/// Detect the board's markers in `image` and solve for the board-to-camera pose.
pub fn estimate_board_pose(
    image: &HdrImage,
    camera: &Camera,
    fid: &Fiducials,
) -> Result<BoardPose, ProbeError> {
    let found = cv::detect_aruco_subpix(image, fid.dictionary)?;
    // a marker id seen twice is ambiguous: it counts as missing
    let m = match_markers(&fid.markers, &found);
    if m.found.len() < 2 {
        return Err(ProbeError::TooFewFiducials {
            found: m.found.len(),
            markers: fid.markers.len(),
            dictionary: fid.dictionary.name().to_string(),
            seen: found.len(),
        });
    }
    let pnp = cv::solve_pnp_matched(&camera.intrinsics, &m.target, &m.pixels, PNP_THRESHOLD_PX)?;
    let r = pnp.pose.r.transpose().to_cols_array_2d();
    Ok(BoardPose {
        r,
        t: pnp.pose.t.to_array(),
        corners_matched: m.target.len(),
        markers_found: m.found,
        markers_missing: m.missing,
        corners_inliers: pnp.inliers.len(),
        rms_px: pnp.rms_px,
    })
}

/// Where the board file's spheres are, for one photograph.
#[derive(Clone, Debug)]
pub struct Placement {
    pub board: Board,
    /// The fiducials' pose, when it placed the spheres.
    pub pose: Option<BoardPose>,
    pub warnings: Vec<String>,
}

impl Placement {
    /// Whether the sphere centres should be refined from their outlines by default
    /// ([`crate::ProbeOptions::refine_centers`]): when the fiducials' pose placed them, whose
    /// error (0.1-0.2 mm) turns the sun by about 0.3 degrees (docs/PROBE.md).
    pub fn refine_by_default(&self) -> bool {
        self.pose.is_some()
    }
}

/// Place the board's spheres in the camera frame: from the fiducials when the board has them
/// and every sphere has a board-frame centre (needs the `opencv` feature), else from the
/// camera-frame centres (FORMATS.md). Without OpenCV a board that has camera-frame centres
/// falls back to them with a warning; one that has not is an error saying the feature is needed.
pub fn place_board(
    spec: &BoardSpec,
    image: &HdrImage,
    camera: &Camera,
) -> Result<Placement, ProbeError> {
    let Some(fid) = spec.fiducials.as_ref().filter(|_| spec.has_board_centres()) else {
        return Ok(Placement {
            board: spec.in_camera_frame()?,
            pose: None,
            warnings: Vec::new(),
        });
    };
    match estimate_board_pose(image, camera, fid) {
        Ok(pose) => {
            let board = spec.with_pose(&pose.board_to_camera())?;
            let mut warnings = Vec::new();
            if !pose.markers_missing.is_empty() {
                warnings.push(format!("fiducials {:?} not found in the image", pose.markers_missing));
            }
            tracing::info!(
                "board pose from {} fiducials: {} of {} corners inliers, RMS {:.3} px",
                pose.markers_found.len(),
                pose.corners_inliers,
                pose.corners_matched,
                pose.rms_px
            );
            Ok(Placement { board, pose: Some(pose), warnings })
        }
        // without OpenCV: the camera-frame centres if every sphere has one, else
        // `in_camera_frame`'s error, which says the opencv feature is needed
        Err(ProbeError::Camera(igi_camera::CameraError::NoOpenCv)) => Ok(Placement {
            board: spec.in_camera_frame()?,
            pose: None,
            warnings: vec![
                "the board has fiducials but igi was built without the opencv feature: using the camera-frame centres"
                    .into(),
            ],
        }),
        Err(e) => Err(e),
    }
}
