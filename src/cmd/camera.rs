//! `igi camera ...`: undistort images, pose from correspondences (PnP), calibration.
use crate::report::{print_json, Ctx};
use igi_camera::job::{
    calibrate_files, pose_file, radiometry_files, undistort_file, CalibrateRequest, PoseRequest,
    RadiometryOutcome, RadiometryRequest, UndistortRequest,
};
use igi_capture::job::{refine_file, RefineRequest};
use std::path::PathBuf;

#[derive(clap::Subcommand, Debug)]
pub enum CameraCmd {
    /// Remove lens distortion: output has the same size and K, no distortion.
    Undistort(UndistortArgs),
    /// Camera pose from 2D-3D correspondences (RANSAC PnP + LM); needs --features opencv.
    Pose(PoseArgs),
    /// Intrinsics from checkerboard photographs (Zhang); needs --features opencv.
    Calibrate(CalibrateArgs),
    /// Radiometric calibration: lens falloff from flat fields, colour matrix from a
    /// photographed ColorChecker Classic; writes the camera radiometry file (JSON) that a
    /// survey's `[radiometry] camera = ...` applies to every photo.
    Radiometry(RadiometryArgs),
    /// Refine a camera pose (e.g. from PnP) by matching the model's edges and silhouette to
    /// the photograph's; the intrinsics are kept.
    Refine(RefineArgs),
}

#[derive(clap::Args, Debug)]
pub struct RefineArgs {
    /// The photograph (linear HDR, the camera's size).
    photo: PathBuf,
    /// The camera to refine (its pose is the starting point).
    #[arg(long)]
    camera: PathBuf,
    /// The model (PLY or OBJ); repeat for several meshes.
    #[arg(long, required = true)]
    mesh: Vec<PathBuf>,
    /// Initial search range along each model edge's normal, pixels (about twice the expected
    /// pose error in pixels).
    #[arg(allow_negative_numbers = true, value_parser = crate::cmd::values::positive, long, default_value_t = 10.0)]
    search: f64,
    /// Also match creases (faces meeting at an angle); by default only silhouettes and
    /// occlusion boundaries are matched, since shading at creases (ambient occlusion, contact
    /// shadows) moves the photographed edge.
    #[arg(long)]
    creases: bool,
    #[arg(long)]
    json: bool,
    /// Output camera JSON (input intrinsics, refined pose).
    #[arg(short, long)]
    output: PathBuf,
}

#[derive(clap::Args, Debug)]
pub struct RadiometryArgs {
    /// Flat-field photographs (linear HDR; same size): an evenly lit, featureless target.
    #[arg(long, num_args = 1..)]
    flat: Vec<PathBuf>,
    /// Photograph of a ColorChecker Classic (24 patches, linear HDR, same size as the flats).
    #[arg(long)]
    checker: Option<PathBuf>,
    /// The checker's patch-grid outer corners in pixels, x,y four times: top-left (dark skin),
    /// top-right (bluish green), bottom-right (black), bottom-left (white). Without it the
    /// chart is found automatically (OpenCV's mcc detector; builds with --features opencv).
    #[arg(long, allow_hyphen_values = true)]
    corners: Option<String>,
    /// Radiance of a perfect white diffuser under the checker's light, for an absolute
    /// calibration; without it the matrix keeps the grey patches' luminance.
    #[arg(allow_negative_numbers = true, value_parser = crate::cmd::values::positive, long)]
    white: Option<f64>,
    #[arg(long)]
    json: bool,
    /// Output camera radiometry file (.json).
    #[arg(short, long)]
    output: PathBuf,
}

#[derive(clap::Args, Debug)]
pub struct UndistortArgs {
    image: PathBuf,
    #[arg(long)]
    camera: PathBuf,
    /// Also write the output camera (same K and pose, no distortion).
    #[arg(long)]
    camera_out: Option<PathBuf>,
    /// Output image (.exr).
    #[arg(short, long)]
    output: PathBuf,
}

#[derive(clap::Args, Debug)]
pub struct PoseArgs {
    #[arg(long)]
    camera: PathBuf,
    /// CSV with u,v,x,y,z per row (pixel, world point); a header line is allowed.
    #[arg(long)]
    points: PathBuf,
    /// RANSAC inlier threshold, pixels.
    #[arg(allow_negative_numbers = true, value_parser = crate::cmd::values::positive, long, default_value_t = 4.0)]
    threshold: f64,
    #[arg(long)]
    json: bool,
    /// Output camera JSON (input intrinsics, estimated pose).
    #[arg(short, long)]
    output: PathBuf,
}

#[derive(clap::Args, Debug)]
pub struct CalibrateArgs {
    #[arg(required = true)]
    images: Vec<PathBuf>,
    /// Inner corners, COLSxROWS (e.g. 9x6).
    #[arg(long)]
    board: String,
    /// Square size, metres.
    #[arg(allow_negative_numbers = true, value_parser = crate::cmd::values::positive, long)]
    square: f64,
    #[arg(long)]
    json: bool,
    /// Output camera JSON (pose of the first view used).
    #[arg(short, long)]
    output: PathBuf,
}

pub fn run(c: CameraCmd, ctx: &Ctx) -> anyhow::Result<()> {
    match c {
        CameraCmd::Undistort(a) => undistort(a),
        CameraCmd::Pose(a) => pose(a),
        CameraCmd::Calibrate(a) => calibrate(a, ctx),
        CameraCmd::Radiometry(a) => radiometry(a, ctx),
        CameraCmd::Refine(a) => refine(a),
    }
}

fn undistort(a: UndistortArgs) -> anyhow::Result<()> {
    let req = UndistortRequest {
        image: a.image,
        camera: a.camera,
        camera_out: a.camera_out,
        output: a.output,
    };
    Ok(undistort_file(&req)?)
}

fn pose(a: PoseArgs) -> anyhow::Result<()> {
    let req = PoseRequest {
        camera: a.camera,
        points: a.points,
        threshold: a.threshold,
        output: a.output.clone(),
    };
    let r = pose_file(&req)?;
    if a.json {
        print_json(&serde_json::json!({
            "output": a.output,
            "correspondences": r.correspondences,
            "inliers": r.inliers,
            "rms_px": r.rms_px,
            "center_world": r.center_world,
        }))?;
    }
    Ok(())
}

fn calibrate(a: CalibrateArgs, ctx: &Ctx) -> anyhow::Result<()> {
    let req = CalibrateRequest {
        images: a.images.clone(),
        board: a.board,
        square: a.square,
        output: a.output.clone(),
    };
    let pb = ctx.progress(a.images.len() as u64, "reading");
    let r = calibrate_files(&req, &|| pb.inc(1))?;
    pb.finish_and_clear();
    if a.json {
        print_json(&serde_json::json!({
            "output": a.output,
            "views_used": r.views_used.iter().map(|p| p.display().to_string()).collect::<Vec<_>>(),
            "rms_px": r.rms_px,
            "fx": r.fx, "fy": r.fy, "cx": r.cx, "cy": r.cy,
            "dist": r.dist,
        }))?;
    }
    Ok(())
}

fn radiometry(a: RadiometryArgs, ctx: &Ctx) -> anyhow::Result<()> {
    let req = RadiometryRequest {
        flats: a.flat.clone(),
        checker: a.checker.clone(),
        corners: a.corners.clone(),
        white: a.white,
        output: a.output.clone(),
    };
    let pb = ctx.progress(a.flat.len() as u64 + a.checker.is_some() as u64, "reading");
    let r = radiometry_files(&req, &|| pb.inc(1))?;
    pb.finish_and_clear();
    report_radiometry(&a, &r)
}

/// The fit as JSON (`--json`), or the detected corners as a `--corners` argument.
fn report_radiometry(a: &RadiometryArgs, r: &RadiometryOutcome) -> anyhow::Result<()> {
    let cal = &r.radiometry;
    if a.json {
        print_json(&serde_json::json!({
            "output": a.output,
            "width": cal.width,
            "height": cal.height,
            "falloff": cal.falloff,
            "color_matrix": cal.color_matrix,
            "fit": cal.fit,
            "checker_corners": r.corners,
            "checker_corners_detected": a.checker.is_some() && a.corners.is_none(),
        }))?;
    } else if let (Some(c), None) = (r.corners, &a.corners) {
        println!(
            "checker detected; --corners {}",
            c.iter()
                .flatten()
                .map(|v| format!("{v:.1}"))
                .collect::<Vec<_>>()
                .join(",")
        );
    }
    Ok(())
}

fn refine(a: RefineArgs) -> anyhow::Result<()> {
    let req = RefineRequest {
        photo: a.photo,
        camera: a.camera,
        meshes: a.mesh,
        search_px: a.search,
        creases: a.creases,
        output: a.output.clone(),
    };
    let r = refine_file(&req)?;
    if a.json {
        print_json(&serde_json::json!({
            "output": a.output,
            "report": r.report,
            "center_world": r.center_world,
        }))?;
    }
    Ok(())
}
