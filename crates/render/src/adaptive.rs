//! Adaptive sampling: where a render's samples go ([`crate::RenderOptions::adaptive`],
//! docs/RENDER.md, "Integrator": adaptive samples).
//!
//! A pilot of [`pilot_spp`] samples per pixel, on a random stream of its own and then
//! discarded, measures each pixel's relative standard deviation per sample `r` (the channels' mean
//! standard deviation over their mean radiance; `r^2` averaged over the 5 x 5 pixels around it, so that one unlucky pilot
//! neither starves nor floods a pixel) and its cost per sample `c` (rays traced). The rest of
//! the budget, `spp - pilot` samples a pixel at the pilot's cost, is dealt as `n = s r / sqrt(c)`:
//! the counts that minimise the summed relative variance `sum r^2 / n` of the image at that
//! cost (a Lagrange multiplier), clamped to `[spp / 4, 4 spp]`, with `s` found by bisection.
//! The counts depend on the pilot alone, never on the samples they are spent on, so every
//! pixel's mean stays an unbiased estimate. Several images can share one budget
//! ([`sample_counts_over`], [`crate::integrator::render_images`]): the same rule over all
//! their pixels, so a noisier image takes more of it.

/// What the pilot measured at one pixel, each averaged over the three channels: the mean
/// radiance and the standard deviation per sample; and the rays one sample traced there.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PilotPixel {
    pub mean: f32,
    pub sd: f32,
    pub cost: f32,
}

/// The fewest samples per pixel an adaptive render takes: below it the pilot is too short to
/// tell the pixels apart.
pub const MIN_SPP: u32 = 16;

/// Radius in pixels of the window over which the pilot's relative variance is averaged.
const SMOOTHING_RADIUS: usize = 2;

/// Samples per pixel of the pilot of a render at `spp`: an eighth of them.
pub fn pilot_spp(spp: u32) -> u32 {
    (spp / 8).max(2)
}

/// What the pilot of one image measured: one [`PilotPixel`] per pixel, row-major.
#[derive(Clone, Debug, Default)]
pub struct ImagePilot {
    pub width: usize,
    pub height: usize,
    pub pixels: Vec<PilotPixel>,
}

/// Samples per pixel of a `w x h` render at a mean of `spp` whose pilot measured `pilot`
/// (row-major, one per pixel).
pub fn sample_counts(pilot: &[PilotPixel], w: usize, h: usize, spp: u32) -> Vec<u32> {
    let image = ImagePilot {
        width: w,
        height: h,
        pixels: pilot.to_vec(),
    };
    sample_counts_over(std::slice::from_ref(&image), spp).remove(0)
}

/// Samples per pixel of several renders that share one budget, a mean of `spp` over all their
/// pixels: the same rule as for one image, over the pixels of all of them (the relative noise
/// still smoothed within each image), so a noisier image takes more of the budget.
pub fn sample_counts_over(images: &[ImagePilot], spp: u32) -> Vec<Vec<u32>> {
    let mut weights = Vec::new();
    let mut cost = Vec::new();
    for im in images {
        debug_assert_eq!(im.pixels.len(), im.width * im.height);
        let r = smoothed_relative_sd(&im.pixels, im.width, im.height);
        for (r, p) in r.iter().zip(&im.pixels) {
            let c = f64::from(p.cost).max(1.0);
            weights.push(r / c.sqrt());
            cost.push(c);
        }
    }
    let budget = f64::from(spp - pilot_spp(spp)) * cost.iter().sum::<f64>();
    let (lo, hi) = (f64::from((spp / 4).max(1)), f64::from(spp) * 4.0);
    let mut counts = deal(&weights, &cost, budget, lo, hi).into_iter();
    images
        .iter()
        .map(|im| counts.by_ref().take(im.pixels.len()).collect())
        .collect()
}

/// Per pixel, the square root of the mean over its window of `(sd / mean)^2` (0 where the
/// pilot saw nothing).
fn smoothed_relative_sd(pilot: &[PilotPixel], w: usize, h: usize) -> Vec<f64> {
    let rel2: Vec<f64> = pilot
        .iter()
        .map(|p| {
            let r = f64::from(p.sd) / f64::from(p.mean);
            if p.mean > 0.0 && r.is_finite() {
                r * r
            } else {
                0.0
            }
        })
        .collect();
    let k = SMOOTHING_RADIUS;
    (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let (xs, ys) = (
                x.saturating_sub(k)..(x + k + 1).min(w),
                y.saturating_sub(k)..(y + k + 1).min(h),
            );
            let n = xs.len() * ys.len();
            let sum: f64 = ys
                .flat_map(|yy| xs.clone().map(move |xx| yy * w + xx))
                .map(|j| rel2[j])
                .sum();
            (sum / n as f64).sqrt()
        })
        .collect()
}

/// Counts `round(clamp(s w_i, lo, hi))` with the scale `s` that spends `budget` at the costs
/// `cost` (bisection on `log s`); all `lo` when every weight is 0, all `hi` when even that
/// leaves budget over.
fn deal(weights: &[f64], cost: &[f64], budget: f64, lo: f64, hi: f64) -> Vec<u32> {
    let spent = |s: f64| -> f64 {
        weights
            .iter()
            .zip(cost)
            .map(|(w, c)| (s * w).clamp(lo, hi) * c)
            .sum()
    };
    let max_w = weights.iter().copied().fold(0.0, f64::max);
    let scale = if !(max_w > 0.0) {
        0.0
    } else {
        // spent(s) grows with s from spent(lo / max_w) <= spent at all-lo to spent at all-hi
        let (mut a, mut b) = ((lo / max_w).ln() - 60.0, (hi / max_w).ln() + 60.0);
        for _ in 0..200 {
            let m = 0.5 * (a + b);
            if spent(m.exp()) < budget {
                a = m;
            } else {
                b = m;
            }
        }
        b.exp()
    };
    weights
        .iter()
        .map(|w| (scale * w).clamp(lo, hi).round() as u32)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn px(mean: f32, sd: f32, cost: f32) -> PilotPixel {
        PilotPixel { mean, sd, cost }
    }

    #[test]
    fn counts_follow_the_relative_noise_and_spend_the_budget() {
        // two uniform halves of a 20 x 10 image: the right one 4 times noisier (relative)
        let (w, h, spp) = (20, 10, 64);
        let pilot: Vec<PilotPixel> = (0..w * h)
            .map(|i| {
                if i % w < w / 2 {
                    px(1.0, 0.1, 3.0)
                } else {
                    px(0.5, 0.2, 3.0)
                }
            })
            .collect();
        let n = sample_counts(&pilot, w, h, spp);
        let budget = (spp - pilot_spp(spp)) as usize * w * h;
        let total: usize = n.iter().map(|&k| k as usize).sum();
        assert!(
            total.abs_diff(budget) <= w * h / 2,
            "spent {total} of {budget}"
        );
        // far from the boundary the counts are in the ratio of the relative noise (4:1)
        let (left, right) = (n[5 * w + 2], n[5 * w + w - 3]);
        assert!(
            (right as f64 / left as f64 - 4.0).abs() < 0.15,
            "{left} {right}"
        );
        assert!(n.iter().all(|&k| (spp / 4..=4 * spp).contains(&k)));
    }

    #[test]
    fn costly_pixels_get_fewer_samples_and_noiseless_ones_the_floor() {
        let (w, h, spp) = (10, 10, 32);
        // same relative noise, the top half 4 times as costly: sqrt(4) = 2 times fewer samples
        let pilot: Vec<PilotPixel> = (0..w * h)
            .map(|i| px(1.0, 0.3, if i / w < h / 2 { 8.0 } else { 2.0 }))
            .collect();
        let n = sample_counts(&pilot, w, h, spp);
        let (top, bottom) = (n[w + 5], n[(h - 2) * w + 5]);
        assert!(
            (bottom as f64 / top as f64 - 2.0).abs() < 0.1,
            "{top} {bottom}"
        );
        // a black image (nothing to measure) takes the floor everywhere
        let dark = vec![px(0.0, 0.0, 1.0); w * h];
        assert!(sample_counts(&dark, w, h, spp)
            .iter()
            .all(|&k| k == spp / 4));
        // a pixel that is NaN in the pilot is no noisier than a black one
        let mut odd = vec![px(1.0, 0.1, 1.0); w * h];
        odd[0] = px(f32::NAN, f32::NAN, 1.0);
        let n = sample_counts(&odd, w, h, spp);
        assert!(n.iter().all(|&k| (spp / 4..=4 * spp).contains(&k)));
    }

    #[test]
    fn images_sharing_a_budget_take_it_by_their_noise() {
        // two 12 x 8 images, the second twice as noisy (relative) everywhere, at equal cost
        let (w, h, spp) = (12, 8, 48);
        let image = |sd: f32| ImagePilot {
            width: w,
            height: h,
            pixels: vec![px(1.0, sd, 2.0); w * h],
        };
        let (calm, noisy) = (image(0.1), image(0.2));
        let n = sample_counts_over(&[calm.clone(), noisy.clone()], spp);
        let mean = |c: &[u32]| c.iter().map(|&k| f64::from(k)).sum::<f64>() / c.len() as f64;
        // the budget of both together, dealt 1 : 2
        let pair = (spp - pilot_spp(spp)) as f64;
        assert!((mean(&n[0]) + mean(&n[1]) - 2.0 * pair).abs() < 1.0);
        assert!((mean(&n[1]) / mean(&n[0]) - 2.0).abs() < 0.05);
        // one image alone keeps its own budget
        let alone = sample_counts_over(std::slice::from_ref(&noisy), spp);
        assert!((mean(&alone[0]) - pair).abs() < 1.0);
    }

    #[test]
    fn the_clamps_hold_when_one_pixel_holds_all_the_noise() {
        let (w, h, spp) = (16, 16, 64);
        let mut pilot = vec![px(1.0, 0.0, 2.0); w * h];
        pilot[8 * w + 8] = px(1.0, 5.0, 2.0);
        let n = sample_counts(&pilot, w, h, spp);
        assert_eq!(n[8 * w + 8], 4 * spp);
        assert_eq!(n[0], spp / 4);
    }
}
