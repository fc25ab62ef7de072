//! `igi slf build` and `igi slf render` as one call each, from a request of paths and options:
//! a surface light field built from a multi-view capture and stored ([`build_file`]); a stored
//! field rendered through a camera, on its own mesh or a deformed copy ([`render_file`]).

use crate::capture::{build_from_rig, GridOptions};
use crate::store::{self, StoreReport};
use crate::{BuildOptions, LightFieldError, Method, RenderSlfOptions};
use igi_camera::{Camera, Rig};
use igi_geometry::TriMesh;
use std::path::{Path, PathBuf};

/// `igi slf build`: the capture file, the object's mesh, how the lumispheres are fitted, the
/// grid, and the folder to write (new, empty, or an earlier field's, which is replaced).
#[derive(Clone, Debug)]
pub struct BuildRequest {
    pub rig: PathBuf,
    pub mesh: PathBuf,
    pub method: Method,
    pub options: BuildOptions,
    pub grid: GridOptions,
    pub output: PathBuf,
}

/// One step of [`build_file`], for a progress bar and the log.
#[derive(Clone, Copy, Debug)]
pub enum BuildStep<'a> {
    /// Stage `k` of [`crate::capture::STAGES`] begins.
    Stage(usize),
    /// The fit is done; a warning about a view (its mask and the mesh disagree).
    Warning(&'a str),
}

/// What [`build_file`] built and stored.
#[derive(Clone, Debug)]
pub struct BuildOutcome {
    /// The stored folder's byte counts (`report.json`).
    pub report: StoreReport,
    pub views: usize,
    /// Grid points, those no view sees, and the samples gathered.
    pub points: usize,
    pub unseen_points: usize,
    pub samples: usize,
    /// The atlas texel and the median pixel footprint on the surface, metres.
    pub texel_size: f64,
    pub median_pixel_footprint: f64,
    /// Seconds from the first stage to the stored folder's report.
    pub seconds: f64,
    /// The view-angle gain's knots (`AngleGain`, stored in `header.json`; empty: none).
    pub angle_gain: Vec<f32>,
}

/// Checks the request, reads the rig and the mesh, builds the field and stores it (with a
/// `report.json` that records the inputs and the gather; the time is returned, not stored).
pub fn build_file(
    req: &BuildRequest,
    step: &dyn Fn(BuildStep),
) -> Result<BuildOutcome, LightFieldError> {
    req.options.validate(req.method)?;
    req.grid.validate()?;
    check_sizes(req)?;
    // the output checked and claimed before the work (its lock, a staging folder of this run)
    let staging = igi_files::Staging::begin(&req.output)?;
    store::check_output(&req.output)?;
    let rig = Rig::load(&req.rig)?;
    rig.require_views(1)?;
    let mesh = igi_geometry::read_mesh(&req.mesh)?;
    let t = std::time::Instant::now();
    let built = build_from_rig(&rig, &mesh, req.grid, req.method, &req.options, &|k| {
        step(BuildStep::Stage(k))
    })?;
    for w in &built.warnings {
        step(BuildStep::Warning(w));
    }
    let seconds = t.elapsed().as_secs_f64();
    // no wall-clock time in report.json: identical builds give identical bytes (the command
    // prints the time)
    let extra = serde_json::json!({
        "rig": req.rig, "mesh": req.mesh, "views": built.views, "invalid_pixels": built.invalid_pixels,
        "gather": built.report, "atlas_texel_m": built.atlas.texel_size,
        "warnings": built.warnings,
    });
    let report = store::save_staged(staging, &built.field, &built.atlas.mesh, extra)?;
    Ok(BuildOutcome {
        report,
        views: built.views,
        points: built.report.points,
        unseen_points: built.report.unseen_points,
        samples: built.report.samples,
        texel_size: built.atlas.texel_size,
        median_pixel_footprint: built.report.median_pixel_footprint,
        seconds,
        angle_gain: built.field.gain.knots.clone(),
    })
}

/// Refuses, before any work, options whose buffers would not fit in memory (see
/// `igi_files::memory`): the atlas (position, normal and coverage, f32 RGB and a validity byte
/// a texel), FQ's codebook of `--codewords` lumispheres, and PFA's `--q`+1 prototypes, the
/// (q+1)^2 Gram matrix of each worker and q+1 weights a grid point (at most one a texel).
fn check_sizes(req: &BuildRequest) -> Result<(), LightFieldError> {
    let texels = req.grid.atlas as u128 * req.grid.atlas as u128;
    let check = |what: String, bytes: u128| igi_files::check_alloc_default(&what, bytes);
    check(
        format!("the atlas (--atlas {})", req.grid.atlas),
        texels * 39,
    )?;
    // octahedron subdivision level s: 4^(s+1) + 2 directions a lumisphere, RGB f32
    let lumisphere = ((4u128 << (2 * req.options.level.min(16))) + 2) * 12;
    let threads = rayon::current_num_threads() as u128;
    match req.method {
        Method::Fq { codewords } => check(
            format!("the codebook (--codewords {codewords})"),
            codewords as u128 * lumisphere,
        )?,
        Method::Pfa { q } => {
            let k = q as u128 + 1;
            check(
                format!("the prototypes and weights (--q {q})"),
                k * lumisphere + threads * k * k * 4 + texels * k * 4,
            )?
        }
        _ => {}
    }
    Ok(())
}

/// `igi slf render`: the stored field, the camera, a rotated or deformed copy of its mesh
/// (same vertices, triangles and UVs; optional), the highlight edit, the RGBA EXR to write.
#[derive(Clone, Debug)]
pub struct RenderRequest {
    pub slf_dir: PathBuf,
    pub camera: PathBuf,
    pub mesh: Option<PathBuf>,
    /// Perlin bias on the output values (0.5: unchanged).
    pub bias: f32,
    /// The value mapped to 1 before the bias.
    pub white: f32,
    pub output: PathBuf,
}

/// What [`render_file`] rendered.
#[derive(Clone, Copy, Debug)]
pub struct RenderOutcome {
    /// Seconds spent rendering (not loading).
    pub seconds: f64,
    pub width: usize,
    pub height: usize,
}

/// Renders the stored field through the camera and writes the RGBA EXR (alpha 1 where the
/// surface is seen, colour premultiplied).
pub fn render_file(req: &RenderRequest) -> Result<RenderOutcome, LightFieldError> {
    if !(req.bias > 0.0 && req.bias < 1.0) || !(req.white > 0.0 && req.white.is_finite()) {
        return Err(LightFieldError::Arguments(format!(
            "--bias must lie in (0, 1) and --white be positive (got {} and {})",
            req.bias, req.white
        )));
    }
    // an RGBA EXR is written: another extension would name the wrong format
    igi_files::check_output_extension(&req.output, &["exr"])?;
    igi_files::check_output_file(&req.output)?;
    if !req.slf_dir.join("header.json").is_file() {
        return Err(LightFieldError::Format {
            path: req.slf_dir.clone(),
            msg: "is not a surface light field folder (it has no header.json); make one with igi slf build".into(),
        });
    }
    let camera = Camera::load(&req.camera)?;
    let (field, stored) = store::load(&req.slf_dir).map_err(|e| LightFieldError::Reading {
        path: req.slf_dir.clone(),
        source: Box::new(e),
    })?;
    let mesh = match &req.mesh {
        Some(p) => deformed_mesh(p, stored, &req.slf_dir)?,
        None => stored,
    };
    let t = std::time::Instant::now();
    let opts = RenderSlfOptions {
        bias: req.bias,
        white: req.white,
    };
    let (img, alpha) = field.render(&mesh, &camera, &opts)?;
    let seconds = t.elapsed().as_secs_f64();
    igi_imaging::write_exr_rgba(&req.output, &img, &alpha)?;
    Ok(RenderOutcome {
        seconds,
        width: img.width,
        height: img.height,
    })
}

/// The mesh at `path`, which must be a deformed copy of the stored one (its UVs when it has
/// none; its normals recomputed by the renderer).
fn deformed_mesh(path: &Path, stored: TriMesh, slf_dir: &Path) -> Result<TriMesh, LightFieldError> {
    let mut m = igi_geometry::read_mesh(path)?;
    if m.positions.len() != stored.positions.len() || m.indices != stored.indices {
        return Err(LightFieldError::Format {
            path: path.to_path_buf(),
            msg: format!(
                "not a deformed copy of {} (vertex count or triangles differ)",
                slf_dir.join("mesh.ply").display()
            ),
        });
    }
    if m.uvs.is_none() {
        m.uvs = stored.uvs;
    }
    m.normals = None;
    Ok(m)
}
