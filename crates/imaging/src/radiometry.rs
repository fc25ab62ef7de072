//! Radiometric calibration helpers: lens falloff (vignetting) and 3x3 colour matrices.

use crate::{HdrImage, ImagingError};
use nalgebra::{DMatrix, DVector, Matrix3};

/// Radial falloff `f(r) = 1 + a2 r^2 + a4 r^4 + a6 r^6`, `r` = distance from the image
/// centre divided by the half-diagonal (so r = 1 at the corners), f(0) = 1.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Falloff {
    pub a2: f64,
    pub a4: f64,
    pub a6: f64,
}

impl Falloff {
    pub fn eval(&self, r: f64) -> f64 {
        let r2 = r * r;
        1.0 + r2 * (self.a2 + r2 * (self.a4 + r2 * self.a6))
    }

    /// Normalised radius of pixel (x, y) (pixel centres at integers) in a `w` x `h` image.
    pub fn radius(x: f64, y: f64, w: usize, h: usize) -> f64 {
        let cx = (w as f64 - 1.0) * 0.5;
        let cy = (h as f64 - 1.0) * 0.5;
        let half_diag = 0.5 * ((w * w + h * h) as f64).sqrt();
        ((x - cx).powi(2) + (y - cy).powi(2)).sqrt() / half_diag
    }

    /// Least-squares fit of `value = s f(r)` (centre value `s` free) to `(r, value)` samples.
    /// Returns the falloff and `s`.
    pub fn fit(samples: &[(f64, f64)]) -> Result<(Falloff, f64), ImagingError> {
        if samples.len() < 4 {
            return Err(ImagingError::InvalidInput(format!(
                "falloff fit needs at least 4 samples, got {}",
                samples.len()
            )));
        }
        if samples
            .iter()
            .any(|(r, v)| !r.is_finite() || !v.is_finite())
        {
            return Err(ImagingError::InvalidInput(
                "falloff samples contain NaN or infinite values".into(),
            ));
        }
        let mut a = DMatrix::<f64>::zeros(samples.len(), 4);
        let mut b = DVector::<f64>::zeros(samples.len());
        for (i, &(r, v)) in samples.iter().enumerate() {
            let r2 = r * r;
            a[(i, 0)] = 1.0;
            a[(i, 1)] = r2;
            a[(i, 2)] = r2 * r2;
            a[(i, 3)] = r2 * r2 * r2;
            b[i] = v;
        }
        let x = a.svd(true, true).solve(&b, 1e-12).map_err(|e| {
            ImagingError::InvalidInput(format!("falloff least squares failed: {e}"))
        })?;
        let s = x[0];
        if !(s.abs() > 0.0) || !s.is_finite() {
            return Err(ImagingError::InvalidInput(
                "falloff fit: centre value is zero (flat field too dark?)".into(),
            ));
        }
        Ok((
            Falloff {
                a2: x[1] / s,
                a4: x[2] / s,
                a6: x[3] / s,
            },
            s,
        ))
    }

    /// Fit to a flat-field image (mean of the three channels of every valid pixel).
    pub fn fit_image(flat: &HdrImage) -> Result<(Falloff, f64), ImagingError> {
        let mut samples = Vec::with_capacity(flat.pixels.len());
        for y in 0..flat.height {
            for x in 0..flat.width {
                if flat.is_valid(x, y) {
                    let p = flat.get(x, y);
                    samples.push((
                        Self::radius(x as f64, y as f64, flat.width, flat.height),
                        (p[0] as f64 + p[1] as f64 + p[2] as f64) / 3.0,
                    ));
                }
            }
        }
        Self::fit(&samples)
    }

    /// Divide the falloff out of `img` in place (pixels where f(r) <= 0 become invalid).
    pub fn apply(&self, img: &mut HdrImage) {
        for y in 0..img.height {
            for x in 0..img.width {
                let f = self.eval(Self::radius(x as f64, y as f64, img.width, img.height));
                let i = img.index(x, y);
                if f > 1e-6 {
                    for c in 0..3 {
                        img.pixels[i][c] = (img.pixels[i][c] as f64 / f) as f32;
                    }
                } else {
                    img.pixels[i] = [0.0; 3];
                    img.valid[i] = false;
                }
            }
        }
    }
}

/// Least-squares 3x3 colour matrix `M` with `target ~= M * source` (e.g. camera RGB of
/// colour-checker patches -> their reference linear RGB). Needs at least 3 pairs spanning
/// colour space.
pub fn fit_color_matrix(
    source: &[[f64; 3]],
    target: &[[f64; 3]],
) -> Result<[[f64; 3]; 3], ImagingError> {
    if source.len() != target.len() {
        return Err(ImagingError::InvalidInput(format!(
            "colour matrix: {} source patches but {} targets",
            source.len(),
            target.len()
        )));
    }
    if source.len() < 3 {
        return Err(ImagingError::InvalidInput(
            "colour matrix needs at least 3 patches".into(),
        ));
    }
    if source
        .iter()
        .chain(target)
        .flatten()
        .any(|v| !v.is_finite())
    {
        return Err(ImagingError::InvalidInput(
            "colour patches contain NaN or infinite values".into(),
        ));
    }
    let n = source.len();
    let a = DMatrix::<f64>::from_fn(n, 3, |i, j| source[i][j]);
    let svd = a.clone().svd(true, true);
    let sv = &svd.singular_values;
    let (smax, smin) = (sv.max(), sv.min());
    if !(smin > smax * 1e-9) {
        return Err(ImagingError::InvalidInput(
            "colour patches are degenerate (do not span RGB)".into(),
        ));
    }
    let mut m = [[0.0; 3]; 3];
    for r in 0..3 {
        let b = DVector::<f64>::from_fn(n, |i, _| target[i][r]);
        let x = svd.solve(&b, 1e-12).map_err(|e| {
            ImagingError::InvalidInput(format!("colour matrix least squares failed: {e}"))
        })?;
        m[r] = [x[0], x[1], x[2]];
    }
    Ok(m)
}

/// Apply a colour matrix to every pixel in place.
pub fn apply_color_matrix(img: &mut HdrImage, m: &[[f64; 3]; 3]) {
    let mm = Matrix3::from_fn(|r, c| m[r][c] as f32);
    for p in &mut img.pixels {
        let v = mm * nalgebra::Vector3::new(p[0], p[1], p[2]);
        *p = [v.x, v.y, v.z];
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn falloff_fit_recovers_known_polynomial() {
        let truth = Falloff {
            a2: -0.35,
            a4: 0.08,
            a6: -0.03,
        };
        let (w, h) = (120, 80);
        let mut flat = HdrImage::new(w, h);
        let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
        for y in 0..h {
            for x in 0..w {
                let f = truth.eval(Falloff::radius(x as f64, y as f64, w, h));
                let v = (0.7 * f * (1.0 + rng.gen_range(-0.002..0.002))) as f32;
                flat.set(x, y, [v, v, v]);
            }
        }
        let (fit, s) = Falloff::fit_image(&flat).unwrap();
        assert!((s - 0.7).abs() < 1e-3, "{s}");
        for r in [0.0, 0.3, 0.6, 0.9, 1.0] {
            assert!(
                (fit.eval(r) - truth.eval(r)).abs() < 2e-3,
                "r={r}: {} vs {}",
                fit.eval(r),
                truth.eval(r)
            );
        }
        assert!((fit.a2 - truth.a2).abs() < 0.02, "{fit:?}");
        // corners: r = 1 exactly at the outer pixel corner; the corner pixel centre is just inside
        assert!(Falloff::radius(0.0, 0.0, w, h) < 1.0 && Falloff::radius(0.0, 0.0, w, h) > 0.98);
        fit.apply(&mut flat);
        for p in &flat.pixels {
            assert!((p[0] / 0.7 - 1.0).abs() < 0.006, "{p:?}");
        }
        assert!(Falloff::fit(&[(0.0, 1.0)]).is_err());
    }

    #[test]
    fn color_matrix_recovered_from_noisy_patches() {
        let m = [[1.6, -0.4, -0.2], [-0.3, 1.5, -0.2], [0.05, -0.5, 1.45]];
        let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
        let mut src = Vec::new();
        let mut dst = Vec::new();
        for _ in 0..24 {
            let s = [
                rng.gen_range(0.02..0.9),
                rng.gen_range(0.02..0.9),
                rng.gen_range(0.02..0.9),
            ];
            let mut t = [0.0; 3];
            for r in 0..3 {
                t[r] = (0..3).map(|c| m[r][c] * s[c]).sum::<f64>()
                    * (1.0 + rng.gen_range(-0.005..0.005));
            }
            src.push(s);
            dst.push(t);
        }
        let fit = fit_color_matrix(&src, &dst).unwrap();
        for r in 0..3 {
            for c in 0..3 {
                assert!((fit[r][c] - m[r][c]).abs() < 0.02, "{fit:?}");
            }
        }
        let mut img = HdrImage::new(1, 1);
        img.pixels[0] = [1.0, 0.0, 0.0];
        apply_color_matrix(&mut img, &m);
        assert!((img.pixels[0][0] - 1.6).abs() < 1e-6 && (img.pixels[0][2] - 0.05).abs() < 1e-6);
        // degenerate: all grey patches
        let grey: Vec<[f64; 3]> = (1..6).map(|i| [i as f64 * 0.1; 3]).collect();
        assert!(fit_color_matrix(&grey, &grey).is_err());
        assert!(fit_color_matrix(&src[..2], &dst[..2]).is_err());
    }
}
