//! Fitting a Lafortune BRDF (Lambertian + retroreflective lobe + specular lobe) to samples with
//! Levenberg-Marquardt, in the stages of Debevec et al. 2004 (3.2.2): `rho_d` first, then each lobe
//! on its own, then everything together.
//!
//! Parameterisation (constraints by construction, no bounds needed):
//! - colours `rho = exp(x)` per channel (positive; dark and bright materials alike);
//! - retroreflective lobe `Cxy = exp(a) > 0`, specular lobe `Cxy = -exp(a) < 0`;
//! - `Cz = 1` for both lobes: a lobe's value `rho (Cxy(..) + Cz(..))^N` is unchanged by scaling
//!   `(Cxy, Cz)` by `k` and `rho` by `k^-N`, so a free `Cz` would be a direction of zero curvature
//!   (singular `J^T J`, infinite standard errors). Fixing `Cz = 1` removes exactly that redundancy
//!   and keeps every lobe shape (`Cz > 0`);
//! - `N = 1 + exp(m)`, clamped to `N <= max_n`.
//!
//! Residuals are relative: `(model - data) / (data + floor)` per channel with
//! `floor = rel_floor * mean(data)` of that channel and material, so dark materials fit as well as
//! bright ones and samples near zero do not dominate. The model is evaluated in f64 (a twin of
//! [`crate::Lobe::eval`] for the optimiser's finite differences; the sharp lobes need the precision).
//! Standard errors: `sqrt(diag((J^T J)^-1) sigma^2)`, `sigma^2 = sum r^2 / (m - p)`, with the
//! pseudo-inverse regularised so an unconstrained parameter gets a large, finite error.

// Loops index several parallel per-sample / per-channel arrays at once.
#![allow(clippy::needless_range_loop)]

use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::{storage::Owned, DMatrix, DVector, Dyn};
use serde::{Deserialize, Serialize};

use crate::{BrdfError, BrdfSample, Lafortune, Lobe};
use glam::Vec3;

/// Options of [`fit_material`].
#[derive(Clone, Debug)]
pub struct FitOptions {
    /// Largest lobe exponent.
    pub max_n: f64,
    /// Relative-residual floor as a fraction of the channel's mean value.
    pub rel_floor: f64,
    /// Weight of the energy bound: residuals `w (albedo - 1)` wherever the directional albedo
    /// (Lambertian plus lobes, per channel) exceeds 1 at an incidence angle; 0 turns it off.
    pub energy_weight: f64,
    /// Weights of the smoothness prior `ln|Cxy| ~ 0` (lobes that neither grow nor shrink toward
    /// grazing unless the samples demand it) among which the cross-validation chooses; without
    /// cross-validation the first is used.
    pub smooth: Vec<f64>,
    /// With at least this many distinct light directions, choose between one lobe (specular)
    /// and two, and among [`FitOptions::smooth`], by leave-one-light-out cross-validation;
    /// 0 = never (always two lobes).
    pub cv_min_lights: usize,
    /// Weight each sample by its coverage of the space of direction pairs
    /// ([`crate::coverage::coverage_weights`]), each weight at most this; 0 = unweighted.
    pub coverage_cap: f64,
    /// Largest grazing gain `|Cxy|^N` of a lobe (how much its peak may grow from normal incidence
    /// to grazing); infinite = unbounded.
    pub max_gain: f64,
}

/// Default [`FitOptions::coverage_cap`].
pub const COVERAGE_CAP: f64 = 4.0;
/// Default [`FitOptions::max_gain`].
pub const MAX_GAIN: f64 = 30.0;

impl Default for FitOptions {
    /// What `igi brdf fit` uses: the plain weighted least squares with every sample weighted by
    /// its coverage of the direction pairs (cap [`COVERAGE_CAP`]) and each lobe's grazing gain
    /// bounded by [`MAX_GAIN`] (issue 16: fits from sparse samples that generalise; docs/BRDF.md).
    fn default() -> Self {
        FitOptions {
            coverage_cap: COVERAGE_CAP,
            max_gain: MAX_GAIN,
            ..FitOptions::plain()
        }
    }
}

impl FitOptions {
    /// The plain weighted least squares: unweighted samples, no bound, no prior, no model
    /// selection (the default before issue 16).
    pub fn plain() -> Self {
        FitOptions {
            max_n: 2.0e4,
            rel_floor: 0.05,
            energy_weight: 0.0,
            smooth: vec![0.0],
            cv_min_lights: 0,
            coverage_cap: 0.0,
            max_gain: f64::INFINITY,
        }
    }

    /// The default plus the energy bound, a choice among smoothness weights, and one or two
    /// lobes, by leave-one-light-out cross-validation (issue 16; not better on the Mitsuba
    /// fixtures, docs/BRDF.md).
    pub fn regularised() -> Self {
        FitOptions {
            energy_weight: 10.0,
            smooth: vec![0.0, 0.1, 1.0],
            cv_min_lights: 3,
            ..FitOptions::default()
        }
    }
}

/// One candidate of the cross-validation and its score.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CvScore {
    /// 1 (specular only) or 2 (retroreflective and specular).
    pub lobes: usize,
    pub smooth: f64,
    /// RMS of the weighted residuals of each left-out light's samples under the fit to the others.
    pub score: f64,
}

/// Standard errors of a fit, laid out like the material (as `materials.json` holds them).
pub use igi_formats::materials::{LobeStderr, Stderr};

/// The result of fitting one material.
#[derive(Clone, Debug)]
pub struct FitReport {
    pub material: String,
    /// Lobes in order: retroreflective, specular.
    pub brdf: Lafortune,
    /// RMS of the relative (weighted) residuals over all samples and channels.
    pub rms: f64,
    /// RMS of `model - data` in the file's units (pi times the BRDF).
    pub rms_abs: f64,
    pub stderr: Stderr,
    pub samples: usize,
    /// Lobes the model selection kept: 1 (the retro lobe's colour is zero) or 2.
    pub lobes_used: usize,
    /// The cross-validation's candidates and scores (empty without cross-validation).
    pub cv: Vec<CvScore>,
    /// How the final Levenberg-Marquardt stage ended.
    pub termination: String,
    /// Fitted parameters (the layout of [`Model`]) and their covariance (`sigma^2 (J^T J)^+`,
    /// prior rows included), for [`FitReport::value_stderr`].
    params: [f64; NP],
    covariance: DMatrix<f64>,
    max_n: f64,
    retro: bool,
}

impl FitReport {
    /// Standard error of the fitted `pi f` at the direction pair `(light, view)`, per channel:
    /// `sqrt(g^T C g)` with `g` the gradient of the model value in the parameters and `C` their
    /// covariance. Small where the samples constrain the model, growing away from them (a lobe
    /// shape the samples never saw has a large variance, and so has every value it reaches).
    pub fn value_stderr(&self, light: Vec3, view: Vec3) -> Vec3 {
        let d3 = |v: Vec3| {
            let v = v.normalize_or_zero();
            [v.x as f64, v.y as f64, v.z as f64]
        };
        let (l, v) = (d3(light), d3(view));
        if l[2] <= 0.0 || v[2] <= 0.0 {
            return Vec3::ZERO;
        }
        let model = Model {
            retro: self.retro,
            ..Model::plain(self.max_n)
        };
        let mut g = DMatrix::zeros(NP, 3);
        for i in 0..NP {
            let h = 1e-6 * (1.0 + self.params[i].abs());
            let (mut a, mut b) = (self.params, self.params);
            a[i] += h;
            b[i] -= h;
            let (fa, fb) = (model.value(&a, &l, &v), model.value(&b, &l, &v));
            for c in 0..3 {
                g[(i, c)] = (fa[c] - fb[c]) / (2.0 * h);
            }
        }
        let var = g.transpose() * &self.covariance * &g;
        let se = |c: usize| {
            let x = var[(c, c)].abs().sqrt();
            if x.is_finite() {
                x.min(1e30) as f32
            } else {
                1e30
            }
        };
        Vec3::new(se(0), se(1), se(2))
    }
}

pub(crate) const NP: usize = 13;
const PRIOR: f64 = 1e-3;
// parameter layout
const LD: usize = 0; // rho_d log colour (3)
const RR: usize = 3; // retro log colour (3)
const RA: usize = 6; // retro log cxy
const RM: usize = 7; // retro log(n - 1)
const SR: usize = 8; // specular log colour (3)
const SA: usize = 11; // specular log -cxy
const SM: usize = 12; // specular log(n - 1)

#[derive(Clone, Copy)]
struct LobeF64 {
    rho: [f64; 3],
    cxy: f64,
    n: f64,
}

/// f64 lobe shape `max(0, cxy (l.x v.x + l.y v.y) + l.z v.z)^n` (Cz = 1).
#[inline]
fn shape(cxy: f64, n: f64, l: &[f64; 3], v: &[f64; 3]) -> f64 {
    let d = cxy * (l[0] * v[0] + l[1] * v[1]) + l[2] * v[2];
    if d <= 0.0 {
        0.0
    } else {
        (n * d.ln()).min(300.0).exp()
    }
}

pub(crate) struct Model {
    pub(crate) max_n: f64,
    /// With the retroreflective lobe (false: Lambertian + specular lobe only; the retro colour
    /// is held at zero and its parameters are not optimised).
    pub(crate) retro: bool,
    /// Weight of the energy bound's residuals (directional albedo above 1), 0 = off.
    pub(crate) energy: f64,
    /// Weight of the smoothness prior `ln|Cxy| ~ 0` on both lobes (a lobe that neither grows
    /// nor shrinks toward grazing unless the data ask for it), 0 = only the weak [`PRIOR`].
    pub(crate) smooth: f64,
    /// Bound on each lobe's grazing gain `|Cxy|^N` (its peak at grazing over its peak at normal
    /// incidence), enforced as residuals `GAIN_WEIGHT (N ln|Cxy| - ln max_gain)` above it;
    /// infinite = off.
    pub(crate) max_gain: f64,
}

/// Most folds of the cross-validation over light positions.
const CV_FOLDS: usize = 8;

/// Incidence angles (degrees) at which the energy bound is enforced.
const ENERGY_THETAS: [f64; 7] = [0.0, 30.0, 50.0, 65.0, 75.0, 82.0, 87.0];

/// Number of prior rows after the data residuals.
pub(crate) const N_PRIOR: usize = 4 + 3 * ENERGY_THETAS.len();

/// Weight of the grazing-gain bound's residuals (per unit of `ln` gain above the bound).
const GAIN_WEIGHT: f64 = 10.0;

impl Model {
    /// The plain least-squares model (no energy bound, no smoothness prior; both lobes).
    pub(crate) fn plain(max_n: f64) -> Self {
        Model {
            max_n,
            retro: true,
            energy: 0.0,
            smooth: 0.0,
            max_gain: f64::INFINITY,
        }
    }

    /// Parameters the optimiser may change (all but the retro lobe's without it).
    pub(crate) fn free_all(&self) -> Vec<usize> {
        (0..NP)
            .filter(|&i| self.retro || !(RR..=RM).contains(&i))
            .collect()
    }

    /// Directional albedo per channel at incidence `theta` of the Lambertian term plus both
    /// lobes, with the closed form of a lobe over the whole sphere: `rho |c|^N 2 pi / (N + 2) a_z`
    /// (`c = (Cxy sin, 0, cos)`, `a = c / |c|`; `a_z` floored at `1/sqrt(N + 1)`, the lobe's
    /// width, so a lobe lying on the horizon still counts about half its energy).
    fn albedo(&self, p: &[f64], theta: f64) -> [f64; 3] {
        let (d, r, s) = self.lobes(p);
        let (st, ct) = theta.sin_cos();
        let lobe = |l: &LobeF64| {
            let len = (l.cxy * l.cxy * st * st + ct * ct).sqrt();
            let az = (ct / len).max(1.0 / (l.n + 1.0).sqrt());
            (l.n * len.ln()).min(300.0).exp() * std::f64::consts::TAU / (l.n + 2.0) * az
        };
        let (kr, ks) = (lobe(&r), lobe(&s));
        [0, 1, 2].map(|c| d[c] + r.rho[c] * kr + s.rho[c] * ks)
    }

    /// The prior rows: the weak `ln|Cxy|` prior (stronger with [`Model::smooth`]) and the energy
    /// bound (albedo above 1 at [`ENERGY_THETAS`], weighted by [`Model::energy`]).
    fn prior(&self, p: &[f64], out: &mut [f64]) {
        let w = PRIOR + self.smooth;
        out[0] = if self.retro { w * p[RA] } else { 0.0 };
        out[1] = w * p[SA];
        for (k, t) in ENERGY_THETAS.iter().enumerate() {
            let a = if self.energy > 0.0 {
                self.albedo(p, t.to_radians())
            } else {
                [0.0; 3]
            };
            for c in 0..3 {
                out[2 + 3 * k + c] = self.energy * (a[c] - 1.0).max(0.0);
            }
        }
        let (_, r, s) = self.lobes(p);
        let lg = self.max_gain.ln();
        let gain = |l: &LobeF64| {
            if lg.is_finite() {
                GAIN_WEIGHT * (l.n * l.cxy.abs().ln() - lg).max(0.0)
            } else {
                0.0
            }
        };
        let e = 2 + 3 * ENERGY_THETAS.len();
        out[e] = if self.retro { gain(&r) } else { 0.0 };
        out[e + 1] = gain(&s);
    }

    fn lobes(&self, p: &[f64]) -> ([f64; 3], LobeF64, LobeF64) {
        let col = |i: usize| {
            if !self.retro && i == RR {
                return [0.0; 3];
            }
            [
                p[i].clamp(-40.0, 20.0).exp(),
                p[i + 1].clamp(-40.0, 20.0).exp(),
                p[i + 2].clamp(-40.0, 20.0).exp(),
            ]
        };
        let nmax = (self.max_n - 1.0).ln();
        let retro = LobeF64 {
            rho: col(RR),
            cxy: p[RA].clamp(-6.0, 3.0).exp(),
            n: 1.0 + p[RM].clamp(-12.0, nmax).exp(),
        };
        let spec = LobeF64 {
            rho: col(SR),
            cxy: -p[SA].clamp(-6.0, 3.0).exp(),
            n: 1.0 + p[SM].clamp(-12.0, nmax).exp(),
        };
        (col(LD), retro, spec)
    }

    /// pi * f per channel.
    pub(crate) fn value(&self, p: &[f64], l: &[f64; 3], v: &[f64; 3]) -> [f64; 3] {
        let (d, r, s) = self.lobes(p);
        let gr = std::f64::consts::PI * shape(r.cxy, r.n, l, v);
        let gs = std::f64::consts::PI * shape(s.cxy, s.n, l, v);
        [0, 1, 2].map(|c| d[c] + r.rho[c] * gr + s.rho[c] * gs)
    }

    pub(crate) fn to_lafortune(&self, p: &[f64]) -> Lafortune {
        let (d, r, s) = self.lobes(p);
        let v = |c: [f64; 3]| Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32);
        Lafortune {
            rho_d: v(d),
            lobes: vec![
                Lobe {
                    rho: v(r.rho),
                    cxy: r.cxy as f32,
                    cz: 1.0,
                    n: r.n as f32,
                },
                Lobe {
                    rho: v(s.rho),
                    cxy: s.cxy as f32,
                    cz: 1.0,
                    n: s.n as f32,
                },
            ],
        }
    }
}

pub(crate) struct Data {
    pub(crate) light: Vec<[f64; 3]>,
    pub(crate) view: Vec<[f64; 3]>,
    pub(crate) value: Vec<[f64; 3]>,
    /// `sqrt(sample weight) / (data + floor)` per sample and channel (the sample weight is 1
    /// without [`Data::with_sample_weights`]).
    pub(crate) weight: Vec<[f64; 3]>,
}

impl Data {
    pub(crate) fn new(
        light: Vec<[f64; 3]>,
        view: Vec<[f64; 3]>,
        value: Vec<[f64; 3]>,
        floor: [f64; 3],
    ) -> Self {
        let weight = value
            .iter()
            .map(|v| [0, 1, 2].map(|c| 1.0 / (v[c] + floor[c])))
            .collect();
        Data {
            light,
            view,
            value,
            weight,
        }
    }

    /// Multiplies each sample's squared residual by `w[i]` (e.g.
    /// [`crate::coverage::coverage_weights`]).
    pub(crate) fn with_sample_weights(mut self, w: &[f64]) -> Self {
        for (i, &wi) in w.iter().enumerate() {
            let r = wi.max(0.0).sqrt();
            for c in 0..3 {
                self.weight[i][c] *= r;
            }
        }
        self
    }

    /// The weighted residual of sample `i`, channel `c`, for the model value `f`.
    #[inline]
    pub(crate) fn residual(&self, i: usize, c: usize, f: f64) -> f64 {
        (f - self.value[i][c]) * self.weight[i][c]
    }

    /// Sum of squared weighted residuals of the parameters `p`.
    pub(crate) fn cost(&self, model: &Model, p: &[f64; NP]) -> f64 {
        let mut s = 0.0;
        for i in 0..self.light.len() {
            let f = model.value(p, &self.light[i], &self.view[i]);
            for c in 0..3 {
                s += self.residual(i, c, f[c]).powi(2);
            }
        }
        s
    }
}

pub(crate) struct Problem<'a> {
    pub(crate) model: &'a Model,
    pub(crate) data: &'a Data,
    pub(crate) p: [f64; NP],
    pub(crate) free: Vec<usize>,
}

impl Problem<'_> {
    pub(crate) fn residuals_at(&self, p: &[f64]) -> DVector<f64> {
        let m = self.data.light.len();
        let mut r = DVector::zeros(3 * m + N_PRIOR);
        for i in 0..m {
            let f = self.model.value(p, &self.data.light[i], &self.data.view[i]);
            for c in 0..3 {
                r[3 * i + c] = self.data.residual(i, c, f[c]);
            }
        }
        // A weak prior |Cxy| ~ 1 (ln|Cxy| ~ 0): keeps the Cxy of a lobe the data do not support at
        // a sane value instead of drifting to the clamp; negligible wherever the data constrain it.
        // Then the smoothness prior and the energy bound of the model's options.
        self.model.prior(p, r.as_mut_slice()[3 * m..].as_mut());
        r
    }
    fn cost(&self) -> f64 {
        self.residuals_at(&self.p).norm_squared()
    }
    pub(crate) fn jacobian_at(&self, p: &[f64; NP], free: &[usize]) -> DMatrix<f64> {
        let m = 3 * self.data.light.len() + N_PRIOR;
        let mut j = DMatrix::zeros(m, free.len());
        for (k, &i) in free.iter().enumerate() {
            let h = 1e-6 * (1.0 + p[i].abs());
            let mut a = *p;
            let mut b = *p;
            a[i] += h;
            b[i] -= h;
            let col = (self.residuals_at(&a) - self.residuals_at(&b)) / (2.0 * h);
            j.set_column(k, &col);
        }
        j
    }
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for Problem<'_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, x: &DVector<f64>) {
        for (k, &i) in self.free.iter().enumerate() {
            self.p[i] = x[k];
        }
    }
    fn params(&self) -> DVector<f64> {
        DVector::from_iterator(self.free.len(), self.free.iter().map(|&i| self.p[i]))
    }
    fn residuals(&self) -> Option<DVector<f64>> {
        let r = self.residuals_at(&self.p);
        r.iter().all(|x| x.is_finite()).then_some(r)
    }
    fn jacobian(&self) -> Option<DMatrix<f64>> {
        let j = self.jacobian_at(&self.p, &self.free);
        j.iter().all(|x| x.is_finite()).then_some(j)
    }
}

/// Run LM over `free` from `p`; returns the new parameters, the cost and the termination text.
fn lm(model: &Model, data: &Data, p: [f64; NP], free: &[usize]) -> ([f64; NP], f64, String) {
    let prob = Problem {
        model,
        data,
        p,
        free: free.to_vec(),
    };
    let start_cost = prob.cost();
    let (prob, report) = LevenbergMarquardt::new().with_patience(200).minimize(prob);
    let cost = prob.cost();
    if cost.is_finite() && cost <= start_cost {
        (prob.p, cost, format!("{:?}", report.termination))
    } else {
        (
            p,
            start_cost,
            format!("{:?} (step rejected)", report.termination),
        )
    }
}

/// Minimise `x^T G x - 2 x.b` over `x >= 0` for the first `k` (<= 3) unknowns by trying every
/// active set (the problem is tiny); returns `x` and the minimum (`-x.b`).
fn nnls_small(g: &[[f64; 3]; 3], b: &[f64; 3], k: usize) -> ([f64; 3], f64) {
    let mut best = ([0.0; 3], 0.0);
    for set in 1u32..(1 << k) {
        let idx: Vec<usize> = (0..k).filter(|i| set & (1 << i) != 0).collect();
        let n = idx.len();
        // Gaussian elimination with partial pivoting on the n x n subsystem
        let mut a = [[0.0f64; 4]; 3];
        for (r, &i) in idx.iter().enumerate() {
            for (c, &j) in idx.iter().enumerate() {
                a[r][c] = g[i][j];
            }
            a[r][3] = b[i];
        }
        let scale = (0..n).map(|r| a[r][r].abs()).fold(0.0, f64::max);
        let mut ok = scale > 0.0;
        for col in 0..n {
            if !ok {
                break;
            }
            let piv = (col..n)
                .max_by(|&x, &y| a[x][col].abs().total_cmp(&a[y][col].abs()))
                .unwrap_or(col);
            a.swap(col, piv);
            if a[col][col].abs() <= 1e-12 * scale {
                ok = false;
                break;
            }
            for r in 0..n {
                if r != col {
                    let f = a[r][col] / a[col][col];
                    for c in col..4 {
                        a[r][c] -= f * a[col][c];
                    }
                }
            }
        }
        if !ok {
            continue;
        }
        let mut x = [0.0; 3];
        for (r, &i) in idx.iter().enumerate() {
            x[i] = a[r][3] / a[r][r];
        }
        if x.iter().any(|v| *v < 0.0 || !v.is_finite()) {
            continue;
        }
        let val = -(0..k).map(|i| x[i] * b[i]).sum::<f64>();
        if val < best.1 {
            best = (x, val);
        }
    }
    best
}

/// Exponent grid of the lobe searches: `1.5 * 1.6^k` up to `max_n`.
fn n_grid(max_n: f64) -> Vec<f64> {
    (0..40)
        .map(|k| 1.5 * 1.6f64.powi(k))
        .take_while(|&n| n <= max_n)
        .collect()
}

/// Stage "one lobe alone", global part: a grid over the lobe's `(|Cxy|, N)`; at every node the
/// colours (`rho_d`, the other lobe's colour at its current shape, this lobe's colour) enter
/// linearly and are solved exactly (non-negative weighted least squares per channel), so the
/// search is over the two shape parameters only (variable projection). Returns the best node of
/// each exponent range (N < 8, < 60, < 500, >= 500) as starting points, best first.
fn grid_starts(
    model: &Model,
    data: &Data,
    p: &[f64; NP],
    colour: usize,
    a: usize,
    m: usize,
) -> Vec<[f64; NP]> {
    let grid = LobeGrid::new(model, data, p, colour, a, m);
    let cxys: &[f64] = if grid.spec {
        &[
            0.7, 0.85, 0.95, 1.0, 1.02, 1.05, 1.1, 1.2, 1.35, 1.6, 2.0, 2.5,
        ]
    } else {
        &[0.2, 0.5, 0.8, 0.95, 1.0, 1.05, 1.2, 1.5]
    };
    let ns = n_grid(model.max_n);
    let mut best: [Option<(f64, [f64; NP])>; 4] = [None; 4];
    let mut g2 = vec![0.0f64; data.light.len()];
    for &cxy in cxys {
        for &n in &ns {
            let Some((cost, q)) = grid.node(p, cxy, n, &mut g2) else {
                continue;
            };
            let slot = &mut best[exponent_bucket(n)];
            if slot.as_ref().is_none_or(|s| cost < s.0) {
                *slot = Some((cost, q));
            }
        }
    }
    let mut v: Vec<(f64, [f64; NP])> = best.into_iter().flatten().collect();
    v.sort_by(|x, y| x.0.total_cmp(&y.0));
    v.into_iter().map(|x| x.1).collect()
}

/// The exponent range of a grid node: N < 8, < 60, < 500, >= 500.
fn exponent_bucket(n: f64) -> usize {
    if n < 8.0 {
        0
    } else if n < 60.0 {
        1
    } else if n < 500.0 {
        2
    } else {
        3
    }
}

/// What [`grid_starts`] keeps fixed over its grid: the lobe's parameter indices, the other lobe's
/// basis values `g1` and the weighted Gram sums that do not involve the grid lobe.
struct LobeGrid<'a> {
    data: &'a Data,
    /// The grid lobe is the specular one (its `Cxy` is negative).
    spec: bool,
    colour: usize,
    a: usize,
    m: usize,
    /// Colour index of the other lobe.
    oc: usize,
    /// The other lobe has any colour (and so is a basis function).
    has_other: bool,
    g1: Vec<f64>,
    g_fix: [[[f64; 3]; 3]; 3],
    b_fix: [[f64; 3]; 3],
}

impl<'a> LobeGrid<'a> {
    fn new(
        model: &Model,
        data: &'a Data,
        p: &[f64; NP],
        colour: usize,
        a: usize,
        m: usize,
    ) -> Self {
        let spec = colour == SR;
        let pi = std::f64::consts::PI;
        // the other lobe, as it stands (a basis only if it has any colour)
        let oc = if spec { RR } else { SR };
        let (_, retro, specl) = model.lobes(p);
        let other = if spec { retro } else { specl };
        let has_other = (0..3).any(|c| p[oc + c] > -39.0);
        let g1: Vec<f64> = data
            .light
            .iter()
            .zip(&data.view)
            .map(|(l, v)| pi * shape(other.cxy, other.n, l, v))
            .collect();
        let mut g_fix = [[[0.0f64; 3]; 3]; 3];
        let mut b_fix = [[0.0f64; 3]; 3];
        for i in 0..data.light.len() {
            for c in 0..3 {
                let w2 = data.weight[i][c] * data.weight[i][c];
                let d = data.value[i][c];
                g_fix[c][0][0] += w2;
                g_fix[c][0][1] += w2 * g1[i];
                g_fix[c][1][1] += w2 * g1[i] * g1[i];
                b_fix[c][0] += w2 * d;
                b_fix[c][1] += w2 * g1[i] * d;
            }
        }
        LobeGrid {
            data,
            spec,
            colour,
            a,
            m,
            oc,
            has_other,
            g1,
            g_fix,
            b_fix,
        }
    }

    /// The cost and parameters (from `p`, with the lobe's shape set and every colour solved) at
    /// the node `(cxy, n)`; `None` where the lobe overflows. `g2` is scratch of the data's length.
    fn node(&self, p: &[f64; NP], cxy: f64, n: f64, g2: &mut [f64]) -> Option<(f64, [f64; NP])> {
        let data = self.data;
        let signed = if self.spec { -cxy } else { cxy };
        let mut big = false;
        for i in 0..data.light.len() {
            g2[i] = std::f64::consts::PI * shape(signed, n, &data.light[i], &data.view[i]);
            big |= g2[i] > 1e12;
        }
        if big {
            return None;
        }
        let mut q = *p;
        q[self.a] = cxy.ln();
        q[self.m] = (n - 1.0).max(1e-6).ln();
        let mut cost = 0.0;
        for c in 0..3 {
            let (x, val) = self.solve_channel(c, g2);
            cost += val;
            let (xd, xo, xs) = if self.has_other {
                (x[0], x[1], x[2])
            } else {
                (x[0], 0.0, x[1])
            };
            let ln = |v: f64| if v > 0.0 { v.ln().max(-40.0) } else { -40.0 };
            q[LD + c] = ln(xd);
            if self.has_other {
                q[self.oc + c] = ln(xo);
            }
            q[self.colour + c] = ln(xs);
        }
        Some((cost, q))
    }

    /// Channel `c`'s non-negative least-squares colours with the grid lobe's basis `g2`;
    /// unknown order: rho_d, [other lobe], this lobe.
    fn solve_channel(&self, c: usize, g2: &[f64]) -> ([f64; 3], f64) {
        let data = self.data;
        let mut g = self.g_fix[c];
        let mut b = self.b_fix[c];
        for i in 0..data.light.len() {
            let w2 = data.weight[i][c] * data.weight[i][c];
            g[0][2] += w2 * g2[i];
            g[1][2] += w2 * self.g1[i] * g2[i];
            g[2][2] += w2 * g2[i] * g2[i];
            b[2] += w2 * g2[i] * data.value[i][c];
        }
        if self.has_other {
            let mut s = g;
            for r in 0..3 {
                for cc in r..3 {
                    s[cc][r] = s[r][cc];
                }
            }
            nnls_small(&s, &b, 3)
        } else {
            nnls_small(
                &[[g[0][0], g[0][2], 0.0], [g[0][2], g[2][2], 0.0], [0.0; 3]],
                &[b[0], b[2], 0.0],
                2,
            )
        }
    }
}

/// One lobe fitted alone: LM over the lobe's colour, `Cxy` and `N` from fixed starting exponents
/// (`Cxy = +-1`, colour solved linearly with the rest fixed) and, with `grid`, from the
/// variable-projection grid's starts ([`grid_starts`]); the best result.
fn fit_lobe(
    model: &Model,
    data: &Data,
    p: [f64; NP],
    colour: usize,
    a: usize,
    m: usize,
    grid: bool,
) -> [f64; NP] {
    let free = [colour, colour + 1, colour + 2, a, m];
    let mut best = (p, f64::INFINITY);
    let starts: &[f64] = if colour == SR {
        &[3.0, 15.0, 60.0, 300.0, 1500.0, 8000.0, 2.0e4]
    } else {
        &[2.0, 8.0, 30.0, 150.0]
    };
    for &n0 in starts {
        if n0 > model.max_n {
            continue;
        }
        let mut q = p;
        q[a] = 0.0;
        q[m] = (n0 - 1.0).max(1e-3).ln();
        linear_colour(model, data, &mut q, colour);
        let (q, cost, _) = lm(model, data, q, &free);
        if cost < best.1 {
            best = (q, cost);
        }
    }
    let grid_starts = if grid {
        grid_starts(model, data, &p, colour, a, m)
    } else {
        Vec::new()
    };
    for q in grid_starts {
        let (q, cost, _) = lm(model, data, q, &free);
        if cost < best.1 {
            best = (q, cost);
        }
    }
    best.0
}

/// Colour of the lobe at `ci` (log colour index) that best explains the data left over by the
/// rest of the model, in the weighted least-squares sense (the colour enters linearly).
fn linear_colour(model: &Model, data: &Data, p: &mut [f64; NP], ci: usize) {
    for c in 0..3 {
        p[ci + c] = -40.0;
    }
    let mut probe = *p;
    for c in 0..3 {
        probe[ci + c] = 0.0; // unit colour
    }
    for c in 0..3 {
        let (mut num, mut den) = (0.0, 0.0);
        for i in 0..data.light.len() {
            let base = model.value(p, &data.light[i], &data.view[i])[c];
            let g = model.value(&probe, &data.light[i], &data.view[i])[c] - base;
            let w2 = data.weight[i][c] * data.weight[i][c];
            num += w2 * g * (data.value[i][c] - base);
            den += w2 * g * g;
        }
        let rho = if den > 0.0 {
            (num / den).max(1e-12)
        } else {
            1e-12
        };
        p[ci + c] = rho.ln().max(-40.0);
    }
}

fn percentile(mut v: Vec<f64>, q: f64) -> f64 {
    v.sort_by(|a, b| a.partial_cmp(b).unwrap_or(std::cmp::Ordering::Equal));
    let i = ((v.len() - 1) as f64 * q).round() as usize;
    v[i]
}

/// The staged fit of Debevec et al. on prepared data with the fixed starting exponents only
/// (what Lensch clustering uses for its pooled and per-cluster fits; see [`fit_staged`]).
pub(crate) fn fit_data(model: &Model, data: &Data) -> ([f64; NP], f64, String) {
    fit_staged(model, data, false)
}

/// The staged fit of Debevec et al. on prepared data: returns parameters, cost, termination.
/// `grid` adds the variable-projection grid starts to each single-lobe stage.
fn fit_staged(model: &Model, data: &Data, grid: bool) -> ([f64; NP], f64, String) {
    // Stage 1: rho_d from the lower part of the data (pi f = rho_d where no lobe reaches).
    let mut p0 = [0.0; NP];
    for c in 0..3 {
        let q = percentile(data.value.iter().map(|v| v[c]).collect(), 0.3);
        p0[LD + c] = q.max(1e-12).ln();
    }
    for c in 0..3 {
        p0[RR + c] = -40.0;
        p0[SR + c] = -40.0;
    }
    p0[RM] = 1.0f64.ln();
    p0[SM] = 9.0f64.ln();
    let all = model.free_all();

    // Stages 2-3 in the paper's order (retro, then specular), and the other order as a second
    // candidate; stage 4: all parameters jointly. Keep the better joint fit.
    let mut best: Option<([f64; NP], f64, String)> = None;
    let orders: &[[usize; 2]] = if model.retro {
        &[[0, 1], [1, 0]]
    } else {
        &[[1, 1]]
    };
    for order in orders {
        let mut p = p0;
        let once = if order[0] == order[1] {
            &order[..1]
        } else {
            &order[..]
        };
        for &which in once {
            p = if which == 0 {
                fit_lobe(model, data, p, RR, RA, RM, grid)
            } else {
                fit_lobe(model, data, p, SR, SA, SM, grid)
            };
        }
        let (p, cost, term) = lm(model, data, p, &all);
        if best.as_ref().is_none_or(|b| cost < b.1) {
            best = Some((p, cost, term));
        }
    }
    best.expect("two candidates")
}

/// Joint LM over all parameters from `p` (warm start).
pub(crate) fn refine(model: &Model, data: &Data, p: [f64; NP]) -> ([f64; NP], f64) {
    let all = model.free_all();
    let (p, cost, _) = lm(model, data, p, &all);
    (p, cost)
}

impl Data {
    /// The samples at `idx`, with their weights.
    fn subset(&self, idx: &[usize]) -> Data {
        Data {
            light: idx.iter().map(|&i| self.light[i]).collect(),
            view: idx.iter().map(|&i| self.view[i]).collect(),
            value: idx.iter().map(|&i| self.value[i]).collect(),
            weight: idx.iter().map(|&i| self.weight[i]).collect(),
        }
    }

    /// Sample indices grouped by light direction (directions within about 0.1 degree are one).
    fn light_groups(&self) -> Vec<Vec<usize>> {
        let mut groups: Vec<([f64; 3], Vec<usize>)> = Vec::new();
        for (i, l) in self.light.iter().enumerate() {
            let same = |g: &[f64; 3]| g[0] * l[0] + g[1] * l[1] + g[2] * l[2] > 1.0 - 2e-6;
            match groups.iter_mut().find(|g| same(&g.0)) {
                Some(g) => g.1.push(i),
                None => groups.push((*l, vec![i])),
            }
        }
        groups.into_iter().map(|g| g.1).collect()
    }
}

/// The model of `opts`: one or two lobes and the smoothness weight, by leave-one-light-out
/// cross-validation when the samples have at least `opts.cv_min_lights` light directions (each
/// candidate fitted to all lights but one, scored by the weighted residuals of the one left out).
fn select_model(data: &Data, opts: &FitOptions) -> (Model, Vec<CvScore>) {
    let smooth0 = opts.smooth.first().copied().unwrap_or(0.0);
    let base = Model {
        max_n: opts.max_n,
        retro: true,
        energy: opts.energy_weight,
        smooth: smooth0,
        max_gain: opts.max_gain,
    };
    let lights = data.light_groups();
    if opts.cv_min_lights == 0 || lights.len() < opts.cv_min_lights.max(2) {
        return (base, Vec::new());
    }
    // at most CV_FOLDS folds: light k goes to fold k mod CV_FOLDS
    let folds = lights.len().min(CV_FOLDS);
    let mut groups = vec![Vec::new(); folds];
    for (k, g) in lights.into_iter().enumerate() {
        groups[k % folds].extend(g);
    }
    let mut scores = Vec::new();
    for retro in [false, true] {
        for &smooth in &opts.smooth {
            let model = Model {
                retro,
                smooth,
                ..base
            };
            let (mut se, mut n) = (0.0, 0usize);
            for k in 0..groups.len() {
                let train: Vec<usize> = groups
                    .iter()
                    .enumerate()
                    .filter(|(g, _)| *g != k)
                    .flat_map(|(_, v)| v.iter().copied())
                    .collect();
                let (p, _, _) = fit_staged(&model, &data.subset(&train), false);
                let test = data.subset(&groups[k]);
                se += test.cost(&model, &p);
                n += 3 * groups[k].len();
            }
            let score = (se / n.max(1) as f64).sqrt();
            scores.push(CvScore {
                lobes: if retro { 2 } else { 1 },
                smooth,
                score: if score.is_finite() { score } else { f64::MAX },
            });
        }
    }
    let best = scores
        .iter()
        .min_by(|a, b| a.score.total_cmp(&b.score))
        .expect("candidates");
    (
        Model {
            retro: best.lobes == 2,
            smooth: best.smooth,
            ..base
        },
        scores,
    )
}

/// The samples in f64 with the relative-residual weights of `opts` (floor `rel_floor` times the
/// channel's mean) and, with `opts.coverage_cap > 0`, the coverage weights.
fn prepared_data(samples: &[BrdfSample], opts: &FitOptions) -> Data {
    let d3 = |v: Vec3| [v.x as f64, v.y as f64, v.z as f64];
    let value: Vec<[f64; 3]> = samples.iter().map(|s| d3(s.value)).collect();
    let mean: [f64; 3] =
        [0, 1, 2].map(|c| value.iter().map(|v| v[c]).sum::<f64>() / value.len() as f64);
    let floor = mean.map(|m| opts.rel_floor * m + 1e-12);
    let data = Data::new(
        samples.iter().map(|s| d3(s.light.normalize())).collect(),
        samples.iter().map(|s| d3(s.view.normalize())).collect(),
        value,
        floor,
    );
    if opts.coverage_cap > 0.0 {
        let w = crate::coverage::coverage_weights(&data.light, &data.view, opts.coverage_cap);
        data.with_sample_weights(&w)
    } else {
        data
    }
}

/// Fit every material in `samples` ([`fit_material`] with `opts`), in parallel; materials in
/// the order they first appear, each with its samples. `done` is called as each finishes.
pub fn fit_materials(
    samples: &[BrdfSample],
    opts: &FitOptions,
    done: &(dyn Fn() + Sync),
) -> Result<Vec<(Vec<BrdfSample>, FitReport)>, BrdfError> {
    use rayon::prelude::*;
    crate::samples::group_by_material(samples)
        .into_par_iter()
        .map(|(name, s)| {
            let r = fit_material(&name, &s, opts);
            done();
            r.map(|r| (s, r))
        })
        .collect()
}

/// Fit Lambertian + retroreflective + specular lobes to one material's samples.
pub fn fit_material(
    material: &str,
    samples: &[BrdfSample],
    opts: &FitOptions,
) -> Result<FitReport, BrdfError> {
    let fail = |msg: String| BrdfError::Fit {
        material: material.to_string(),
        msg,
    };
    check_samples(samples).map_err(fail)?;
    let data = prepared_data(samples, opts);
    let (model, cv) = select_model(&data, opts);
    let (p, cost, termination) = fit_staged(&model, &data, true);
    if !cost.is_finite() || p.iter().any(|x| !x.is_finite()) {
        return Err(fail("the optimiser produced non-finite values".into()));
    }
    let stats = FitStats::new(&model, &data, p);
    let stderr = parameter_stderr(&model, &p, &stats.stderr());
    let brdf = model.to_lafortune(&p);
    if !brdf.rho_d.is_finite()
        || brdf
            .lobes
            .iter()
            .any(|l| !l.rho.is_finite() || !l.n.is_finite())
    {
        return Err(fail("the fitted parameters overflow f32".into()));
    }
    Ok(FitReport {
        material: material.to_string(),
        brdf,
        rms: stats.rms,
        rms_abs: stats.rms_abs,
        stderr,
        samples: samples.len(),
        termination,
        params: p,
        covariance: stats.cov * stats.sigma2,
        max_n: opts.max_n,
        retro: model.retro,
        lobes_used: if model.retro { 2 } else { 1 },
        cv,
    })
}

/// Enough samples for the model, every value finite and non-negative, every direction above the
/// surface; the message of the first failure otherwise.
fn check_samples(samples: &[BrdfSample]) -> Result<(), String> {
    if samples.len() < 5 {
        return Err(format!(
            "{} samples are too few for the {NP}-parameter model (need at least 5, i.e. 15 values)",
            samples.len()
        ));
    }
    let pairs = distinct_pairs(samples);
    if pairs < 5 {
        return Err(format!(
            "its {} samples hold {pairs} distinct light/view direction pair{}: the {NP}-parameter \
             model needs at least 5 (repeating a measurement adds no direction to fit the lobes \
             to)",
            samples.len(),
            if pairs == 1 { "" } else { "s" }
        ));
    }
    for (i, s) in samples.iter().enumerate() {
        if !(s.light.is_finite() && s.view.is_finite() && s.value.is_finite())
            || s.value.min_element() < 0.0
        {
            return Err(format!("sample {i} has non-finite or negative values"));
        }
        if s.light.z <= 0.0 || s.view.z <= 0.0 {
            return Err(format!("sample {i} has a direction below the surface"));
        }
    }
    Ok(())
}

/// How many different (light, view) direction pairs the samples hold (directions that agree
/// to 1e-4 in every component count as one).
fn distinct_pairs(samples: &[BrdfSample]) -> usize {
    let key = |v: Vec3| v.to_array().map(|c| (c * 1e4).round() as i64);
    samples
        .iter()
        .map(|s| (key(s.light), key(s.view)))
        .collect::<std::collections::HashSet<_>>()
        .len()
}

/// Residual statistics of a fit: relative and absolute RMS, the residual variance and the
/// (unscaled) parameter covariance `(J^T J)^-1`.
struct FitStats {
    rms: f64,
    rms_abs: f64,
    sigma2: f64,
    cov: DMatrix<f64>,
}

impl FitStats {
    fn new(model: &Model, data: &Data, p: [f64; NP]) -> Self {
        let all: Vec<usize> = (0..NP).collect();
        let prob = Problem {
            model,
            data,
            p,
            free: all.clone(),
        };
        let r = prob.residuals_at(&p);
        let m = 3 * data.light.len(); // data residuals (the prior's two come after them)
        let rms = (r.rows(0, m).norm_squared() / m as f64).sqrt();
        let mut abs2 = 0.0;
        for i in 0..data.light.len() {
            let f = model.value(&p, &data.light[i], &data.view[i]);
            for c in 0..3 {
                abs2 += (f[c] - data.value[i][c]).powi(2);
            }
        }
        let rms_abs = (abs2 / m as f64).sqrt();
        let sigma2 = r.rows(0, m).norm_squared() / (m.saturating_sub(NP)).max(1) as f64;
        let j = prob.jacobian_at(&p, &all);
        let jtj = j.transpose() * &j;
        FitStats {
            rms,
            rms_abs,
            sigma2,
            cov: pseudo_inverse(jtj),
        }
    }

    /// Standard error of every (log-space) parameter.
    fn stderr(&self) -> Vec<f64> {
        (0..NP)
            .map(|i| (self.cov[(i, i)].abs() * self.sigma2).sqrt().min(1e30))
            .collect()
    }
}

/// The inverse of the symmetric `jtj` by its SVD, tiny singular values clamped.
fn pseudo_inverse(jtj: DMatrix<f64>) -> DMatrix<f64> {
    let svd = jtj.svd(true, true);
    let (u, vt) = (svd.u.expect("u"), svd.v_t.expect("v_t"));
    let smax = svd.singular_values.max().max(1e-300);
    let mut cov = DMatrix::zeros(NP, NP);
    for k in 0..NP {
        let s = svd.singular_values[k].max(smax * 1e-14).max(1e-300);
        cov += (u.column(k) * vt.row(k)) / s;
    }
    cov
}

/// Standard errors of the model's parameters at `p` from those `se` of the log-space parameters
/// (first order: `d exp(x) = exp(x) dx`), capped at 1e30.
fn parameter_stderr(model: &Model, p: &[f64; NP], se: &[f64]) -> Stderr {
    let (d, re, sp) = model.lobes(p);
    let cap = |x: f64| if x.is_finite() { x.min(1e30) } else { 1e30 };
    Stderr {
        rho_d: [0, 1, 2].map(|c| cap(d[c] * se[LD + c])),
        lobes: vec![
            LobeStderr {
                rho: [0, 1, 2].map(|c| cap(re.rho[c] * se[RR + c])),
                cxy: cap(re.cxy.abs() * se[RA]),
                n: cap((re.n - 1.0) * se[RM]),
            },
            LobeStderr {
                rho: [0, 1, 2].map(|c| cap(sp.rho[c] * se[SR + c])),
                cxy: cap(sp.cxy.abs() * se[SA]),
                n: cap((sp.n - 1.0) * se[SM]),
            },
        ],
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_distr_free::normal;

    /// Box-Muller standard normal (keeps the crate free of rand_distr).
    mod rand_distr_free {
        use rand::Rng;
        pub fn normal(rng: &mut impl Rng) -> f32 {
            let u1: f32 = rng.gen_range(1e-7f32..1.0);
            let u2: f32 = rng.gen();
            (-2.0 * u1.ln()).sqrt() * (std::f32::consts::TAU * u2).cos()
        }
    }

    pub fn dir(theta_deg: f32, phi_deg: f32) -> Vec3 {
        let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
        Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
    }

    /// The paper's capture: light at 0, 30, 50, 75 degrees in one plane, views every 8 degrees
    /// across the plane of incidence, plus a few out-of-plane views.
    pub fn paper_pairs() -> Vec<(Vec3, Vec3)> {
        let mut v = Vec::new();
        for lt in [0.0f32, 30.0, 50.0, 75.0] {
            for k in 0..21 {
                let vt = -80.0 + 8.0 * k as f32;
                v.push((
                    dir(lt, 180.0),
                    dir(vt.abs(), if vt < 0.0 { 180.0 } else { 0.0 }),
                ));
            }
            for vt in [20.0, 45.0, 70.0] {
                v.push((dir(lt, 180.0), dir(vt, 60.0)));
            }
        }
        v
    }

    pub fn random_pairs(n: usize, seed: u64) -> Vec<(Vec3, Vec3)> {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
        (0..n)
            .map(|_| {
                let a = dir(rng.gen_range(0.0..85.0), rng.gen_range(0.0..360.0));
                let b = dir(rng.gen_range(0.0..85.0), rng.gen_range(0.0..360.0));
                (a, b)
            })
            .collect()
    }

    /// Pairs near the mirror configuration (within `spread` degrees), for sharp lobes.
    pub fn mirror_pairs(n: usize, spread: f32, seed: u64) -> Vec<(Vec3, Vec3)> {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
        (0..n)
            .map(|_| {
                let t = rng.gen_range(10.0..70.0);
                let p = rng.gen_range(0.0..360.0);
                let l = dir(t, p);
                let v = dir(
                    t + rng.gen_range(-spread..spread),
                    p + 180.0 + rng.gen_range(-spread..spread),
                );
                (l, v)
            })
            .collect()
    }

    pub fn synth(
        m: &Lafortune,
        name: &str,
        pairs: &[(Vec3, Vec3)],
        noise: f32,
        seed: u64,
    ) -> Vec<BrdfSample> {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
        pairs
            .iter()
            .map(|&(l, v)| {
                let f = m.as_ref().eval(l, v) * std::f32::consts::PI;
                let n = Vec3::new(normal(&mut rng), normal(&mut rng), normal(&mut rng));
                BrdfSample {
                    material: name.into(),
                    light: l,
                    view: v,
                    value: (f * (Vec3::ONE + noise * n)).max(Vec3::ZERO),
                }
            })
            .collect()
    }

    /// Max relative error of the fitted model against the truth over `pairs`, relative to
    /// (true value + 5% of the mean true value) as in the residuals.
    pub fn heldout_rel(truth: &Lafortune, fit: &Lafortune, pairs: &[(Vec3, Vec3)]) -> (f32, f32) {
        let t: Vec<Vec3> = pairs
            .iter()
            .map(|&(l, v)| truth.as_ref().eval(l, v))
            .collect();
        let f: Vec<Vec3> = pairs
            .iter()
            .map(|&(l, v)| fit.as_ref().eval(l, v))
            .collect();
        let mean = t.iter().copied().sum::<Vec3>() / t.len() as f32;
        let (mut mx, mut s2) = (0.0f32, 0.0f32);
        for (a, b) in t.iter().zip(&f) {
            let e = (*b - *a).abs() / (*a + 0.05 * mean);
            mx = mx.max(e.max_element());
            s2 += e.length_squared();
        }
        (mx, (s2 / (3 * t.len()) as f32).sqrt())
    }

    fn truth() -> Lafortune {
        Lafortune {
            rho_d: Vec3::new(0.3, 0.25, 0.2),
            lobes: vec![
                Lobe {
                    rho: Vec3::new(0.08, 0.07, 0.06),
                    cxy: 0.8,
                    cz: 1.0,
                    n: 4.0,
                },
                Lobe {
                    rho: Vec3::new(2.0, 2.2, 2.4),
                    cxy: -1.0,
                    cz: 1.0,
                    n: 60.0,
                },
            ],
        }
    }

    fn rel(a: f32, b: f32) -> f32 {
        (a - b).abs() / b.abs()
    }

    #[test]
    fn recovers_known_parameters_from_exact_data() {
        let t = truth();
        let mut pairs = paper_pairs();
        pairs.extend(random_pairs(150, 1));
        let s = synth(&t, "m", &pairs, 0.0, 0);
        let r = fit_material("m", &s, &FitOptions::default()).unwrap();
        let b = &r.brdf;
        assert!(r.rms < 1e-3, "rms {}", r.rms);
        for c in 0..3 {
            assert!(rel(b.rho_d[c], t.rho_d[c]) < 0.01, "{b:?}");
            assert!(rel(b.lobes[0].rho[c], t.lobes[0].rho[c]) < 0.03, "{b:?}");
            assert!(rel(b.lobes[1].rho[c], t.lobes[1].rho[c]) < 0.02, "{b:?}");
        }
        assert!(
            rel(b.lobes[0].cxy, 0.8) < 0.02 && rel(b.lobes[0].n, 4.0) < 0.03,
            "{b:?}"
        );
        assert!(
            rel(b.lobes[1].cxy, -1.0) < 0.01 && rel(b.lobes[1].n, 60.0) < 0.01,
            "{b:?}"
        );
        // standard errors of exact data are tiny
        assert!(r.stderr.lobes[1].n < 0.1, "{:?}", r.stderr);
    }

    #[test]
    fn cz_not_one_is_recovered_as_an_equivalent_lobe() {
        // (cxy, cz) = (-0.95, 0.9) equals (cxy/cz, 1) with rho * 0.9^n.
        let t = Lafortune {
            rho_d: Vec3::splat(0.2),
            lobes: vec![Lobe {
                rho: Vec3::splat(3.0),
                cxy: -0.95,
                cz: 0.9,
                n: 40.0,
            }],
        };
        let mut pairs = paper_pairs();
        pairs.extend(random_pairs(150, 2));
        let r = fit_material("m", &synth(&t, "m", &pairs, 0.0, 0), &FitOptions::default()).unwrap();
        let spec = r.brdf.lobes[1];
        assert!(rel(spec.cxy, -0.95 / 0.9) < 0.01, "{spec:?}");
        assert!(rel(spec.n, 40.0) < 0.01, "{spec:?}");
        assert!(rel(spec.rho.x, 3.0 * 0.9f32.powf(40.0)) < 0.03, "{spec:?}");
        let (mx, _) = heldout_rel(&t, &r.brdf, &random_pairs(500, 99));
        assert!(mx < 0.02, "held-out max relative error {mx}");
    }

    #[test]
    fn stiff_exponent_1e4_is_recovered() {
        let n = 1.0e4f32;
        let t = Lafortune {
            rho_d: Vec3::splat(0.05),
            lobes: vec![Lobe {
                rho: Vec3::splat(0.5 * (n + 2.0) / std::f32::consts::TAU),
                cxy: -1.0,
                cz: 1.0,
                n,
            }],
        };
        let mut pairs = random_pairs(120, 3);
        pairs.extend(mirror_pairs(60, 1.5, 4));
        let r = fit_material("m", &synth(&t, "m", &pairs, 0.0, 0), &FitOptions::default()).unwrap();
        let spec = r.brdf.lobes[1];
        eprintln!(
            "n=1e4: fitted n {:.1} +- {:.1}, cxy {:.5}, rms {:.2e}",
            spec.n, r.stderr.lobes[1].n, spec.cxy, r.rms
        );
        assert!(rel(spec.n, n) < 0.05, "{spec:?} rms {}", r.rms);
        assert!(rel(spec.cxy, -1.0) < 0.001, "{spec:?}");
        assert!(rel(r.brdf.rho_d.x, 0.05) < 0.01, "{:?}", r.brdf);
        let (mx, _) = heldout_rel(&t, &r.brdf, &mirror_pairs(300, 1.5, 5));
        assert!(mx < 0.05, "held-out max relative error near the peak {mx}");
    }

    #[test]
    fn grazing_samples_beyond_85_degrees_fit() {
        let t = truth();
        let mut pairs = paper_pairs();
        let mut rng = rand_pcg::Pcg64::seed_from_u64(6);
        for _ in 0..60 {
            pairs.push((
                dir(rng.gen_range(85.0..89.5), rng.gen_range(0.0..360.0)),
                dir(rng.gen_range(85.0..89.5), rng.gen_range(0.0..360.0)),
            ));
        }
        let s = synth(&t, "m", &pairs, 0.0, 0);
        let r = fit_material("m", &s, &FitOptions::default()).unwrap();
        assert!(r.rms < 2e-3, "rms {}", r.rms);
        let mut graze = Vec::new();
        for _ in 0..200 {
            graze.push((
                dir(rng.gen_range(85.0..89.5), rng.gen_range(0.0..360.0)),
                dir(rng.gen_range(85.0..89.5), rng.gen_range(0.0..360.0)),
            ));
        }
        let (mx, _) = heldout_rel(&t, &r.brdf, &graze);
        assert!(mx < 0.02, "grazing held-out max relative error {mx}");
    }

    #[test]
    fn near_zero_reflectance_fits_relatively() {
        let mut t = truth();
        t.rho_d *= 1e-4;
        for l in &mut t.lobes {
            l.rho *= 1e-4;
        }
        let mut pairs = paper_pairs();
        pairs.extend(random_pairs(100, 7));
        let r = fit_material(
            "dark",
            &synth(&t, "dark", &pairs, 0.0, 0),
            &FitOptions::default(),
        )
        .unwrap();
        assert!(r.rms < 2e-3, "rms {}", r.rms);
        assert!(rel(r.brdf.rho_d.y, t.rho_d.y) < 0.01, "{:?}", r.brdf);
        assert!(rel(r.brdf.lobes[1].n, 60.0) < 0.02, "{:?}", r.brdf);
        // and a material that is black in one channel
        let mut t2 = truth();
        t2.rho_d.z = 0.0;
        t2.lobes[0].rho.z = 0.0;
        t2.lobes[1].rho.z = 0.0;
        let r2 = fit_material(
            "m",
            &synth(&t2, "m", &pairs, 0.0, 0),
            &FitOptions::default(),
        )
        .unwrap();
        assert!(
            r2.brdf.rho_d.z < 1e-6 && r2.brdf.lobes[1].rho.z < 1e-6,
            "{:?}",
            r2.brdf
        );
        assert!(rel(r2.brdf.rho_d.x, 0.3) < 0.01);
    }

    #[test]
    fn five_percent_noise() {
        let t = truth();
        let mut pairs = paper_pairs();
        pairs.extend(random_pairs(200, 8));
        let r = fit_material(
            "m",
            &synth(&t, "m", &pairs, 0.05, 9),
            &FitOptions::default(),
        )
        .unwrap();
        assert!(
            r.rms > 0.03 && r.rms < 0.06,
            "rms {} should be about the noise level",
            r.rms
        );
        for c in 0..3 {
            assert!(rel(r.brdf.rho_d[c], t.rho_d[c]) < 0.03, "{:?}", r.brdf);
        }
        assert!(rel(r.brdf.lobes[1].n, 60.0) < 0.15, "{:?}", r.brdf);
        // the standard error is consistent with the actual error (within 4 sigma)
        let err = (r.brdf.lobes[1].n - 60.0).abs() as f64;
        assert!(
            err < 4.0 * r.stderr.lobes[1].n + 1e-9,
            "n error {err}, stderr {}",
            r.stderr.lobes[1].n
        );
        let (_, rms) = heldout_rel(&t, &r.brdf, &random_pairs(500, 10));
        eprintln!(
            "5% noise: fit rms {:.4}, n = {:.2} +- {:.2}, rho_d {:?}, held-out rel rms {rms:.4}",
            r.rms, r.brdf.lobes[1].n, r.stderr.lobes[1].n, r.brdf.rho_d
        );
        assert!(rms < 0.03, "held-out relative rms {rms}");
    }

    #[test]
    fn ten_samples_converge_without_nan() {
        let t = truth();
        let pairs: Vec<_> = paper_pairs().into_iter().step_by(9).take(10).collect();
        assert_eq!(pairs.len(), 10);
        let r = fit_material("m", &synth(&t, "m", &pairs, 0.0, 0), &FitOptions::default()).unwrap();
        let b = &r.brdf;
        assert!(
            b.rho_d.is_finite()
                && b.lobes
                    .iter()
                    .all(|l| l.rho.is_finite() && l.n.is_finite() && l.n <= 2.0e4)
        );
        assert!(
            r.rms < 0.02,
            "10 samples, 13 parameters: data fitted, rms {}",
            r.rms
        );
        assert!(rel(b.rho_d.x, 0.3) < 0.1, "{b:?}");
    }

    #[test]
    fn unconstrained_lobe_gets_large_stderr_not_wild_values() {
        // Lambertian data with 2% noise: no lobe is supported by the data.
        let t = Lafortune::lambertian(Vec3::new(0.4, 0.5, 0.6));
        let mut pairs = paper_pairs();
        pairs.extend(random_pairs(100, 11));
        let r = fit_material(
            "m",
            &synth(&t, "m", &pairs, 0.02, 12),
            &FitOptions::default(),
        )
        .unwrap();
        for c in 0..3 {
            assert!(rel(r.brdf.rho_d[c], t.rho_d[c]) < 0.02, "{:?}", r.brdf);
        }
        let (mx, _) = heldout_rel(&t, &r.brdf, &random_pairs(500, 13));
        assert!(mx < 0.05, "predictions stay sane: max relative error {mx}");
        assert!(r.brdf.is_energy_conserving(), "{:?}", r.brdf);
        // at least one parameter of each lobe is undetermined: its standard error dwarfs its value
        for (l, e) in r.brdf.lobes.iter().zip(&r.stderr.lobes) {
            eprintln!("unconstrained: lobe {l:?} stderr {e:?}");
            let big = e.n > (l.n as f64)
                || e.cxy > l.cxy.abs() as f64
                || e.rho
                    .iter()
                    .zip(l.rho.to_array())
                    .any(|(s, v)| *s > v as f64);
            assert!(big, "lobe {l:?} stderr {e:?}");
            assert!(l.n >= 1.0 && l.n <= 2.0e4 && l.cxy.abs() < 30.0, "{l:?}");
        }
    }

    #[test]
    fn clear_errors() {
        let t = truth();
        let s = synth(&t, "m", &paper_pairs()[..4], 0.0, 0);
        let e = fit_material("m", &s, &FitOptions::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("`m`") && e.contains("4 samples are too few"),
            "{e}"
        );
        let mut s = synth(&t, "m", &paper_pairs(), 0.0, 0);
        s[3].value.y = f32::NAN;
        let e = fit_material("m", &s, &FitOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("sample 3 has non-finite"), "{e}");
    }
}
