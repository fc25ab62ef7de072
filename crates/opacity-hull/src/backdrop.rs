//! The multi-background matting patterns (Matusik et al. 2002, Eq. 1) and alpha from a pattern
//! pair (Eq. 2).
//!
//! Eq. 1: `C_i(x, y, n) = (1 + n sin(2 pi (x + y) / lambda + i pi / 3)) * 127` for channel
//! `i = 0, 1, 2`, `n = +1, -1`, `lambda = 27, 40, 53` (pixels of the backdrop display).
//!
//! Eq. 2: with `R_n` the backdrop alone and `O_n` the object in front of it,
//! `alpha = 1 - sum_i (O_n - O_-n)(R_n - R_-n) / sum_i (R_n - R_-n)^2`. Where the backdrop
//! pair differs by less than a noise level in every channel the ratio is undefined and the
//! pixel is **invalid** (not opaque). The matte of a view is the maximum over its lambdas of
//! the valid alphas.

use crate::HullError;
use igi_imaging::{HdrImage, ImagingError};
use std::path::{Path, PathBuf};

/// The wavelengths of the paper, in display pixels.
pub const LAMBDAS: [f64; 3] = [27.0, 40.0, 53.0];

/// Eq. 1 value of channel `i` at display pixel (x, y), in 8-bit units (0..254).
pub fn pattern_value(x: f64, y: f64, i: usize, lambda: f64, n: i32) -> f64 {
    let phase =
        2.0 * std::f64::consts::PI * (x + y) / lambda + i as f64 * std::f64::consts::PI / 3.0;
    (1.0 + n as f64 * phase.sin()) * 127.0
}

/// The Eq. 1 pattern as a linear image with values `C / 255` in [0, 1].
pub fn pattern_image(width: usize, height: usize, lambda: f64, n: i32) -> HdrImage {
    let mut img = HdrImage::new(width, height);
    for y in 0..height {
        for x in 0..width {
            let v =
                [0, 1, 2].map(|i| (pattern_value(x as f64, y as f64, i, lambda, n) / 255.0) as f32);
            img.set(x, y, v);
        }
    }
    img
}

/// File name of the pattern for (lambda, n), e.g. `backdrop-l27-p.png`.
pub fn pattern_file_name(lambda: f64, n: i32) -> String {
    format!("backdrop-l{}-{}.png", lambda, if n > 0 { "p" } else { "m" })
}

/// Write the six patterns (three lambdas, n = +-1) as 8-bit RGB PNGs holding the Eq. 1 values
/// rounded to integers (what a monitor is sent), atomically, into `dir` (created after the size
/// is checked). Returns the paths written.
pub fn write_patterns(dir: &Path, width: usize, height: usize) -> Result<Vec<PathBuf>, HullError> {
    if width == 0 || height == 0 || width > 1 << 15 || height > 1 << 15 {
        return Err(HullError::BackdropSize { width, height });
    }
    // one pattern at a time: its 8-bit RGB pixels and the PNG encoder's zlib stream, which it
    // holds whole (as large as the pixels when they do not compress)
    igi_files::check_alloc_default(
        &format!("a backdrop pattern (--width {width} --height {height})"),
        width as u128 * height as u128 * 6,
    )?;
    igi_files::check_output_folder(dir)?;
    std::fs::create_dir_all(dir).map_err(|e| HullError::io(dir, e))?;
    // the temporary files of an earlier run that was killed mid-write
    igi_files::remove_dead_temps(dir, false)?;
    let mut out = Vec::new();
    for lambda in LAMBDAS {
        for n in [1, -1] {
            let path = dir.join(pattern_file_name(lambda, n));
            let mut bytes = Vec::with_capacity(width * height * 3);
            for y in 0..height {
                for x in 0..width {
                    for i in 0..3 {
                        bytes.push(pattern_value(x as f64, y as f64, i, lambda, n).round() as u8);
                    }
                }
            }
            let img = image::RgbImage::from_raw(width as u32, height as u32, bytes)
                .expect("size matches");
            igi_files::write_atomic(&path, |tmp| {
                img.save_with_format(tmp, image::ImageFormat::Png)
                    .map_err(|e| ImagingError::Encode {
                        path: path.clone(),
                        msg: e.to_string(),
                    })
            })?;
            out.push(path);
        }
    }
    Ok(out)
}

/// An alpha matte: opacity in [0, 1] per pixel and whether it could be measured.
#[derive(Clone, Debug, PartialEq)]
pub struct Matte {
    pub width: usize,
    pub height: usize,
    pub alpha: Vec<f32>,
    pub valid: Vec<bool>,
}

impl Matte {
    /// A matte with every pixel invalid.
    pub fn invalid(width: usize, height: usize) -> Matte {
        Matte {
            width,
            height,
            alpha: vec![0.0; width * height],
            valid: vec![false; width * height],
        }
    }

    /// Per pixel, the larger valid alpha of the two (Matusik: the maximum over lambdas).
    pub fn max_with(&mut self, other: &Matte) {
        for i in 0..self.alpha.len() {
            if other.valid[i] && (!self.valid[i] || other.alpha[i] > self.alpha[i]) {
                self.alpha[i] = other.alpha[i];
                self.valid[i] = true;
            }
        }
    }

    /// As an image: alpha in every channel, the validity as the image's mask.
    pub fn to_image(&self) -> HdrImage {
        HdrImage {
            width: self.width,
            height: self.height,
            pixels: self.alpha.iter().map(|&a| [a; 3]).collect(),
            valid: self.valid.clone(),
        }
    }

    /// From an image written by [`Matte::to_image`] (first channel, mask kept).
    pub fn from_image(img: &HdrImage) -> Matte {
        Matte {
            width: img.width,
            height: img.height,
            alpha: img.pixels.iter().map(|p| p[0]).collect(),
            valid: img.valid.clone(),
        }
    }
}

/// Eq. 2 for one lambda. `min_signal` is the smallest backdrop difference `|R_n - R_-n|`
/// (root of the sum over channels of squares) that counts as signal. Alpha is clamped to [0, 1].
pub fn alpha_from_pair(
    o_pos: &HdrImage,
    o_neg: &HdrImage,
    r_pos: &HdrImage,
    r_neg: &HdrImage,
    min_signal: f32,
) -> Matte {
    let (w, h) = (r_pos.width, r_pos.height);
    let mut m = Matte::invalid(w, h);
    for i in 0..w * h {
        if !(o_pos.valid[i] && o_neg.valid[i] && r_pos.valid[i] && r_neg.valid[i]) {
            continue;
        }
        let (mut num, mut den) = (0.0f64, 0.0f64);
        for c in 0..3 {
            let dr = (r_pos.pixels[i][c] - r_neg.pixels[i][c]) as f64;
            let d_o = (o_pos.pixels[i][c] - o_neg.pixels[i][c]) as f64;
            num += d_o * dr;
            den += dr * dr;
        }
        if den.sqrt() < min_signal as f64 {
            continue;
        }
        m.alpha[i] = (1.0 - num / den).clamp(0.0, 1.0) as f32;
        m.valid[i] = true;
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eq1_values_and_the_pairs_signal() {
        // at x + y = 0: sin(i pi / 3) for i = 0, 1, 2
        assert_eq!(pattern_value(0.0, 0.0, 0, 27.0, 1), 127.0);
        assert!(
            (pattern_value(0.0, 0.0, 1, 27.0, 1) - 127.0 * (1.0 + (3f64).sqrt() / 2.0)).abs()
                < 1e-9
        );
        assert!(
            (pattern_value(3.0, 4.0, 2, 40.0, -1) + pattern_value(3.0, 4.0, 2, 40.0, 1) - 254.0)
                .abs()
                < 1e-9
        );
        // sum over channels of (C_n - C_-n)^2 is constant: 3/2 * (2 * 127)^2 everywhere
        for (x, y) in [(0.0, 0.0), (5.0, 9.0), (13.5, 0.25)] {
            let s: f64 = (0..3)
                .map(|i| {
                    (pattern_value(x, y, i, 53.0, 1) - pattern_value(x, y, i, 53.0, -1)).powi(2)
                })
                .sum();
            assert!((s - 1.5 * 254.0f64.powi(2)).abs() < 1e-6, "{s}");
        }
    }

    #[test]
    fn analytic_composites_recover_alpha() {
        let (w, h) = (40, 3);
        let fg = [0.3f32, 0.6, 0.1];
        let obj = |n: i32| {
            let r = pattern_image(w, h, 27.0, n);
            let mut o = r.clone();
            for y in 0..h {
                for x in 0..w {
                    let a = x as f32 / (w - 1) as f32;
                    let b = r.get(x, y);
                    o.set(x, y, [0, 1, 2].map(|c| a * fg[c] * 0.7 + (1.0 - a) * b[c]));
                }
            }
            (r, o)
        };
        let ((rp, op), (rn, on)) = (obj(1), obj(-1));
        let m = alpha_from_pair(&op, &on, &rp, &rn, 0.01);
        for x in 0..w {
            let a = m.alpha[x];
            assert!(
                m.valid[x] && (a - x as f32 / (w - 1) as f32).abs() < 1e-5,
                "{x}: {a}"
            );
        }
        // no signal in the pair: invalid, not opaque
        let flat = HdrImage::new(w, h);
        let m = alpha_from_pair(&flat, &flat, &flat, &flat, 0.01);
        assert!(m.valid.iter().all(|v| !v));
    }
}
