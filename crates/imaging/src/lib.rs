//! # igi-imaging
//!
//! Images, as every pipeline shares them (above `igi-files`, which writes them atomically):
//!
//! * [`HdrImage`]: linear `f32` RGB image with a validity mask (row 0 at the top).
//! * [`io`]: [`read_image`] (EXR, Radiance HDR, PNG/JPEG/TIFF; headers checked against the
//!   pixel limit before decoding), [`write_exr`], [`write_hdr`], [`write_png_tonemapped`] (its
//!   bytes in memory: [`png_tonemapped`]; an exposure for people: [`auto_exposure`]), the sRGB
//!   transfer functions.
//! * [`photo`]: photographs as cameras write them made linear ([`photo::read_photo`]: 8-bit
//!   through a Debevec-Malik camera response or sRGB, 16-bit linear, clipped pixels masked and
//!   counted; [`photo::read_response_csv`]).
//! * [`raw`]: camera RAW files (DNG and common raw formats) to linear Rec. 709 RGB with the
//!   file's white balance and colour matrix ([`raw::read_raw`], the optional `raw` feature:
//!   the `rawler` decoder, LGPL-2.1).
//! * [`exif`]: when a photograph was taken and how it was exposed, from its EXIF
//!   ([`exif::read_exif`], [`exif::PhotoExif::exposure`]).
//! * [`hdr`]: merging exposure brackets (linear sensors, the least-squares slope of Matusik
//!   et al. 2002, or LDR via Debevec & Malik 1997 response recovery), EXIF exposure times.
//! * [`merge`]: `igi hdr merge` as one job ([`merge::merge_files`]: brackets and times read,
//!   checked, merged, written).
//! * [`latlong`]: the lat-long (equirectangular) mapping of FORMATS.md (world Z up).
//! * [`color`]: shared conventions (Rec. 709 luminance, the median, the default sun size).
//! * [`metrics`]: image comparison (RMSE, relative mean difference, PSNR, noise-explained
//!   RMSE) and false-colour difference pictures; `igi compare` as one job
//!   ([`metrics::compare_files`]: the image files read, uncovered pixels masked, compared).
//! * [`mask`]: binary masks (threshold, disk dilation and erosion, hole filling up to an area,
//!   frame contact, IoU).
//! * [`csv`]: the one reader of igi's numeric CSV tables (header by name, comments, errors
//!   naming file and line).
//!
//! Cameras (the model, poses, calibration, radiometry, rigs, OpenCV) are `igi-camera`'s.
//! Conventions: linear radiance, pixel centres at integer coordinates (the centre of the
//! top-left pixel is (0, 0)).

// `!(x > 0.0)` is used on purpose: it is also true for NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod color;
pub mod csv;
mod error;
pub mod exif;
pub mod hdr;
mod image;
pub mod io;
pub mod latlong;
pub mod mask;
pub mod merge;
pub mod metrics;
pub mod photo;
pub mod raw;
#[cfg(all(test, feature = "raw"))]
mod tests_libraw;

pub use error::{CompareError, FileSizes, HdrError, ImagingError};
pub use image::HdrImage;
pub use io::{
    auto_exposure, png_tonemapped, read_exr_alpha, read_image, write_exr, write_exr_rgba,
    write_hdr, write_png_tonemapped,
};
pub use mask::Mask;
