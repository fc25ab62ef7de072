//! The isotropic Lafortune BRDF with a Lambertian term: evaluation, importance sampling, albedo.
//!
//! In the local shading frame (z = normal):
//!
//! ```text
//! f(u, v) = rho_d / pi + sum_l rho_l * max(0, Cxy_l (ux vx + uy vy) + Cz_l uz vz) ^ N_l
//! ```
//!
//! A lobe term can be rewritten, for a fixed `wo`, as `rho |c(wo)|^N cos^N(wi, s)` with
//! `c(wo) = (Cxy wo.x, Cxy wo.y, Cz wo.z)` and the lobe axis `s = c / |c|`. Sampling therefore
//! draws a cosine-power lobe of exponent `N` around `s` (pdf `(N+1)/(2 pi) cos^N` on the sphere),
//! the diffuse term is cosine-weighted, and the strategies are mixed with weights proportional to
//! an estimate of each component's albedo (luminance). The pdf of a direction is the mixture pdf,
//! so multiple importance sampling works.
//!
//! Energy: a Lafortune lobe is not normalised. With `|C| > 1` or a large `rho` its directional
//! albedo can exceed 1 (`|c(wo)|^N` grows without bound with N). Use [`Lafortune::max_albedo`] and
//! [`Lafortune::is_energy_conserving`] to check a material.

use glam::{Vec2, Vec3};
use rand::{Rng, SeedableRng};
use serde::{Deserialize, Serialize};

use crate::frame::Frame;

const INV_PI: f32 = std::f32::consts::FRAC_1_PI;
const TWO_PI: f32 = std::f32::consts::TAU;
/// Largest `ln` of a lobe's power term before clamping (e^80 ~ 5.5e34, finite in f32 even times rho ~ 1e3).
const MAX_LOG_POWER: f32 = 80.0;

/// Rec. 709 luminance, used to weigh sampling strategies.
#[inline]
pub fn luminance(c: Vec3) -> f32 {
    igi_imaging::color::luminance(c.to_array())
}

/// One Lafortune lobe: colour `rho`, coefficients `cxy`, `cz` and exponent `n`.
/// Specular: `cxy < 0 < cz`; retroreflective: `cxy > 0`, `cz > 0`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Lobe {
    pub rho: Vec3,
    pub cxy: f32,
    pub cz: f32,
    pub n: f32,
}

/// A Lafortune BRDF that owns its lobes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Lafortune {
    pub rho_d: Vec3,
    pub lobes: Vec<Lobe>,
}

/// A borrowed Lafortune BRDF: a per-texel `rho_d` with shared lobes, no allocation.
#[derive(Clone, Copy, Debug)]
pub struct LafortuneRef<'a> {
    pub rho_d: Vec3,
    pub lobes: &'a [Lobe],
}

/// A sampled incident direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfSample {
    /// Sampled direction (local frame, unit, `wi.z > 0`).
    pub wi: Vec3,
    /// `f(wi, wo)`, NOT multiplied by the cosine.
    pub value: Vec3,
    /// Solid-angle pdf of `wi` under the mixture (the same as [`LafortuneRef::pdf`]).
    pub pdf: f32,
}

impl Lobe {
    /// Whether the parameters can be a lobe: finite, non-negative colour, finite coefficients
    /// and a finite, non-negative exponent (the rule of the materials file,
    /// [`igi_formats::materials::Lobe::is_valid`]).
    pub fn is_valid(&self) -> bool {
        igi_formats::materials::Lobe {
            rho: self.rho,
            cxy: self.cxy,
            cz: self.cz,
            n: self.n,
        }
        .is_valid()
    }

    /// The lobe term `rho * max(0, Cxy (wi.x wo.x + wi.y wo.y) + Cz wi.z wo.z)^N`, finite for any input.
    #[inline]
    pub fn eval(&self, wi: Vec3, wo: Vec3) -> Vec3 {
        let d = self.cxy * (wi.x * wo.x + wi.y * wo.y) + self.cz * wi.z * wo.z;
        if d.is_nan() || d <= 0.0 {
            return Vec3::ZERO;
        }
        self.rho * pow_clamped(d, self.n)
    }

    /// Lobe axis for `wo` and the length of `c(wo)`; `None` when the lobe is degenerate for `wo`.
    #[inline]
    fn axis(&self, wo: Vec3) -> Option<(Vec3, f32)> {
        let c = Vec3::new(self.cxy * wo.x, self.cxy * wo.y, self.cz * wo.z);
        let len = c.length();
        if !(len > 0.0) || !len.is_finite() || !(self.n >= 0.0) || !self.n.is_finite() {
            return None;
        }
        Some((c / len, len))
    }

    /// `ln` of an albedo estimate of this lobe at `wo` (luminance), `-inf` when it cannot contribute.
    #[inline]
    fn log_weight(&self, wo: Vec3) -> f32 {
        let lum = luminance(self.rho);
        let Some((s, len)) = self.axis(wo) else {
            return f32::NEG_INFINITY;
        };
        if !(lum > 0.0) {
            return f32::NEG_INFINITY;
        }
        let n = self.n;
        // integral of cos^N around s is 2 pi / (N + 1); the cosine factor is about s.z for sharp
        // lobes and about 1/sqrt(N) when the axis lies at the horizon.
        let cos_factor = s.z.max(0.0) + 0.5 / (n + 1.0).sqrt();
        lum.ln() + n * len.ln() + (TWO_PI / (n + 1.0)).ln() + cos_factor.ln()
    }

    /// Solid-angle pdf of the cosine-power strategy around the axis `s`.
    #[inline]
    fn strategy_pdf(&self, s: Vec3, wi: Vec3) -> f32 {
        let c = s.dot(wi);
        if !(c > 0.0) {
            return 0.0;
        }
        (self.n + 1.0) / TWO_PI * pow_clamped(c.min(1.0), self.n)
    }
}

/// `d^n` for `d > 0` computed as `exp(n ln d)` with the exponent clamped (finite for huge n and d > 1).
#[inline]
fn pow_clamped(d: f32, n: f32) -> f32 {
    let l = n * d.ln();
    if l.is_nan() {
        return 0.0;
    }
    l.min(MAX_LOG_POWER).exp()
}

#[inline]
fn finite_dir(v: Vec3) -> bool {
    v.is_finite()
}

/// Replace non-finite components by 0 (NaN) or the largest finite value (+inf).
#[inline]
fn sanitize(v: Vec3) -> Vec3 {
    let f = |x: f32| {
        if x.is_nan() {
            0.0
        } else {
            x.clamp(-f32::MAX, f32::MAX)
        }
    };
    Vec3::new(f(v.x), f(v.y), f(v.z))
}

impl<'a> LafortuneRef<'a> {
    /// `f(wi, wo)` (local frame). Zero when either direction is at or below the horizon.
    pub fn eval(&self, wi: Vec3, wo: Vec3) -> Vec3 {
        if !(wi.z > 0.0 && wo.z > 0.0) || !finite_dir(wi) || !finite_dir(wo) {
            return Vec3::ZERO;
        }
        let mut f = self.rho_d * INV_PI;
        for l in self.lobes {
            f += l.eval(wi, wo);
        }
        sanitize(f)
    }

    /// Normalised mixture weights: index 0 diffuse, 1.. lobes. Calls `k(i, weight, axis)`.
    #[inline]
    fn for_each_strategy(&self, wo: Vec3, mut k: impl FnMut(usize, f32, Option<Vec3>)) {
        let ld = {
            let lum = luminance(self.rho_d);
            if lum > 0.0 {
                lum.ln()
            } else {
                f32::NEG_INFINITY
            }
        };
        let mut max = ld;
        for l in self.lobes {
            max = max.max(l.log_weight(wo));
        }
        if max == f32::NEG_INFINITY || max.is_nan() {
            // Nothing reflects (or nothing can be estimated): cosine sampling alone.
            k(0, 1.0, None);
            return;
        }
        let mut sum = (ld - max).exp();
        for l in self.lobes {
            sum += (l.log_weight(wo) - max).exp();
        }
        k(0, (ld - max).exp() / sum, None);
        for (i, l) in self.lobes.iter().enumerate() {
            let w = (l.log_weight(wo) - max).exp() / sum;
            if w > 0.0 {
                k(i + 1, w, l.axis(wo).map(|a| a.0));
            }
        }
    }

    /// Solid-angle pdf with which [`Self::sample`] draws `wi` given `wo` (arguments in the
    /// order of [`Self::eval`]).
    pub fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        if !(wi.z > 0.0 && wo.z > 0.0) || !finite_dir(wi) || !finite_dir(wo) {
            return 0.0;
        }
        let mut pdf = 0.0;
        self.for_each_strategy(wo, |i, w, axis| {
            if i == 0 {
                pdf += w * wi.z * INV_PI;
            } else if let Some(s) = axis {
                pdf += w * self.lobes[i - 1].strategy_pdf(s, wi);
            }
        });
        if pdf.is_finite() {
            pdf
        } else {
            0.0
        }
    }

    /// Value and pdf in one call (arguments in the order of [`Self::eval`]).
    pub fn eval_pdf(&self, wi: Vec3, wo: Vec3) -> (Vec3, f32) {
        (self.eval(wi, wo), self.pdf(wi, wo))
    }

    /// Sample an incident direction given `wo`: `u_select` picks the strategy, `u` drives it.
    /// `None` when the sample falls below the horizon (that probability mass is missing from the
    /// pdf) or `wo` is at/below the horizon.
    pub fn sample(&self, wo: Vec3, u_select: f32, u: Vec2) -> Option<BsdfSample> {
        if !(wo.z > 0.0) || !finite_dir(wo) {
            return None;
        }
        let mut chosen: Option<(usize, Option<Vec3>)> = None;
        let mut last: Option<(usize, Option<Vec3>)> = None;
        let mut cdf = 0.0f32;
        self.for_each_strategy(wo, |i, w, axis| {
            last = Some((i, axis));
            cdf += w;
            if chosen.is_none() && u_select < cdf {
                chosen = Some((i, axis));
            }
        });
        let (i, axis) = chosen.or(last)?;
        let wi = if i == 0 {
            cosine_hemisphere(u)
        } else {
            let s = axis?;
            let local = cosine_power(u, self.lobes[i - 1].n);
            Frame::from_normal(s).to_world(local).normalize()
        };
        if !(wi.z > 0.0) || !wi.is_finite() {
            return None;
        }
        let pdf = self.pdf(wi, wo);
        if !(pdf > 0.0) {
            return None;
        }
        Some(BsdfSample {
            wi,
            value: self.eval(wi, wo),
            pdf,
        })
    }

    /// Directional albedo `integral f(wi, wo) cos(wi) dwi` by importance sampling (seeded).
    pub fn albedo(&self, wo: Vec3, samples: u32, seed: u64) -> Vec3 {
        if !(wo.z > 0.0) || samples == 0 {
            return Vec3::ZERO;
        }
        let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
        let mut sum = glam::DVec3::ZERO;
        for _ in 0..samples {
            let us: f32 = rng.gen();
            let u = Vec2::new(rng.gen(), rng.gen());
            if let Some(s) = self.sample(wo, us, u) {
                sum += (s.value * s.wi.z / s.pdf).as_dvec3();
            }
        }
        sanitize((sum / samples as f64).as_vec3())
    }
}

/// Cosine-weighted direction on the upper hemisphere.
#[inline]
fn cosine_hemisphere(u: Vec2) -> Vec3 {
    let r = u.x.max(0.0).sqrt();
    let phi = TWO_PI * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u.x).max(0.0).sqrt())
}

/// Direction about +z with pdf `(n+1)/(2 pi) cos^n`, accurate for n up to 1e4 and beyond.
#[inline]
fn cosine_power(u: Vec2, n: f32) -> Vec3 {
    // cos = u^(1/(n+1)); 1 - cos via expm1 to keep sin accurate for sharp lobes.
    let x = u.x.max(f32::MIN_POSITIVE).ln() / (n + 1.0);
    let cos = x.exp();
    let one_minus = -x.exp_m1();
    let sin = (one_minus * (1.0 + cos)).max(0.0).sqrt();
    let phi = TWO_PI * u.y;
    Vec3::new(sin * phi.cos(), sin * phi.sin(), cos)
}

impl Lafortune {
    /// Borrow as the allocation-free evaluator.
    #[allow(clippy::should_implement_trait)]
    pub fn as_ref(&self) -> LafortuneRef<'_> {
        LafortuneRef {
            rho_d: self.rho_d,
            lobes: &self.lobes,
        }
    }

    /// A pure Lambertian material.
    pub fn lambertian(rho_d: Vec3) -> Self {
        Lafortune {
            rho_d,
            lobes: Vec::new(),
        }
    }

    /// Per channel, the largest directional albedo over 32 view elevations from normal to
    /// 88.6 degrees (isotropic model: azimuth is irrelevant), each from 8192 importance samples
    /// with a fixed seed (Monte Carlo error of a few 0.1%).
    pub fn max_albedo(&self) -> Vec3 {
        let mut m = Vec3::ZERO;
        let r = self.as_ref();
        for k in 0..32 {
            let theta = (k as f32 + 0.5) / 32.0 * 0.495 * std::f32::consts::PI;
            let wo = Vec3::new(theta.sin(), 0.0, theta.cos());
            m = m.max(r.albedo(wo, 8192, 0x5eed + k));
        }
        m
    }

    /// True when no channel's directional albedo exceeds 1 (with 1% tolerance for the estimate).
    pub fn is_energy_conserving(&self) -> bool {
        self.max_albedo().max_element() <= 1.01
    }
}
