//! `igi camera`'s jobs, each one call from a request of paths and options: undistort an image,
//! a pose from correspondences (PnP), intrinsics from checkerboards, the camera radiometry
//! from flat fields and a colour checker. (Pose refinement against a model is
//! `igi_capture::refine`'s.)

use crate::radiometry::{fit_radiometry, CameraRadiometry, RadiometryInputs};
use crate::{camera::undistort_image, cv, Camera, CameraError};
use glam::{DVec2, DVec3};
use igi_imaging::{read_image, write_exr, HdrImage};
use std::path::{Path, PathBuf};

/// `igi camera undistort`: an image, its camera, the undistorted image (.exr) and optionally
/// the camera it now has.
#[derive(Clone, Debug)]
pub struct UndistortRequest {
    pub image: PathBuf,
    pub camera: PathBuf,
    pub camera_out: Option<PathBuf>,
    pub output: PathBuf,
}

/// Removes the lens distortion of `req.image`: same size and K, no distortion.
pub fn undistort_file(req: &UndistortRequest) -> Result<(), CameraError> {
    igi_files::check_output_extension(&req.output, &["exr"])?;
    // both outputs checked before the work, so neither is written when the other cannot be
    igi_files::check_output_file(&req.output)?;
    if let Some(p) = &req.camera_out {
        igi_files::check_output_file(p)?;
        igi_files::check_distinct(
            &[
                ("--output", req.output.as_path()),
                ("--camera-out", p.as_path()),
            ],
            &[
                ("--camera", req.camera.as_path()),
                ("the image", req.image.as_path()),
            ],
        )?;
    }
    let cam = Camera::load(&req.camera)?;
    let img = read_image(&req.image)?;
    let (out, ocam) = undistort_image(&img, &cam).map_err(|e| CameraError::at(&req.image, e))?;
    write_exr(&req.output, &out)?;
    if let Some(p) = &req.camera_out {
        ocam.save(p)?;
    }
    Ok(())
}

/// `igi camera pose`: a camera, 2D-3D correspondences (CSV `u,v,x,y,z`), the RANSAC inlier
/// threshold in pixels, and the camera file to write (input intrinsics, estimated pose).
#[derive(Clone, Debug)]
pub struct PoseRequest {
    pub camera: PathBuf,
    pub points: PathBuf,
    pub threshold: f64,
    pub output: PathBuf,
}

/// What [`pose_file`] estimated.
#[derive(Clone, Debug)]
pub struct PoseOutcome {
    pub correspondences: usize,
    pub inliers: usize,
    pub rms_px: f64,
    pub center_world: [f64; 3],
}

/// Solves the camera's pose from the correspondences (RANSAC PnP + LM; `--features opencv`)
/// and writes the camera with it.
pub fn pose_file(req: &PoseRequest) -> Result<PoseOutcome, CameraError> {
    let cam = Camera::load(&req.camera)?;
    let (px, world) = read_correspondences(&req.points)?;
    let res = cv::solve_pnp(&cam.intrinsics, &world, &px, req.threshold)
        .map_err(|e| CameraError::at(&req.points, e))?;
    let out = Camera {
        pose: res.pose,
        ..cam
    };
    out.save(&req.output)?;
    Ok(PoseOutcome {
        correspondences: px.len(),
        inliers: res.inliers.len(),
        rms_px: res.rms_px,
        center_world: out.center_world().to_array(),
    })
}

fn read_correspondences(path: &Path) -> Result<(Vec<DVec2>, Vec<DVec3>), CameraError> {
    let text = std::fs::read_to_string(path).map_err(|e| CameraError::io(path, e))?;
    let rows = igi_imaging::csv::number_rows::<f64, 5>(&text, path, "u,v,x,y,z")?;
    let px = rows.iter().map(|r| DVec2::new(r[0], r[1])).collect();
    let world = rows.iter().map(|r| DVec3::new(r[2], r[3], r[4])).collect();
    Ok((px, world))
}

/// `igi camera calibrate`: checkerboard photographs, the board's inner corners as written
/// (`COLSxROWS`, e.g. `9x6`), the square size in metres, the camera file to write.
#[derive(Clone, Debug)]
pub struct CalibrateRequest {
    pub images: Vec<PathBuf>,
    pub board: String,
    pub square: f64,
    pub output: PathBuf,
}

/// What [`calibrate_files`] found.
#[derive(Clone, Debug)]
pub struct CalibrateOutcome {
    /// The photographs the board was found in.
    pub views_used: Vec<PathBuf>,
    pub rms_px: f64,
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    pub dist: [f64; 5],
}

/// Zhang calibration from the checkerboard photographs (`--features opencv`); writes the camera
/// (the pose of the first view used). `read` is called after each photograph is read.
pub fn calibrate_files(
    req: &CalibrateRequest,
    read: &dyn Fn(),
) -> Result<CalibrateOutcome, CameraError> {
    let (cols, rows) = parse_board(&req.board)?;
    // per view: the board's object points (3 f64) and the found corners (2 f32), and the
    // template; refused before any is allocated
    igi_files::check_alloc_default(
        &format!("the board's corners (--board {cols}x{rows})"),
        cols as u128 * rows as u128 * 32 * (req.images.len() as u128 + 1),
    )?;
    if !(req.square > 0.0 && req.square.is_finite()) {
        return Err(CameraError::Arguments(format!(
            "--square {}: must be a positive length in metres",
            req.square
        )));
    }
    let mut imgs = Vec::new();
    for p in &req.images {
        imgs.push(read_image(p)?);
        read();
    }
    let (cal, used) = cv::calibrate_checkerboard(&imgs, cols, rows, req.square)?;
    cal.camera.save(&req.output)?;
    let i = cal.camera.intrinsics;
    Ok(CalibrateOutcome {
        views_used: used.iter().map(|&k| req.images[k].clone()).collect(),
        rms_px: cal.rms_px,
        fx: i.fx,
        fy: i.fy,
        cx: i.cx,
        cy: i.cy,
        dist: i.dist.to_array(),
    })
}

/// `COLSxROWS` inner corners, each at least 2.
fn parse_board(text: &str) -> Result<(usize, usize), CameraError> {
    text.split_once(['x', 'X'])
        .and_then(|(c, r)| Some((c.trim().parse().ok()?, r.trim().parse().ok()?)))
        .filter(|&(c, r): &(usize, usize)| c >= 2 && r >= 2)
        .ok_or_else(|| {
            CameraError::Arguments(format!(
                "--board {text:?}: expected COLSxROWS inner corners, e.g. 9x6"
            ))
        })
}

/// `igi camera radiometry`: flat fields, a colour-checker photograph with its patch grid's
/// corners as written (`x,y` four times; found by OpenCV's mcc when `None`), the white's
/// radiance, and the radiometry file to write (.json).
#[derive(Clone, Debug)]
pub struct RadiometryRequest {
    pub flats: Vec<PathBuf>,
    pub checker: Option<PathBuf>,
    pub corners: Option<String>,
    pub white: Option<f64>,
    pub output: PathBuf,
}

/// What [`radiometry_files`] fitted, and the checker's corners it used.
#[derive(Clone, Debug)]
pub struct RadiometryOutcome {
    pub radiometry: CameraRadiometry,
    pub corners: Option<[[f64; 2]; 4]>,
}

/// Fits the lens falloff and the colour matrix and writes the radiometry file. `read` is
/// called after each image is read.
pub fn radiometry_files(
    req: &RadiometryRequest,
    read: &dyn Fn(),
) -> Result<RadiometryOutcome, CameraError> {
    let given = check_radiometry_request(req)?;
    let (flats, checker) = read_radiometry_images(req, read)?;
    let corners = match (&req.checker, &checker, given) {
        (Some(path), Some(img), None) => Some(detect_checker(path, img)?),
        (_, _, given) => given,
    };
    let inputs = RadiometryInputs {
        flats: &flats,
        checker: checker.as_ref().zip(corners),
        white: req.white,
    };
    let cal = fit_radiometry(&inputs).map_err(|e| CameraError::RadiometryFitting {
        source: Box::new(e),
    })?;
    cal.save(&req.output)?;
    Ok(RadiometryOutcome {
        radiometry: cal,
        corners: corners.map(|c| c.map(|p| p.to_array())),
    })
}

/// The output's name and what is to be fitted, before any work; the corners given.
fn check_radiometry_request(req: &RadiometryRequest) -> Result<Option<[DVec2; 4]>, CameraError> {
    igi_files::check_output_extension(&req.output, &["json"])?;
    if req.flats.is_empty() && req.checker.is_none() {
        return Err(CameraError::Arguments("give flat fields (--flat), a colour checker (--checker, optionally --corners), or both".into()));
    }
    match (&req.checker, &req.corners) {
        (Some(_), Some(c)) => Ok(Some(parse_corners(c)?)),
        (Some(c), None) if !cfg!(feature = "opencv") => Err(CameraError::Arguments(format!(
            "{}: give the checker's four corners with --corners (automatic detection needs a build with --features opencv)",
            c.display()
        ))),
        (None, Some(_)) => Err(CameraError::Arguments("--corners needs --checker".into())),
        _ => Ok(None),
    }
}

fn parse_corners(text: &str) -> Result<[DVec2; 4], CameraError> {
    let v: Vec<f64> = text
        .split(',')
        .map(|s| s.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .ok()
        .filter(|v: &Vec<f64>| v.len() == 8 && v.iter().all(|x| x.is_finite()))
        .ok_or_else(|| {
            CameraError::Arguments(format!(
                "--corners {text:?}: expected 8 finite numbers x,y,x,y,x,y,x,y"
            ))
        })?;
    Ok([0, 1, 2, 3].map(|k| DVec2::new(v[2 * k], v[2 * k + 1])))
}

/// The flat fields and the checker photo, all of one size (the first one's).
fn read_radiometry_images(
    req: &RadiometryRequest,
    read: &dyn Fn(),
) -> Result<(Vec<HdrImage>, Option<HdrImage>), CameraError> {
    let mut flats = Vec::new();
    for p in &req.flats {
        flats.push(read_image(p)?);
        read();
    }
    let checker = match &req.checker {
        Some(p) => Some(read_image(p)?),
        None => None,
    };
    let size = |img: &HdrImage| (img.width, img.height);
    let first = flats.first().or(checker.as_ref()).map(size);
    let named = req.flats.iter().zip(&flats);
    for (p, img) in named.chain(req.checker.iter().zip(&checker)) {
        if Some(size(img)) != first {
            return Err(CameraError::ImageSize {
                path: p.clone(),
                size: size(img),
                first: first.unwrap_or_default(),
            });
        }
    }
    Ok((flats, checker))
}

/// The checker's patch-grid corners found by OpenCV's mcc detector, the file named on failure.
fn detect_checker(path: &Path, img: &HdrImage) -> Result<[DVec2; 4], CameraError> {
    cv::detect_color_checker(img).map_err(|e| CameraError::CheckerDetection {
        path: path.to_path_buf(),
        source: Box::new(e),
    })
}
