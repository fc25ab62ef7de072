//! The documented weighting and stability rules of the ratio update.
//!
//! For a texel `p` seen by photo `I`:
//! - **View angle.** The weight starts at `cos(view angle)`; views more grazing than
//!   `min_cos` are dropped (their pixel footprint smears over a long stretch of surface).
//! - **Occlusion boundaries.** Rays from the camera through the projected pixel offset by
//!   `boundary_offset_px` in the four axis directions must land on the texel's tangent plane,
//!   where that plane would put them, within `depth_tolerance` times the camera distance
//!   (comparing with the texel's own depth instead would flag every surface seen at a grazing
//!   angle, whose depth changes by several percent per pixel); otherwise the pixel's footprint mixes two surfaces (or a
//!   slightly misregistered photo puts the wrong surface there) and the weight is multiplied
//!   by `boundary_factor`. The rays must also meet a surface whose normal agrees with the
//!   texel's (`|cos| >= min_normal_agreement`), which catches convex edges where depth barely
//!   changes.
//! - **Only unreliable views.** A texel whose every observation is near an occlusion boundary
//!   or on a shadow edge is not counted as seen: it is filled from its neighbours (see
//!   [`crate::fill`]) rather than trusted.
//! - **Shadow edges.** When the photo's lighting has a sun, a texel whose sun visibility differs
//!   from that of an atlas neighbour lies on a shadow edge, where a small misregistration or
//!   the sun's penumbra changes the pixel a lot: weight times `shadow_edge_factor`.
//! - **Saturated or invalid pixels** (the image's validity mask, any of the four bilinear taps)
//!   are dropped.
//! - **Near-zero rendered radiance** (deep shadow): an observation whose rendered luminance is
//!   below `min_radiance_fraction` of the photo's median rendered luminance, or whose Monte-Carlo
//!   relative standard error exceeds `max_rel_stderr`, is dropped: the ratio `I / L` is
//!   meaningless there.
//! - **Outliers.** With three or more observations, proposals whose luminance is more than
//!   `outlier_ratio` times away from the weighted median (either way) are dropped before the
//!   weighted mean (a misregistered photo or a transient object).
//! - **One observation** is kept (its count is reported, so users can mask such texels).
//! - Proposals are clamped to `[0, max_albedo]` per channel.

use glam::Vec3;
use igi_brdf::luminance;
use serde::{Deserialize, Serialize};

/// Weighting and clamping rules (defaults as documented in the module).
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
pub struct WeightRules {
    pub min_cos: f32,
    pub boundary_offset_px: f64,
    pub depth_tolerance: f32,
    pub min_normal_agreement: f32,
    pub boundary_factor: f32,
    pub shadow_edge_factor: f32,
    pub min_radiance_fraction: f32,
    pub max_rel_stderr: f32,
    pub outlier_ratio: f32,
    pub max_albedo: f32,
}

impl Default for WeightRules {
    fn default() -> Self {
        WeightRules {
            min_cos: 0.1,
            boundary_offset_px: 1.5,
            depth_tolerance: 0.03,
            min_normal_agreement: 0.9,
            boundary_factor: 0.1,
            shadow_edge_factor: 0.1,
            min_radiance_fraction: 1e-3,
            max_rel_stderr: 0.5,
            outlier_ratio: 1.5,
            max_albedo: 1.0,
        }
    }
}

/// One photo's proposal for a texel's albedo: the value, its weight, and the variance per
/// channel that the Monte-Carlo noise of the rendered radiance puts into it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Proposal {
    pub value: Vec3,
    pub weight: f32,
    /// `(value * stderr(L) / L)^2` per channel (`L` the rendered radiance).
    pub mc_var: Vec3,
}

/// The combined albedo of a texel: value, sum of the kept weights, and standard error.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Combined {
    pub value: Vec3,
    pub weight: f32,
    /// Standard error of `value` per channel (see [`standard_error`]).
    pub stderr: Vec3,
    /// The part of `stderr` beyond the Monte-Carlo noise: the photographs' own noise (with
    /// registration, lighting and model error); 0 for a single proposal.
    pub photo_noise: Vec3,
}

/// Combines weighted proposals into one value: outlier rejection around the weighted median
/// (three or more observations), then the weighted mean and its standard error. Returns
/// `None` when nothing with positive weight remains.
pub fn combine(proposals: &[Proposal], rules: &WeightRules) -> Option<Combined> {
    let mut kept: Vec<Proposal> = proposals
        .iter()
        .copied()
        .filter(|p| p.weight > 0.0 && p.value.is_finite() && p.mc_var.is_finite())
        .collect();
    if kept.is_empty() {
        return None;
    }
    if kept.len() >= 3 {
        kept.sort_by(|a, b| luminance(a.value).total_cmp(&luminance(b.value)));
        let total: f32 = kept.iter().map(|k| k.weight).sum();
        let mut acc = 0.0;
        let mut median = luminance(kept[0].value);
        for k in &kept {
            acc += k.weight;
            if acc >= 0.5 * total {
                median = luminance(k.value);
                break;
            }
        }
        let r = rules.outlier_ratio;
        kept.retain(|k| {
            let l = luminance(k.value);
            l <= median * r + 1e-6 && l * r + 1e-6 >= median
        });
    }
    let wsum: f32 = kept.iter().map(|k| k.weight).sum();
    if !(wsum > 0.0) {
        return None;
    }
    let mean = kept.iter().fold(Vec3::ZERO, |a, k| a + k.value * k.weight) / wsum;
    let (stderr, photo_noise) = error_parts(&kept, mean, wsum);
    Some(Combined {
        value: mean.clamp(Vec3::ZERO, Vec3::splat(rules.max_albedo)),
        weight: wsum,
        stderr,
        photo_noise,
    })
}

/// Standard error of the weighted mean `mean` of the kept proposals (weights summing to
/// `wsum`), per channel. With normalised weights `a_i = w_i / W` and the proposals' Monte-Carlo
/// variances `v_i`:
///
/// - spread (reliability-weighted, unbiased): `s^2 = sum a_i (p_i - mean)^2 / (1 - sum a_i^2)`;
/// - noise beyond the Monte-Carlo noise (photo noise, registration, lighting and model error),
///   common to every proposal: `x^2 = max(0, s^2 - sum a_i v_i)`;
/// - `var(mean) = sum a_i^2 (v_i + x^2)`.
///
/// A single proposal has no spread: its standard error is the Monte-Carlo part alone (a lower
/// bound). Always finite and non-negative.
pub fn standard_error(kept: &[Proposal], mean: Vec3, wsum: f32) -> Vec3 {
    error_parts(kept, mean, wsum).0
}

/// The standard error of [`standard_error`] and its part beyond the Monte-Carlo noise,
/// `sqrt(sum a_i^2 x^2)` per channel: what the photographs themselves leave uncertain
/// (more samples per estimate do not reduce it).
fn error_parts(kept: &[Proposal], mean: Vec3, wsum: f32) -> (Vec3, Vec3) {
    let a = |k: &Proposal| (k.weight / wsum) as f64;
    let sum_a2: f64 = kept.iter().map(|k| a(k) * a(k)).sum();
    let root = |v: f64| {
        if v.is_finite() {
            v.max(0.0).sqrt() as f32
        } else {
            0.0
        }
    };
    let parts = |ch: usize| -> (f32, f32) {
        let mc: f64 = kept.iter().map(|k| a(k) * k.mc_var[ch] as f64).sum();
        let mc_of_mean: f64 = kept.iter().map(|k| a(k) * a(k) * k.mc_var[ch] as f64).sum();
        let extra = if kept.len() >= 2 && sum_a2 < 1.0 - 1e-9 {
            let s2: f64 = kept
                .iter()
                .map(|k| a(k) * ((k.value[ch] - mean[ch]) as f64).powi(2))
                .sum::<f64>()
                / (1.0 - sum_a2);
            (s2 - mc).max(0.0)
        } else {
            0.0
        };
        (root(mc_of_mean + extra * sum_a2), root(extra * sum_a2))
    };
    let [x, y, z] = [parts(0), parts(1), parts(2)];
    (Vec3::new(x.0, y.0, z.0), Vec3::new(x.1, y.1, z.1))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn props(v: &[(Vec3, f32)]) -> Vec<Proposal> {
        v.iter()
            .map(|&(value, weight)| Proposal {
                value,
                weight,
                mc_var: Vec3::ZERO,
            })
            .collect()
    }

    #[test]
    fn the_photographs_noise_is_the_spread_beyond_the_monte_carlo_noise() {
        let rules = WeightRules::default();
        // two equal-weight proposals 0.2 and 0.4: s^2 = (0.5 * 0.01 + 0.5 * 0.01) / (1 - 0.5)
        // = 0.02; without Monte-Carlo noise all of it is the photographs': sqrt(0.02 * 0.5)
        let mut p = props(&[(Vec3::splat(0.2), 1.0), (Vec3::splat(0.4), 1.0)]);
        let c = combine(&p, &rules).unwrap();
        assert!((c.photo_noise.x - 0.1).abs() < 1e-6, "{c:?}");
        assert_eq!(c.photo_noise, c.stderr);
        // Monte-Carlo variance 0.004 each: x^2 = 0.02 - 0.004, photo noise sqrt(0.016 * 0.5);
        // the total adds the Monte-Carlo variance of the mean, 0.25 * 0.004 * 2
        p.iter_mut().for_each(|q| q.mc_var = Vec3::splat(0.004));
        let c = combine(&p, &rules).unwrap();
        assert!((c.photo_noise.x - 0.008f32.sqrt()).abs() < 1e-6, "{c:?}");
        assert!(
            (c.stderr.x - (0.008f32 + 0.002).sqrt()).abs() < 1e-6,
            "{c:?}"
        );
        // proposals that agree better than their Monte-Carlo noise: no photograph noise left
        p.iter_mut().for_each(|q| q.mc_var = Vec3::splat(0.1));
        let c = combine(&p, &rules).unwrap();
        assert_eq!(c.photo_noise, Vec3::ZERO);
        assert!(c.stderr.x > 0.2);
        // a single proposal has no spread: no photograph noise
        let one = combine(&props(&[(Vec3::splat(0.3), 1.0)]), &rules).unwrap();
        assert_eq!(one.photo_noise, Vec3::ZERO);
    }

    #[test]
    fn combine_is_the_weighted_mean_without_outliers() {
        let rules = WeightRules::default();
        let p = vec![(Vec3::splat(0.2), 1.0), (Vec3::splat(0.4), 3.0)];
        let c = combine(&props(&p), &rules).unwrap();
        let (v, w) = (c.value, c.weight);
        assert!((v.x - 0.35).abs() < 1e-6, "{v}");
        assert_eq!(w, 4.0);
    }

    #[test]
    fn a_misregistered_photo_is_rejected_as_an_outlier() {
        // Four photos agree on 0.30; a misregistered one sees a dark neighbour (0.05).
        let rules = WeightRules::default();
        let p = vec![
            (Vec3::splat(0.30), 1.0),
            (Vec3::splat(0.31), 1.0),
            (Vec3::splat(0.29), 1.0),
            (Vec3::splat(0.30), 1.0),
            (Vec3::splat(0.05), 1.0),
        ];
        let c = combine(&props(&p), &rules).unwrap();
        let (v, w) = (c.value, c.weight);
        assert!((v.x - 0.30).abs() < 1e-3, "{v}");
        assert_eq!(w, 4.0);
    }

    #[test]
    fn a_single_observation_is_kept_and_clamped() {
        let rules = WeightRules::default();
        let p = vec![(Vec3::new(1.7, 0.5, -0.1), 0.3)];
        let c = combine(&props(&p), &rules).unwrap();
        let (v, w) = (c.value, c.weight);
        assert_eq!(v, Vec3::new(1.0, 0.5, 0.0));
        assert_eq!(w, 0.3);
        let none: Vec<(Vec3, f32)> = vec![(Vec3::ONE, 0.0), (Vec3::NAN, 1.0)];
        assert!(combine(&props(&none), &rules).is_none());
    }

    #[test]
    fn standard_error_of_two_equal_proposals_is_their_sample_error() {
        // values 0.2 and 0.4: sample standard deviation 0.1414, error of the mean 0.1
        let rules = WeightRules::default();
        let c = combine(
            &props(&[(Vec3::splat(0.2), 2.0), (Vec3::splat(0.4), 2.0)]),
            &rules,
        )
        .unwrap();
        assert!((c.stderr.x - 0.1).abs() < 1e-6, "{}", c.stderr);
        // Monte-Carlo noise larger than the spread: the Monte-Carlo part alone remains,
        // var = sum a_i^2 v_i = 2 * 0.25 * 0.04
        let mut p = props(&[(Vec3::splat(0.3), 1.0), (Vec3::splat(0.31), 1.0)]);
        for q in &mut p {
            q.mc_var = Vec3::splat(0.04);
        }
        let c = combine(&p, &rules).unwrap();
        assert!((c.stderr.y - 0.02f32.sqrt()).abs() < 1e-6, "{}", c.stderr);
        // one proposal: its Monte-Carlo error only
        p.truncate(1);
        assert!((combine(&p, &rules).unwrap().stderr.z - 0.2).abs() < 1e-6);
    }

    #[test]
    fn z_scores_of_noisy_proposals_have_unit_spread() {
        // 4000 texels, 6 proposals each with Gaussian noise (sigma 0.05) and unequal weights:
        // (mean - truth) / stderr must have a standard deviation near 1 (t with 5 degrees of
        // freedom: sqrt(5/3) = 1.29 for equal weights).
        let rules = WeightRules {
            outlier_ratio: 1e9,
            ..WeightRules::default()
        };
        let mut state = 0x9e3779b97f4a7c15u64;
        let mut uniform = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        let mut z2 = 0.0;
        let n = 4000;
        for _ in 0..n {
            let p: Vec<Proposal> = (0..6)
                .map(|k| {
                    let g = (-2.0 * uniform().ln()).sqrt()
                        * (2.0 * std::f64::consts::PI * uniform()).cos();
                    Proposal {
                        value: Vec3::splat(0.4 + 0.05 * g as f32),
                        weight: 0.5 + 0.1 * k as f32,
                        mc_var: Vec3::ZERO,
                    }
                })
                .collect();
            let c = combine(&p, &rules).unwrap();
            z2 += (((c.value.x - 0.4) / c.stderr.x) as f64).powi(2);
        }
        let sd = (z2 / n as f64).sqrt();
        eprintln!("z rms over {n} simulated texels: {sd:.3}");
        assert!((1.1..1.45).contains(&sd), "z spread {sd}");
    }
}
