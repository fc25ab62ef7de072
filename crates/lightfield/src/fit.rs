//! Fitting lumispheres to the irregular data lumispheres (Sec. 4 of Wood et al. 2000):
//! pointwise fairing (Eqs. 5-8), function quantization (Eqs. 11-12) and principal function
//! analysis (Eqs. 13-14). Every fit minimises E_lambda against the data samples themselves
//! (never against faired lumispheres); the samples are already reparameterised (median removed,
//! divided by the view-angle gain, directions reflected about the normal, Eqs. 9-10).
//!
//! Sums over points are taken in fixed chunks whose partial sums are added in order, so results
//! are the same bytes whatever the rayon thread count.

use crate::lumisphere::{eval_bary, Bary, Octahedron};
use glam::Vec3;
use rayon::prelude::*;

/// One reparameterised observation of a grid point: where its reflected direction falls on the
/// lumisphere and its colour minus the point's median, over the view-angle gain at its n . w.
#[derive(Clone, Copy, Debug)]
pub struct Sample {
    pub bary: Bary,
    pub colour: Vec3,
}

/// The reparameterised data lumisphere of one grid point.
#[derive(Clone, Debug, Default)]
pub struct DataLumisphere {
    pub samples: Vec<Sample>,
}

/// Options shared by the fits.
#[derive(Clone, Copy, Debug)]
pub struct FitOptions {
    /// The fairing weight lambda of Eq. 8 (> 0).
    pub lambda: f32,
    /// Conjugate-gradient iterations per solve.
    pub cg_iterations: usize,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            lambda: 0.02,
            cg_iterations: 120,
        }
    }
}

pub(crate) const CHUNK: usize = 64;

/// lambda' = lambda N_s / (4 pi): the weight of sum_k |Delta F(w_k)|^2 in Eq. 7.
pub(crate) fn thin_weight(oct: &Octahedron, lambda: f32) -> f32 {
    lambda * oct.len() as f32 / (4.0 * std::f32::consts::PI)
}

/// L^T L x (the thin-plate normal operator), into `out`.
pub(crate) fn thin_normal(oct: &Octahedron, x: &[Vec3], tmp: &mut [Vec3], out: &mut [Vec3]) {
    oct.laplacian(x, tmp);
    oct.laplacian_transpose(tmp, out);
}

/// out += s * (1/m) B^T B x for one data lumisphere.
pub(crate) fn add_data_normal(d: &DataLumisphere, s: f32, x: &[Vec3], out: &mut [Vec3]) {
    if d.samples.is_empty() {
        return;
    }
    let k = s / d.samples.len() as f32;
    for smp in &d.samples {
        let v = eval_bary(x, &smp.bary) * k;
        for t in 0..3 {
            out[smp.bary.vertices[t] as usize] += v * smp.bary.weights[t];
        }
    }
}

/// out += s * (1/m) B^T c for one data lumisphere.
pub(crate) fn add_data_rhs(d: &DataLumisphere, s: f32, out: &mut [Vec3]) {
    if d.samples.is_empty() {
        return;
    }
    let k = s / d.samples.len() as f32;
    for smp in &d.samples {
        for t in 0..3 {
            out[smp.bary.vertices[t] as usize] += smp.colour * (k * smp.bary.weights[t]);
        }
    }
}

fn dot3(a: &[Vec3], b: &[Vec3]) -> Vec3 {
    a.iter().zip(b).fold(Vec3::ZERO, |s, (x, y)| s + *x * *y)
}

/// Conjugate gradients for an SPD operator, run on the three colour channels at once (each
/// channel its own step sizes). Starts from `x`.
pub fn conjugate_gradients(
    apply: &mut dyn FnMut(&[Vec3], &mut [Vec3]),
    b: &[Vec3],
    x: &mut [Vec3],
    iterations: usize,
) {
    let n = b.len();
    let mut ax = vec![Vec3::ZERO; n];
    apply(x, &mut ax);
    let mut r: Vec<Vec3> = b.iter().zip(&ax).map(|(b, a)| *b - *a).collect();
    let mut p = r.clone();
    let mut rr = dot3(&r, &r);
    let bb = dot3(b, b).max_element().max(1e-30);
    for _ in 0..iterations {
        if rr.max_element() <= 1e-14 * bb {
            break;
        }
        apply(&p, &mut ax);
        let pap = dot3(&p, &ax);
        let alpha = Vec3::select(pap.cmpgt(Vec3::splat(1e-30)), rr / pap, Vec3::ZERO);
        for i in 0..n {
            x[i] += alpha * p[i];
            r[i] -= alpha * ax[i];
        }
        let rr_new = dot3(&r, &r);
        let beta = Vec3::select(rr.cmpgt(Vec3::splat(1e-30)), rr_new / rr, Vec3::ZERO);
        for i in 0..n {
            p[i] = r[i] + beta * p[i];
        }
        rr = rr_new;
    }
}

/// E_lambda(F, L) of Eq. 8 (summed over the colour channels); `thin` is sum_k |Delta F(w_k)|^2
/// of F (precomputed, it does not depend on the data).
pub fn energy(d: &DataLumisphere, f: &[Vec3], thin: f32, thin_w: f32) -> f32 {
    let dist = if d.samples.is_empty() {
        0.0
    } else {
        d.samples
            .iter()
            .map(|s| (eval_bary(f, &s.bary) - s.colour).length_squared())
            .sum::<f32>()
            / d.samples.len() as f32
    };
    dist + thin_w * thin
}

/// sum_k |Delta F(w_k)|^2.
pub fn thin_energy(oct: &Octahedron, f: &[Vec3]) -> f32 {
    let mut l = vec![Vec3::ZERO; f.len()];
    oct.laplacian(f, &mut l);
    l.iter().map(|v| v.length_squared()).sum()
}

/// Pointwise fairing (Eq. 8): one piecewise-linear lumisphere per data lumisphere, in parallel.
/// A point without samples gets the zero lumisphere (its median alone).
pub fn fair_pointwise(
    oct: &Octahedron,
    data: &[DataLumisphere],
    opts: &FitOptions,
) -> Vec<Vec<Vec3>> {
    data.par_iter()
        .map(|d| fit_cluster(oct, &[d], None, opts))
        .collect()
}

/// The lumisphere minimising sum_i E_lambda(F, L_i) over a set of data lumispheres (Eq. 12; one
/// member is Eq. 8), by conjugate gradients from `start` (zero when `None`).
pub fn fit_cluster(
    oct: &Octahedron,
    members: &[&DataLumisphere],
    start: Option<&[Vec3]>,
    opts: &FitOptions,
) -> Vec<Vec3> {
    let n = oct.len();
    let mut x = start
        .map(|s| s.to_vec())
        .unwrap_or_else(|| vec![Vec3::ZERO; n]);
    if members.iter().all(|d| d.samples.is_empty()) {
        return x;
    }
    let tw = thin_weight(oct, opts.lambda) * members.len() as f32;
    let mut b = vec![Vec3::ZERO; n];
    members.iter().for_each(|d| add_data_rhs(d, 1.0, &mut b));
    let mut tmp = vec![Vec3::ZERO; n];
    let mut thin = vec![Vec3::ZERO; n];
    let mut apply = |v: &[Vec3], out: &mut [Vec3]| {
        thin_normal(oct, v, &mut tmp, &mut thin);
        out.iter_mut().zip(&thin).for_each(|(o, t)| *o = *t * tw);
        if members.len() > CHUNK {
            let data = chunked_sum(members, n, |d, acc| add_data_normal(d, 1.0, v, acc));
            out.iter_mut().zip(data).for_each(|(o, d)| *o += d);
        } else {
            members.iter().for_each(|d| add_data_normal(d, 1.0, v, out));
        }
    };
    conjugate_gradients(&mut apply, &b, &mut x, opts.cg_iterations);
    x
}

/// Chunked, order-stable parallel sum of per-point contributions into an `len`-vector.
pub(crate) fn chunked_sum<T: Sync>(
    items: &[T],
    len: usize,
    f: impl Fn(&T, &mut [Vec3]) + Sync,
) -> Vec<Vec3> {
    let partials: Vec<Vec<Vec3>> = items
        .par_chunks(CHUNK)
        .map(|chunk| {
            let mut acc = vec![Vec3::ZERO; len];
            chunk.iter().for_each(|it| f(it, &mut acc));
            acc
        })
        .collect();
    let mut out = vec![Vec3::ZERO; len];
    for p in partials {
        out.iter_mut().zip(p).for_each(|(o, v)| *o += v);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(oct: &Octahedron, w: Vec3, c: Vec3) -> Sample {
        Sample {
            bary: oct.locate(w),
            colour: c,
        }
    }

    #[test]
    fn fairing_recovers_a_lumisphere_sampled_at_its_vertices_and_fills_the_gaps_smoothly() {
        let oct = Octahedron::new(3);
        // a smooth function of direction, sampled at every vertex direction of the upper half
        let truth = |w: Vec3| Vec3::new(w.z.max(0.0), 0.5 * w.x + 0.5, 0.2);
        let samples: Vec<Sample> = (0..oct.len())
            .map(|v| oct.direction(v))
            .filter(|w| w.z > -0.05)
            .map(|w| sample(&oct, w, truth(w)))
            .collect();
        let d = DataLumisphere { samples };
        let f = fit_cluster(
            &oct,
            &[&d],
            None,
            &FitOptions {
                lambda: 1e-4,
                cg_iterations: 500,
            },
        );
        for v in 0..oct.len() {
            let w = oct.direction(v);
            if w.z > 0.0 {
                assert!(
                    (f[v] - truth(w)).length() < 0.02,
                    "vertex {v} {w}: {} vs {}",
                    f[v],
                    truth(w)
                );
            }
        }
        // the unobserved lower half is filled (finite, bounded by the data range)
        assert!(f
            .iter()
            .all(|v| v.is_finite() && v.max_element() < 2.0 && v.min_element() > -1.0));
        // fairing energy: a larger lambda smooths more
        let rough = thin_energy(&oct, &f);
        let smooth = fit_cluster(
            &oct,
            &[&d],
            None,
            &FitOptions {
                lambda: 1.0,
                cg_iterations: 500,
            },
        );
        assert!(thin_energy(&oct, &smooth) < rough);
    }

    #[test]
    fn conjugate_gradients_solves_a_diagonal_system_per_channel() {
        let b = vec![Vec3::new(1.0, 2.0, 3.0), Vec3::new(4.0, 0.0, -1.0)];
        let diag = [Vec3::new(2.0, 1.0, 4.0), Vec3::new(1.0, 3.0, 0.5)];
        let mut x = vec![Vec3::ZERO; 2];
        conjugate_gradients(
            &mut |v: &[Vec3], o: &mut [Vec3]| {
                o[0] = v[0] * diag[0];
                o[1] = v[1] * diag[1];
            },
            &b,
            &mut x,
            10,
        );
        assert!((x[0] - Vec3::new(0.5, 2.0, 0.75)).length() < 1e-5);
        assert!((x[1] - Vec3::new(4.0, 0.0, -2.0)).length() < 1e-5);
    }
}
