//! `igi hdr merge`: merge exposure brackets into linear radiance (EXR or Radiance HDR).
use crate::report::Ctx;
use igi_imaging::hdr::{LinearParams, ResponseParams};
use igi_imaging::merge::{merge_files, ExposureTimes, MergeMethod, MergeRequest, MergeStep};
use std::path::PathBuf;

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
    #[arg(allow_negative_numbers = true, value_parser = crate::cmd::values::non_negative_f32, long, default_value_t = 0.002)]
    noise_floor: f32,
    /// Linear merge: values at or above this are saturated.
    #[arg(allow_negative_numbers = true, value_parser = crate::cmd::values::positive_f32, long, default_value_t = 0.98)]
    saturation: f32,
    /// Response recovery: smoothness weight lambda.
    #[arg(allow_negative_numbers = true, value_parser = crate::cmd::values::non_negative, long, default_value_t = 50.0)]
    lambda: f64,
    /// Response recovery: number of sampled pixels.
    #[arg(long, default_value_t = 1000)]
    samples: usize,
    /// Seed of the pixel sampling.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Write the recovered response g(z) = ln exposure as CSV (z,g_r,g_g,g_b). A survey's
    /// `response = FILE` (per photo or under `[radiometry]`) makes 8-bit photos of this camera
    /// linear through it (docs/IMAGING.md, "Linearising photographs").
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

impl MergeArgs {
    /// The merge `igi hdr merge` asks for.
    fn request(&self) -> MergeRequest {
        let times = if !self.times.is_empty() {
            ExposureTimes::Given(self.times.clone())
        } else if let Some(f) = &self.times_file {
            ExposureTimes::File(f.clone())
        } else {
            ExposureTimes::Exif
        };
        let method = if self.linear {
            MergeMethod::Linear(LinearParams {
                noise_floor: self.noise_floor,
                saturation: self.saturation,
            })
        } else {
            MergeMethod::DebevecMalik(ResponseParams {
                lambda: self.lambda,
                samples: self.samples,
                seed: self.seed,
            })
        };
        MergeRequest {
            images: self.images.clone(),
            times,
            method,
            response_out: self.response_out.clone(),
            output: self.output.clone(),
        }
    }
}

fn merge(a: MergeArgs, ctx: &Ctx) -> anyhow::Result<()> {
    let pb = ctx.progress(a.images.len() as u64 + 2, "reading");
    let r = merge_files(&a.request(), &|s| match s {
        MergeStep::Read => pb.inc(1),
        MergeStep::Merging => pb.set_message("merging"),
        MergeStep::Merged => pb.inc(2),
    })?;
    pb.finish_and_clear();
    if a.json {
        let mut j = serde_json::json!({
            "output": a.output,
            "method": if a.linear { "linear" } else { "debevec-malik" },
            "exposures": r.stats.exposures,
            "width": r.stats.width,
            "height": r.stats.height,
            "valid_fraction": r.stats.valid_fraction,
            "times": r.times,
        });
        if let Some(resp) = &r.response {
            j["response_monotonic"] = serde_json::json!(resp.monotonic);
            j["lambda"] = serde_json::json!(resp.lambda);
        }
        crate::report::print_json(&j)?;
    } else {
        tracing::info!(
            "merged {} exposures, valid fraction {:.4}",
            r.stats.exposures,
            r.stats.valid_fraction
        );
    }
    Ok(())
}
