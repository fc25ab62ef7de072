//! `igi import`: photogrammetry models as survey folders.
use crate::report::{print_json, Ctx};
use igi_import::icp::IcpOptions;
use igi_import::{import_colmap, AlignOptions, ColmapImport, ModelFormat};
use std::path::PathBuf;

#[derive(clap::Subcommand, Debug)]
pub enum ImportCmd {
    /// A COLMAP sparse model (text or binary), a Metashape cameras XML or a nerfstudio
    /// transforms.json (--format) as a survey folder: one contract camera per image
    /// (cameras/NAME.json, NAME the image's file stem), survey.toml and alignment.json.
    ///
    /// Conventions: COLMAP's poses are world to camera with Hamilton quaternions (w, x, y, z)
    /// and OpenCV's axes, kept as they are; COLMAP puts the centre of the top-left pixel at
    /// (0.5, 0.5), the contract at (0, 0), so each principal point moves by -0.5 px. Camera
    /// models SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV and FULL_OPENCV (with
    /// k4 = k5 = k6 = 0) convert exactly to OpenCV's (k1, k2, p1, p2, k3); others are refused.
    /// Each of cameras, images, points3D is read from its .bin when present, else its .txt.
    ///
    /// --format metashape (File > Export Cameras, Agisoft XML): principal point w/2 + cx - 0.5
    /// (Metashape's cx, cy are offsets from the image centre, its top-left pixel centre at
    /// (0.5, 0.5)), fx = f + b1, fy = f, OpenCV's p1, p2 = Metashape's P2, P1; nonzero b2, k4,
    /// p3, p4 and sensor types other than frame are refused; each camera's transform (camera
    /// to chunk, OpenCV axes) is taken through its component's and the chunk's transforms;
    /// cameras without a transform (not aligned) are left out and listed. A label without an
    /// extension finds the one photo in --images with that stem.
    ///
    /// --format nerfstudio (transforms.json or its folder): camera to world in OpenGL axes,
    /// y and z flipped to OpenCV's; principal point cx - 0.5, cy - 0.5 (nerfstudio's pixel
    /// centres are at +0.5, as COLMAP's); intrinsics global or per frame; camera_model OPENCV
    /// or PINHOLE (OPENCV_FISHEYE and others refused, as is nonzero k4); applied_transform, if
    /// present, is undone so the cameras are in the original tool's frame. A file_path is
    /// looked up in --images as written, else by its file name.
    ///
    /// With --control, each control point is triangulated from its observations (u, v in the
    /// contract's pixels, at least two images each) and the similarity x_scan = s R x_model + t
    /// fitted (Umeyama inside a deterministic RANSAC, refitted on the inliers) moves every
    /// camera into the scan's frame; without it the cameras stay in the model's own frame.
    ///
    /// Each photo's EXIF gives its survey `time` (DateTimeOriginal with OffsetTimeOriginal,
    /// else the GPS date and time, UTC; a time without a known offset is left out, not
    /// guessed) and `exposure` (ExposureTime x ISO/100 / FNumber^2; written only when every
    /// photo has one). What was left out is listed per photo, and so is a clock 10 minutes or
    /// more off the photo's GPS stamp (the time stays the clock's: check its UTC offset).
    ///
    /// With --icp (COLMAP models, after --control), the alignment is refined by trimmed ICP
    /// of the model's sparse 3D points against --mesh: each point paired with its closest
    /// point on the mesh (a kiddo k-d tree of surface samples, then the exact closest point on
    /// their triangles), the closest --icp-keep fraction kept, the similarity (scale
    /// included) moved by point-to-plane steps (the small rotation, scale and translation
    /// minimising the kept pairs' distances along the mesh's normals) until it settles.
    /// Refused when the refinement would turn the points by more than 5 degrees, change the
    /// scale by more than 10% or move them by more than 0.2 of their spread, or when it does
    /// not lower the kept points' RMS distance to the mesh. alignment.json keeps both
    /// similarities.
    ///
    /// Nothing is written unless every check passes.
    Colmap(ColmapArgs),
}

#[derive(clap::Args, Debug)]
pub struct ColmapArgs {
    /// The sparse model folder (cameras, images, points3D as .bin or .txt); with --format
    /// metashape the cameras XML file, with --format nerfstudio transforms.json or its folder.
    pub sparse: PathBuf,
    /// Whose cameras SPARSE is.
    #[arg(long, value_enum, default_value_t = Format::Colmap)]
    pub format: Format,
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
    /// The site's mesh (the scan, PLY or OBJ) the survey names; repeat it for a scan in several
    /// meshes (the survey's `meshes`; --icp matches the points against all of them).
    #[arg(long, required = true)]
    pub mesh: Vec<PathBuf>,
    /// Metres: the control points' inlier threshold and largest accepted RMS residual
    /// (default: 5% of the control points' spread).
    #[arg(long)]
    pub max_residual: Option<f64>,
    /// Refine the control-point alignment by trimmed ICP of the sparse points against --mesh
    /// (COLMAP models; needs --control).
    #[arg(long)]
    pub icp: bool,
    /// With --icp: the fraction of sparse points kept each iteration (the closest ones;
    /// outliers and parts the scan misses are left out).
    #[arg(long, default_value_t = 0.8, requires = "icp")]
    pub icp_keep: f64,
    /// The survey folder to write (must not exist, or be empty).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
}

/// The photogrammetry tool that wrote SPARSE.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum Format {
    /// A COLMAP sparse model folder.
    Colmap,
    /// Metashape's cameras XML (Agisoft XML).
    Metashape,
    /// nerfstudio's transforms.json.
    Nerfstudio,
}

pub fn run(c: ImportCmd, _ctx: &Ctx) -> anyhow::Result<()> {
    match c {
        ImportCmd::Colmap(a) => run_colmap(a),
    }
}

fn run_colmap(a: ColmapArgs) -> anyhow::Result<()> {
    let format = match a.format {
        Format::Colmap => ModelFormat::Colmap,
        Format::Metashape => ModelFormat::Metashape,
        Format::Nerfstudio => ModelFormat::Nerfstudio,
    };
    let job = ColmapImport {
        format,
        sparse: a.sparse,
        images: a.images,
        control: a.control,
        lighting: a.lighting,
        meshes: a.mesh,
        output: a.output,
        align: AlignOptions {
            max_residual: a.max_residual,
        },
        icp: a.icp.then(|| IcpOptions {
            keep: a.icp_keep,
            ..IcpOptions::default()
        }),
    };
    let r = import_colmap(&job)?;
    if a.json {
        return print_json(&r);
    }
    let read: Vec<String> = r.read.iter().map(|p| p.display().to_string()).collect();
    println!("read                  {}", read.join(", "));
    println!(
        "model                 {}: {} cameras, {} images, {} 3D points",
        r.format, r.cameras, r.images, r.points3d
    );
    if !r.unposed.is_empty() {
        println!(
            "left out              {} images without a pose: {}",
            r.unposed.len(),
            r.unposed.join(", ")
        );
    }
    match (r.rms_m, r.max_residual_m) {
        (Some(rms), Some(bound)) => {
            println!("frame                 scan (scale {:.6})", r.scale);
            println!("control RMS           {rms:.4} m (bound {bound:.4} m)");
            println!("control outliers      {:?}", r.outliers);
            if let Some(i) = &r.icp {
                println!(
                    "ICP                   {} of {} points kept, RMS to the mesh {:.4} -> {:.4} m in {} iterations",
                    i.kept, i.points, i.rms_before_m, i.rms_after_m, i.iterations
                );
                println!(
                    "ICP correction        {:.4} deg, scale x{:.6}, {:.4} m",
                    i.turn_deg,
                    1.0 + i.scale_change,
                    i.shift_m
                );
            }
        }
        _ => println!(
            "frame                 the model's own (no --control: not aligned to the scan)"
        ),
    }
    println!(
        "EXIF                  {} of {} photos with a time, {} with an exposure",
        r.times, r.images, r.exposures
    );
    for (id, note) in &r.exif_notes {
        println!("  {id:<20} {note}");
    }
    if !r.lighting {
        println!("note                  photos have no lighting: add lighting (or photo times and the site's location) before `igi solve`");
    }
    println!("survey                {}", r.survey.display());
    Ok(())
}
