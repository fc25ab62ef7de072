//! `igi render`: path-trace a scene file through a camera.
use crate::report::Ctx;
use igi_render::RenderOptions;
use igi_workflow::render::{render, RenderRequest, RenderStep};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct RenderArgs {
    /// Scene file (TOML, FORMATS.md), or the result folder of `igi solve` (then --lighting is required).
    pub input: PathBuf,
    /// Camera file (JSON, OpenCV model).
    #[arg(long)]
    pub camera: PathBuf,
    /// Samples per pixel.
    #[arg(allow_negative_numbers = true, value_parser = clap::builder::RangedU64ValueParser::<u32>::new().range(1..), long, default_value_t = 64)]
    pub spp: u32,
    /// Random seed (same seed, same image).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Indirect bounces after direct lighting (Mitsuba max_depth = K + 2).
    #[arg(allow_negative_numbers = true, value_parser = clap::builder::RangedU64ValueParser::<u32>::new().range(0..=64), long, default_value_t = 2)]
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

pub fn run(a: RenderArgs, ctx: &Ctx) -> anyhow::Result<()> {
    let req = RenderRequest {
        input: a.input,
        camera: a.camera,
        lighting: a.lighting,
        options: RenderOptions {
            spp: a.spp,
            seed: a.seed,
            indirect: a.indirect,
            russian_roulette: a.rr,
            stratified: a.stratified,
            adaptive: a.adaptive,
        },
        output: a.output,
        stderr: a.stderr,
    };
    let pb = ctx.progress(0, "render");
    let r = render(&req, &|s| match s {
        RenderStep::Warning(w) => eprintln!("warning: {w}"),
        RenderStep::Rows(n) => pb.set_length(n),
        RenderStep::Rendered(n) => pb.inc(n),
    })?;
    pb.finish_and_clear();
    let pixels = r.width as f64 * r.height as f64;
    let adaptive = if a.adaptive {
        format!(
            " on average, adaptive: {:.1} a pixel traced with the pilot",
            r.samples as f64 / pixels
        )
    } else {
        String::new()
    };
    println!(
        "wrote {} ({} x {}, {} spp{adaptive}, K = {}) in {:.2} s: {:.2} M rays/s, {:.2} M samples/s",
        req.output.display(),
        r.width,
        r.height,
        a.spp,
        a.indirect,
        r.seconds,
        r.rays as f64 / r.seconds / 1e6,
        r.samples as f64 / r.seconds / 1e6
    );
    Ok(())
}
