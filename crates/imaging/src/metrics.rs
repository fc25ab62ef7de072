//! Image comparison metrics, the one home of the maths behind `igi compare`, the Mitsuba
//! reference tests, the demo and [`HdrImage::psnr_inside`]: RMSE, relative mean difference,
//! PSNR, and the RMSE that Monte-Carlo noise alone explains when per-pixel standard errors are
//! known.

use crate::error::CompareError;
use crate::{HdrImage, ImagingError};
use serde::Serialize;

/// Metrics of image `a` against reference `b` over pixels valid in both (all channels).
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct Comparison {
    pub width: usize,
    pub height: usize,
    /// Pixels compared (valid in both images).
    pub pixels: usize,
    /// sqrt(mean((a - b)^2)) over pixels and channels.
    pub rmse: f64,
    /// (mean(a) - mean(b)) / mean(b).
    pub relative_mean_difference: f64,
    pub mean_a: f64,
    pub mean_b: f64,
    /// 20 log10(max(b) / rmse) (infinite when the images are equal).
    pub psnr_db: f64,
    /// sqrt(mean(se_a^2 + se_b^2)) when standard-error images were given.
    pub noise_rmse: Option<f64>,
}

/// PSNR in dB of an error `rmse` against a signal peak `peak`: 20 log10(peak / rmse), infinite
/// when `rmse` is 0.
pub fn psnr_db(peak: f64, rmse: f64) -> f64 {
    if rmse > 0.0 {
        20.0 * (peak / rmse).log10()
    } else {
        f64::INFINITY
    }
}

/// Running sums over compared pixels (every channel counted), in f64.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct ErrorSums {
    /// Sum of (a - b)^2.
    pub squared_error: f64,
    pub sum_a: f64,
    pub sum_b: f64,
    /// Largest channel value of b.
    pub peak_b: f64,
    /// Sum of se_a^2 + se_b^2.
    pub noise: f64,
    /// Pixels added.
    pub pixels: usize,
}

impl ErrorSums {
    /// Adds one pixel of `a` and `b`, with the standard errors `se_a` and `se_b` (0 if unknown).
    #[inline]
    pub fn add(&mut self, a: [f32; 3], b: [f32; 3], se_a: [f32; 3], se_b: [f32; 3]) {
        self.pixels += 1;
        for c in 0..3 {
            let (x, y) = (a[c] as f64, b[c] as f64);
            self.squared_error += (x - y) * (x - y);
            self.sum_a += x;
            self.sum_b += y;
            self.peak_b = self.peak_b.max(y);
            let (ea, eb) = (se_a[c] as f64, se_b[c] as f64);
            self.noise += ea * ea + eb * eb;
        }
    }

    /// Number of channel values added.
    fn values(&self) -> f64 {
        (3 * self.pixels) as f64
    }

    /// sqrt(mean((a - b)^2)) (NaN when nothing was added).
    pub fn rmse(&self) -> f64 {
        (self.squared_error / self.values()).sqrt()
    }
}

fn check_size(what: &str, img: &HdrImage, w: usize, h: usize) -> Result<(), CompareError> {
    if img.width != w || img.height != h {
        return Err(CompareError::ImageSize {
            what: what.to_string(),
            size: (img.width, img.height),
            expected: (w, h),
        });
    }
    Ok(())
}

/// Compares `a` with the reference `b`; `se_a` / `se_b` are optional standard-error images.
pub fn compare_images(
    a: &HdrImage,
    b: &HdrImage,
    se_a: Option<&HdrImage>,
    se_b: Option<&HdrImage>,
) -> Result<Comparison, ImagingError> {
    let (w, h) = (b.width, b.height);
    check_size("image A", a, w, h)?;
    if let Some(s) = se_a {
        check_size("standard-error image of A", s, w, h)?;
    }
    if let Some(s) = se_b {
        check_size("standard-error image of B", s, w, h)?;
    }
    let mut sums = ErrorSums::default();
    let se_at = |s: Option<&HdrImage>, i: usize| s.map_or([0.0; 3], |s| s.pixels[i]);
    for i in 0..w * h {
        if a.valid[i] && b.valid[i] {
            sums.add(a.pixels[i], b.pixels[i], se_at(se_a, i), se_at(se_b, i));
        }
    }
    if sums.pixels == 0 {
        return Err(CompareError::NoCommonPixels.into());
    }
    let m = sums.values();
    let rmse = sums.rmse();
    let (mean_a, mean_b) = (sums.sum_a / m, sums.sum_b / m);
    Ok(Comparison {
        width: w,
        height: h,
        pixels: sums.pixels,
        rmse,
        relative_mean_difference: if mean_b != 0.0 {
            (mean_a - mean_b) / mean_b
        } else {
            f64::NAN
        },
        mean_a,
        mean_b,
        psnr_db: psnr_db(sums.peak_b, rmse),
        noise_rmse: (se_a.is_some() || se_b.is_some()).then(|| (sums.noise / m).sqrt()),
    })
}

/// A false-colour picture of |a - b| (mean over channels), black -> blue -> red -> yellow ->
/// white, scaled so that `max_abs` (or the largest difference when `None`) is white. Returned
/// as linear RGB, ready for `write_png_tonemapped(.., 1.0)`.
pub fn difference_image(
    a: &HdrImage,
    b: &HdrImage,
    max_abs: Option<f32>,
) -> Result<HdrImage, ImagingError> {
    check_size("image A", a, b.width, b.height)?;
    let diffs: Vec<f32> = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .map(|(x, y)| ((x[0] - y[0]).abs() + (x[1] - y[1]).abs() + (x[2] - y[2]).abs()) / 3.0)
        .map(|d| if d.is_finite() { d } else { 0.0 })
        .collect();
    let scale = max_abs.unwrap_or_else(|| diffs.iter().cloned().fold(0.0, f32::max));
    let mut out = HdrImage::new(b.width, b.height);
    const STOPS: [[f32; 3]; 5] = [
        [0.0, 0.0, 0.0],
        [0.1, 0.1, 0.9],
        [0.9, 0.1, 0.1],
        [1.0, 0.9, 0.1],
        [1.0, 1.0, 1.0],
    ];
    for (i, d) in diffs.iter().enumerate() {
        let t = if scale > 0.0 {
            (d / scale).clamp(0.0, 1.0)
        } else {
            0.0
        } * 4.0;
        let k = (t.floor() as usize).min(3);
        let f = t - k as f32;
        let srgb: [f32; 3] = std::array::from_fn(|c| STOPS[k][c] * (1.0 - f) + STOPS[k + 1][c] * f);
        out.pixels[i] = srgb.map(crate::io::srgb_to_linear);
    }
    Ok(out)
}

/// Comparison of an image against a reference over a pixel mask (defined here, beside the
/// sums it uses, so the image type does not depend on the metrics).
impl HdrImage {
    /// PSNR in dB of `self` against `reference` over the pixels where `inside` is true (every
    /// channel counted), with `peak` the reference's white: `None` when no pixel is inside or
    /// the sizes differ, infinite when the two agree exactly there (this module's sums).
    pub fn psnr_inside(&self, reference: &HdrImage, inside: &[bool], peak: f64) -> Option<f64> {
        if (self.width, self.height) != (reference.width, reference.height)
            || inside.len() != self.pixels.len()
        {
            return None;
        }
        let mut sums = ErrorSums::default();
        for (i, _) in inside.iter().enumerate().filter(|(_, &m)| m) {
            sums.add(self.pixels[i], reference.pixels[i], [0.0; 3], [0.0; 3]);
        }
        (sums.pixels > 0).then(|| psnr_db(peak, sums.rmse()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn img(w: usize, h: usize, f: impl Fn(usize) -> [f32; 3]) -> HdrImage {
        let mut m = HdrImage::new(w, h);
        for i in 0..w * h {
            m.pixels[i] = f(i);
        }
        m
    }

    #[test]
    fn metrics_on_known_images() {
        let b = img(4, 2, |i| [i as f32, i as f32, i as f32]); // max 7, mean 3.5
        let a = img(4, 2, |i| [i as f32 + 0.5, i as f32 - 0.5, i as f32 + 0.5]);
        let c = compare_images(&a, &b, None, None).unwrap();
        assert!((c.rmse - 0.5).abs() < 1e-12);
        assert!((c.mean_b - 3.5).abs() < 1e-12);
        assert!((c.relative_mean_difference - (0.5 / 3.0) / 3.5).abs() < 1e-12);
        assert!((c.psnr_db - 20.0 * (7.0f64 / 0.5).log10()).abs() < 1e-9);
        assert_eq!(c.noise_rmse, None);
        let se = img(4, 2, |_| [0.3, 0.3, 0.3]);
        let c = compare_images(&a, &b, Some(&se), Some(&se)).unwrap();
        assert!((c.noise_rmse.unwrap() - (0.18f64).sqrt()).abs() < 1e-6);
        let same = compare_images(&b, &b, None, None).unwrap();
        assert_eq!(same.rmse, 0.0);
        assert!(same.psnr_db.is_infinite());
        // Invalid pixels are skipped.
        let mut a2 = a.clone();
        a2.pixels[0] = [100.0; 3];
        a2.valid[0] = false;
        let c2 = compare_images(&a2, &b, None, None).unwrap();
        assert_eq!(c2.pixels, 7);
        assert!((c2.rmse - 0.5).abs() < 1e-12);
        let small = img(2, 2, |_| [0.0; 3]);
        assert!(compare_images(&small, &b, None, None)
            .unwrap_err()
            .to_string()
            .contains("2 x 2"));
    }

    #[test]
    fn difference_image_maps_zero_to_black_and_max_to_white() {
        let b = img(3, 1, |_| [1.0; 3]);
        let a = img(3, 1, |i| [1.0 + i as f32; 3]);
        let d = difference_image(&a, &b, None).unwrap();
        assert_eq!(d.pixels[0], [0.0; 3]);
        assert!(d.pixels[2].iter().all(|&c| (c - 1.0).abs() < 1e-5));
        assert!(d.pixels[1].iter().all(|c| c.is_finite()));
    }
}

/// What `igi compare` compares: image `a` against the reference `b`, each an image file (an
/// RGBA EXR's pixels of alpha 0 are not compared), with optional standard-error images, a mask
/// from another render's coverage and a difference picture to write.
#[derive(Clone, Debug, Default)]
pub struct CompareRequest {
    pub a: std::path::PathBuf,
    pub b: std::path::PathBuf,
    /// Compare only the pixels this RGBA EXR covers (alpha > 0).
    pub within: Option<std::path::PathBuf>,
    /// Per-pixel standard error of `a` (to report the RMSE that noise explains).
    pub stderr_a: Option<std::path::PathBuf>,
    /// Per-pixel standard error of `b`.
    pub stderr_b: Option<std::path::PathBuf>,
    /// A false-colour picture of |a - b| to write (PNG).
    pub diff: Option<std::path::PathBuf>,
}

/// `igi compare`: reads the images of `req` (masking uncovered pixels), compares them and
/// writes the difference picture when asked.
pub fn compare_files(req: &CompareRequest) -> Result<Comparison, ImagingError> {
    if let Some(d) = &req.diff {
        // the difference picture is a PNG: another extension would name the wrong format
        igi_files::check_output_extension(d, &["png"])?;
        igi_files::check_output_file(d)?;
    }
    // the sizes from the headers, before either image is decoded
    let a_size = crate::io::image_size(&req.a).map_err(|e| CompareError::read(&req.a, e))?;
    let b_size = crate::io::image_size(&req.b).map_err(|e| CompareError::read(&req.b, e))?;
    if a_size != b_size {
        return Err(CompareError::FileSizes(Box::new(crate::error::FileSizes {
            a: req.a.clone(),
            a_size,
            b: req.b.clone(),
            b_size,
        }))
        .into());
    }
    let mut a = read_covered(&req.a)?;
    let b = read_covered(&req.b)?;
    if let Some(w) = &req.within {
        keep_within(&mut a, w, &req.a)?;
    }
    let sa = req.stderr_a.as_deref().map(read_named).transpose()?;
    let sb = req.stderr_b.as_deref().map(read_named).transpose()?;
    let c =
        compare_images(&a, &b, sa.as_ref(), sb.as_ref()).map_err(|e| CompareError::Comparing {
            a: req.a.clone(),
            b: req.b.clone(),
            source: Box::new(e),
        })?;
    if c.mean_b == 0.0 {
        return Err(CompareError::ZeroReference {
            path: req.b.clone(),
        }
        .into());
    }
    if let Some(d) = &req.diff {
        let img = difference_image(&a, &b, None)?;
        crate::write_png_tonemapped(d, &img, 1.0)?;
    }
    Ok(c)
}

/// The image at `path`, a failure naming it as being read.
fn read_named(path: &std::path::Path) -> Result<HdrImage, ImagingError> {
    crate::read_image(path).map_err(|e| CompareError::read(path, e).into())
}

/// An image whose pixels of alpha 0 (an RGBA EXR's uncovered pixels, e.g. `igi slf render`'s
/// background) are invalid, so that they are not compared.
fn read_covered(path: &std::path::Path) -> Result<HdrImage, ImagingError> {
    let mut img = read_named(path)?;
    let is_exr = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("exr"));
    if is_exr {
        if let Some(alpha) = crate::read_exr_alpha(path)? {
            for (v, a) in img.valid.iter_mut().zip(alpha) {
                *v &= a > 0.0;
            }
        }
    }
    Ok(img)
}

/// Keeps valid only the pixels of `img` (read from `img_path`) that the RGBA EXR `within`
/// covers.
fn keep_within(
    img: &mut HdrImage,
    within: &std::path::Path,
    img_path: &std::path::Path,
) -> Result<(), ImagingError> {
    let alpha = crate::read_exr_alpha(within)
        .map_err(|e| CompareError::read(within, e))?
        .ok_or_else(|| CompareError::NoAlpha {
            path: within.to_path_buf(),
        })?;
    if alpha.len() != img.valid.len() {
        return Err(CompareError::WithinSize {
            within: within.to_path_buf(),
            within_pixels: alpha.len(),
            image: img_path.to_path_buf(),
            image_pixels: img.valid.len(),
        }
        .into());
    }
    for (v, al) in img.valid.iter_mut().zip(alpha) {
        *v &= al > 0.0;
    }
    Ok(())
}
