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

/// Combines weighted proposals into one value: outlier rejection around the weighted median
/// (three or more observations), then the weighted mean. Returns the value and the sum of the
/// kept weights, or `None` when nothing with positive weight remains.
pub fn combine(proposals: &mut [(Vec3, f32)], rules: &WeightRules) -> Option<(Vec3, f32)> {
    let mut kept: Vec<(Vec3, f32)> = proposals
        .iter()
        .copied()
        .filter(|(v, w)| *w > 0.0 && v.is_finite())
        .collect();
    if kept.is_empty() {
        return None;
    }
    if kept.len() >= 3 {
        kept.sort_by(|a, b| luminance(a.0).total_cmp(&luminance(b.0)));
        let total: f32 = kept.iter().map(|k| k.1).sum();
        let mut acc = 0.0;
        let mut median = luminance(kept[0].0);
        for (v, w) in &kept {
            acc += w;
            if acc >= 0.5 * total {
                median = luminance(*v);
                break;
            }
        }
        let r = rules.outlier_ratio;
        kept.retain(|(v, _)| {
            let l = luminance(*v);
            l <= median * r + 1e-6 && l * r + 1e-6 >= median
        });
    }
    let wsum: f32 = kept.iter().map(|k| k.1).sum();
    if !(wsum > 0.0) {
        return None;
    }
    let mean = kept.iter().fold(Vec3::ZERO, |a, (v, w)| a + *v * *w) / wsum;
    Some((mean.clamp(Vec3::ZERO, Vec3::splat(rules.max_albedo)), wsum))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn combine_is_the_weighted_mean_without_outliers() {
        let rules = WeightRules::default();
        let mut p = vec![(Vec3::splat(0.2), 1.0), (Vec3::splat(0.4), 3.0)];
        let (v, w) = combine(&mut p, &rules).unwrap();
        assert!((v.x - 0.35).abs() < 1e-6, "{v}");
        assert_eq!(w, 4.0);
    }

    #[test]
    fn a_misregistered_photo_is_rejected_as_an_outlier() {
        // Four photos agree on 0.30; a misregistered one sees a dark neighbour (0.05).
        let rules = WeightRules::default();
        let mut p = vec![
            (Vec3::splat(0.30), 1.0),
            (Vec3::splat(0.31), 1.0),
            (Vec3::splat(0.29), 1.0),
            (Vec3::splat(0.30), 1.0),
            (Vec3::splat(0.05), 1.0),
        ];
        let (v, w) = combine(&mut p, &rules).unwrap();
        assert!((v.x - 0.30).abs() < 1e-3, "{v}");
        assert_eq!(w, 4.0);
    }

    #[test]
    fn a_single_observation_is_kept_and_clamped() {
        let rules = WeightRules::default();
        let mut p = vec![(Vec3::new(1.7, 0.5, -0.1), 0.3)];
        let (v, w) = combine(&mut p, &rules).unwrap();
        assert_eq!(v, Vec3::new(1.0, 0.5, 0.0));
        assert_eq!(w, 0.3);
        let mut none: Vec<(Vec3, f32)> = vec![(Vec3::ONE, 0.0), (Vec3::NAN, 1.0)];
        assert!(combine(&mut none, &rules).is_none());
    }
}
