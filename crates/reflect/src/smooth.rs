//! Edge-aware smoothing of the rendered shading across neighbouring texels.
//!
//! A texel's proposal is `pixel / shading`, the shading (`L / rho_eval`, the radiance per unit
//! albedo toward the camera) being a Monte-Carlo estimate of its own: its noise is white from
//! texel to texel and goes straight into the albedo, and the footprint deblurring
//! ([`crate::deblur`]) amplifies it. The shading itself varies slowly over a surface (the
//! albedo carries the texture), except at shadow edges and creases. So per photograph each
//! observation's shading is replaced by the mean over its 3 x 3 atlas neighbourhood of the
//! observations of the same photograph and part that are the same surface (world distance at
//! most [`MAX_DISTANCE_TEXELS`] texel sizes, normals within [`MIN_NORMAL_DOT`]) and in the same
//! light (shading luminance within [`MAX_RATIO`] of the neighbourhood's median, so a shadow edge
//! is never averaged across). An observation outside that band keeps its own shading. The
//! proposal, its Monte-Carlo variance (divided by the number averaged) and the residual follow.
//!
//! Deterministic: it reads only the observations, in their order, whatever the thread count.

use crate::parts::Part;
use crate::record::Obs;
use glam::Vec3;
use igi_brdf::luminance;
use rayon::prelude::*;

/// Largest ratio between a neighbour's shading luminance and the neighbourhood's median.
pub const MAX_RATIO: f32 = 1.25;
/// Largest world distance between neighbours, in texel sizes.
pub const MAX_DISTANCE_TEXELS: f64 = 2.5;
/// Smallest cosine between neighbours' normals.
pub const MIN_NORMAL_DOT: f32 = 0.95;

/// Smooths the shading of `obs` (see the module overview). The observations come photograph
/// by photograph (each photograph's in one run, as the solver makes them); each run is
/// smoothed on its own, its observations in parallel. A photograph whose observations come
/// in two runs is a programming error (its runs would be smoothed apart): it panics.
pub(crate) fn smooth_shading<P: AsRef<Part> + Sync>(obs: &mut [Obs], parts: &[P]) {
    let mut start = 0;
    let mut done = std::collections::BTreeSet::new();
    while start < obs.len() {
        let photo = obs[start].photo;
        assert!(
            done.insert(photo),
            "smooth_shading: photograph {photo}'s observations are not contiguous"
        );
        let len = obs[start..]
            .iter()
            .position(|o| o.photo != photo)
            .unwrap_or(obs.len() - start);
        let run = &mut obs[start..start + len];
        let smoothed: Vec<Option<(Vec3, usize)>> = {
            let index = NeighbourIndex::new(run, parts, DENSE_SLOTS);
            (0..run.len())
                .into_par_iter()
                .map(|k| index.smoothed(run, parts, k))
                .collect()
        };
        for (o, s) in run.iter_mut().zip(smoothed) {
            if let Some((shading, n)) = s {
                apply(o, shading, n);
            }
        }
        start += len;
    }
}

/// Where each (part, atlas texel) observation of one photograph sits in its run: a dense
/// table over the atlases of the parts it sees when they hold at most [`DENSE_SLOTS`] slots
/// per observation, else a sorted list.
enum NeighbourIndex {
    Dense {
        /// Each part's first slot (`usize::MAX` for a part the photograph does not see).
        base: Vec<usize>,
        slots: Vec<u32>,
    },
    Sorted(Vec<(u64, u32)>),
}

/// The dense table's largest size in slots per observation (beyond it, a sorted list).
const DENSE_SLOTS: usize = 16;

impl NeighbourIndex {
    /// The index of one photograph's run, dense when it needs at most `dense_slots` slots per
    /// observation.
    fn new<P: AsRef<Part>>(obs: &[Obs], parts: &[P], dense_slots: usize) -> NeighbourIndex {
        let mut base = vec![usize::MAX; parts.len()];
        let mut total = 0;
        for o in obs {
            let b = &mut base[o.part as usize];
            if *b == usize::MAX {
                *b = total;
                total += parts[o.part as usize].as_ref().resolution().pow(2);
            }
        }
        if total <= dense_slots * obs.len() {
            let mut slots = vec![u32::MAX; total];
            for (k, o) in obs.iter().enumerate() {
                slots[base[o.part as usize] + o.atlas as usize] = k as u32;
            }
            return NeighbourIndex::Dense { base, slots };
        }
        let mut keys: Vec<(u64, u32)> = obs
            .iter()
            .enumerate()
            .map(|(k, o)| (key(o.part, o.atlas), k as u32))
            .collect();
        keys.sort_unstable();
        NeighbourIndex::Sorted(keys)
    }

    /// The observation of texel `atlas` of `part` in the run, if any.
    fn get(&self, part: u32, atlas: u32) -> Option<usize> {
        match self {
            NeighbourIndex::Dense { base, slots } => {
                let k = slots[base[part as usize] + atlas as usize];
                (k != u32::MAX).then_some(k as usize)
            }
            NeighbourIndex::Sorted(keys) => {
                let i = keys
                    .binary_search_by_key(&key(part, atlas), |&(k, _)| k)
                    .ok()?;
                Some(keys[i].1 as usize)
            }
        }
    }

    /// The mean shading over observation `k`'s admissible neighbourhood and how many were
    /// averaged, or `None` when it keeps its own.
    fn smoothed<P: AsRef<Part>>(
        &self,
        obs: &[Obs],
        parts: &[P],
        k: usize,
    ) -> Option<(Vec3, usize)> {
        let o = &obs[k];
        if o.shading.min_element() <= 0.0 {
            return None;
        }
        let part = parts[o.part as usize].as_ref();
        let r = part.resolution() as i64;
        let me = &part.cache.texels[o.texel as usize];
        let reach = (MAX_DISTANCE_TEXELS * part.texel_size) as f32;
        let (x, y) = ((o.atlas as i64) % r, (o.atlas as i64) / r);
        let mut near = [Vec3::ZERO; 9];
        let mut n = 0;
        for (nx, ny) in (-1..=1).flat_map(|dy| (-1..=1).map(move |dx| (x + dx, y + dy))) {
            if nx < 0 || ny < 0 || nx >= r || ny >= r {
                continue;
            }
            let Some(j) = self.get(o.part, (ny * r + nx) as u32) else {
                continue;
            };
            let t = &part.cache.texels[obs[j].texel as usize];
            if t.position.distance(me.position) <= reach
                && t.normal.dot(me.normal) >= MIN_NORMAL_DOT
                && obs[j].shading.min_element() > 0.0
            {
                near[n] = obs[j].shading;
                n += 1;
            }
        }
        if n < 2 {
            return None;
        }
        let mut lums = [0f32; 9];
        for (l, s) in lums.iter_mut().zip(&near[..n]) {
            *l = luminance(*s);
        }
        let median = *lums[..n]
            .select_nth_unstable_by(n / 2, |a, b| a.total_cmp(b))
            .1;
        let within = |s: Vec3| {
            let l = luminance(s);
            l <= MAX_RATIO * median && median <= MAX_RATIO * l
        };
        if !within(o.shading) {
            return None;
        }
        let (sum, count) = near[..n]
            .iter()
            .filter(|s| within(**s))
            .fold((Vec3::ZERO, 0), |(sum, c), s| (sum + *s, c + 1));
        Some((sum / count as f32, count))
    }
}

/// A (part, atlas texel) pair as one sortable key.
fn key(part: u32, atlas: u32) -> u64 {
    (u64::from(part) << 32) | u64::from(atlas)
}

/// Observation `o` with its shading replaced by `shading`, a mean over `n` texels.
fn apply(o: &mut Obs, shading: Vec3, n: usize) {
    let old = o.shading;
    for c in 0..3 {
        if old[c] > 0.0 && shading[c] > 0.0 {
            let rho = (o.residual[c] + o.pixel[c]) / old[c];
            o.proposal[c] = o.pixel[c] / shading[c];
            o.mc_var[c] *= (old[c] / shading[c]).powi(2) / n as f32;
            o.residual[c] = shading[c] * rho - o.pixel[c];
            o.shading[c] = shading[c];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec2;

    fn ground() -> Vec<Part> {
        crate::parts::square_part(64)
    }

    /// Observations of an albedo with texel detail under a shading with a shadow edge at
    /// x = 0.3 (1.0 in the sun, 0.1 in the shade), each shading estimate with 10 % Monte-Carlo
    /// noise: the texels away from the edge lose most of their error, those beside it keep
    /// theirs unbiased (the edge is never averaged across), and nothing changes where the
    /// shading is exact.
    #[test]
    fn smoothing_takes_the_shading_noise_out_and_never_crosses_a_shadow_edge() {
        let parts = ground();
        let albedo = |p: Vec3| if (p.x * 7.3).sin() > 0.0 { 0.7 } else { 0.25 };
        let light = |p: Vec3| if p.x < 0.3 { 1.0 } else { 0.1 };
        let mut rng = igi_render::sampling::Rng::new(5, 0);
        let make = |noise: &mut dyn FnMut() -> f32| -> Vec<Obs> {
            let texels = &parts[0].cache.texels;
            texels
                .iter()
                .enumerate()
                .map(|(k, t)| {
                    let (rho, s) = (albedo(t.position), light(t.position));
                    let pixel = Vec3::splat(rho * s);
                    let shading = Vec3::splat(s * (1.0 + noise()));
                    Obs {
                        part: 0,
                        texel: k as u32,
                        atlas: t.index,
                        photo: 0,
                        px: Vec2::ZERO,
                        shading,
                        deblur_gain: 0.0,
                        proposal: pixel / shading,
                        weight: 1.0,
                        mc_var: Vec3::splat(0.01),
                        clean: true,
                        residual: shading * 0.5 - pixel,
                        pixel,
                    }
                })
                .collect()
        };
        let error = |obs: &[Obs], pick: &dyn Fn(f32) -> bool| {
            let (mut sum, mut n) = (0.0, 0);
            for o in obs {
                let p = parts[0].cache.texels[o.texel as usize].position;
                if pick(p.x) {
                    sum += ((o.proposal.x - albedo(p)) / albedo(p)).abs();
                    n += 1;
                }
            }
            sum / n as f32
        };
        let mut noisy = make(&mut || (rng.uniform() - 0.5) * 0.35);
        let before = make(&mut || 0.0);
        let raw = noisy.clone();
        smooth_shading(&mut noisy, &parts);
        let mut exact = before.clone();
        smooth_shading(&mut exact, &parts);
        let texel = parts[0].texel_size as f32;
        let away = |x: f32| (x - 0.3).abs() > 2.0 * texel;
        let beside = |x: f32| (x - 0.3).abs() <= 1.0 * texel;
        let (e_raw, e_smooth) = (error(&raw, &away), error(&noisy, &away));
        let (b_raw, b_smooth) = (error(&raw, &beside), error(&noisy, &beside));
        eprintln!(
            "away from the edge {e_raw:.4} -> {e_smooth:.4}; beside it {b_raw:.4} -> {b_smooth:.4}"
        );
        assert!(e_smooth < 0.45 * e_raw, "{e_raw} -> {e_smooth}");
        // an average across the edge would be off by a factor of up to 5
        assert!(b_smooth < 1.2 * b_raw, "{b_raw} -> {b_smooth}");
        assert!(exact
            .iter()
            .zip(&before)
            .all(|(a, b)| (a.proposal - b.proposal).abs().max_element() < 1e-6));
        // the variance follows the average, the residual the new shading
        assert!(noisy.iter().all(|o| o.proposal.is_finite()));
        let var = noisy.iter().map(|o| o.mc_var.x).sum::<f32>() / noisy.len() as f32;
        assert!(var < 0.005, "{var}");
        for o in &noisy {
            let rho = (o.residual.x + o.pixel.x) / o.shading.x;
            assert!((rho - 0.5).abs() < 1e-4, "{rho}");
        }
        // a photograph's observations in two runs are refused, not smoothed apart
        let mut split = before.clone();
        let n = split.len();
        split[n / 3..2 * n / 3].iter_mut().for_each(|o| o.photo = 1);
        let refused = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            smooth_shading(&mut split, &parts)
        }));
        assert!(refused.is_err(), "photograph 0 in two runs was smoothed");
        // the sorted index finds the same neighbours as the dense table
        let (dense, sorted) = (
            NeighbourIndex::new(&raw, &parts, DENSE_SLOTS),
            NeighbourIndex::new(&raw, &parts, 0),
        );
        assert!(matches!(dense, NeighbourIndex::Dense { .. }));
        assert!(matches!(sorted, NeighbourIndex::Sorted(_)));
        let mut averaged = 0;
        for k in 0..raw.len() {
            let (a, b) = (
                dense.smoothed(&raw, &parts, k),
                sorted.smoothed(&raw, &parts, k),
            );
            assert_eq!(a, b, "observation {k}");
            averaged += usize::from(a.is_some_and(|(_, n)| n == 9));
        }
        assert!(averaged > raw.len() / 2, "{averaged} of {}", raw.len());
    }
}
