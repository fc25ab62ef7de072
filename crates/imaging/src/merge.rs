//! `igi hdr merge` as one job: the brackets and their exposure times read and checked, merged
//! (linear sensor values, or Debevec-Malik response recovery then the merge through it), the
//! response and the merged image written.

use crate::error::HdrError;
use crate::hdr::{self, LinearParams, MergeStats, Response, ResponseParams};
use crate::{read_image, write_exr, write_hdr, HdrImage, ImagingError};
use std::path::{Path, PathBuf};

/// Where the exposure times of the brackets come from.
#[derive(Clone, Debug)]
pub enum ExposureTimes {
    /// One time per image as written (seconds, decimal or a fraction such as `1/250`).
    Given(Vec<String>),
    /// A file of whitespace-separated times.
    File(PathBuf),
    /// Each image's EXIF ExposureTime.
    Exif,
}

/// How the brackets are merged.
#[derive(Clone, Copy, Debug)]
pub enum MergeMethod {
    /// Linear sensor values (1 = full scale), hat-weighted.
    Linear(LinearParams),
    /// 8-bit values through a response recovered by Debevec-Malik.
    DebevecMalik(ResponseParams),
}

/// What `igi hdr merge` merges and writes.
#[derive(Clone, Debug)]
pub struct MergeRequest {
    /// The brackets, in order of strictly increasing or decreasing exposure time.
    pub images: Vec<PathBuf>,
    pub times: ExposureTimes,
    pub method: MergeMethod,
    /// The recovered response g(z) as CSV (Debevec-Malik only).
    pub response_out: Option<PathBuf>,
    /// The merged image (.exr or .hdr).
    pub output: PathBuf,
}

/// One step of [`merge_files`], for a progress bar.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MergeStep {
    /// One bracket read.
    Read,
    /// Every bracket read and checked; merging begins.
    Merging,
    /// Merged and written.
    Merged,
}

/// What [`merge_files`] did.
#[derive(Clone, Debug)]
pub struct MergeOutcome {
    pub stats: MergeStats,
    /// The exposure time of each bracket, seconds.
    pub times: Vec<f64>,
    /// The recovered response's smoothness weight and whether it is monotonic (Debevec-Malik).
    pub response: Option<ResponseSummary>,
}

/// The recovered response, as reported.
#[derive(Clone, Copy, Debug)]
pub struct ResponseSummary {
    pub lambda: f64,
    pub monotonic: bool,
}

/// `igi hdr merge`: checks the request, reads the brackets and their times, merges them and
/// writes the response (when asked) and the merged image.
pub fn merge_files(
    req: &MergeRequest,
    step: &dyn Fn(MergeStep),
) -> Result<MergeOutcome, ImagingError> {
    check_request(req)?;
    let times = exposure_times(&req.images, &req.times)?;
    let mut images = Vec::with_capacity(req.images.len());
    for p in &req.images {
        images.push(read_image(p)?);
        step(MergeStep::Read);
    }
    hdr::validate_brackets(&images, &times, &req.images)?;
    step(MergeStep::Merging);
    let (merged, stats, response) = merge_images(req.method, &images, &times)?;
    step(MergeStep::Merged);
    if let (Some(path), Some(r)) = (&req.response_out, &response) {
        r.write_csv(path)?;
    }
    write_merged(&req.output, &merged)?;
    let response = response.map(|r| ResponseSummary {
        lambda: r.lambda,
        monotonic: r.is_monotonic(),
    });
    Ok(MergeOutcome {
        stats,
        times,
        response,
    })
}

/// The output's format and the response file, before any work.
fn check_request(req: &MergeRequest) -> Result<(), ImagingError> {
    igi_files::check_output_extension(&req.output, &["exr", "hdr"])?;
    if matches!(req.method, MergeMethod::Linear(_)) && req.response_out.is_some() {
        return Err(HdrError::ResponseOutLinear.into());
    }
    Ok(())
}

/// Writes `img` as EXR or, for a `.hdr` name, Radiance HDR.
fn write_merged(path: &Path, img: &HdrImage) -> Result<(), ImagingError> {
    let ext = path.extension().map(|e| e.to_string_lossy().to_lowercase());
    match ext.as_deref() {
        Some("hdr") => write_hdr(path, img),
        _ => write_exr(path, img),
    }
}

/// One exposure time per image: given, from a file, or each image's EXIF.
fn exposure_times(images: &[PathBuf], source: &ExposureTimes) -> Result<Vec<f64>, ImagingError> {
    let times: Vec<f64> = match source {
        ExposureTimes::Given(t) => t
            .iter()
            .map(|t| hdr::parse_time(t))
            .collect::<Result<_, _>>()?,
        ExposureTimes::File(f) => hdr::read_times_file(f)?,
        ExposureTimes::Exif => images
            .iter()
            .map(|p| hdr::exif_exposure_time(p))
            .collect::<Result<_, _>>()
            .map_err(|e| HdrError::MissingTimes {
                source: Box::new(e),
            })?,
    };
    if times.len() != images.len() {
        return Err(HdrError::TimesPerImage {
            images: images.len(),
            times: times.len(),
        }
        .into());
    }
    Ok(times)
}

/// Linear merge, or Debevec-Malik: the recovered response, then the merge through it.
fn merge_images(
    method: MergeMethod,
    images: &[HdrImage],
    times: &[f64],
) -> Result<(HdrImage, MergeStats, Option<Response>), ImagingError> {
    match method {
        MergeMethod::Linear(p) => {
            let (m, s) = hdr::merge_linear(images, times, p)?;
            Ok((m, s, None))
        }
        MergeMethod::DebevecMalik(p) => {
            let r = hdr::recover_response(images, times, p)?;
            let (m, s) = hdr::merge_ldr(images, times, &r)?;
            Ok((m, s, Some(r)))
        }
    }
}
