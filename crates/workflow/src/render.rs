//! `igi render` as one job: a scene file, or a solve result folder re-lit (its `scene.toml`
//! holds the recovered materials and no lighting), path-traced through a camera; the
//! arguments and outputs checked before any work, the images written after.

use crate::WorkflowError;
use igi_camera::Camera;
use igi_render::{render_image, Lighting, RenderOptions, Scene};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What `igi render` renders and writes.
#[derive(Clone, Debug)]
pub struct RenderRequest {
    /// A scene file (TOML), or the result folder of `igi solve` (then `lighting` is required).
    pub input: PathBuf,
    pub camera: PathBuf,
    /// A lighting file used instead of the scene's own.
    pub lighting: Option<PathBuf>,
    pub options: RenderOptions,
    /// The image (.exr, .hdr or .png).
    pub output: PathBuf,
    /// The per-pixel standard error of the mean, as an image.
    pub stderr: Option<PathBuf>,
}

/// One step of [`render`], for a progress bar and the log.
#[derive(Clone, Copy, Debug)]
pub enum RenderStep<'a> {
    /// A warning about the lighting (e.g. a sun below the horizon).
    Warning(&'a str),
    /// The scene and camera are loaded: this many rows will be rendered.
    Rows(u64),
    /// This many more rows rendered.
    Rendered(u64),
}

/// What [`render`] rendered.
#[derive(Clone, Copy, Debug)]
pub struct RenderOutcome {
    pub width: u32,
    pub height: u32,
    /// Seconds spent rendering.
    pub seconds: f64,
    /// Rays and camera samples traced.
    pub rays: u64,
    pub samples: u64,
}

/// Renders the request's scene under its lighting (the request's, else the scene's own) and
/// writes the image and, when asked, its standard error.
pub fn render(
    req: &RenderRequest,
    step: &(dyn Fn(RenderStep) + Sync),
) -> Result<RenderOutcome, WorkflowError> {
    let scene_file = checked_scene_file(req)?;
    let t0 = Instant::now();
    let (scene, lighting) = load_scene(req, &scene_file, step)?;
    let camera = Camera::load(&req.camera)?;
    tracing::info!(
        "scene {}: {} objects, {} triangles ({} degenerate skipped), loaded in {:.2} s",
        req.input.display(),
        scene.objects.len(),
        scene.triangle_count(),
        scene.skipped_triangles,
        t0.elapsed().as_secs_f64()
    );
    step(RenderStep::Rows(camera.height as u64));
    let t1 = Instant::now();
    let out = render_image(&scene, &lighting, &camera, &req.options, &|n| {
        step(RenderStep::Rendered(n))
    })
    .map_err(|e| WorkflowError::Rendering {
        path: req.input.clone(),
        source: Box::new(e),
    })?;
    let seconds = t1.elapsed().as_secs_f64();
    if out.bad_samples > 0 {
        tracing::warn!(
            "{} samples were NaN/infinite and were dropped",
            out.bad_samples
        );
    }
    // the temporary files a killed render of these outputs left behind
    for out in std::iter::once(&req.output).chain(req.stderr.as_ref()) {
        if let Some(dir) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
            igi_files::remove_dead_temps(dir, false)?;
        } else {
            igi_files::remove_dead_temps(Path::new("."), false)?;
        }
    }
    write_image(&req.output, &out.mean)?;
    if let Some(se) = &req.stderr {
        write_image(se, &out.stderr)?;
    }
    Ok(RenderOutcome {
        width: camera.width,
        height: camera.height,
        seconds,
        rays: out.rays,
        samples: out.samples,
    })
}

/// The scene file to render and checks of the request, before any work: a solve result
/// folder is re-lit (so the lighting is required); the outputs are checked before the render,
/// not after it.
fn checked_scene_file(req: &RenderRequest) -> Result<PathBuf, WorkflowError> {
    let scene_file = if req.input.is_dir() {
        if req.lighting.is_none() {
            return Err(WorkflowError::file(
                &req.input,
                "re-lighting a solve result needs --lighting LIGHTING.toml",
            ));
        }
        igi_reflect::load_result_scene(&req.input)?
    } else {
        req.input.clone()
    };
    let spp = req.options.spp;
    if spp == 0 {
        return Err(WorkflowError::Arguments("--spp must be at least 1".into()));
    }
    if req.options.adaptive && spp < igi_render::adaptive::MIN_SPP {
        return Err(WorkflowError::Arguments(format!(
            "--adaptive needs --spp {} or more (got {spp}): its pilot takes an eighth of the samples",
            igi_render::adaptive::MIN_SPP,
        )));
    }
    for out in std::iter::once(&req.output).chain(req.stderr.as_ref()) {
        image_format(out)?;
        igi_files::check_output_file(out)?;
    }
    let mut outputs = vec![("--output", req.output.as_path())];
    outputs.extend(req.stderr.as_deref().map(|p| ("--stderr", p)));
    let mut inputs = vec![
        ("the scene", scene_file.as_path()),
        ("--camera", req.camera.as_path()),
    ];
    inputs.extend(req.lighting.as_deref().map(|p| ("--lighting", p)));
    igi_files::check_distinct(&outputs, &inputs)?;
    Ok(scene_file)
}

/// The scene and the lighting it is rendered under, which must light something; its warnings
/// are told to `step`.
fn load_scene(
    req: &RenderRequest,
    scene_file: &Path,
    step: &(dyn Fn(RenderStep) + Sync),
) -> Result<(Scene, Lighting), WorkflowError> {
    let (scene, scene_lighting) = Scene::load(scene_file)?;
    let lighting = match &req.lighting {
        Some(p) => Lighting::load(p)?,
        None => scene_lighting,
    };
    lighting.check_lights_something()?;
    for w in lighting.warnings() {
        step(RenderStep::Warning(&w));
    }
    Ok((scene, lighting))
}

/// `exr`, `hdr` or `png`: the image format of an output name (its extension, any case).
fn image_format(path: &Path) -> Result<&'static str, WorkflowError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("exr") => Ok("exr"),
        Some("hdr") => Ok("hdr"),
        Some("png") => Ok("png"),
        _ => Err(WorkflowError::file(
            path,
            "unknown output format (use .exr, .hdr or .png)",
        )),
    }
}

fn write_image(path: &Path, img: &igi_imaging::HdrImage) -> Result<(), WorkflowError> {
    match image_format(path)? {
        "exr" => igi_imaging::write_exr(path, img)?,
        "hdr" => igi_imaging::write_hdr(path, img)?,
        _ => igi_imaging::write_png_tonemapped(path, img, 1.0)?,
    }
    Ok(())
}
