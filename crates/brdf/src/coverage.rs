//! Coverage weights of BRDF samples: how much of the space of direction pairs each sample stands
//! for.
//!
//! An isotropic, reciprocal BRDF is a function of `(cos theta_l, cos theta_v, |phi_l - phi_v|)`,
//! unchanged by swapping the two directions; direction pairs uniform on the hemisphere are uniform
//! in `(mu_a, mu_b, dphi / pi)` with `mu_a >= mu_b` (the larger and the smaller cosine). A
//! sample's weight is the volume of its Voronoi cell in that box (Monte-Carlo with a fixed seed,
//! nearest sample by kiddo), normalised to a mean of 1 and capped, so a weighted fit approximates
//! the error integrated over all direction pairs instead of over where the samples cluster (a
//! hand-held capture: mostly near-normal lights, few grazing pairs).

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rand::{Rng, SeedableRng};

/// Monte-Carlo points per sample (plus a fixed base).
const POINTS_PER_SAMPLE: usize = 200;

/// Point of the isotropic pair space of the directions `l`, `v` (unit, z up).
fn pair_point(l: &[f64; 3], v: &[f64; 3]) -> [f64; 3] {
    let (ml, mv) = (l[2].clamp(0.0, 1.0), v[2].clamp(0.0, 1.0));
    let mut d = (l[1].atan2(l[0]) - v[1].atan2(v[0])).abs() % std::f64::consts::TAU;
    if d > std::f64::consts::PI {
        d = std::f64::consts::TAU - d;
    }
    [ml.max(mv), ml.min(mv), d / std::f64::consts::PI]
}

/// The distinct pair points (to 1e-9) of the first `n` samples, and each sample's index among them.
fn unique_points(light: &[[f64; 3]], view: &[[f64; 3]], n: usize) -> (Vec<[f64; 3]>, Vec<usize>) {
    let mut unique = Vec::new();
    let mut index = std::collections::HashMap::new();
    let of = (0..n)
        .map(|i| {
            let p = pair_point(&light[i], &view[i]);
            let key = p.map(|x| (x * 1e9).round() as i64);
            *index.entry(key).or_insert_with(|| {
                unique.push(p);
                unique.len() - 1
            })
        })
        .collect();
    (unique, of)
}

/// Coverage weights of the sample pairs `(light[i], view[i])`: mean 1, each at most `cap`
/// (`cap >= 1`; the capped mass goes to the others by renormalising).
pub fn coverage_weights(light: &[[f64; 3]], view: &[[f64; 3]], cap: f64) -> Vec<f64> {
    let n = light.len().min(view.len());
    if n == 0 {
        return Vec::new();
    }
    let (unique, of) = unique_points(light, view, n);
    let tree: ImmutableKdTree<f64, 3> = ImmutableKdTree::new_from_slice(&unique);
    let mut rng = rand_pcg::Pcg64::seed_from_u64(0x5eed_c0fe);
    let m = 4000 + POINTS_PER_SAMPLE * n;
    let mut cell = vec![0.0f64; unique.len()];
    for _ in 0..m {
        let (a, b): (f64, f64) = (rng.gen(), rng.gen());
        let q = [a.max(b), a.min(b), rng.gen::<f64>()];
        let i = tree.nearest_one::<SquaredEuclidean>(&q).item as usize;
        cell[i.min(unique.len() - 1)] += 1.0;
    }
    // samples at the same point (repeated measurements) share its cell
    let mut mult = vec![0.0f64; unique.len()];
    of.iter().for_each(|&u| mult[u] += 1.0);
    let count: Vec<f64> = of.iter().map(|&u| cell[u] / mult[u]).collect();
    let cap = cap.max(1.0);
    // water-filling: the scale s with mean(min(s c_i, cap)) = 1 (bisection; s c_i = cap
    // for the capped samples, the others share the rest in proportion to their cells)
    let mean_at = |s: f64| count.iter().map(|c| (s * c).min(cap)).sum::<f64>() / n as f64;
    let (mut lo, mut hi) = (0.0, n as f64 / count.iter().sum::<f64>().max(1.0));
    while mean_at(hi) < 1.0 && hi < 1e300 {
        hi *= 2.0;
    }
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if mean_at(mid) < 1.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    count.iter().map(|c| (hi * c).min(cap)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(theta_deg: f64, phi_deg: f64) -> [f64; 3] {
        let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
        [t.sin() * p.cos(), t.sin() * p.sin(), t.cos()]
    }

    /// Samples spread evenly over the pair space get equal weights; a cluster of near-normal
    /// samples shares the weight of its region while a lone grazing sample gets a large one.
    #[test]
    fn weights_follow_the_coverage_of_the_pair_space() {
        // 4 x 4 x 4 grid of cell centres in (mu_a, mu_b, dphi) folded: use mu_l, mu_v, dphi
        let (mut l, mut v) = (Vec::new(), Vec::new());
        for i in 0..6 {
            for j in 0..=i {
                for k in 0..4 {
                    let (ma, mb) = ((i as f64 + 0.5) / 6.0, (j as f64 + 0.5) / 6.0);
                    l.push(dir(ma.acos().to_degrees(), 0.0));
                    v.push(dir(mb.acos().to_degrees(), (k as f64 + 0.5) * 45.0));
                }
            }
        }
        let w = coverage_weights(&l, &v, 1e9);
        let (lo, hi) = w
            .iter()
            .fold((f64::MAX, 0.0f64), |a, &x| (a.0.min(x), a.1.max(x)));
        let mean = w.iter().sum::<f64>() / w.len() as f64;
        assert!((mean - 1.0).abs() < 1e-6);
        // the diagonal cells are half cells of the folded box: weights 0.5 .. 1.x
        assert!(lo > 0.35 && hi < 1.6, "{lo} {hi}");

        // 30 near-normal pairs and one grazing pair
        let mut l: Vec<[f64; 3]> = (0..30).map(|k| dir(5.0 + k as f64 * 0.3, 0.0)).collect();
        let mut v: Vec<[f64; 3]> = (0..30).map(|k| dir(10.0, k as f64 * 6.2)).collect();
        l.push(dir(80.0, 0.0));
        v.push(dir(85.0, 180.0));
        let w = coverage_weights(&l, &v, 1e9);
        assert!(
            w[30] > 10.0 * w[..30].iter().cloned().fold(0.0, f64::max),
            "{w:?}"
        );
        let capped = coverage_weights(&l, &v, 4.0);
        assert!(capped.iter().all(|&x| x <= 4.0 && x > 0.0), "{capped:?}");
        assert!((capped[30] - 4.0).abs() < 1e-3, "{}", capped[30]);
        assert!(coverage_weights(&[], &[], 4.0).is_empty());

        // repeated measurements of one pair share its cell: equal weights, as without repeats
        let (mut l3, mut v3) = (l.clone(), v.clone());
        for _ in 0..2 {
            l3.push(l[30]);
            v3.push(v[30]);
        }
        let w3 = coverage_weights(&l3, &v3, 1e9);
        assert!((w3[30] - w3[31]).abs() < 1e-12 && (w3[31] - w3[32]).abs() < 1e-12);
        let per = w[30] / w.len() as f64;
        let per3 = 3.0 * w3[30] / w3.len() as f64;
        assert!((per - per3).abs() < 0.02 * per, "{per} {per3}"); // MC noise only
                                                                  // all samples at one point: all weights 1
        let same = coverage_weights(&[[0.0, 0.0, 1.0]; 5], &[[0.6, 0.0, 0.8]; 5], 4.0);
        assert!(same.iter().all(|&x| (x - 1.0).abs() < 1e-9), "{same:?}");
    }
}
