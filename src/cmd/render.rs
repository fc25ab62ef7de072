//! `igi render`: path-trace a scene file through a camera.
use crate::report::Ctx;
use anyhow::{bail, Context};
use igi_render::{render_image, Lighting, RenderOptions, Scene};
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(clap::Args, Debug)]
pub struct RenderArgs {
    /// Scene file (TOML, FORMATS.md), or the result folder of `igi solve` (then --lighting is required).
    pub input: PathBuf,
    /// Camera file (JSON, OpenCV model).
    #[arg(long)]
    pub camera: PathBuf,
    /// Samples per pixel.
    #[arg(long, default_value_t = 64)]
    pub spp: u32,
    /// Random seed (same seed, same image).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Indirect bounces after direct lighting (Mitsuba max_depth = K + 2).
    #[arg(long, default_value_t = 2)]
    pub indirect: u32,
    /// Use this lighting file instead of the one the scene names.
    #[arg(long)]
    pub lighting: Option<PathBuf>,
    /// Also write the per-pixel standard error of the mean (EXR).
    #[arg(long)]
    pub stderr: Option<PathBuf>,
    /// Russian roulette on long paths.
    #[arg(long)]
    pub rr: bool,
    /// Stratify each pixel's samples (pixel position, first light and bounce): far less noise
    /// for the same samples; --stderr then bounds the error from above instead of estimating it.
    #[arg(long)]
    pub stratified: bool,
    /// Deal the samples by each pixel's noise: --spp is then the mean over the image; a pilot
    /// of an eighth of it measures every pixel's relative noise and cost, and the rest goes
    /// where it lowers the image's relative variance most (spp/4 to 4 spp a pixel; unbiased;
    /// needs --spp 16 or more).
    #[arg(long)]
    pub adaptive: bool,
    /// Output image: .exr (f32), .hdr (RGBE) or .png (sRGB preview).
    #[arg(short, long)]
    pub output: PathBuf,
}

fn check_image_name(path: &Path) -> anyhow::Result<()> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    if !matches!(ext.as_deref(), Some("exr" | "hdr" | "png")) {
        bail!(
            "{}: unknown output format (use .exr, .hdr or .png)",
            path.display()
        );
    }
    Ok(())
}

fn write_any(path: &Path, img: &igi_imaging::HdrImage) -> anyhow::Result<()> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("exr") => igi_imaging::write_exr(path, img)?,
        Some("hdr") => igi_imaging::write_hdr(path, img)?,
        Some("png") => igi_imaging::write_png_tonemapped(path, img, 1.0)?,
        _ => bail!(
            "{}: unknown output format (use .exr, .hdr or .png)",
            path.display()
        ),
    }
    Ok(())
}

/// The scene file to render and checks of the arguments, before any work: a solve result
/// folder is re-lit (its scene.toml holds the recovered materials and no lighting, so
/// --lighting is required); the outputs are checked before the render, not after it.
fn checked_scene_file(a: &RenderArgs) -> anyhow::Result<PathBuf> {
    let scene_file = if a.input.is_dir() {
        if a.lighting.is_none() {
            bail!(
                "{}: re-lighting a solve result needs --lighting LIGHTING.toml",
                a.input.display()
            );
        }
        igi_reflect::load_result_scene(&a.input)?
    } else {
        a.input.clone()
    };
    if a.spp == 0 {
        bail!("--spp must be at least 1");
    }
    if a.adaptive && a.spp < igi_render::adaptive::MIN_SPP {
        bail!(
            "--adaptive needs --spp {} or more (got {}): its pilot takes an eighth of the samples",
            igi_render::adaptive::MIN_SPP,
            a.spp
        );
    }
    for out in std::iter::once(&a.output).chain(a.stderr.as_ref()) {
        check_image_name(out)?;
        igi_files::check_output_file(out)?;
    }
    Ok(scene_file)
}

/// The scene and the lighting it is rendered under (--lighting, else the scene's own), which
/// must light something; its warnings are printed.
fn load_scene(a: &RenderArgs, scene_file: &Path) -> anyhow::Result<(Scene, Lighting)> {
    let (scene, scene_lighting) = Scene::load(scene_file)?;
    let lighting = match &a.lighting {
        Some(p) => Lighting::load(p)?,
        None => scene_lighting,
    };
    lighting.check_lights_something()?;
    for w in lighting.warnings() {
        eprintln!("warning: {w}");
    }
    Ok((scene, lighting))
}

pub fn run(a: RenderArgs, ctx: &Ctx) -> anyhow::Result<()> {
    let scene_file = checked_scene_file(&a)?;
    let t0 = Instant::now();
    let (scene, lighting) = load_scene(&a, &scene_file)?;
    let camera = igi_camera::Camera::load(&a.camera)?;
    let load_s = t0.elapsed().as_secs_f64();
    tracing::info!(
        "scene {}: {} objects, {} triangles ({} degenerate skipped), loaded in {:.2} s",
        a.input.display(),
        scene.objects.len(),
        scene.triangle_count(),
        scene.skipped_triangles,
        load_s
    );
    let opts = RenderOptions {
        spp: a.spp,
        seed: a.seed,
        indirect: a.indirect,
        russian_roulette: a.rr,
        stratified: a.stratified,
        adaptive: a.adaptive,
    };
    let pb = ctx.progress(camera.height as u64, "render");
    let t1 = Instant::now();
    let out = render_image(&scene, &lighting, &camera, &opts, &|n| pb.inc(n))
        .with_context(|| format!("rendering {}", a.input.display()))?;
    pb.finish_and_clear();
    let secs = t1.elapsed().as_secs_f64();
    if out.bad_samples > 0 {
        tracing::warn!(
            "{} samples were NaN/infinite and were dropped",
            out.bad_samples
        );
    }
    write_any(&a.output, &out.mean)?;
    if let Some(se) = &a.stderr {
        write_any(se, &out.stderr)?;
    }
    let pixels = camera.width as f64 * camera.height as f64;
    let adaptive = if a.adaptive {
        format!(
            " on average, adaptive: {:.1} a pixel traced with the pilot",
            out.samples as f64 / pixels
        )
    } else {
        String::new()
    };
    println!(
        "wrote {} ({} x {}, {} spp{adaptive}, K = {}) in {:.2} s: {:.2} M rays/s, {:.2} M samples/s",
        a.output.display(),
        camera.width,
        camera.height,
        a.spp,
        a.indirect,
        secs,
        out.rays as f64 / secs / 1e6,
        out.samples as f64 / secs / 1e6
    );
    Ok(())
}
