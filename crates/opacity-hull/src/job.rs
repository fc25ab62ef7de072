//! `igi hull build` and `igi hull render` as one call each, from a request of paths and
//! options: the rig read and built into a hull folder ([`build_file`]); a hull folder (relit
//! under a lighting file when asked) rendered through a camera and written ([`render_file`]).

use crate::build::{build, load_model, load_relit_model, BuildOptions, BuildReport, Stage};
use crate::render::{render, RenderOptions};
use crate::HullError;
use igi_camera::{Camera, Rig};
use igi_formats::lighting::LightingRadiance;
use std::path::PathBuf;

/// `igi hull build`: the capture file, the hull folder to write, the carving cells per axis,
/// and the depth in pixels of the frame's edge band that does not carve.
#[derive(Clone, Debug)]
pub struct BuildRequest {
    pub rig: PathBuf,
    pub output: PathBuf,
    pub resolution: usize,
    pub frame_band: usize,
}

/// One step of [`build_file`], for a progress bar.
#[derive(Clone, Copy, Debug)]
pub enum BuildStep {
    /// The rig is read: the build has this many stages.
    Stages(u64),
    /// A stage begins.
    Stage(Stage),
}

/// Reads the rig and builds its hull folder (nothing written on failure).
pub fn build_file(
    req: &BuildRequest,
    step: &mut dyn FnMut(BuildStep),
) -> Result<BuildReport, HullError> {
    let rig = Rig::load(&req.rig)?;
    let mut opts = BuildOptions {
        resolution: req.resolution,
        ..Default::default()
    };
    opts.matte.frame_band = req.frame_band;
    let lit = rig.views.iter().any(|v| !v.lights.is_empty());
    step(BuildStep::Stages(6 + lit as u64));
    build(&rig, &req.output, opts, &mut |s| step(BuildStep::Stage(s)))
}

/// `igi hull render`: the hull folder, the camera, a lighting file to relight the views under
/// (optional), the RGBA EXR to write, the views blended per surfel.
#[derive(Clone, Debug)]
pub struct RenderRequest {
    pub hull: PathBuf,
    pub camera: PathBuf,
    pub lighting: Option<PathBuf>,
    pub output: PathBuf,
    pub k: usize,
}

/// What [`render_file`] rendered.
#[derive(Clone, Copy, Debug)]
pub struct RenderOutcome {
    /// Seconds spent rendering (not loading).
    pub seconds: f64,
    pub width: usize,
    pub height: usize,
    pub surfels: usize,
}

/// Renders the hull folder through the camera (relit first under the lighting file when one
/// is given) and writes the RGBA EXR (colour premultiplied by alpha).
pub fn render_file(req: &RenderRequest) -> Result<RenderOutcome, HullError> {
    // an RGBA EXR is written: another extension would name the wrong format
    igi_files::check_output_extension(&req.output, &["exr"])?;
    igi_files::check_output_file(&req.output)?;
    let camera = Camera::load(&req.camera)?;
    let lighting = req
        .lighting
        .as_ref()
        .map(|l| LightingRadiance::load(l))
        .transpose()?;
    if !req.hull.join("hull.json").is_file() {
        return Err(HullError::HullFolder {
            path: req.hull.clone(),
            msg: "is not a hull folder (it has no hull.json); make one with igi hull build".into(),
        });
    }
    let model = match &lighting {
        Some(l) => load_relit_model(&req.hull, l)?,
        None => load_model(&req.hull)?,
    };
    let t = std::time::Instant::now();
    let opts = RenderOptions {
        k: req.k,
        ..Default::default()
    };
    let (img, alpha) = render(&model, &camera, opts);
    let seconds = t.elapsed().as_secs_f64();
    igi_imaging::write_exr_rgba(&req.output, &img, &alpha)?;
    Ok(RenderOutcome {
        seconds,
        width: img.width,
        height: img.height,
        surfels: model.surfels.len(),
    })
}
