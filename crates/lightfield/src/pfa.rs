//! Principal function analysis (Sec. 4.6, Eqs. 13-14): q + 1 prototype lumispheres spanning an
//! affine subspace; every data lumisphere is represented by the point of the prototypes' convex
//! hull that minimises E_lambda against its samples. The prototypes minimise E_lambda(V) over a
//! training subset plus the spring term mu sum_k ||P_k - P_mean||^2 (||F||^2 = sum of squared
//! vertex values / N_s). The minimisation alternates between the projections (a small convex
//! quadratic programme on the simplex per point) and the prototypes (a linear least-squares
//! problem solved by conjugate gradients); each step lowers Eq. 14.
//!
//! Initialisation: the mean and the q leading principal directions of the pointwise-faired
//! training lumispheres, with the prototypes on a regular simplex around the mean large enough
//! to contain every training point. Only the start uses faired lumispheres; the fit is to the data.

use crate::fit::{
    add_data_rhs, chunked_sum, conjugate_gradients, fair_pointwise, thin_normal, thin_weight,
    DataLumisphere, FitOptions,
};
use crate::lumisphere::{eval_bary, Octahedron};
use glam::Vec3;
use rand::SeedableRng;
use rayon::prelude::*;

/// Options of principal function analysis.
#[derive(Clone, Copy, Debug)]
pub struct PfaOptions {
    /// Subspace dimension q (>= 1): q + 1 prototypes.
    pub q: usize,
    /// Spring weight mu of Eq. 14.
    pub mu: f32,
    /// Alternations of projection and prototype fitting.
    pub iterations: usize,
    /// Size of the training subset (grid points with samples).
    pub training: usize,
    pub seed: u64,
    pub fit: FitOptions,
}

impl Default for PfaOptions {
    fn default() -> Self {
        PfaOptions {
            q: 2,
            mu: 1e-4,
            iterations: 6,
            training: 2000,
            seed: 0,
            fit: FitOptions::default(),
        }
    }
}

/// The fitted subspace and every point's barycentric coordinates in it.
#[derive(Clone, Debug)]
pub struct Pfa {
    pub prototypes: Vec<Vec<Vec3>>,
    /// Per grid point, q + 1 non-negative weights summing to 1.
    pub coefficients: Vec<Vec<f32>>,
    /// Eq. 14 on the training set after each alternation (non-increasing up to CG tolerance).
    pub energy_history: Vec<f32>,
}

/// A seeded training subset: indices of points with samples, at most `count`, in increasing order.
pub fn training_subset(data: &[DataLumisphere], count: usize, seed: u64) -> Vec<usize> {
    let seen: Vec<usize> = (0..data.len())
        .filter(|&i| !data[i].samples.is_empty())
        .collect();
    if seen.len() <= count {
        return seen;
    }
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let mut pick: Vec<usize> = rand::seq::index::sample(&mut rng, seen.len(), count)
        .into_iter()
        .map(|k| seen[k])
        .collect();
    pick.sort_unstable();
    pick
}

/// Fits the prototypes on a training subset and projects every data lumisphere.
pub fn fit_pfa(oct: &Octahedron, data: &[DataLumisphere], opts: &PfaOptions) -> Pfa {
    let train_idx = training_subset(data, opts.training, opts.seed);
    let train: Vec<&DataLumisphere> = train_idx.iter().map(|&i| &data[i]).collect();
    let mut prototypes = initial_prototypes(oct, &train, opts);
    let mut energy_history = Vec::new();
    for _ in 0..opts.iterations {
        let alphas: Vec<Vec<f32>> = project_all(oct, &prototypes, &train, &opts.fit);
        prototypes = fit_prototypes(oct, &train, &alphas, &prototypes, opts);
        let alphas = project_all(oct, &prototypes, &train, &opts.fit);
        energy_history.push(subspace_energy(oct, &prototypes, &train, &alphas, opts));
    }
    let all: Vec<&DataLumisphere> = data.iter().collect();
    let coefficients = project_all(oct, &prototypes, &all, &opts.fit);
    Pfa {
        prototypes,
        coefficients,
        energy_history,
    }
}

/// Eq. 14 on the training set for given projections.
pub fn subspace_energy(
    oct: &Octahedron,
    protos: &[Vec<Vec3>],
    train: &[&DataLumisphere],
    alphas: &[Vec<f32>],
    opts: &PfaOptions,
) -> f32 {
    let tw = thin_weight(oct, opts.fit.lambda);
    let e: f32 = train
        .iter()
        .zip(alphas)
        .map(|(d, a)| {
            let f = combine(protos, a);
            crate::fit::energy(d, &f, crate::fit::thin_energy(oct, &f), tw)
        })
        .sum::<f32>()
        / train.len().max(1) as f32;
    e + opts.mu * spring(protos)
}

fn spring(protos: &[Vec<Vec3>]) -> f32 {
    let n = protos[0].len();
    let mean = combine(protos, &vec![1.0 / protos.len() as f32; protos.len()]);
    protos
        .iter()
        .map(|p| {
            p.iter()
                .zip(&mean)
                .map(|(a, b)| (*a - *b).length_squared())
                .sum::<f32>()
        })
        .sum::<f32>()
        / n as f32
}

/// sum_k a_k P_k.
pub fn combine(protos: &[Vec<Vec3>], a: &[f32]) -> Vec<Vec3> {
    let mut f = vec![Vec3::ZERO; protos[0].len()];
    for (p, &w) in protos.iter().zip(a) {
        f.iter_mut().zip(p).for_each(|(o, v)| *o += *v * w);
    }
    f
}

fn project_all(
    oct: &Octahedron,
    protos: &[Vec<Vec3>],
    data: &[&DataLumisphere],
    fit: &FitOptions,
) -> Vec<Vec<f32>> {
    let k = protos.len();
    let tw = thin_weight(oct, fit.lambda);
    let lap: Vec<Vec<Vec3>> = protos
        .iter()
        .map(|p| {
            let mut l = vec![Vec3::ZERO; p.len()];
            oct.laplacian(p, &mut l);
            l
        })
        .collect();
    let mut gram = vec![0.0f32; k * k];
    for a in 0..k {
        for b in 0..k {
            gram[a * k + b] = tw
                * lap[a]
                    .iter()
                    .zip(&lap[b])
                    .map(|(x, y)| x.dot(*y))
                    .sum::<f32>();
        }
    }
    data.par_iter()
        .map(|d| project_one(protos, d, &gram))
        .collect()
}

/// The convex-hull projection of one data lumisphere: minimise a^T Q a - 2 r^T a over the simplex.
fn project_one(protos: &[Vec<Vec3>], d: &DataLumisphere, thin_gram: &[f32]) -> Vec<f32> {
    let k = protos.len();
    let mut q = thin_gram.to_vec();
    let mut r = vec![0.0f32; k];
    let m = d.samples.len().max(1) as f32;
    let mut vals = vec![Vec3::ZERO; k];
    for s in &d.samples {
        for (v, p) in vals.iter_mut().zip(protos) {
            *v = eval_bary(p, &s.bary);
        }
        for a in 0..k {
            r[a] += vals[a].dot(s.colour) / m;
            for b in 0..k {
                q[a * k + b] += vals[a].dot(vals[b]) / m;
            }
        }
    }
    simplex_qp(&q, &r, k)
}

/// Accelerated projected gradient for min a^T Q a - 2 r^T a, a in the simplex.
pub fn simplex_qp(q: &[f32], r: &[f32], k: usize) -> Vec<f32> {
    let lmax: f32 = (0..k)
        .map(|a| (0..k).map(|b| q[a * k + b].abs()).sum::<f32>())
        .fold(0.0, f32::max);
    let mut a = vec![1.0 / k as f32; k];
    if !(lmax > 1e-30) {
        return a;
    }
    let step = 0.5 / lmax;
    let mut y = a.clone();
    let mut t = 1.0f32;
    for _ in 0..300 {
        let g: Vec<f32> = (0..k)
            .map(|i| 2.0 * ((0..k).map(|j| q[i * k + j] * y[j]).sum::<f32>() - r[i]))
            .collect();
        let next = project_simplex(
            &y.iter()
                .zip(&g)
                .map(|(y, g)| y - step * g)
                .collect::<Vec<_>>(),
        );
        let t_next = 0.5 * (1.0 + (1.0 + 4.0 * t * t).sqrt());
        y = next
            .iter()
            .zip(&a)
            .map(|(n, o)| n + (t - 1.0) / t_next * (n - o))
            .collect();
        a = next;
        t = t_next;
    }
    a
}

/// Euclidean projection onto the probability simplex.
pub fn project_simplex(v: &[f32]) -> Vec<f32> {
    let mut u = v.to_vec();
    u.sort_by(|a, b| b.total_cmp(a));
    let (mut css, mut theta) = (0.0f32, 0.0f32);
    for (i, x) in u.iter().enumerate() {
        css += x;
        let th = (css - 1.0) / (i + 1) as f32;
        if x - th > 0.0 {
            theta = th;
        }
    }
    v.iter().map(|x| (x - theta).max(0.0)).collect()
}

/// The prototypes minimising Eq. 14 for fixed projections (normal equations, conjugate gradients).
fn fit_prototypes(
    oct: &Octahedron,
    train: &[&DataLumisphere],
    alphas: &[Vec<f32>],
    start: &[Vec<Vec3>],
    opts: &PfaOptions,
) -> Vec<Vec<Vec3>> {
    let (n, k) = (oct.len(), start.len());
    let t = train.len().max(1) as f32;
    let tw = thin_weight(oct, opts.fit.lambda);
    let pairs: Vec<(&DataLumisphere, &Vec<f32>)> = train.iter().copied().zip(alphas).collect();
    let b = chunked_sum(&pairs, n * k, |(d, a), acc| {
        for (c, w) in a.iter().enumerate() {
            if *w > 0.0 {
                add_data_rhs(d, w / t, &mut acc[c * n..(c + 1) * n]);
            }
        }
    });
    let mut s = vec![0.0f32; k * k];
    for a in alphas {
        for i in 0..k {
            for j in 0..k {
                s[i * k + j] += a[i] * a[j] / t;
            }
        }
    }
    let spring_w = opts.mu / n as f32;
    let mut x: Vec<Vec3> = start.iter().flatten().copied().collect();
    let mut apply = |v: &[Vec3], out: &mut [Vec3]| {
        apply_prototype_normal(oct, &pairs, &s, tw, spring_w, t, v, out)
    };
    conjugate_gradients(&mut apply, &b, &mut x, opts.fit.cg_iterations);
    x.chunks(n).map(|c| c.to_vec()).collect()
}

/// The normal operator of Eq. 14 in the stacked prototypes `v` (k blocks of N).
#[allow(clippy::too_many_arguments)]
fn apply_prototype_normal(
    oct: &Octahedron,
    pairs: &[(&DataLumisphere, &Vec<f32>)],
    s: &[f32],
    tw: f32,
    spring_w: f32,
    t: f32,
    v: &[Vec3],
    out: &mut [Vec3],
) {
    let n = oct.len();
    let k = v.len() / n;
    let data = chunked_sum(pairs, n * k, |(d, a), acc| {
        let m = d.samples.len().max(1) as f32;
        for smp in &d.samples {
            let f: Vec3 = (0..k)
                .map(|c| eval_bary(&v[c * n..(c + 1) * n], &smp.bary) * a[c])
                .sum();
            for (c, w) in a.iter().enumerate() {
                if *w > 0.0 {
                    let g = f * (w / (m * t));
                    for j in 0..3 {
                        acc[c * n + smp.bary.vertices[j] as usize] += g * smp.bary.weights[j];
                    }
                }
            }
        }
    });
    out.copy_from_slice(&data);
    let (mut tmp, mut lt) = (vec![Vec3::ZERO; n], vec![Vec3::ZERO; n]);
    let mean: Vec<Vec3> = (0..n)
        .map(|i| (0..k).map(|c| v[c * n + i]).sum::<Vec3>() / k as f32)
        .collect();
    for c in 0..k {
        let mix: Vec<Vec3> = (0..n)
            .map(|i| (0..k).map(|l| v[l * n + i] * s[c * k + l]).sum())
            .collect();
        thin_normal(oct, &mix, &mut tmp, &mut lt);
        for i in 0..n {
            out[c * n + i] += lt[i] * tw + (v[c * n + i] - mean[i]) * spring_w;
        }
    }
}

/// Mean and leading principal directions of the faired training lumispheres; prototypes on a
/// regular simplex (circumradius q times the largest training coordinate norm) around the mean.
fn initial_prototypes(
    oct: &Octahedron,
    train: &[&DataLumisphere],
    opts: &PfaOptions,
) -> Vec<Vec<Vec3>> {
    let owned: Vec<DataLumisphere> = train.iter().map(|d| (*d).clone()).collect();
    let faired = fair_pointwise(oct, &owned, &opts.fit);
    let n = oct.len();
    let mean: Vec<Vec3> = (0..n)
        .map(|i| faired.iter().map(|f| f[i]).sum::<Vec3>() / faired.len().max(1) as f32)
        .collect();
    let centred: Vec<Vec<f32>> = faired
        .iter()
        .map(|f| {
            f.iter()
                .zip(&mean)
                .flat_map(|(a, b)| (*a - *b).to_array())
                .collect()
        })
        .collect();
    let dirs = principal_directions(&centred, opts.q, 3 * n);
    let coords: Vec<Vec<f32>> = centred
        .iter()
        .map(|x| dirs.iter().map(|d| dot(x, d)).collect())
        .collect();
    let radius = coords
        .iter()
        .map(|c| dot(c, c).sqrt())
        .fold(0.0f32, f32::max)
        .max(1e-3)
        * opts.q as f32
        * 1.05;
    regular_simplex(opts.q)
        .iter()
        .map(|s| {
            let mut p: Vec<f32> = mean.iter().flat_map(|m| m.to_array()).collect();
            for (d, sd) in dirs.iter().zip(s) {
                p.iter_mut().zip(d).for_each(|(x, y)| *x += radius * sd * y);
            }
            p.chunks(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect()
        })
        .collect()
}

fn dot(a: &[f32], b: &[f32]) -> f32 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// q orthonormal leading eigenvectors of the sample covariance (power iteration with deflation,
/// deterministic start).
fn principal_directions(x: &[Vec<f32>], q: usize, dim: usize) -> Vec<Vec<f32>> {
    let mut dirs: Vec<Vec<f32>> = Vec::new();
    for c in 0..q {
        let mut v: Vec<f32> = (0..dim)
            .map(|i| ((i * 7919 + c * 104729) % 1009) as f32 / 1009.0 - 0.5)
            .collect();
        for _ in 0..60 {
            let mut w = vec![0.0f32; dim];
            for row in x {
                let p = dot(row, &v);
                w.iter_mut().zip(row).for_each(|(a, b)| *a += p * b);
            }
            for d in &dirs {
                let p = dot(&w, d);
                w.iter_mut().zip(d).for_each(|(a, b)| *a -= p * b);
            }
            let norm = dot(&w, &w).sqrt();
            if !(norm > 1e-20) {
                break;
            }
            v = w.iter().map(|a| a / norm).collect();
        }
        dirs.push(v);
    }
    dirs
}

/// Vertices (q + 1 of them) of a regular simplex in R^q, centred at 0 with circumradius 1.
pub fn regular_simplex(q: usize) -> Vec<Vec<f32>> {
    let k = q + 1;
    let centred: Vec<Vec<f32>> = (0..k)
        .map(|i| {
            (0..k)
                .map(|j| (if i == j { 1.0 } else { 0.0 }) - 1.0 / k as f32)
                .collect()
        })
        .collect();
    let mut basis: Vec<Vec<f32>> = Vec::new();
    for v in centred.iter().take(q) {
        let mut u = v.clone();
        for b in &basis {
            let p = dot(&u, b);
            u.iter_mut().zip(b).for_each(|(x, y)| *x -= p * y);
        }
        let nrm = dot(&u, &u).sqrt();
        basis.push(u.iter().map(|x| x / nrm).collect());
    }
    let r = (1.0 - 1.0 / k as f32).sqrt();
    centred
        .iter()
        .map(|v| basis.iter().map(|b| dot(v, b) / r).collect())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn simplex_projection_and_qp_match_analytic_answers() {
        assert_eq!(project_simplex(&[0.2, 0.3, 0.5]), vec![0.2, 0.3, 0.5]);
        let p = project_simplex(&[2.0, 0.0, 0.0]);
        assert!((p[0] - 1.0).abs() < 1e-6 && p[1] == 0.0);
        // min |a - c|^2 with c inside the simplex: a = c
        let q = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        let a = simplex_qp(&q, &[0.1, 0.6, 0.3], 3);
        assert!(
            (a[0] - 0.1).abs() < 1e-4 && (a[1] - 0.6).abs() < 1e-4,
            "{a:?}"
        );
        // c outside: the nearest simplex point
        let a = simplex_qp(&q, &[1.5, 0.5, -1.0], 3);
        assert!((a[0] - 1.0).abs() < 1e-3 && a[1].abs() < 1e-3, "{a:?}");
    }

    #[test]
    fn the_regular_simplex_has_equal_edges_and_unit_circumradius() {
        for q in 1..6 {
            let s = regular_simplex(q);
            assert_eq!(s.len(), q + 1);
            let edge = |a: &Vec<f32>, b: &Vec<f32>| {
                a.iter()
                    .zip(b)
                    .map(|(x, y)| (x - y).powi(2))
                    .sum::<f32>()
                    .sqrt()
            };
            let e0 = edge(&s[0], &s[1]);
            for i in 0..=q {
                assert!((dot(&s[i], &s[i]).sqrt() - 1.0).abs() < 1e-5);
                for j in 0..i {
                    assert!((edge(&s[i], &s[j]) - e0).abs() < 1e-4);
                }
            }
        }
    }
}
