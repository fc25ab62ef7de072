//! Lensch et al. 2001: lumitexels, BRDF clustering by splitting, per-lumitexel basis weights.
//!
//! A [`Lumitexel`] is a surface point, its normal and its samples `(light, view, rgb)` with world
//! directions (unit, pointing away from the surface) and `rgb` = pi times the BRDF (as in the
//! samples CSV). Directions are taken to the local frame of the normal (the model is isotropic, so
//! the tangent does not matter); samples with the light or the view below the surface are dropped.
//!
//! Clustering: fit one BRDF to all lumitexels (the staged LM fit of [`crate::fit`]); then, until there
//! are `k` clusters, split the cluster with the largest error: every member lumitexel proposes a
//! damped Gauss-Newton step of the cluster's parameters toward its own samples; the principal
//! direction `v` (and spread `sigma`) of these steps is the direction of largest parameter variance,
//! and the two children start at `p +- sigma v`. Each lumitexel is assigned to the BRDF that fits its
//! samples best, every cluster is refitted (LM, warm start), and assignment and refit repeat until
//! no lumitexel changes cluster. Finally each lumitexel gets least-squares weights over the cluster
//! BRDFs (SVD), `rgb ~ sum_k w_k pi f_k`.

use glam::Vec3;
use igi_imaging::csv::{Row, Table};
use nalgebra::{DMatrix, DVector, SymmetricEigen};
use rand::{seq::SliceRandom, SeedableRng};

use crate::fit::{fit_data, refine, Data, Model, Problem, NP};
use crate::{BrdfError, Frame, Lafortune, Lobe};

/// A surface point with its radiance samples.
#[derive(Clone, Debug, PartialEq)]
pub struct Lumitexel {
    pub position: Vec3,
    pub normal: Vec3,
    /// (direction to the light, direction to the viewer, pi times the BRDF value), world frame.
    pub samples: Vec<(Vec3, Vec3, Vec3)>,
}

/// Options of [`cluster`].
#[derive(Clone, Debug)]
pub struct ClusterOptions {
    /// Number of clusters (materials).
    pub k: usize,
    /// Assignment/refit rounds per split.
    pub max_rounds: usize,
    /// At most this many samples enter a cluster's fit (a seeded random subset).
    pub max_fit_samples: usize,
    /// Relative-residual floor (fraction of the mean value per channel), as in the fitter.
    pub rel_floor: f64,
    pub max_n: f64,
    pub seed: u64,
}

impl Default for ClusterOptions {
    fn default() -> Self {
        ClusterOptions {
            k: 2,
            max_rounds: 12,
            max_fit_samples: 3000,
            rel_floor: 0.05,
            max_n: 2.0e4,
            seed: 1,
        }
    }
}

/// The outcome of [`cluster`].
#[derive(Clone, Debug)]
pub struct ClusterResult {
    /// One BRDF per cluster (lobes: retroreflective, specular).
    pub brdfs: Vec<Lafortune>,
    /// Cluster of each lumitexel (`usize::MAX` for a lumitexel without usable samples).
    pub assignment: Vec<usize>,
    /// Per lumitexel, least-squares weights over `brdfs`.
    pub weights: Vec<Vec<f32>>,
    /// Per lumitexel, RMS relative residual under its cluster's BRDF.
    pub errors: Vec<f64>,
}

struct Local {
    light: Vec<[f64; 3]>,
    view: Vec<[f64; 3]>,
    value: Vec<[f64; 3]>,
}

fn to_local(lt: &Lumitexel) -> Local {
    let n = lt.normal.normalize_or_zero();
    let mut out = Local {
        light: vec![],
        view: vec![],
        value: vec![],
    };
    if n == Vec3::ZERO {
        return out;
    }
    let f = Frame::from_normal(n);
    for &(l, v, rgb) in &lt.samples {
        let (l, v) = (
            f.to_local(l.normalize_or_zero()),
            f.to_local(v.normalize_or_zero()),
        );
        if l.z > 0.0 && v.z > 0.0 && rgb.is_finite() {
            let d = |x: Vec3| [x.x as f64, x.y as f64, x.z as f64];
            out.light.push(d(l));
            out.view.push(d(v));
            out.value.push(d(rgb.max(Vec3::ZERO)));
        }
    }
    out
}

struct Ctx<'a> {
    locals: &'a [Local],
    floor: [f64; 3],
    model: Model,
    opts: &'a ClusterOptions,
}

impl Ctx<'_> {
    fn data_of(&self, members: &[usize]) -> Data {
        let mut idx: Vec<(usize, usize)> = members
            .iter()
            .flat_map(|&t| (0..self.locals[t].light.len()).map(move |i| (t, i)))
            .collect();
        if idx.len() > self.opts.max_fit_samples {
            let mut rng = rand_pcg::Pcg64::seed_from_u64(self.opts.seed ^ idx.len() as u64);
            idx.shuffle(&mut rng);
            idx.truncate(self.opts.max_fit_samples);
        }
        let g = |f: &dyn Fn(&Local, usize) -> [f64; 3]| {
            idx.iter()
                .map(|&(t, i)| f(&self.locals[t], i))
                .collect::<Vec<_>>()
        };
        Data::new(
            g(&|l, i| l.light[i]),
            g(&|l, i| l.view[i]),
            g(&|l, i| l.value[i]),
            self.floor,
        )
    }
    fn data_one(&self, t: usize) -> Data {
        let l = &self.locals[t];
        Data::new(l.light.clone(), l.view.clone(), l.value.clone(), self.floor)
    }
    /// Mean squared relative residual of lumitexel `t` under `p`.
    fn err(&self, t: usize, p: &[f64; NP]) -> f64 {
        let n = self.locals[t].light.len();
        self.data_one(t).cost(&self.model, p) / (3 * n).max(1) as f64
    }
    fn assign(&self, usable: &[usize], params: &[[f64; NP]]) -> Vec<usize> {
        let mut a = vec![usize::MAX; self.locals.len()];
        for &t in usable {
            let mut best = (0, f64::INFINITY);
            for (k, p) in params.iter().enumerate() {
                let e = self.err(t, p);
                if e < best.1 {
                    best = (k, e);
                }
            }
            a[t] = best.0;
        }
        a
    }
    /// Children of cluster `p` with `members`: p +- sigma v along the principal direction of the
    /// members' damped Gauss-Newton steps.
    fn split(&self, p: &[f64; NP], members: &[usize]) -> Option<([f64; NP], [f64; NP], Vec<f64>)> {
        let all: Vec<usize> = (0..NP).collect();
        let pooled = self.data_of(members);
        let pj = Problem {
            model: &self.model,
            data: &pooled,
            p: *p,
            free: all.clone(),
        }
        .jacobian_at(p, &all);
        let jtj = pj.transpose() * &pj;
        let per = pooled.light.len().max(1) as f64;
        // damping: the average per-sample curvature times a typical lumitexel's sample count
        let avg_n = members
            .iter()
            .map(|&t| self.locals[t].light.len())
            .sum::<usize>() as f64
            / members.len() as f64;
        let tr = (0..NP).map(|i| jtj[(i, i)]).sum::<f64>() / NP as f64;
        let damp: Vec<f64> = (0..NP)
            .map(|i| (jtj[(i, i)] / per * avg_n).max(1e-9 * tr / per * avg_n + 1e-12))
            .collect();
        let mut steps: Vec<DVector<f64>> = Vec::new();
        for &t in members {
            let d = self.data_one(t);
            let prob = Problem {
                model: &self.model,
                data: &d,
                p: *p,
                free: all.clone(),
            };
            let j = prob.jacobian_at(p, &all);
            let r = prob.residuals_at(p);
            let mut a = j.transpose() * &j;
            for i in 0..NP {
                a[(i, i)] += damp[i];
            }
            let b = -(j.transpose() * r);
            if let Some(x) = a.cholesky().map(|c| c.solve(&b)) {
                if x.iter().all(|v| v.is_finite()) {
                    steps.push(x);
                }
            }
        }
        if steps.len() < 2 {
            return None;
        }
        let mean = steps.iter().fold(DVector::zeros(NP), |acc, s| acc + s) / steps.len() as f64;
        let mut cov = DMatrix::zeros(NP, NP);
        for s in &steps {
            let d = s - &mean;
            cov += &d * d.transpose();
        }
        cov /= steps.len() as f64;
        let eig = SymmetricEigen::new(cov);
        let k = eig.eigenvalues.imax();
        let sigma = eig.eigenvalues[k].max(0.0).sqrt();
        if !(sigma > 0.0) {
            return None;
        }
        let v = eig.eigenvectors.column(k).into_owned();
        let proj: Vec<f64> = steps.iter().map(|s| (s - &mean).dot(&v)).collect();
        let (mut a, mut b) = (*p, *p);
        for i in 0..NP {
            a[i] += mean[i] + sigma * v[i];
            b[i] += mean[i] - sigma * v[i];
        }
        Some((a, b, proj))
    }
}

/// Split clustering of lumitexels into `opts.k` BRDFs, then per-lumitexel basis weights.
pub fn cluster(
    lumitexels: &[Lumitexel],
    opts: &ClusterOptions,
) -> Result<ClusterResult, BrdfError> {
    if opts.k == 0 {
        return Err(BrdfError::NoClusters);
    }
    let locals: Vec<Local> = lumitexels.iter().map(to_local).collect();
    let usable = usable_lumitexels(&locals, opts.k)?;
    let ctx = Ctx {
        locals: &locals,
        floor: residual_floor(&locals, &usable, opts.rel_floor),
        model: Model::plain(opts.max_n),
        opts,
    };

    let (p0, _, _) = fit_data(&ctx.model, &ctx.data_of(&usable));
    let mut params: Vec<[f64; NP]> = vec![p0];
    let mut assignment = ctx.assign(&usable, &params);
    while params.len() < opts.k {
        assignment = ctx.split_worst(&usable, &mut params, assignment)?;
    }
    ctx.refit_from_scratch(&usable, &mut params, &assignment);
    assignment = ctx.assign(&usable, &params);
    assignment = ctx.reseed_empty(&usable, &mut params, assignment)?;
    let brdfs: Vec<Lafortune> = params.iter().map(|p| ctx.model.to_lafortune(p)).collect();
    let weights = lumitexels
        .iter()
        .map(|lt| basis_weights(&brdfs, lt))
        .collect();
    let errors = ctx.errors(&assignment, &params);
    Ok(ClusterResult {
        brdfs,
        assignment,
        weights,
        errors,
    })
}

/// Indices of the lumitexels with samples above the surface; an error when they are too few
/// (or carry too few samples) for `k` clusters.
fn usable_lumitexels(locals: &[Local], k: usize) -> Result<Vec<usize>, BrdfError> {
    let usable: Vec<usize> = (0..locals.len())
        .filter(|&t| !locals[t].light.is_empty())
        .collect();
    let total: usize = usable.iter().map(|&t| locals[t].light.len()).sum();
    if usable.len() < k || total < 5 * k {
        return Err(BrdfError::TooFewLumitexels {
            lumitexels: usable.len(),
            samples: total,
            k,
        });
    }
    Ok(usable)
}

/// The relative-residual floor per channel: `rel_floor` times the mean sample value of the
/// usable lumitexels (plus a tiny constant, so a black channel still has a floor).
fn residual_floor(locals: &[Local], usable: &[usize], rel_floor: f64) -> [f64; 3] {
    let total: usize = usable.iter().map(|&t| locals[t].light.len()).sum();
    let mut mean = [0.0f64; 3];
    for &t in usable {
        for v in &locals[t].value {
            for c in 0..3 {
                mean[c] += v[c] / total as f64;
            }
        }
    }
    mean.map(|m| rel_floor * m + 1e-12)
}

impl Ctx<'_> {
    /// The usable lumitexels assigned to cluster `c`.
    fn members(&self, usable: &[usize], assignment: &[usize], c: usize) -> Vec<usize> {
        usable
            .iter()
            .copied()
            .filter(|&t| assignment[t] == c)
            .collect()
    }

    /// The cluster (of at least two members) with the largest total error.
    fn worst_cluster(&self, usable: &[usize], assignment: &[usize], params: &[[f64; NP]]) -> usize {
        let mut worst = (0usize, -1.0f64);
        for k in 0..params.len() {
            let e: f64 = usable
                .iter()
                .filter(|&&t| assignment[t] == k)
                .map(|&t| self.err(t, &params[k]))
                .sum();
            let members = usable.iter().filter(|&&t| assignment[t] == k).count();
            if members >= 2 && e > worst.1 {
                worst = (k, e);
            }
        }
        worst.0
    }

    /// Splits the worst cluster in two (one child replaces it, the other is appended to
    /// `params`), then assigns and refits until the assignment settles; returns the assignment.
    fn split_worst(
        &self,
        usable: &[usize],
        params: &mut Vec<[f64; NP]>,
        assignment: Vec<usize>,
    ) -> Result<Vec<usize>, BrdfError> {
        let k = self.worst_cluster(usable, &assignment, params);
        let members = self.members(usable, &assignment, k);
        let (a, b, proj) = self
            .split(&params[k], &members)
            .ok_or(BrdfError::Unsplittable {
                cluster: k,
                members: members.len(),
            })?;
        let kb = params.len();
        params[k] = a;
        params.push(b);
        let mut assignment = self.assign(usable, params);
        // a degenerate split (one child empty): fall back to the sign of the projection
        if !usable.iter().any(|&t| assignment[t] == kb)
            || !usable.iter().any(|&t| assignment[t] == k)
        {
            for (m, &t) in members.iter().enumerate() {
                assignment[t] = if proj[m] >= 0.0 { k } else { kb };
            }
        }
        Ok(self.settle(usable, params, assignment))
    }

    /// Alternates a warm-started refit of every cluster and a reassignment, at most
    /// `max_rounds` times or until no lumitexel changes cluster.
    fn settle(
        &self,
        usable: &[usize],
        params: &mut [[f64; NP]],
        mut assignment: Vec<usize>,
    ) -> Vec<usize> {
        for _round in 0..self.opts.max_rounds {
            for (c, p) in params.iter_mut().enumerate() {
                let mem = self.members(usable, &assignment, c);
                if !mem.is_empty() {
                    *p = refine(&self.model, &self.data_of(&mem), *p).0;
                }
            }
            let next = self.assign(usable, params);
            let changed = next != assignment;
            assignment = next;
            if !changed {
                break;
            }
        }
        assignment
    }

    /// Gives every cluster that lost all its members (k-means style) a new seed: the
    /// worst-fitting lumitexel of a cluster that keeps another member, fitted alone, then
    /// settles and refits. An empty cluster's parameters fit nothing (they were seen with a
    /// lobe rho of 4.85e8), so one that stays empty is an error, never a result.
    fn reseed_empty(
        &self,
        usable: &[usize],
        params: &mut [[f64; NP]],
        mut assignment: Vec<usize>,
    ) -> Result<Vec<usize>, BrdfError> {
        for _ in 0..=params.len() {
            let count = |a: &[usize], c: usize| usable.iter().filter(|&&t| a[t] == c).count();
            let Some(c) = (0..params.len()).find(|&c| count(&assignment, c) == 0) else {
                return Ok(assignment);
            };
            let seed = usable
                .iter()
                .copied()
                .filter(|&t| count(&assignment, assignment[t]) >= 2)
                .map(|t| (t, self.err(t, &params[assignment[t]])))
                .filter(|(_, e)| e.is_finite())
                .max_by(|a, b| a.1.total_cmp(&b.1));
            let Some((t, _)) = seed else {
                break;
            };
            assignment[t] = c;
            params[c] = fit_data(&self.model, &self.data_of(&[t])).0;
            assignment = self.settle(usable, params, assignment);
            self.refit_from_scratch(usable, params, &assignment);
            assignment = self.assign(usable, params);
        }
        match (0..params.len()).find(|&c| !usable.iter().any(|&t| assignment[t] == c)) {
            None => Ok(assignment),
            Some(c) => Err(BrdfError::EmptyCluster {
                cluster: c,
                k: params.len(),
            }),
        }
    }

    /// A final full refit of every cluster from scratch (multi-start), kept where it lowers the
    /// cluster's cost.
    fn refit_from_scratch(&self, usable: &[usize], params: &mut [[f64; NP]], assignment: &[usize]) {
        for (c, p) in params.iter_mut().enumerate() {
            let mem = self.members(usable, assignment, c);
            if !mem.is_empty() {
                let d = self.data_of(&mem);
                let (q, cost, _) = fit_data(&self.model, &d);
                if cost <= d.cost(&self.model, p) {
                    *p = q;
                }
            }
        }
    }

    /// RMS relative residual of every lumitexel under its cluster's BRDF (0 when unassigned).
    fn errors(&self, assignment: &[usize], params: &[[f64; NP]]) -> Vec<f64> {
        (0..self.locals.len())
            .map(|t| {
                if assignment[t] == usize::MAX {
                    0.0
                } else {
                    self.err(t, &params[assignment[t]]).sqrt()
                }
            })
            .collect()
    }
}

/// Least-squares weights `w` with `rgb ~ sum_k w_k pi f_k(light, view)` over the lumitexel's
/// samples and channels, solved with the SVD (minimum-norm for a rank-deficient basis).
/// Zeros when the lumitexel has no usable sample.
pub fn basis_weights(brdfs: &[Lafortune], lt: &Lumitexel) -> Vec<f32> {
    let l = to_local(lt);
    let m = 3 * l.light.len();
    if m == 0 || brdfs.is_empty() {
        return vec![0.0; brdfs.len()];
    }
    let mut a = DMatrix::<f64>::zeros(m, brdfs.len());
    let mut b = DVector::<f64>::zeros(m);
    for i in 0..l.light.len() {
        let f = |x: [f64; 3]| Vec3::new(x[0] as f32, x[1] as f32, x[2] as f32);
        let (li, vi) = (f(l.light[i]), f(l.view[i]));
        for (k, brdf) in brdfs.iter().enumerate() {
            let v = brdf.as_ref().eval(li, vi) * std::f32::consts::PI;
            for c in 0..3 {
                a[(3 * i + c, k)] = v[c] as f64;
            }
        }
        for c in 0..3 {
            b[3 * i + c] = l.value[i][c];
        }
    }
    let svd = a.svd(true, true);
    let eps = svd.singular_values.max() * 1e-9;
    match svd.solve(&b, eps) {
        Ok(x) => x
            .iter()
            .map(|v| if v.is_finite() { *v as f32 } else { 0.0 })
            .collect(),
        Err(_) => vec![0.0; brdfs.len()],
    }
}

/// The numeric columns of a lumitexels CSV, in the order [`lumitexel_row`] returns them.
const LUMITEXEL_COLUMNS: [&str; 15] = [
    "px", "py", "pz", "nx", "ny", "nz", "light_x", "light_y", "light_z", "view_x", "view_y",
    "view_z", "r", "g", "b",
];

/// Lumitexels CSV: `id,px,py,pz,nx,ny,nz,light_x,light_y,light_z,view_x,view_y,view_z,r,g,b`,
/// one row per sample, rows of one lumitexel share `id` (world directions, r g b = pi f).
/// Returns the ids (in order of first appearance) and the lumitexels.
pub fn read_lumitexels(path: &std::path::Path) -> Result<(Vec<String>, Vec<Lumitexel>), BrdfError> {
    let text = std::fs::read_to_string(path).map_err(|source| BrdfError::Io {
        path: path.into(),
        source,
    })?;
    let table = Table::parse(&text, path)?;
    let iid = table.column("id")?;
    let idx = table.columns(&LUMITEXEL_COLUMNS)?;
    table.require_rows("lumitexel rows")?;
    let mut ids: Vec<String> = Vec::new();
    let mut lts: Vec<Lumitexel> = Vec::new();
    let mut index = std::collections::HashMap::new();
    for row in table.rows() {
        let v = lumitexel_row(&table, row, &idx)?;
        let id = row.cells[iid].to_string();
        let t = *index.entry(id.clone()).or_insert_with(|| {
            ids.push(id);
            lts.push(Lumitexel {
                position: Vec3::new(v[0], v[1], v[2]),
                normal: Vec3::new(v[3], v[4], v[5]).normalize(),
                samples: vec![],
            });
            lts.len() - 1
        });
        lts[t].samples.push((
            Vec3::new(v[6], v[7], v[8]),
            Vec3::new(v[9], v[10], v[11]),
            Vec3::new(v[12], v[13], v[14]),
        ));
    }
    Ok((ids, lts))
}

/// The finite numbers of [`LUMITEXEL_COLUMNS`] in `row` (at positions `idx`); an error for a
/// non-number, a non-finite value or a zero normal.
fn lumitexel_row(table: &Table, row: &Row, idx: &[usize]) -> Result<[f32; 15], BrdfError> {
    let mut v = [0.0f32; 15];
    for k in 0..15 {
        v[k] = table.number_f32(row, idx[k], LUMITEXEL_COLUMNS[k])?;
    }
    if Vec3::new(v[3], v[4], v[5]).length() < 1e-6 {
        return Err(BrdfError::Parse {
            path: table.path().into(),
            line: row.line,
            msg: "zero normal".into(),
        });
    }
    Ok(v)
}

/// Three well-separated materials, the ground truth of the clustering tests and benchmark:
/// matte red with a weak retro lobe, glossy dark blue, and a strongly retroreflective grey.
pub fn separated_materials() -> [Lafortune; 3] {
    [
        // matte red with a weak retro lobe
        Lafortune {
            rho_d: Vec3::new(0.6, 0.12, 0.1),
            lobes: vec![Lobe {
                rho: Vec3::new(0.1, 0.02, 0.02),
                cxy: 0.9,
                cz: 1.0,
                n: 3.0,
            }],
        },
        // glossy dark blue
        Lafortune {
            rho_d: Vec3::new(0.04, 0.06, 0.3),
            lobes: vec![Lobe {
                rho: Vec3::splat(6.0),
                cxy: -1.0,
                cz: 1.0,
                n: 80.0,
            }],
        },
        // grey, strongly retroreflective
        Lafortune {
            rho_d: Vec3::splat(0.25),
            lobes: vec![Lobe {
                rho: Vec3::splat(0.6),
                cxy: 1.0,
                cz: 1.0,
                n: 12.0,
            }],
        },
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::tests::dir;
    use rand::Rng;

    fn materials() -> Vec<Lafortune> {
        separated_materials().to_vec()
    }

    /// `n_per` lumitexels per weight vector, `samples` random (light, view) pairs each, random normals.
    fn lumitexels(
        mix: &[Vec<f32>],
        n_per: usize,
        samples: usize,
        noise: f32,
        seed: u64,
    ) -> Vec<(Lumitexel, usize)> {
        let mats = materials();
        let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
        let mut out = Vec::new();
        for (label, w) in mix.iter().enumerate() {
            for _ in 0..n_per {
                let normal = dir(rng.gen_range(0.0..60.0), rng.gen_range(0.0..360.0));
                let f = Frame::from_normal(normal);
                let mut s = Vec::new();
                while s.len() < samples {
                    let l = dir(rng.gen_range(0.0..80.0), rng.gen_range(0.0..360.0));
                    // half the views near the mirror direction so glossy texels show their lobe
                    let v = if rng.gen_bool(0.5) {
                        dir(rng.gen_range(0.0..80.0), rng.gen_range(0.0..360.0))
                    } else {
                        let t = l.z.acos().to_degrees();
                        let p = l.y.atan2(l.x).to_degrees();
                        dir(
                            (t + rng.gen_range(-8.0..8.0)).clamp(0.0, 85.0),
                            p + 180.0 + rng.gen_range(-8.0..8.0),
                        )
                    };
                    let mut val = Vec3::ZERO;
                    for (k, m) in mats.iter().enumerate() {
                        val += w[k] * m.as_ref().eval(l, v) * std::f32::consts::PI;
                    }
                    let nz = Vec3::new(
                        rng.gen_range(-1.0..1.0),
                        rng.gen_range(-1.0..1.0),
                        rng.gen_range(-1.0..1.0),
                    );
                    s.push((f.to_world(l), f.to_world(v), val * (Vec3::ONE + noise * nz)));
                }
                out.push((
                    Lumitexel {
                        position: Vec3::ZERO,
                        normal,
                        samples: s,
                    },
                    label,
                ));
            }
        }
        out
    }

    /// Issue 36 item 4: two matte materials (albedo 0.1 and 0.8, 20 lumitexels each) in two
    /// clusters. It returned one empty cluster with a lobe rho of 4.85e8 and the other holding
    /// all 40 lumitexels.
    #[test]
    fn two_matte_materials_make_two_clusters_none_empty() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
        let mut lts = Vec::new();
        for albedo in [0.1f32, 0.8] {
            for _ in 0..20 {
                let normal = dir(rng.gen_range(0.0..40.0), rng.gen_range(0.0..360.0));
                let f = Frame::from_normal(normal);
                let samples = (0..12)
                    .map(|_| {
                        let l = dir(rng.gen_range(0.0..80.0), rng.gen_range(0.0..360.0));
                        let v = dir(rng.gen_range(0.0..80.0), rng.gen_range(0.0..360.0));
                        (f.to_world(l), f.to_world(v), Vec3::splat(albedo))
                    })
                    .collect();
                lts.push(Lumitexel {
                    position: Vec3::ZERO,
                    normal,
                    samples,
                });
            }
        }
        let r = cluster(
            &lts,
            &ClusterOptions {
                k: 2,
                ..Default::default()
            },
        )
        .unwrap();
        let first = r.assignment[0];
        assert!(
            r.assignment[..20].iter().all(|&a| a == first),
            "{:?}",
            r.assignment
        );
        assert!(
            r.assignment[20..].iter().all(|&a| a == 1 - first),
            "{:?}",
            r.assignment
        );
        for (k, albedo) in [(first, 0.1f32), (1 - first, 0.8)] {
            let b = &r.brdfs[k];
            eprintln!("cluster {k}: rho_d {:?}, lobes {:?}", b.rho_d, b.lobes);
            // what the cluster's BRDF predicts (pi f) is the matte albedo, within 10 %
            for (lt, lp, vt, vp) in [(30.0, 0.0, 30.0, 180.0), (10.0, 90.0, 60.0, 0.0)] {
                let y = b.as_ref().eval(dir(lt, lp), dir(vt, vp)) * std::f32::consts::PI;
                let rel = ((y - Vec3::splat(albedo)).abs() / albedo).max_element();
                assert!(
                    rel < 0.1,
                    "cluster {k}: pi f = {y:?} for albedo {albedo}: {b:?}"
                );
            }
            let lobe: f32 = b.lobes.iter().map(|l| l.rho.max_element()).sum();
            assert!(lobe.is_finite() && lobe < 1.0, "cluster {k}: {b:?}");
        }
        assert!(r.errors.iter().all(|e| e.is_finite()));
    }

    #[test]
    fn three_materials_cluster_with_high_purity() {
        let eye = vec![
            vec![1.0, 0.0, 0.0],
            vec![0.0, 1.0, 0.0],
            vec![0.0, 0.0, 1.0],
        ];
        let data = lumitexels(&eye, 60, 10, 0.03, 5);
        let lts: Vec<Lumitexel> = data.iter().map(|d| d.0.clone()).collect();
        let r = cluster(
            &lts,
            &ClusterOptions {
                k: 3,
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!(r.brdfs.len(), 3);
        // purity: each cluster counted by its majority label
        let mut counts = [[0usize; 3]; 3];
        for (t, (_, label)) in data.iter().enumerate() {
            counts[r.assignment[t]][*label] += 1;
        }
        let pure: usize = counts.iter().map(|c| *c.iter().max().unwrap()).sum();
        let purity = pure as f64 / data.len() as f64;
        eprintln!("clustering: purity {purity:.3}, counts {counts:?}");
        assert!(purity >= 0.95, "purity {purity}, counts {counts:?}");
        // the clusters map to distinct materials, and their diffuse colours are close to the truth
        let mats = materials();
        let mut seen = [false; 3];
        for (k, c) in counts.iter().enumerate() {
            let label = (0..3).max_by_key(|&i| c[i]).unwrap();
            assert!(
                !seen[label],
                "two clusters for material {label}: {counts:?}"
            );
            seen[label] = true;
            let d = (r.brdfs[k].rho_d - mats[label].rho_d).abs().max_element();
            assert!(
                d < 0.05,
                "cluster {k} rho_d {:?} vs {:?}",
                r.brdfs[k].rho_d,
                mats[label].rho_d
            );
        }
        assert!(r.errors.iter().all(|e| e.is_finite()));
    }

    #[test]
    fn known_mixtures_are_recovered_within_5_percent() {
        let mix = vec![
            vec![0.3, 0.7, 0.0],
            vec![0.5, 0.0, 0.5],
            vec![0.2, 0.3, 0.5],
        ];
        let data = lumitexels(&mix, 10, 15, 0.01, 9);
        let mats = materials();
        let mut worst = 0.0f32;
        for (lt, label) in &data {
            let w = basis_weights(&mats, lt);
            worst = (0..3)
                .map(|k| (w[k] - mix[*label][k]).abs())
                .fold(worst, f32::max);
            for k in 0..3 {
                assert!(
                    (w[k] - mix[*label][k]).abs() < 0.05,
                    "weights {w:?} vs {:?}",
                    mix[*label]
                );
            }
        }
        eprintln!("mixtures: largest weight error {worst:.4}");
    }

    #[test]
    fn bad_input_is_reported() {
        assert!(cluster(&[], &ClusterOptions::default()).is_err());
        let lt = Lumitexel {
            position: Vec3::ZERO,
            normal: Vec3::Z,
            samples: vec![(Vec3::Z, -Vec3::Z, Vec3::ONE)],
        };
        let e = cluster(
            &[lt.clone(), lt],
            &ClusterOptions {
                k: 2,
                ..Default::default()
            },
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("0 samples above the surface"), "{e}");
        assert!(cluster(
            &[],
            &ClusterOptions {
                k: 0,
                ..Default::default()
            }
        )
        .unwrap_err()
        .to_string()
        .contains("at least 1"));
    }
}
