//! The sun's spot on the black (or mirror) sphere to sub-pixel precision.
//!
//! The 0.53 degree sun reflects into a spot `0.0046 r` pixels across on a sphere of `r` pixels:
//! far under a pixel on a board photograph. Its sub-pixel position survives only in how the lens
//! spread it over neighbouring pixels before they integrated it over their area. The
//! intensity-weighted centroid of such pixels is off by up to about `exp(-2 pi^2 s^2) / pi` px
//! for a Gaussian lens blur of `s` px (0.002 px at 0.5, 0.09 px at 0.25; docs/PROBE.md), which
//! on a 40 px sphere is 0.26 degrees of sun direction at `s` = 0.25. [`fit_spot`] fits the spot as
//! what it is: the sun disk's reflection (its shape in pixels given, from the sphere's geometry)
//! blurred by a Gaussian lens of unknown width and integrated over square pixels
//! ([`pixel_response`] in each axis), on a constant background; that has no such bias when the
//! lens is Gaussian, and a disk a pixel or more across is modelled as a disk.

use glam::DVec2;
use nalgebra::{DMatrix, DVector};

/// Fraction of a point's light at offset `d` (pixels, along one axis) from a pixel's centre that
/// the pixel collects: the pixel's box convolved with a Gaussian lens blur of `sigma` px.
pub fn pixel_response(d: f64, sigma: f64) -> f64 {
    if sigma <= 0.0 {
        return if d.abs() < 0.5 { 1.0 } else { 0.0 };
    }
    let k = 1.0 / (sigma * std::f64::consts::SQRT_2);
    0.5 * (libm::erf((0.5 - d) * k) - libm::erf((-0.5 - d) * k))
}

/// One pixel around the spot: its centre and value (background already roughly removed).
#[derive(Clone, Copy, Debug)]
pub struct SpotSample {
    pub x: f64,
    pub y: f64,
    pub v: f64,
}

/// Intensity-weighted centroid of the positive values.
pub fn centroid(samples: &[SpotSample]) -> Option<DVec2> {
    let (mut sw, mut sx, mut sy) = (0.0, 0.0, 0.0);
    for s in samples {
        let w = s.v.max(0.0);
        sw += w;
        sx += w * s.x;
        sy += w * s.y;
    }
    (sw > 0.0).then(|| DVec2::new(sx / sw, sy / sw))
}

/// The least spread (pixels, standard deviation per axis of the fitted spot: lens blur and disk
/// together) for which [`fit_spot`] answers: a spot confined to a pixel tells nothing of where
/// inside it it lies, and the fit's centre then wanders (the centroid is kept).
pub const MIN_SPOT_SPREAD_PX: f64 = 0.2;

/// The fitted spot.
#[derive(Clone, Copy, Debug)]
pub struct SpotFit {
    pub center: DVec2,
    /// Blur of the fitted Gaussian (pixels).
    pub sigma: f64,
    /// Total light of the spot and the background level.
    pub flux: f64,
    pub background: f64,
}

/// Parameters: cx, cy, ln sigma, flux, background; `shape`: the disk's points (offsets from its
/// centre, pixels, equal shares of the light).
fn model(p: &[f64; 5], shape: &[DVec2], s: &SpotSample) -> f64 {
    let sigma = p[2].exp();
    let sum: f64 = shape
        .iter()
        .map(|o| pixel_response(s.x - p[0] - o.x, sigma) * pixel_response(s.y - p[1] - o.y, sigma))
        .sum();
    p[4] + p[3] * sum / shape.len() as f64
}

/// Least-squares fit of `background + flux (disk * Gaussian * pixel box)` to the samples: the
/// disk given by `shape` (points sampling it evenly, offsets in pixels from its centre; `[0, 0]`
/// alone for a point), the Gaussian's width, the centre, flux and background free; from the
/// centroid `start`, by Gauss-Newton with Levenberg damping. `None` when it does not converge,
/// the centre leaves 1 px of the start, the blur leaves [0.02, 4] px or the spot's spread is
/// under [`MIN_SPOT_SPREAD_PX`] (the caller keeps the centroid).
pub fn fit_spot(samples: &[SpotSample], start: DVec2, shape: &[DVec2]) -> Option<SpotFit> {
    if samples.len() < 9 || shape.is_empty() {
        return None;
    }
    let model = |p: &[f64; 5], s: &SpotSample| model(p, shape, s);
    let flux0: f64 = samples.iter().map(|s| s.v.max(0.0)).sum();
    let mut p = [start.x, start.y, 0.5f64.ln(), flux0, 0.0];
    let cost = |p: &[f64; 5]| -> f64 { samples.iter().map(|s| (model(p, s) - s.v).powi(2)).sum() };
    let mut c = cost(&p);
    let mut lambda = 1e-3;
    let mut converged = false;
    for _ in 0..100 {
        let n = samples.len();
        let (mut jac, mut r) = (DMatrix::<f64>::zeros(n, 5), DVector::<f64>::zeros(n));
        for (i, s) in samples.iter().enumerate() {
            let m0 = model(&p, s);
            r[i] = s.v - m0;
            for k in 0..5 {
                let h = 1e-6 * p[k].abs().max(1e-3);
                let mut q = p;
                q[k] += h;
                jac[(i, k)] = (model(&q, s) - m0) / h;
            }
        }
        let jtj = jac.transpose() * &jac;
        let jtr = jac.transpose() * r;
        let mut a = jtj.clone();
        for k in 0..5 {
            a[(k, k)] += lambda * jtj[(k, k)].max(1e-12);
        }
        let step = a.lu().solve(&jtr)?;
        let mut q = p;
        for k in 0..5 {
            q[k] += step[k];
        }
        let cq = cost(&q);
        if cq.is_finite() && cq <= c {
            let small =
                (0..5).all(|k| step[k].abs() <= 1e-10 * (1.0 + p[k].abs())) || c - cq <= 1e-15 * c;
            p = q;
            c = cq;
            lambda = (lambda * 0.3).max(1e-9);
            if small {
                converged = true;
                break;
            }
        } else {
            lambda *= 10.0;
            if lambda > 1e8 {
                converged = true;
                break;
            }
        }
    }
    let center = DVec2::new(p[0], p[1]);
    let sigma = p[2].exp();
    let disk_var =
        shape.iter().map(|o| o.length_squared()).sum::<f64>() / (2.0 * shape.len() as f64);
    let ok = converged
        && (sigma * sigma + disk_var).sqrt() >= MIN_SPOT_SPREAD_PX
        && center.distance(start) <= 1.0
        && (0.02..=4.0).contains(&sigma)
        && p[3] > 0.0
        && center.is_finite();
    ok.then_some(SpotFit {
        center,
        sigma,
        flux: p[3],
        background: p[4],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A point of light blurred by a Gaussian of `sigma` and integrated over the pixels, around
    /// sub-pixel position `c`.
    fn spot(c: DVec2, sigma: f64) -> Vec<SpotSample> {
        let (cx, cy) = (c.x.round() as i64, c.y.round() as i64);
        let mut v = Vec::new();
        for y in cy - 4..=cy + 4 {
            for x in cx - 4..=cx + 4 {
                let (xf, yf) = (x as f64, y as f64);
                let val = 0.2
                    + 1000.0 * pixel_response(xf - c.x, sigma) * pixel_response(yf - c.y, sigma);
                v.push(SpotSample {
                    x: xf,
                    y: yf,
                    v: val - 0.2,
                });
            }
        }
        v
    }

    #[test]
    fn pixel_response_sums_to_one_and_tends_to_the_box() {
        for d in [0.0, 0.13, 0.5, 0.77] {
            let s: f64 = (-10..=10).map(|k| pixel_response(k as f64 - d, 0.4)).sum();
            assert!((s - 1.0).abs() < 1e-9, "{s}");
        }
        assert!((pixel_response(0.3, 1e-4) - 1.0).abs() < 1e-9);
        assert!(pixel_response(0.7, 1e-4).abs() < 1e-9);
        assert_eq!(pixel_response(0.7, 0.0), 0.0);
    }

    /// With a sharp lens (0.25 px) the centroid is off by up to a tenth of a pixel; the fit is
    /// not, over sub-pixel positions across a pixel.
    #[test]
    fn fit_removes_the_centroid_bias_of_a_sharp_spot() {
        let (mut worst_c, mut worst_f): (f64, f64) = (0.0, 0.0);
        for i in 0..10 {
            let c = DVec2::new(20.0 + 0.1 * i as f64, 30.0 + 0.037 * i as f64);
            let s = spot(c, 0.25);
            let cen = centroid(&s).unwrap();
            let fit = fit_spot(&s, cen, &[DVec2::ZERO]).expect("fit");
            worst_c = worst_c.max(cen.distance(c));
            worst_f = worst_f.max(fit.center.distance(c));
            assert!((fit.sigma - 0.25).abs() < 0.01, "{fit:?} {c}");
        }
        assert!(worst_c > 0.05, "centroid {worst_c}");
        assert!(worst_f < 1e-3, "fit {worst_f}");
    }

    /// A point spot with (almost) no blur sits in one pixel: the fit declines.
    #[test]
    fn fit_declines_a_spot_confined_to_a_pixel() {
        let c = DVec2::new(20.3, 30.2);
        let s = spot(c, 0.05);
        assert!(fit_spot(&s, centroid(&s).unwrap(), &[DVec2::ZERO]).is_none());
    }

    #[test]
    fn fit_refuses_a_flat_window() {
        let s: Vec<SpotSample> = (0..81)
            .map(|i| SpotSample {
                x: (i % 9) as f64,
                y: (i / 9) as f64,
                v: 0.0,
            })
            .collect();
        assert!(fit_spot(&s, DVec2::new(4.0, 4.0), &[DVec2::ZERO]).is_none());
    }
}
