//! The board photograph as `igi probe` reads it: one linear HDR image, one 8-bit image (its
//! clipped values masked), or exposure brackets merged in linear (`igi_imaging::hdr`), with an
//! optional sRGB decode for JPEG photographs.

use crate::ProbeError;
use igi_imaging::hdr::{merge_linear, LinearParams};
use igi_imaging::io::srgb_to_linear;
use igi_imaging::{read_image, HdrImage};
use std::path::{Path, PathBuf};

/// Linear sensor values at or above this (before an sRGB decode) count as clipped.
pub const CLIP: f32 = 0.98;
/// Bracket values below this carry too little signal to merge.
pub const NOISE_FLOOR: f32 = 0.002;

/// Where the photograph comes from.
#[derive(Clone, Debug)]
pub enum PhotoSource {
    /// One image (EXR/HDR linear, or PNG/JPEG/TIFF 8-bit).
    Image(PathBuf),
    /// Exposure brackets with their exposure times in seconds.
    Brackets {
        images: Vec<PathBuf>,
        times: Vec<f64>,
    },
}

/// The photograph and the saturation level to mask at (from `saturation` when given; for
/// brackets and 8-bit images the clip level, `None` for a single HDR image).
pub fn load_photograph(
    source: &PhotoSource,
    srgb: bool,
    saturation: Option<f32>,
) -> Result<(HdrImage, Option<f32>), ProbeError> {
    let clip = if srgb { srgb_to_linear(CLIP) } else { CLIP };
    match source {
        PhotoSource::Image(path) => {
            let im = read(path, srgb)?;
            Ok((im, saturation.or(is_ldr(path).then_some(clip))))
        }
        PhotoSource::Brackets { images, times } => {
            if images.len() != times.len() {
                return Err(ProbeError::BracketTimes {
                    brackets: images.len(),
                    times: times.len(),
                });
            }
            let imgs = images
                .iter()
                .map(|p| read(p, srgb))
                .collect::<Result<Vec<_>, _>>()?;
            let params = LinearParams {
                noise_floor: NOISE_FLOOR,
                saturation: saturation.unwrap_or(clip),
            };
            let (merged, stats) =
                merge_linear(&imgs, times, params).map_err(|source| ProbeError::Merge {
                    files: images
                        .iter()
                        .map(|p| p.display().to_string())
                        .collect::<Vec<_>>()
                        .join(", "),
                    source: Box::new(source),
                })?;
            tracing::info!(
                "merged {} brackets, {:.2}% of pixels valid",
                stats.exposures,
                100.0 * stats.valid_fraction
            );
            Ok((merged, None))
        }
    }
}

fn read(path: &Path, srgb: bool) -> Result<HdrImage, ProbeError> {
    let mut im = read_image(path)?;
    if srgb {
        for p in im.pixels.iter_mut() {
            *p = p.map(srgb_to_linear);
        }
    }
    Ok(im)
}

/// An 8-bit image format (by extension).
fn is_ldr(p: &Path) -> bool {
    matches!(
        p.extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .as_deref(),
        Some("png" | "jpg" | "jpeg" | "tif" | "tiff")
    )
}
