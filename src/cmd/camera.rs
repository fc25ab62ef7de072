//! `igi camera ...`: undistort images, pose from correspondences (PnP), calibration.
use crate::report::Ctx;
use anyhow::{bail, Context};
use glam::{DVec2, DVec3};
use igi_camera::{camera::undistort_image, cv, Camera};
use igi_imaging::{read_image, write_exr};
use std::path::{Path, PathBuf};

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
    #[arg(long, default_value_t = 10.0)]
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
    #[arg(long)]
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
    #[arg(long, default_value_t = 4.0)]
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
    #[arg(long)]
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
    super::require_extension(&a.output, "exr")?;
    let cam = Camera::load(&a.camera)?;
    let img = read_image(&a.image)?;
    let (out, ocam) =
        undistort_image(&img, &cam).with_context(|| format!("{}", a.image.display()))?;
    write_exr(&a.output, &out)?;
    if let Some(p) = &a.camera_out {
        ocam.save(p)?;
    }
    Ok(())
}

fn read_correspondences(path: &Path) -> anyhow::Result<(Vec<DVec2>, Vec<DVec3>)> {
    let text = std::fs::read_to_string(path).with_context(|| format!("{}", path.display()))?;
    let rows = igi_imaging::csv::number_rows::<f64, 5>(&text, path, "u,v,x,y,z")?;
    let px = rows.iter().map(|r| DVec2::new(r[0], r[1])).collect();
    let world = rows.iter().map(|r| DVec3::new(r[2], r[3], r[4])).collect();
    Ok((px, world))
}

fn pose(a: PoseArgs) -> anyhow::Result<()> {
    let cam = Camera::load(&a.camera)?;
    let (px, world) = read_correspondences(&a.points)?;
    let res = cv::solve_pnp(&cam.intrinsics, &world, &px, a.threshold)
        .with_context(|| format!("{}", a.points.display()))?;
    let out = Camera {
        pose: res.pose,
        ..cam
    };
    out.save(&a.output)?;
    if a.json {
        crate::report::print_json(&serde_json::json!({
            "output": a.output,
            "correspondences": px.len(),
            "inliers": res.inliers.len(),
            "rms_px": res.rms_px,
            "center_world": out.center_world().to_array(),
        }))?;
    }
    Ok(())
}

fn calibrate(a: CalibrateArgs, ctx: &Ctx) -> anyhow::Result<()> {
    let (cols, rows) = a
        .board
        .split_once(['x', 'X'])
        .and_then(|(c, r)| {
            Some((
                c.trim().parse::<usize>().ok()?,
                r.trim().parse::<usize>().ok()?,
            ))
        })
        .filter(|&(c, r)| c >= 2 && r >= 2)
        .with_context(|| {
            format!(
                "--board {:?}: expected COLSxROWS inner corners, e.g. 9x6",
                a.board
            )
        })?;
    if !(a.square > 0.0 && a.square.is_finite()) {
        bail!("--square {}: must be a positive length in metres", a.square);
    }
    let pb = ctx.progress(a.images.len() as u64, "reading");
    let mut imgs = Vec::new();
    for p in &a.images {
        imgs.push(read_image(p)?);
        pb.inc(1);
    }
    pb.finish_and_clear();
    let (cal, used) = cv::calibrate_checkerboard(&imgs, cols, rows, a.square)?;
    cal.camera.save(&a.output)?;
    if a.json {
        let i = cal.camera.intrinsics;
        crate::report::print_json(&serde_json::json!({
            "output": a.output,
            "views_used": used.iter().map(|&k| a.images[k].display().to_string()).collect::<Vec<_>>(),
            "rms_px": cal.rms_px,
            "fx": i.fx, "fy": i.fy, "cx": i.cx, "cy": i.cy,
            "dist": i.dist.to_array(),
        }))?;
    }
    Ok(())
}

fn parse_corners(text: &str) -> anyhow::Result<[DVec2; 4]> {
    let v: Vec<f64> = text
        .split(',')
        .map(|s| s.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .ok()
        .filter(|v: &Vec<f64>| v.len() == 8 && v.iter().all(|x| x.is_finite()))
        .with_context(|| {
            format!("--corners {text:?}: expected 8 finite numbers x,y,x,y,x,y,x,y")
        })?;
    Ok([0, 1, 2, 3].map(|k| DVec2::new(v[2 * k], v[2 * k + 1])))
}

fn radiometry(a: RadiometryArgs, ctx: &Ctx) -> anyhow::Result<()> {
    use igi_camera::radiometry::{fit_radiometry, RadiometryInputs};
    super::require_extension(&a.output, "json")?;
    if a.flat.is_empty() && a.checker.is_none() {
        bail!("give flat fields (--flat), a colour checker (--checker, optionally --corners), or both");
    }
    let given = match (&a.checker, &a.corners) {
        (Some(_), Some(c)) => Some(parse_corners(c)?),
        (Some(c), None) if !cfg!(feature = "opencv") => bail!(
            "{}: give the checker's four corners with --corners (automatic detection needs a build with --features opencv)",
            c.display()
        ),
        (None, Some(_)) => bail!("--corners needs --checker"),
        _ => None,
    };
    let (flats, checker) = read_radiometry_images(&a, ctx)?;
    let corners = match (&a.checker, &checker, given) {
        (Some(path), Some(img), None) => Some(detect_checker(path, img)?),
        (_, _, given) => given,
    };
    let inputs = RadiometryInputs {
        flats: &flats,
        checker: checker.as_ref().zip(corners),
        white: a.white,
    };
    let cal = fit_radiometry(&inputs).context("fitting the camera radiometry")?;
    cal.save(&a.output)?;
    report_radiometry(&a, &cal, corners)
}

/// The flat fields and the checker photo, all of one size (the first one's).
fn read_radiometry_images(
    a: &RadiometryArgs,
    ctx: &Ctx,
) -> anyhow::Result<(Vec<igi_imaging::HdrImage>, Option<igi_imaging::HdrImage>)> {
    let pb = ctx.progress(a.flat.len() as u64 + a.checker.is_some() as u64, "reading");
    let mut flats = Vec::new();
    for p in &a.flat {
        flats.push(read_image(p)?);
        pb.inc(1);
    }
    let checker = match &a.checker {
        Some(p) => Some(read_image(p)?),
        None => None,
    };
    pb.finish_and_clear();
    let size = |img: &igi_imaging::HdrImage| (img.width, img.height);
    let first = flats.first().or(checker.as_ref()).map(size);
    for (p, img) in a
        .flat
        .iter()
        .zip(&flats)
        .chain(a.checker.iter().zip(&checker))
    {
        if Some(size(img)) != first {
            let (w, h) = first.unwrap_or_default();
            bail!("{}: image is {}x{} but the first is {w}x{h}; all must come from the same camera setting", p.display(), img.width, img.height);
        }
    }
    Ok((flats, checker))
}

/// The fit as JSON (`--json`), or the detected corners as a `--corners` argument.
fn report_radiometry(
    a: &RadiometryArgs,
    cal: &igi_camera::radiometry::CameraRadiometry,
    corners: Option<[DVec2; 4]>,
) -> anyhow::Result<()> {
    let corners_px = corners.map(|c| c.map(|p| p.to_array()));
    if a.json {
        crate::report::print_json(&serde_json::json!({
            "output": a.output,
            "width": cal.width,
            "height": cal.height,
            "falloff": cal.falloff,
            "color_matrix": cal.color_matrix,
            "fit": cal.fit,
            "checker_corners": corners_px,
            "checker_corners_detected": a.checker.is_some() && a.corners.is_none(),
        }))?;
    } else if let (Some(c), None) = (corners_px, &a.corners) {
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

/// The checker's patch-grid corners found by OpenCV's mcc detector, the file named on failure.
fn detect_checker(path: &Path, img: &igi_imaging::HdrImage) -> anyhow::Result<[DVec2; 4]> {
    cv::detect_color_checker(img).with_context(|| {
        format!(
            "{}: automatic colour-checker detection (OpenCV mcc) failed; give the patch grid's corners with --corners",
            path.display()
        )
    })
}

fn refine(a: RefineArgs) -> anyhow::Result<()> {
    use igi_capture::refine::{refine_pose, RefineOptions};
    use igi_raycast::rt_scene_of;
    super::require_extension(&a.output, "json")?;
    if !(a.search > 0.0 && a.search.is_finite()) {
        bail!("--search {}: must be a positive number of pixels", a.search);
    }
    let cam = Camera::load(&a.camera)?;
    let photo = read_image(&a.photo)?;
    if photo.width != cam.width as usize || photo.height != cam.height as usize {
        bail!(
            "{}: image is {}x{} but its camera {} says {}x{}",
            a.photo.display(),
            photo.width,
            photo.height,
            a.camera.display(),
            cam.width,
            cam.height
        );
    }
    let meshes = a
        .mesh
        .iter()
        .map(|m| igi_geometry::read_mesh(m))
        .collect::<Result<Vec<_>, _>>()?;
    let rt = rt_scene_of(&meshes)?;
    let opts = RefineOptions {
        search_px: a.search,
        creases: a.creases,
        ..RefineOptions::default()
    };
    let (out, report) = refine_pose(&photo, &cam, &rt, &opts)
        .with_context(|| format!("refining the pose of {}", a.photo.display()))?;
    out.save(&a.output)?;
    if a.json {
        crate::report::print_json(&serde_json::json!({
            "output": a.output,
            "report": report,
            "center_world": out.center_world().to_array(),
        }))?;
    }
    Ok(())
}
