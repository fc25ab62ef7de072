//! `igi hdr merge`: merge exposure brackets into linear radiance (EXR or Radiance HDR).
use crate::report::Ctx;
use anyhow::{bail, Context};
use igi_imaging::hdr::{self, LinearParams, ResponseParams};
use igi_imaging::{read_image, write_exr, write_hdr, HdrImage};
use std::path::{Path, PathBuf};

#[derive(clap::Subcommand, Debug)]
pub enum HdrCmd {
    /// Merge exposure brackets. 8-bit brackets: Debevec-Malik response recovery then merge;
    /// with --linear: hat-weighted merge of linear sensor values (1 = full scale).
    Merge(MergeArgs),
}

#[derive(clap::Args, Debug)]
pub struct MergeArgs {
    /// Bracket images (same size), in order of strictly increasing or decreasing exposure time.
    #[arg(required = true)]
    images: Vec<PathBuf>,
    /// Exposure times in seconds, one per image (decimal or fraction such as 1/250).
    /// Read from EXIF ExposureTime when neither this nor --times-file is given.
    #[arg(long, num_args = 1..)]
    times: Vec<String>,
    /// File with the exposure times, whitespace separated (e.g. shutter_times.txt).
    #[arg(long, conflicts_with = "times")]
    times_file: Option<PathBuf>,
    /// The brackets are linear sensor values (skip response recovery).
    #[arg(long)]
    linear: bool,
    /// Linear merge: values at or below this are noise.
    #[arg(long, default_value_t = 0.002)]
    noise_floor: f32,
    /// Linear merge: values at or above this are saturated.
    #[arg(long, default_value_t = 0.98)]
    saturation: f32,
    /// Response recovery: smoothness weight lambda.
    #[arg(long, default_value_t = 50.0)]
    lambda: f64,
    /// Response recovery: number of sampled pixels.
    #[arg(long, default_value_t = 1000)]
    samples: usize,
    /// Seed of the pixel sampling.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Write the recovered response g(z) = ln exposure as CSV (z,g_r,g_g,g_b).
    #[arg(long)]
    response_out: Option<PathBuf>,
    /// Print a JSON summary on stdout.
    #[arg(long)]
    json: bool,
    /// Output image (.exr or .hdr).
    #[arg(short, long)]
    output: PathBuf,
}

pub fn run(c: HdrCmd, ctx: &Ctx) -> anyhow::Result<()> {
    match c {
        HdrCmd::Merge(a) => merge(a, ctx),
    }
}

fn write_output(path: &Path, img: &HdrImage) -> anyhow::Result<()> {
    match path
        .extension()
        .map(|e| e.to_string_lossy().to_lowercase())
        .as_deref()
    {
        Some("exr") => write_exr(path, img)?,
        Some("hdr") => write_hdr(path, img)?,
        _ => unreachable!("checked before"),
    }
    Ok(())
}

fn merge(a: MergeArgs, ctx: &Ctx) -> anyhow::Result<()> {
    let ext = a
        .output
        .extension()
        .map(|e| e.to_string_lossy().to_lowercase());
    if !matches!(ext.as_deref(), Some("exr") | Some("hdr")) {
        bail!("{}: output must be .exr or .hdr", a.output.display());
    }
    if a.linear && a.response_out.is_some() {
        bail!("--response-out needs a response: it is not recovered with --linear");
    }
    let times = exposure_times(&a)?;
    let pb = ctx.progress(a.images.len() as u64 + 2, "reading");
    let mut images = Vec::with_capacity(a.images.len());
    for p in &a.images {
        images.push(read_image(p)?);
        pb.inc(1);
    }
    hdr::validate_brackets(&images, &times, &a.images)?;
    pb.set_message("merging");
    let (merged, stats, resp) = merge_images(&a, &images, &times)?;
    pb.inc(2);
    if let (Some(path), Some(r)) = (&a.response_out, &resp) {
        r.write_csv(path)?;
    }
    write_output(&a.output, &merged)?;
    pb.finish_and_clear();
    if a.json {
        let mut j = serde_json::json!({
            "output": a.output,
            "method": if a.linear { "linear" } else { "debevec-malik" },
            "exposures": stats.exposures,
            "width": stats.width,
            "height": stats.height,
            "valid_fraction": stats.valid_fraction,
            "times": times,
        });
        if let Some(r) = &resp {
            j["response_monotonic"] = serde_json::json!(r.is_monotonic());
            j["lambda"] = serde_json::json!(r.lambda);
        }
        crate::report::print_json(&j)?;
    } else {
        tracing::info!(
            "merged {} exposures, valid fraction {:.4}",
            stats.exposures,
            stats.valid_fraction
        );
    }
    Ok(())
}

/// One exposure time per image: `--times`, `--times-file`, or each image's EXIF.
fn exposure_times(a: &MergeArgs) -> anyhow::Result<Vec<f64>> {
    let times: Vec<f64> = if !a.times.is_empty() {
        a.times
            .iter()
            .map(|t| hdr::parse_time(t))
            .collect::<Result<_, _>>()?
    } else if let Some(f) = &a.times_file {
        hdr::read_times_file(f)?
    } else {
        a.images
            .iter()
            .map(|p| hdr::exif_exposure_time(p))
            .collect::<Result<_, _>>()
            .context("missing exposure times: pass --times or --times-file")?
    };
    if times.len() != a.images.len() {
        bail!(
            "missing exposure times: {} image(s) but {} time(s) (pass one time per image)",
            a.images.len(),
            times.len()
        );
    }
    Ok(times)
}

/// Linear merge, or Debevec-Malik: the recovered response, then the merge through it.
fn merge_images(
    a: &MergeArgs,
    images: &[HdrImage],
    times: &[f64],
) -> anyhow::Result<(HdrImage, hdr::MergeStats, Option<hdr::Response>)> {
    if a.linear {
        let p = LinearParams {
            noise_floor: a.noise_floor,
            saturation: a.saturation,
        };
        let (m, s) = hdr::merge_linear(images, times, p)?;
        return Ok((m, s, None));
    }
    let p = ResponseParams {
        lambda: a.lambda,
        samples: a.samples,
        seed: a.seed,
    };
    let r = hdr::recover_response(images, times, p)?;
    let (m, s) = hdr::merge_ldr(images, times, &r)?;
    Ok((m, s, Some(r)))
}
