//! `igi import`: photogrammetry models as survey folders.
use crate::report::{print_json, Ctx};
use igi_import::{import_colmap, AlignOptions, ColmapImport};
use std::path::PathBuf;

#[derive(clap::Subcommand, Debug)]
pub enum ImportCmd {
    /// A COLMAP sparse model (text or binary) as a survey folder: one contract camera per image
    /// (cameras/NAME.json, NAME the image's file stem), survey.toml and alignment.json.
    ///
    /// Conventions: COLMAP's poses are world to camera with Hamilton quaternions (w, x, y, z)
    /// and OpenCV's axes, kept as they are; COLMAP puts the centre of the top-left pixel at
    /// (0.5, 0.5), the contract at (0, 0), so each principal point moves by -0.5 px. Camera
    /// models SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV and FULL_OPENCV (with
    /// k4 = k5 = k6 = 0) convert exactly to OpenCV's (k1, k2, p1, p2, k3); others are refused.
    /// Each of cameras, images, points3D is read from its .bin when present, else its .txt.
    ///
    /// With --control, each control point is triangulated from its observations (u, v in the
    /// contract's pixels, at least two images each) and the similarity x_scan = s R x_model + t
    /// fitted (Umeyama inside a deterministic RANSAC, refitted on the inliers) moves every
    /// camera into the scan's frame; without it the cameras stay in the model's own frame.
    /// Nothing is written unless every check passes.
    Colmap(ColmapArgs),
}

#[derive(clap::Args, Debug)]
pub struct ColmapArgs {
    /// The sparse model folder (cameras, images, points3D as .bin or .txt).
    pub sparse: PathBuf,
    /// The folder of the photographs the model names (each must exist).
    #[arg(long)]
    pub images: PathBuf,
    /// Ground control points (CSV `name,x,y,z,image,u,v`, FORMATS.md) aligning the model to
    /// the scan.
    #[arg(long)]
    pub control: Option<PathBuf>,
    /// A lighting file given to every photo (without it, the survey needs lighting, or photo
    /// times and the site's location, before `igi solve`).
    #[arg(long)]
    pub lighting: Option<PathBuf>,
    /// The site's mesh (the scan, PLY or OBJ) the survey names.
    #[arg(long)]
    pub mesh: PathBuf,
    /// Metres: the control points' inlier threshold and largest accepted RMS residual
    /// (default: 5% of the control points' spread).
    #[arg(long)]
    pub max_residual: Option<f64>,
    /// The survey folder to write (must not exist, or be empty).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
}

pub fn run(c: ImportCmd, _ctx: &Ctx) -> anyhow::Result<()> {
    match c {
        ImportCmd::Colmap(a) => run_colmap(a),
    }
}

fn run_colmap(a: ColmapArgs) -> anyhow::Result<()> {
    let job = ColmapImport {
        sparse: a.sparse,
        images: a.images,
        control: a.control,
        lighting: a.lighting,
        mesh: a.mesh,
        output: a.output,
        align: AlignOptions {
            max_residual: a.max_residual,
        },
    };
    let r = import_colmap(&job)?;
    if a.json {
        return print_json(&r);
    }
    let read: Vec<String> = r.read.iter().map(|p| p.display().to_string()).collect();
    println!("read                  {}", read.join(", "));
    println!(
        "model                 {} cameras, {} images, {} 3D points",
        r.cameras, r.images, r.points3d
    );
    match (r.rms_m, r.max_residual_m) {
        (Some(rms), Some(bound)) => {
            println!("frame                 scan (scale {:.6})", r.scale);
            println!("control RMS           {rms:.4} m (bound {bound:.4} m)");
            println!("control outliers      {:?}", r.outliers);
        }
        _ => println!(
            "frame                 the COLMAP model's own (no --control: not aligned to the scan)"
        ),
    }
    if !r.lighting {
        println!("note                  photos have no lighting: add lighting (or photo times and the site's location) before `igi solve`");
    }
    println!("survey                {}", r.survey.display());
    Ok(())
}
