//! OpenCV-backed geometry: checkerboard calibration (Zhang), PnP pose, homography, ArUco.
//!
//! All OpenCV calls of the workspace live in this module, behind the cargo feature `opencv`.
//! Without the feature the same functions exist and return [`CameraError::NoOpenCv`].
//! OpenCV's RANSAC uses a fixed internal seed, so results are deterministic.

use crate::{Camera, CameraError, Intrinsics, WorldToCamera};
use glam::{DMat3, DVec2, DVec3};
use igi_imaging::HdrImage;

/// Result of [`solve_pnp`].
#[derive(Clone, Debug)]
pub struct PnpResult {
    pub pose: WorldToCamera,
    /// Indices of the RANSAC inliers.
    pub inliers: Vec<usize>,
    /// RMS reprojection error over the inliers after LM refinement, pixels.
    pub rms_px: f64,
}

/// Result of a calibration.
#[derive(Clone, Debug)]
pub struct Calibration {
    /// Intrinsics and distortion; the pose is that of the first view.
    pub camera: Camera,
    /// RMS reprojection error, pixels (as reported by OpenCV).
    pub rms_px: f64,
    /// Board-to-camera pose of every view.
    pub poses: Vec<WorldToCamera>,
}

/// A detected ArUco marker: id and its four corners (pixels, OpenCV order: clockwise from
/// the top-left corner of the marker).
#[derive(Clone, Debug)]
pub struct ArucoMarker {
    pub id: i32,
    pub corners: [DVec2; 4],
}

/// Predefined ArUco dictionaries.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ArucoDict {
    Dict4x4_50,
    Dict5x5_100,
    Dict6x6_250,
    Original,
}

impl ArucoDict {
    /// The dictionary of an OpenCV name (`"DICT_4X4_50"`, `"DICT_5X5_100"`, `"DICT_6X6_250"`,
    /// `"DICT_ARUCO_ORIGINAL"`; case-insensitive, the `DICT_` prefix optional).
    pub fn from_name(name: &str) -> Option<ArucoDict> {
        let n = name.trim().to_ascii_uppercase();
        match n.strip_prefix("DICT_").unwrap_or(&n) {
            "4X4_50" => Some(ArucoDict::Dict4x4_50),
            "5X5_100" => Some(ArucoDict::Dict5x5_100),
            "6X6_250" => Some(ArucoDict::Dict6x6_250),
            "ARUCO_ORIGINAL" | "ORIGINAL" => Some(ArucoDict::Original),
            _ => None,
        }
    }

    /// The OpenCV name of the dictionary.
    pub fn name(self) -> &'static str {
        match self {
            ArucoDict::Dict4x4_50 => "DICT_4X4_50",
            ArucoDict::Dict5x5_100 => "DICT_5X5_100",
            ArucoDict::Dict6x6_250 => "DICT_6X6_250",
            ArucoDict::Original => "DICT_ARUCO_ORIGINAL",
        }
    }
}

/// Object points of a checkerboard with `cols` x `rows` inner corners and `square` metres,
/// in the board plane z = 0, row-major (OpenCV's corner order).
pub fn checkerboard_points(cols: usize, rows: usize, square: f64) -> Vec<DVec3> {
    let mut v = Vec::with_capacity(cols * rows);
    for r in 0..rows {
        for c in 0..cols {
            v.push(DVec3::new(c as f64 * square, r as f64 * square, 0.0));
        }
    }
    v
}

/// Axis-angle (Rodrigues) vector -> rotation matrix.
pub fn rotation_from_rodrigues(r: DVec3) -> DMat3 {
    let th = r.length();
    if th < 1e-15 {
        return DMat3::IDENTITY;
    }
    DMat3::from_axis_angle(r / th, th)
}

/// Rotation angle (radians) between two rotations.
pub fn rotation_angle_between(a: &DMat3, b: &DMat3) -> f64 {
    let m = a.transpose() * *b;
    let tr = m.x_axis.x + m.y_axis.y + m.z_axis.z;
    ((tr - 1.0) * 0.5).clamp(-1.0, 1.0).acos()
}

#[cfg(not(feature = "opencv"))]
mod imp {
    use super::*;
    pub fn solve_pnp(
        _: &Intrinsics,
        _: &[DVec3],
        _: &[DVec2],
        _: f64,
    ) -> Result<PnpResult, CameraError> {
        Err(CameraError::NoOpenCv)
    }
    pub fn calibrate_from_points(
        _: &[Vec<DVec3>],
        _: &[Vec<DVec2>],
        _: u32,
        _: u32,
    ) -> Result<Calibration, CameraError> {
        Err(CameraError::NoOpenCv)
    }
    pub fn find_checkerboard_corners(
        _: &HdrImage,
        _: usize,
        _: usize,
    ) -> Result<Option<Vec<DVec2>>, CameraError> {
        Err(CameraError::NoOpenCv)
    }
    pub fn find_homography(_: &[DVec2], _: &[DVec2], _: f64) -> Result<DMat3, CameraError> {
        Err(CameraError::NoOpenCv)
    }
    pub fn detect_aruco(_: &HdrImage, _: ArucoDict) -> Result<Vec<ArucoMarker>, CameraError> {
        Err(CameraError::NoOpenCv)
    }
    pub fn detect_aruco_subpix(
        _: &HdrImage,
        _: ArucoDict,
    ) -> Result<Vec<ArucoMarker>, CameraError> {
        Err(CameraError::NoOpenCv)
    }
    pub fn solve_pnp_matched(
        _: &Intrinsics,
        _: &[DVec3],
        _: &[DVec2],
        _: f64,
    ) -> Result<PnpResult, CameraError> {
        Err(CameraError::NoOpenCv)
    }
    pub fn aruco_marker_image(_: ArucoDict, _: i32, _: usize) -> Result<Vec<u8>, CameraError> {
        Err(CameraError::NoOpenCv)
    }
}

#[cfg(feature = "opencv")]
mod imp {
    use super::*;
    use crate::PnpError;
    use opencv::core::{self, Mat, Point2f, Point3f, Vector};
    use opencv::prelude::*;
    use opencv::{aruco, calib3d, imgproc};

    fn cv_err(e: opencv::Error) -> CameraError {
        CameraError::OpenCvCall(Box::new(e))
    }

    fn k_mat(i: &Intrinsics) -> Result<Mat, CameraError> {
        Mat::from_slice_2d(&i.k_matrix()).map_err(cv_err)
    }

    fn dist_mat(i: &Intrinsics) -> Result<Mat, CameraError> {
        Mat::from_slice(&i.dist.to_array())
            .map_err(cv_err)
            .and_then(|m| m.try_clone().map_err(cv_err))
    }

    fn vec3(m: &Mat) -> Result<DVec3, CameraError> {
        let mut v = [0.0; 3];
        for (k, x) in v.iter_mut().enumerate() {
            *x = *m.at::<f64>(k as i32).map_err(cv_err)?;
        }
        Ok(DVec3::from_array(v))
    }

    fn pose_of(rvec: &Mat, tvec: &Mat) -> Result<WorldToCamera, CameraError> {
        Ok(WorldToCamera {
            r: rotation_from_rodrigues(vec3(rvec)?),
            t: vec3(tvec)?,
        })
    }

    fn p3(v: &[DVec3]) -> Vector<Point3f> {
        v.iter()
            .map(|p| Point3f::new(p.x as f32, p.y as f32, p.z as f32))
            .collect()
    }

    fn p2(v: &[DVec2]) -> Vector<Point2f> {
        v.iter()
            .map(|p| Point2f::new(p.x as f32, p.y as f32))
            .collect()
    }

    fn gray8(img: &HdrImage) -> Result<Mat, CameraError> {
        let g: Vec<f32> = img
            .pixels
            .iter()
            .map(|p| (p[0] + p[1] + p[2]) / 3.0)
            .collect();
        let mut sorted = g.clone();
        sorted.sort_by(|a, b| a.partial_cmp(b).unwrap_or(std::cmp::Ordering::Equal));
        let hi = sorted
            .get(sorted.len() * 99 / 100)
            .copied()
            .unwrap_or(1.0)
            .max(1e-12);
        let bytes: Vec<u8> = g
            .iter()
            .map(|v| ((v / hi) * 255.0).round().clamp(0.0, 255.0) as u8)
            .collect();
        let m = Mat::from_slice(&bytes).map_err(cv_err)?;
        m.reshape(1, img.height as i32)
            .map_err(cv_err)?
            .try_clone()
            .map_err(cv_err)
    }

    pub fn solve_pnp(
        intr: &Intrinsics,
        world: &[DVec3],
        pixels: &[DVec2],
        threshold_px: f64,
    ) -> Result<PnpResult, CameraError> {
        check_correspondences(world, pixels, 6)?;
        let (obj, imgp) = (p3(world), p2(pixels));
        let (k, d) = (k_mat(intr)?, dist_mat(intr)?);
        let (mut rvec, mut tvec, inliers) = pnp_ransac(&obj, &imgp, &k, &d, threshold_px)?;
        let io: Vector<Point3f> = inliers.iter().map(|&i| obj.get(i).unwrap()).collect();
        let ii: Vector<Point2f> = inliers.iter().map(|&i| imgp.get(i).unwrap()).collect();
        calib3d::solve_pnp_refine_lm(&io, &ii, &k, &d, &mut rvec, &mut tvec, lm_criteria()?)
            .map_err(cv_err)?;
        let pose = pose_of(&rvec, &tvec)?;
        let errs = reprojection_errors(intr, pose, world, pixels);
        Ok(PnpResult {
            pose,
            rms_px: inlier_rms(&errs, &inliers),
            inliers,
        })
    }

    /// OpenCV's RANSAC PnP (iterative solver): the pose (Rodrigues vector, translation) and
    /// the indices of the inliers within `threshold_px`.
    fn pnp_ransac(
        obj: &Vector<Point3f>,
        imgp: &Vector<Point2f>,
        k: &Mat,
        d: &Mat,
        threshold_px: f64,
    ) -> Result<(Mat, Mat, Vec<usize>), CameraError> {
        let mut rvec = Mat::default();
        let mut tvec = Mat::default();
        let mut inl = Mat::default();
        let ok = calib3d::solve_pnp_ransac(
            &obj,
            &imgp,
            &k,
            &d,
            &mut rvec,
            &mut tvec,
            false,
            1000,
            threshold_px as f32,
            0.999,
            &mut inl,
            calib3d::SOLVEPNP_ITERATIVE,
        )
        .map_err(cv_err)?;
        if !ok {
            return Err(PnpError::RansacFailed.into());
        }
        let mut inliers = Vec::new();
        for k in 0..inl.total() as i32 {
            inliers.push(*inl.at::<i32>(k).map_err(cv_err)? as usize);
        }
        Ok((rvec, tvec, inliers))
    }

    /// Levenberg-Marquardt refinement's stopping rule: 50 iterations or a step below 1e-12.
    fn lm_criteria() -> Result<core::TermCriteria, CameraError> {
        core::TermCriteria::new(core::TermCriteria_COUNT + core::TermCriteria_EPS, 50, 1e-12)
            .map_err(cv_err)
    }

    /// One pixel per world point, and at least `min` of them.
    fn check_correspondences(
        world: &[DVec3],
        pixels: &[DVec2],
        min: usize,
    ) -> Result<(), CameraError> {
        if world.len() != pixels.len() {
            return Err(PnpError::Unpaired {
                world: world.len(),
                pixels: pixels.len(),
            }
            .into());
        }
        if world.len() < min {
            return Err(PnpError::TooFew {
                need: min,
                got: world.len(),
            }
            .into());
        }
        Ok(())
    }

    /// RMS of the reprojection errors `errs` over the `inliers`.
    fn inlier_rms(errs: &[f64], inliers: &[usize]) -> f64 {
        (inliers.iter().map(|&i| errs[i] * errs[i]).sum::<f64>() / inliers.len().max(1) as f64)
            .sqrt()
    }

    /// Reprojection errors (pixels) of `world` under `pose`.
    fn reprojection_errors(
        intr: &Intrinsics,
        pose: WorldToCamera,
        world: &[DVec3],
        pixels: &[DVec2],
    ) -> Vec<f64> {
        let cam = Camera {
            width: 1,
            height: 1,
            intrinsics: *intr,
            pose,
        };
        world
            .iter()
            .zip(pixels)
            .map(|(w, p)| cam.project(*w).map_or(f64::INFINITY, |q| (q - *p).length()))
            .collect()
    }

    /// SQPnP on the correspondences `idx`, refined by Levenberg-Marquardt.
    fn sqpnp_refined(
        k: &Mat,
        d: &Mat,
        crit: core::TermCriteria,
        world: &[DVec3],
        pixels: &[DVec2],
        idx: &[usize],
    ) -> Result<WorldToCamera, CameraError> {
        let w: Vec<DVec3> = idx.iter().map(|&i| world[i]).collect();
        let p: Vec<DVec2> = idx.iter().map(|&i| pixels[i]).collect();
        let (obj, imgp) = (p3(&w), p2(&p));
        let mut rvec = Mat::default();
        let mut tvec = Mat::default();
        let ok = calib3d::solve_pnp(
            &obj,
            &imgp,
            k,
            d,
            &mut rvec,
            &mut tvec,
            false,
            calib3d::SOLVEPNP_SQPNP,
        )
        .map_err(cv_err)?;
        if !ok {
            return Err(PnpError::SqpnpFailed.into());
        }
        calib3d::solve_pnp_refine_lm(&obj, &imgp, k, d, &mut rvec, &mut tvec, crit)
            .map_err(cv_err)?;
        pose_of(&rvec, &tvec)
    }

    /// Indices of the points that reproject within `threshold_px` under `pose`.
    fn within_threshold(
        intr: &Intrinsics,
        pose: WorldToCamera,
        world: &[DVec3],
        pixels: &[DVec2],
        threshold_px: f64,
    ) -> Vec<usize> {
        reprojection_errors(intr, pose, world, pixels)
            .iter()
            .enumerate()
            .filter(|(_, e)| **e <= threshold_px)
            .map(|(i, _)| i)
            .collect()
    }

    pub fn solve_pnp_matched(
        intr: &Intrinsics,
        world: &[DVec3],
        pixels: &[DVec2],
        threshold_px: f64,
    ) -> Result<PnpResult, CameraError> {
        check_correspondences(world, pixels, 4)?;
        let (k, d) = (k_mat(intr)?, dist_mat(intr)?);
        let crit = lm_criteria()?;
        let solve = |idx: &[usize]| sqpnp_refined(&k, &d, crit, world, pixels, idx);
        let all: Vec<usize> = (0..world.len()).collect();
        let mut pose = solve(&all)?;
        let mut inliers = within_threshold(intr, pose, world, pixels, threshold_px);
        if inliers.len() < world.len() {
            if inliers.len() < 4 {
                return Err(PnpError::FewInliers {
                    inliers: inliers.len(),
                    points: world.len(),
                    threshold_px,
                }
                .into());
            }
            pose = solve(&inliers)?;
            inliers = within_threshold(intr, pose, world, pixels, threshold_px);
        }
        let errs = reprojection_errors(intr, pose, world, pixels);
        Ok(PnpResult {
            pose,
            rms_px: inlier_rms(&errs, &inliers),
            inliers,
        })
    }

    pub fn calibrate_from_points(
        object: &[Vec<DVec3>],
        image: &[Vec<DVec2>],
        width: u32,
        height: u32,
    ) -> Result<Calibration, CameraError> {
        if object.len() != image.len() || object.len() < 3 {
            return Err(CameraError::InvalidInput(format!(
                "calibration needs at least 3 views with matching point lists ({} object, {} image)",
                object.len(),
                image.len()
            )));
        }
        let obj: Vector<Vector<Point3f>> = object.iter().map(|v| p3(v)).collect();
        let imgp: Vector<Vector<Point2f>> = image.iter().map(|v| p2(v)).collect();
        let mut k = Mat::default();
        let mut d = Mat::default();
        let mut rvecs: Vector<Mat> = Vector::new();
        let mut tvecs: Vector<Mat> = Vector::new();
        let crit = core::TermCriteria::new(
            core::TermCriteria_COUNT + core::TermCriteria_EPS,
            100,
            1e-12,
        )
        .map_err(cv_err)?;
        let rms = calib3d::calibrate_camera(
            &obj,
            &imgp,
            core::Size::new(width as i32, height as i32),
            &mut k,
            &mut d,
            &mut rvecs,
            &mut tvecs,
            0,
            crit,
        )
        .map_err(cv_err)?;
        let kk = |r: i32, c: i32| k.at_2d::<f64>(r, c).copied().map_err(cv_err);
        let mut dist = [0.0; 5];
        for (i, x) in dist.iter_mut().enumerate() {
            *x = *d.at::<f64>(i as i32).map_err(cv_err)?;
        }
        let intrinsics = Intrinsics {
            fx: kk(0, 0)?,
            fy: kk(1, 1)?,
            cx: kk(0, 2)?,
            cy: kk(1, 2)?,
            dist: crate::Distortion::from_array(dist),
        };
        let mut poses = Vec::new();
        for i in 0..rvecs.len() {
            poses.push(pose_of(
                &rvecs.get(i).map_err(cv_err)?,
                &tvecs.get(i).map_err(cv_err)?,
            )?);
        }
        Ok(Calibration {
            camera: Camera {
                width,
                height,
                intrinsics,
                pose: poses[0],
            },
            rms_px: rms,
            poses,
        })
    }

    pub fn find_checkerboard_corners(
        img: &HdrImage,
        cols: usize,
        rows: usize,
    ) -> Result<Option<Vec<DVec2>>, CameraError> {
        let g = gray8(img)?;
        let mut corners: Vector<Point2f> = Vector::new();
        let found = calib3d::find_chessboard_corners(
            &g,
            core::Size::new(cols as i32, rows as i32),
            &mut corners,
            calib3d::CALIB_CB_ADAPTIVE_THRESH + calib3d::CALIB_CB_NORMALIZE_IMAGE,
        )
        .map_err(cv_err)?;
        if !found {
            return Ok(None);
        }
        let crit =
            core::TermCriteria::new(core::TermCriteria_COUNT + core::TermCriteria_EPS, 50, 1e-4)
                .map_err(cv_err)?;
        imgproc::corner_sub_pix(
            &g,
            &mut corners,
            core::Size::new(5, 5),
            core::Size::new(-1, -1),
            crit,
        )
        .map_err(cv_err)?;
        Ok(Some(
            corners
                .iter()
                .map(|p| DVec2::new(p.x as f64, p.y as f64))
                .collect(),
        ))
    }

    pub fn find_homography(
        src: &[DVec2],
        dst: &[DVec2],
        threshold_px: f64,
    ) -> Result<DMat3, CameraError> {
        if src.len() != dst.len() || src.len() < 4 {
            return Err(CameraError::InvalidInput(format!(
                "homography needs at least 4 matching points ({} and {})",
                src.len(),
                dst.len()
            )));
        }
        let mut mask = Mat::default();
        let h =
            calib3d::find_homography(&p2(src), &p2(dst), &mut mask, calib3d::RANSAC, threshold_px)
                .map_err(cv_err)?;
        if h.empty() {
            return Err(CameraError::InvalidInput("no homography found".into()));
        }
        let mut rows = [[0.0; 3]; 3];
        for (r, row) in rows.iter_mut().enumerate() {
            for (c, x) in row.iter_mut().enumerate() {
                *x = *h.at_2d::<f64>(r as i32, c as i32).map_err(cv_err)?;
            }
        }
        Ok(DMat3::from_cols_array_2d(&rows).transpose())
    }

    fn dictionary(dict: ArucoDict) -> Result<core::Ptr<aruco::Dictionary>, CameraError> {
        use aruco::PREDEFINED_DICTIONARY_NAME as N;
        let name = match dict {
            ArucoDict::Dict4x4_50 => N::DICT_4X4_50,
            ArucoDict::Dict5x5_100 => N::DICT_5X5_100,
            ArucoDict::Dict6x6_250 => N::DICT_6X6_250,
            ArucoDict::Original => N::DICT_ARUCO_ORIGINAL,
        };
        aruco::get_predefined_dictionary(name).map_err(cv_err)
    }

    pub fn detect_aruco(img: &HdrImage, dict: ArucoDict) -> Result<Vec<ArucoMarker>, CameraError> {
        detect_with(img, dict, false)
    }

    pub fn detect_aruco_subpix(
        img: &HdrImage,
        dict: ArucoDict,
    ) -> Result<Vec<ArucoMarker>, CameraError> {
        detect_with(img, dict, true)
    }

    pub fn aruco_marker_image(
        dict: ArucoDict,
        id: i32,
        side_px: usize,
    ) -> Result<Vec<u8>, CameraError> {
        let d = dictionary(dict)?;
        let mut m = Mat::default();
        aruco::draw_marker(&d, id, side_px as i32, &mut m, 1).map_err(cv_err)?;
        let bytes = m.data_bytes().map_err(cv_err)?.to_vec();
        if bytes.len() != side_px * side_px {
            return Err(CameraError::OpenCv(format!(
                "draw_marker gave {} bytes for a {side_px} px marker",
                bytes.len()
            )));
        }
        Ok(bytes)
    }

    fn detect_with(
        img: &HdrImage,
        dict: ArucoDict,
        subpix: bool,
    ) -> Result<Vec<ArucoMarker>, CameraError> {
        let d = dictionary(dict)?;
        let g = gray8(img)?;
        let mut corners: Vector<Vector<Point2f>> = Vector::new();
        let mut ids: Vector<i32> = Vector::new();
        if subpix {
            let mut params = aruco::DetectorParameters::create().map_err(cv_err)?;
            aruco::DetectorParametersTrait::set_corner_refinement_method(
                &mut params,
                aruco::CORNER_REFINE_SUBPIX,
            );
            let mut rejected: Vector<Vector<Point2f>> = Vector::new();
            aruco::detect_markers(&g, &d, &mut corners, &mut ids, &params, &mut rejected)
                .map_err(cv_err)?;
        } else {
            aruco::detect_markers_def(&g, &d, &mut corners, &mut ids).map_err(cv_err)?;
        }
        let mut out = Vec::new();
        for (i, id) in ids.iter().enumerate() {
            let c = corners.get(i).map_err(cv_err)?;
            let mut cs = [DVec2::ZERO; 4];
            for (k, p) in c.iter().take(4).enumerate() {
                cs[k] = DVec2::new(p.x as f64, p.y as f64);
            }
            out.push(ArucoMarker { id, corners: cs });
        }
        Ok(out)
    }
}

/// Camera pose from 2D-3D correspondences: RANSAC PnP (`threshold_px` inlier threshold) then
/// Levenberg-Marquardt refinement on the inliers.
pub fn solve_pnp(
    intr: &Intrinsics,
    world: &[DVec3],
    pixels: &[DVec2],
    threshold_px: f64,
) -> Result<PnpResult, CameraError> {
    imp::solve_pnp(intr, world, pixels, threshold_px)
}

/// Zhang calibration from per-view object points (board frame) and detected pixels.
pub fn calibrate_from_points(
    object: &[Vec<DVec3>],
    image: &[Vec<DVec2>],
    width: u32,
    height: u32,
) -> Result<Calibration, CameraError> {
    imp::calibrate_from_points(object, image, width, height)
}

/// Checkerboard inner corners (`cols` x `rows`), refined to sub-pixel; `None` if not found.
pub fn find_checkerboard_corners(
    img: &HdrImage,
    cols: usize,
    rows: usize,
) -> Result<Option<Vec<DVec2>>, CameraError> {
    imp::find_checkerboard_corners(img, cols, rows)
}

/// Calibrate from checkerboard photographs (views where the board is not found are skipped;
/// at least 3 are needed). Returns the calibration and the indices of the views used.
pub fn calibrate_checkerboard(
    images: &[HdrImage],
    cols: usize,
    rows: usize,
    square: f64,
) -> Result<(Calibration, Vec<usize>), CameraError> {
    if images.is_empty() {
        return Err(CameraError::InvalidInput("no calibration images".into()));
    }
    let (w, h) = (images[0].width, images[0].height);
    let obj = checkerboard_points(cols, rows, square);
    let mut objs = Vec::new();
    let mut imgs = Vec::new();
    let mut used = Vec::new();
    for (i, im) in images.iter().enumerate() {
        if (im.width, im.height) != (w, h) {
            return Err(CameraError::InvalidInput(format!(
                "calibration image {i} has a different size"
            )));
        }
        if let Some(c) = find_checkerboard_corners(im, cols, rows)? {
            objs.push(obj.clone());
            imgs.push(c);
            used.push(i);
        }
    }
    if used.len() < 3 {
        return Err(CameraError::InvalidInput(format!(
            "checkerboard {cols}x{rows} found in only {} of {} images (need 3)",
            used.len(),
            images.len()
        )));
    }
    Ok((
        calibrate_from_points(&objs, &imgs, w as u32, h as u32)?,
        used,
    ))
}

/// Homography `dst ~ H src` (RANSAC with `threshold_px`).
pub fn find_homography(
    src: &[DVec2],
    dst: &[DVec2],
    threshold_px: f64,
) -> Result<DMat3, CameraError> {
    imp::find_homography(src, dst, threshold_px)
}

/// Detect ArUco markers (OpenCV 4.6 contrib aruco).
pub fn detect_aruco(img: &HdrImage, dict: ArucoDict) -> Result<Vec<ArucoMarker>, CameraError> {
    imp::detect_aruco(img, dict)
}

/// Camera pose from correspondences that are already matched (e.g. fiducial corners by id):
/// SQPnP (OpenCV `SOLVEPNP_SQPNP`, planar and non-planar points alike, at least 4) and
/// Levenberg-Marquardt refinement; points reprojecting beyond `threshold_px` are dropped and
/// the pose solved again from the rest. [`solve_pnp`]'s RANSAC (OpenCV 4.6) fails on coplanar
/// points, which fiducials on a flat board are.
pub fn solve_pnp_matched(
    intr: &Intrinsics,
    world: &[DVec3],
    pixels: &[DVec2],
    threshold_px: f64,
) -> Result<PnpResult, CameraError> {
    imp::solve_pnp_matched(intr, world, pixels, threshold_px)
}

/// [`detect_aruco`] with OpenCV's sub-pixel corner refinement (`CORNER_REFINE_SUBPIX`), for
/// poses from the marker corners.
pub fn detect_aruco_subpix(
    img: &HdrImage,
    dict: ArucoDict,
) -> Result<Vec<ArucoMarker>, CameraError> {
    imp::detect_aruco_subpix(img, dict)
}

/// The printable image of marker `id`: `side_px` x `side_px` bytes, row-major, 0 black and 255
/// white, with a one-cell black border (OpenCV `drawMarker`). Its corners in
/// [`ArucoMarker::corners`] order are the image's top-left, top-right, bottom-right and
/// bottom-left corners.
pub fn aruco_marker_image(
    dict: ArucoDict,
    id: i32,
    side_px: usize,
) -> Result<Vec<u8>, CameraError> {
    imp::aruco_marker_image(dict, id, side_px)
}

/// Finds a ColorChecker Classic (6 x 4 patches) with OpenCV's `mcc` detector and returns its
/// patch grid's outer corners in pixels, in the order [`crate::radiometry::sample_checker`]
/// takes them: top-left (dark skin), top-right (bluish green), bottom-right (black),
/// bottom-left (white). The linear image is tone-mapped to 8-bit sRGB for the detector (its
/// 99.5th percentile brightest channel to white); the detector's chart box is turned into the
/// patch grid, oriented by the patch colours
/// ([`crate::radiometry::checker_corners_from_box`]) and refined by the patches' centroids
/// ([`crate::radiometry::refine_checker_corners`]).
/// [`crate::RadiometryError::CheckerNotFound`] when no chart is found.
pub fn detect_color_checker(img: &HdrImage) -> Result<[DVec2; 4], CameraError> {
    let chart_box = mcc_imp::chart_box(img)?
        .ok_or_else(|| CameraError::from(crate::RadiometryError::CheckerNotFound))?;
    let (corners, _) = crate::radiometry::checker_corners_from_box(img, &chart_box)?;
    Ok(crate::radiometry::refine_checker_corners(img, &corners))
}

/// 8-bit sRGB bytes (B, G, R per pixel, row-major) of a linear image, scaled so that the
/// 99.5th percentile of the pixels' brightest channel is white (invalid pixels black).
#[cfg_attr(not(feature = "opencv"), allow(dead_code))]
fn bgr8_tonemapped(img: &HdrImage) -> Vec<u8> {
    let mut peaks: Vec<f32> = img
        .pixels
        .iter()
        .zip(&img.valid)
        .filter(|(_, v)| **v)
        .map(|(p, _)| p[0].max(p[1]).max(p[2]))
        .filter(|v| v.is_finite())
        .collect();
    let k = (peaks.len() * 995 / 1000).min(peaks.len().saturating_sub(1));
    let white = match peaks.is_empty() {
        true => 1.0,
        false => *peaks.select_nth_unstable_by(k, |a, b| a.total_cmp(b)).1,
    };
    let scale = if white > 0.0 { 1.0 / white } else { 1.0 };
    let mut out = Vec::with_capacity(img.pixels.len() * 3);
    for (p, ok) in img.pixels.iter().zip(&img.valid) {
        for c in [2, 1, 0] {
            let v = if *ok && p[c].is_finite() {
                p[c] * scale
            } else {
                0.0
            };
            out.push((igi_imaging::io::linear_to_srgb(v) * 255.0 + 0.5) as u8);
        }
    }
    out
}

#[cfg(not(feature = "opencv"))]
mod mcc_imp {
    use super::*;
    pub fn chart_box(_: &HdrImage) -> Result<Option<[DVec2; 4]>, CameraError> {
        Err(CameraError::NoOpenCv)
    }
}

#[cfg(feature = "opencv")]
mod mcc_imp {
    use super::*;
    use opencv::core::{Mat, Point2f, Ptr, Vector, CV_8UC3};
    use opencv::mcc::{MCC_CCheckerDetector, MCC_TYPECHART};
    use opencv::prelude::*;

    fn cv_err(e: opencv::Error) -> CameraError {
        CameraError::OpenCv(e.to_string())
    }

    /// The chart box of the best ColorChecker Classic `mcc` finds (corners in its own order),
    /// or `None`.
    pub fn chart_box(img: &HdrImage) -> Result<Option<[DVec2; 4]>, CameraError> {
        let bytes = bgr8_tonemapped(img);
        let flat = Mat::from_slice(&bytes).map_err(cv_err)?;
        let bgr = flat
            .reshape(3, img.height as i32)
            .map_err(cv_err)?
            .try_clone()
            .map_err(cv_err)?;
        debug_assert_eq!(bgr.typ(), CV_8UC3);
        let mut det: Ptr<MCC_CCheckerDetector> = MCC_CCheckerDetector::create().map_err(cv_err)?;
        if !det
            .process_def(&bgr, MCC_TYPECHART::MCC24)
            .map_err(cv_err)?
        {
            return Ok(None);
        }
        let mut best = det.get_best_color_checker().map_err(cv_err)?;
        let bx: Vector<Point2f> = best.get_box().map_err(cv_err)?;
        let corners: Vec<DVec2> = bx
            .iter()
            .map(|q| DVec2::new(q.x as f64, q.y as f64))
            .collect();
        Ok(<[DVec2; 4]>::try_from(corners).ok())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[cfg(not(feature = "opencv"))]
    #[test]
    fn without_opencv_functions_say_so() {
        let i = Camera::pinhole(10, 10, 10.0, 10.0, 5.0, 5.0).intrinsics;
        let e = solve_pnp(&i, &[], &[], 2.0).unwrap_err().to_string();
        assert!(
            e.contains("built without opencv") && e.contains("--features opencv"),
            "{e}"
        );
        assert!(matches!(
            find_homography(&[], &[], 1.0),
            Err(CameraError::NoOpenCv)
        ));
        assert!(matches!(
            detect_aruco(&HdrImage::new(2, 2), ArucoDict::Dict4x4_50),
            Err(CameraError::NoOpenCv)
        ));
        assert!(matches!(
            detect_aruco_subpix(&HdrImage::new(2, 2), ArucoDict::Dict4x4_50),
            Err(CameraError::NoOpenCv)
        ));
        assert!(matches!(
            aruco_marker_image(ArucoDict::Dict4x4_50, 0, 60),
            Err(CameraError::NoOpenCv)
        ));
        assert!(matches!(
            solve_pnp_matched(&i, &[], &[], 2.0),
            Err(CameraError::NoOpenCv)
        ));
    }

    #[test]
    fn aruco_dictionary_names() {
        for d in [
            ArucoDict::Dict4x4_50,
            ArucoDict::Dict5x5_100,
            ArucoDict::Dict6x6_250,
            ArucoDict::Original,
        ] {
            assert_eq!(ArucoDict::from_name(d.name()), Some(d));
        }
        assert_eq!(ArucoDict::from_name("4x4_50"), Some(ArucoDict::Dict4x4_50));
        assert_eq!(ArucoDict::from_name("DICT_7X7_1000"), None);
    }

    #[test]
    fn rodrigues_and_angle() {
        let r = rotation_from_rodrigues(DVec3::new(0.0, 0.0, std::f64::consts::FRAC_PI_2));
        assert!((r * DVec3::X - DVec3::Y).length() < 1e-12);
        assert!(
            (rotation_angle_between(&DMat3::IDENTITY, &r) - std::f64::consts::FRAC_PI_2).abs()
                < 1e-12
        );
    }

    #[cfg(feature = "opencv")]
    mod with_opencv {
        use super::super::*;
        use crate::Distortion;
        use rand::{Rng, SeedableRng};
        use rand_distr_free::normal;

        mod rand_distr_free {
            use rand::Rng;
            /// Standard normal sample (Box-Muller).
            pub fn normal(rng: &mut impl Rng) -> f64 {
                let u1: f64 = rng.gen_range(1e-12..1.0);
                let u2: f64 = rng.gen();
                (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
            }
        }

        fn truth() -> Camera {
            let r = DMat3::from_rotation_x(0.4)
                * DMat3::from_rotation_y(-0.3)
                * DMat3::from_rotation_z(0.2);
            Camera {
                width: 1280,
                height: 960,
                intrinsics: Intrinsics {
                    fx: 1000.0,
                    fy: 1000.0,
                    cx: 640.0,
                    cy: 480.0,
                    dist: Distortion {
                        k1: -0.1,
                        k2: 0.02,
                        ..Default::default()
                    },
                },
                pose: WorldToCamera {
                    r,
                    t: DVec3::new(0.2, -0.1, 6.0),
                },
            }
        }

        #[test]
        fn pnp_15_points_1px_noise_rotation_within_1_degree() {
            let cam = truth();
            let mut rng = rand_pcg::Pcg64::seed_from_u64(42);
            let mut world = Vec::new();
            let mut px = Vec::new();
            while world.len() < 15 {
                let p = DVec3::new(
                    rng.gen_range(-2.0..2.0),
                    rng.gen_range(-2.0..2.0),
                    rng.gen_range(-1.0..1.0),
                );
                if let Some(q) = cam.project(p) {
                    if q.x > 0.0 && q.y > 0.0 && q.x < 1279.0 && q.y < 959.0 {
                        world.push(p);
                        px.push(q + DVec2::new(normal(&mut rng), normal(&mut rng)));
                    }
                }
            }
            let res = solve_pnp(&cam.intrinsics, &world, &px, 4.0).unwrap();
            let ang = rotation_angle_between(&res.pose.r, &cam.pose.r).to_degrees();
            let dt = (res.pose.t - cam.pose.t).length();
            eprintln!("PnP: rotation error {ang:.4} deg, translation error {dt:.4} m, rms {:.3} px, inliers {}", res.rms_px, res.inliers.len());
            assert!(ang < 1.0, "rotation error {ang} deg");
            assert!(res.rms_px < 2.0);
        }

        #[test]
        fn calibration_of_synthetic_board_views_recovers_focal_within_1_percent() {
            let cam = truth();
            let board = checkerboard_points(9, 6, 0.05);
            let mut rng = rand_pcg::Pcg64::seed_from_u64(9);
            let mut objs = Vec::new();
            let mut imgs = Vec::new();
            for v in 0..12 {
                let r = DMat3::from_rotation_x(rng.gen_range(-0.5..0.5))
                    * DMat3::from_rotation_y(rng.gen_range(-0.5..0.5))
                    * DMat3::from_rotation_z(rng.gen_range(-0.3..0.3));
                let t = DVec3::new(
                    -0.2 + 0.03 * (v % 3) as f64,
                    -0.12 + 0.02 * (v % 4) as f64,
                    rng.gen_range(0.6..1.0),
                );
                let c = Camera {
                    pose: WorldToCamera { r, t },
                    ..cam.clone()
                };
                let px: Vec<DVec2> = board
                    .iter()
                    .map(|p| {
                        c.project(*p).unwrap()
                            + DVec2::new(0.2 * normal(&mut rng), 0.2 * normal(&mut rng))
                    })
                    .collect();
                objs.push(board.clone());
                imgs.push(px);
            }
            let cal = calibrate_from_points(&objs, &imgs, 1280, 960).unwrap();
            let i = cal.camera.intrinsics;
            eprintln!(
                "calibration: fx {:.2} fy {:.2} cx {:.2} cy {:.2} k1 {:.4} rms {:.3}",
                i.fx, i.fy, i.cx, i.cy, i.dist.k1, cal.rms_px
            );
            assert!((i.fx / 1000.0 - 1.0).abs() < 0.01 && (i.fy / 1000.0 - 1.0).abs() < 0.01);
            assert!(cal.rms_px < 0.5);
        }

        #[test]
        fn checkerboard_corners_found_in_rendered_image() {
            // anti-aliased synthetic checkerboard, fronto-parallel, 8x5 inner corners
            let (w, h) = (400, 300);
            let sq = 30.0;
            let (ox, oy) = (65.3, 62.7);
            let mut img = HdrImage::new(w, h);
            for y in 0..h {
                for x in 0..w {
                    let mut acc = 0.0;
                    for sy in 0..4 {
                        for sx in 0..4 {
                            let fx = x as f64 + (sx as f64 + 0.5) / 4.0 - 0.5 - ox;
                            let fy = y as f64 + (sy as f64 + 0.5) / 4.0 - 0.5 - oy;
                            let (i, j) = ((fx / sq).floor() as i64, (fy / sq).floor() as i64);
                            let inside = (-1..=7).contains(&i) && (-1..=4).contains(&j);
                            acc += if inside && (i + j).rem_euclid(2) == 0 {
                                0.05
                            } else {
                                0.9
                            };
                        }
                    }
                    let v = acc as f32 / 16.0;
                    img.set(x, y, [v, v, v]);
                }
            }
            let c = find_checkerboard_corners(&img, 8, 5)
                .unwrap()
                .expect("board found");
            assert_eq!(c.len(), 40);
            // corners lie at (ox + i sq, oy + j sq), i = 0..8, j = 0..5 (in some OpenCV order)
            for p in &c {
                let i = ((p.x - ox) / sq).round();
                let j = ((p.y - oy) / sq).round();
                let e = (*p - DVec2::new(ox + i * sq, oy + j * sq)).length();
                assert!(e < 0.2, "corner {p} off by {e}");
            }
        }

        #[test]
        fn aruco_marker_detected_with_id_and_corners() {
            use opencv::prelude::*;
            let dict = opencv::aruco::get_predefined_dictionary(
                opencv::aruco::PREDEFINED_DICTIONARY_NAME::DICT_4X4_50,
            )
            .unwrap();
            let mut m = opencv::core::Mat::default();
            opencv::aruco::draw_marker(&dict, 7, 120, &mut m, 1).unwrap();
            let bytes = m.data_bytes().unwrap().to_vec();
            assert_eq!(bytes.len(), 120 * 120);
            let (ox, oy) = (90usize, 60usize);
            let mut img = HdrImage::new(300, 240);
            for p in img.pixels.iter_mut() {
                *p = [1.0; 3];
            }
            for y in 0..120 {
                for x in 0..120 {
                    let v = bytes[y * 120 + x] as f32 / 255.0;
                    img.set(ox + x, oy + y, [v, v, v]);
                }
            }
            let found = detect_aruco(&img, ArucoDict::Dict4x4_50).unwrap();
            assert_eq!(found.len(), 1, "{found:?}");
            assert_eq!(found[0].id, 7);
            // outer corners at the pixel edges: 89.5 .. 209.5 (pixel centres at integers)
            let expect = [(89.5, 59.5), (209.5, 59.5), (209.5, 179.5), (89.5, 179.5)];
            for (c, e) in found[0].corners.iter().zip(expect) {
                assert!(
                    (*c - DVec2::new(e.0, e.1)).length() < 1.5,
                    "{:?}",
                    found[0].corners
                );
            }
            assert!(detect_aruco(&HdrImage::new(50, 50), ArucoDict::Dict4x4_50)
                .unwrap()
                .is_empty());
        }

        #[test]
        fn marker_image_is_detected_with_subpixel_corners() {
            let side = 90usize;
            let bytes = aruco_marker_image(ArucoDict::Dict5x5_100, 42, side).unwrap();
            let (ox, oy) = (70usize, 50usize);
            let mut img = HdrImage::new(260, 200);
            img.pixels.iter_mut().for_each(|p| *p = [1.0; 3]);
            for y in 0..side {
                for x in 0..side {
                    let v = bytes[y * side + x] as f32 / 255.0;
                    img.set(ox + x, oy + y, [v, v, v]);
                }
            }
            let found = detect_aruco_subpix(&img, ArucoDict::Dict5x5_100).unwrap();
            assert_eq!(found.len(), 1, "{found:?}");
            assert_eq!(found[0].id, 42);
            let (x0, y0, x1) = (ox as f64 - 0.5, oy as f64 - 0.5, (ox + side) as f64 - 0.5);
            let y1 = (oy + side) as f64 - 0.5;
            for (c, e) in found[0]
                .corners
                .iter()
                .zip([(x0, y0), (x1, y0), (x1, y1), (x0, y1)])
            {
                assert!(
                    (*c - DVec2::new(e.0, e.1)).length() < 0.3,
                    "{:?}",
                    found[0].corners
                );
            }
        }

        #[test]
        fn pnp_matched_on_coplanar_points_with_an_outlier() {
            let mut cam = Camera::pinhole(960, 720, 900.0, 900.0, 479.5, 359.5);
            let tilt = DMat3::from_rotation_y(0.4) * DMat3::from_rotation_x(-0.2);
            cam.pose = WorldToCamera {
                r: tilt * DMat3::from_cols(DVec3::X, -DVec3::Y, -DVec3::Z),
                t: DVec3::new(0.02, 0.03, 1.0),
            };
            let world: Vec<DVec3> = (0..16)
                .map(|k| DVec3::new((k % 4) as f64 * 0.2 - 0.3, (k / 4) as f64 * 0.15 - 0.2, 0.0))
                .collect();
            let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
            let mut px: Vec<DVec2> = world
                .iter()
                .map(|p| {
                    cam.project(*p).unwrap() + 0.1 * DVec2::new(normal(&mut rng), normal(&mut rng))
                })
                .collect();
            px[5] += DVec2::new(12.0, -7.0);
            let res = solve_pnp_matched(&cam.intrinsics, &world, &px, 2.0).unwrap();
            let ang = rotation_angle_between(&res.pose.r, &cam.pose.r).to_degrees();
            let dt = (res.pose.t - cam.pose.t).length();
            assert!(
                ang < 0.05 && dt < 1e-3,
                "rotation {ang} deg, translation {dt} m"
            );
            assert_eq!(res.inliers.len(), 15);
            assert!(
                !res.inliers.contains(&5) && res.rms_px < 0.3,
                "{:?} {}",
                res.inliers,
                res.rms_px
            );
            assert!(solve_pnp_matched(&cam.intrinsics, &world[..3], &px[..3], 2.0).is_err());
        }

        #[test]
        fn homography_recovers_known_matrix() {
            let hm = DMat3::from_cols_array_2d(&[
                [1.1, 0.05, 0.0002],
                [-0.03, 0.95, 0.0001],
                [12.0, -7.0, 1.0],
            ]);
            let src: Vec<DVec2> = (0..20)
                .map(|k| DVec2::new((k % 5) as f64 * 50.0, (k / 5) as f64 * 40.0))
                .collect();
            let dst: Vec<DVec2> = src
                .iter()
                .map(|p| {
                    let q = hm * DVec3::new(p.x, p.y, 1.0);
                    DVec2::new(q.x / q.z, q.y / q.z)
                })
                .collect();
            let h = find_homography(&src, &dst, 1.0).unwrap();
            let h = h / h.z_axis.z;
            assert!(h.abs_diff_eq(hm, 1e-5), "{h}"); // f32 point transfer
        }
    }
}
