//! `igi camera ...`: undistort images, pose from correspondences (PnP), calibration.
use crate::report::Ctx;
use anyhow::{bail, Context};
use glam::{DVec2, DVec3};
use igi_imaging::{camera::undistort_image, cv, read_image, write_exr, Camera};
use std::path::{Path, PathBuf};

#[derive(clap::Subcommand, Debug)]
pub enum CameraCmd {
    /// Remove lens distortion: output has the same size and K, no distortion.
    Undistort(UndistortArgs),
    /// Camera pose from 2D-3D correspondences (RANSAC PnP + LM); needs --features opencv.
    Pose(PoseArgs),
    /// Intrinsics from checkerboard photographs (Zhang); needs --features opencv.
    Calibrate(CalibrateArgs),
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
    }
}

fn undistort(a: UndistortArgs) -> anyhow::Result<()> {
    if a.output
        .extension()
        .map(|e| e.to_string_lossy().to_lowercase())
        .as_deref()
        != Some("exr")
    {
        bail!("{}: output must be .exr", a.output.display());
    }
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
    let (mut px, mut world) = (Vec::new(), Vec::new());
    for (n, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        let nums: Result<Vec<f64>, _> = f.iter().map(|s| s.parse::<f64>()).collect();
        match nums {
            Ok(v) if v.len() == 5 && v.iter().all(|x| x.is_finite()) => {
                px.push(DVec2::new(v[0], v[1]));
                world.push(DVec3::new(v[2], v[3], v[4]));
            }
            Err(_) if n == 0 && px.is_empty() => continue, // header
            _ => bail!(
                "{}: line {}: expected 5 finite numbers u,v,x,y,z, found {:?}",
                path.display(),
                n + 1,
                line
            ),
        }
    }
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
