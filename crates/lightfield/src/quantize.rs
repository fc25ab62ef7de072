//! Function quantization (Sec. 4.5, Eqs. 11-12): a codebook of lumispheres grown from one
//! codeword by Lloyd iteration on a seeded training subset and codeword splitting (each codeword
//! split into two with a smooth seeded perturbation) until it reaches its size (a power of two); then
//! every grid point takes the codeword of least E_lambda against its own data lumisphere.
//!
//! The projection step compares every data lumisphere with every codeword under E_lambda, which
//! is not a distance between fixed vectors (each point has its own sample directions), so no
//! nearest-neighbour tree applies: it is a brute-force search, parallel over points.

use crate::fit::{energy, fit_cluster, thin_energy, thin_weight, DataLumisphere, FitOptions};
use crate::lumisphere::Octahedron;
use crate::pfa::training_subset;
use glam::Vec3;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;

/// Options of function quantization.
#[derive(Clone, Copy, Debug)]
pub struct FqOptions {
    /// Codebook size (a power of two).
    pub codewords: usize,
    pub training: usize,
    /// Lloyd iterations per codebook size at most.
    pub lloyd_iterations: usize,
    /// Stop a Lloyd loop when the training error falls by less than this fraction.
    pub tolerance: f32,
    pub seed: u64,
    pub fit: FitOptions,
}

impl Default for FqOptions {
    fn default() -> Self {
        FqOptions {
            codewords: 256,
            training: 2000,
            lloyd_iterations: 4,
            tolerance: 1e-3,
            seed: 0,
            fit: FitOptions::default(),
        }
    }
}

/// A codebook and each grid point's codeword.
#[derive(Clone, Debug)]
pub struct Codebook {
    pub codewords: Vec<Vec<Vec3>>,
    pub index: Vec<u32>,
}

/// Grows and fits the codebook on a training subset, then assigns every point.
pub fn fit_fq(oct: &Octahedron, data: &[DataLumisphere], opts: &FqOptions) -> Codebook {
    let train_idx = training_subset(data, opts.training, opts.seed);
    let train: Vec<&DataLumisphere> = train_idx.iter().map(|&i| &data[i]).collect();
    let mut codebook = vec![fit_cluster(oct, &train, None, &opts.fit)];
    let mut rng = rand_pcg::Pcg64::seed_from_u64(opts.seed ^ 0x5eed_c0de);
    while codebook.len() < opts.codewords {
        codebook = split(oct, &codebook, &mut rng);
        lloyd(oct, &train, &mut codebook, opts);
    }
    let all: Vec<&DataLumisphere> = data.iter().collect();
    let index = assign(oct, &codebook, &all, &opts.fit);
    Codebook {
        codewords: codebook,
        index,
    }
}

/// Every codeword c split into c + d and c - d, d a smooth seeded perturbation: a random linear
/// function of the vertex direction times a random colour, of 10% of the codeword's RMS value
/// (at least 1e-3). A smooth d keeps both halves' thin-plate energy equal; a white-noise
/// perturbation made every clone rougher than its original, so that no clone ever won a data
/// lumisphere under E_lambda and the codebook stayed at its first few codewords.
fn split(oct: &Octahedron, codebook: &[Vec<Vec3>], rng: &mut rand_pcg::Pcg64) -> Vec<Vec<Vec3>> {
    let mut out = Vec::with_capacity(codebook.len() * 2);
    let mut unit = || rng.gen_range(-1.0f32..1.0);
    for c in codebook {
        let rms = (c.iter().map(|v| v.length_squared()).sum::<f32>() / c.len() as f32).sqrt();
        let eps = (0.1 * rms).max(1e-3);
        let g = Vec3::new(unit(), unit(), unit()).normalize_or(Vec3::Z);
        let colour = Vec3::new(unit(), unit(), unit()) * eps;
        let d: Vec<Vec3> = (0..c.len())
            .map(|k| colour * g.dot(oct.direction(k)))
            .collect();
        out.push(c.iter().zip(&d).map(|(v, d)| *v + *d).collect());
        out.push(c.iter().zip(&d).map(|(v, d)| *v - *d).collect());
    }
    out
}

/// Lloyd iteration (Eqs. 11-12) until the training error stops falling.
fn lloyd(
    oct: &Octahedron,
    train: &[&DataLumisphere],
    codebook: &mut [Vec<Vec3>],
    opts: &FqOptions,
) {
    let mut last = f32::INFINITY;
    for _ in 0..opts.lloyd_iterations {
        let idx = assign(oct, codebook, train, &opts.fit);
        let refit: Vec<Option<Vec<Vec3>>> = (0..codebook.len())
            .into_par_iter()
            .map(|k| {
                let members: Vec<&DataLumisphere> = train
                    .iter()
                    .zip(&idx)
                    .filter(|(_, i)| **i as usize == k)
                    .map(|(d, _)| *d)
                    .collect();
                (!members.is_empty())
                    .then(|| fit_cluster(oct, &members, Some(&codebook[k]), &opts.fit))
            })
            .collect();
        for (c, r) in codebook.iter_mut().zip(refit) {
            if let Some(r) = r {
                *c = r;
            }
        }
        let err = training_error(oct, codebook, train, &opts.fit);
        if last.is_finite() && last - err <= opts.tolerance * last {
            break;
        }
        last = err;
    }
}

fn training_error(
    oct: &Octahedron,
    codebook: &[Vec<Vec3>],
    train: &[&DataLumisphere],
    fit: &FitOptions,
) -> f32 {
    let tw = thin_weight(oct, fit.lambda);
    let thin: Vec<f32> = codebook.iter().map(|c| thin_energy(oct, c)).collect();
    let idx = assign(oct, codebook, train, fit);
    train
        .iter()
        .zip(&idx)
        .map(|(d, &k)| energy(d, &codebook[k as usize], thin[k as usize], tw))
        .sum::<f32>()
        / train.len().max(1) as f32
}

/// Eq. 11: each data lumisphere's codeword of least E_lambda (ties to the lower index).
pub fn assign(
    oct: &Octahedron,
    codebook: &[Vec<Vec3>],
    data: &[&DataLumisphere],
    fit: &FitOptions,
) -> Vec<u32> {
    let tw = thin_weight(oct, fit.lambda);
    let thin: Vec<f32> = codebook.iter().map(|c| thin_energy(oct, c)).collect();
    data.par_iter()
        .map(|d| {
            let mut best = (f32::INFINITY, 0u32);
            for (k, c) in codebook.iter().enumerate() {
                let e = energy(d, c, thin[k], tw);
                if e < best.0 {
                    best = (e, k as u32);
                }
            }
            best.1
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::Sample;

    #[test]
    fn four_constant_clusters_take_four_codewords() {
        let oct = Octahedron::new(2);
        let colours = [
            Vec3::new(0.5, 0.0, 0.0),
            Vec3::new(0.0, 0.5, 0.0),
            Vec3::new(0.0, 0.0, 0.5),
            Vec3::splat(-0.3),
        ];
        let dirs = igi_geometry::procedural::fibonacci_directions(24, 0.0);
        let data: Vec<DataLumisphere> = (0..200)
            .map(|i| DataLumisphere {
                samples: dirs
                    .iter()
                    .skip(i % 5)
                    .map(|d| Sample {
                        bary: oct.locate(*d),
                        colour: colours[i % 4],
                    })
                    .collect(),
            })
            .collect();
        let opts = FqOptions {
            codewords: 4,
            training: 100,
            ..FqOptions::default()
        };
        let cb = fit_fq(&oct, &data, &opts);
        for k in 0..4 {
            let first = cb.index[k];
            assert!(
                (0..200)
                    .filter(|i| i % 4 == k)
                    .all(|i| cb.index[i] == first),
                "cluster {k} split over codewords: {:?}",
                &cb.index[..8]
            );
            let v = oct.eval(&cb.codewords[first as usize], Vec3::Z);
            assert!(
                (v - colours[k]).length() < 0.02,
                "cluster {k}: {v} vs {}",
                colours[k]
            );
        }
        let used: std::collections::BTreeSet<u32> = cb.index.iter().copied().collect();
        assert_eq!(used.len(), 4);
    }
}
