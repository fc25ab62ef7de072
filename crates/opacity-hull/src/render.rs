//! New views: unstructured-lumigraph blending (Matusik et al. 2002, Eq. 4) and surfel splatting
//! with order-independent alpha blending.
//!
//! Per surfel and new camera: for every input view that sees the surfel, the penalty
//! `p_i = 1 - cos theta_i` (theta_i the angle at the surfel between the view and the new
//! camera); the `k` smallest are kept, `cos theta_t` is that of the k-th,
//! `w_i = (cos theta_i - cos theta_t) / (1 - cos theta_t) / p_i`, normalised. A view with
//! `p_i = 0` (the new camera is that view) takes all the weight. Colour and opacity are the
//! weighted means of the view's samples.
//!
//! Splatting: each surfel covers the pixels within its projected radius; a first pass keeps the
//! nearest depth per pixel, a second pass averages, with weights `1 - (d / r)^2`, the surfels
//! within a depth tolerance of it. Both passes are sums and minima, so the image does not depend
//! on the order of the surfels. Output: RGB premultiplied by alpha, and alpha.

use crate::surfel::Surfels;
use glam::{DVec3, Vec3};
use igi_imaging::{Camera, HdrImage};
use rayon::prelude::*;

/// What the splatter needs per surfel and view: the input cameras' centres and the colour and
/// opacity each visible view saw.
#[derive(Clone, Debug)]
pub struct HullModel {
    pub surfels: Surfels,
    pub centres: Vec<DVec3>,
    /// `colors[s * views + v]`: the photo of view v at surfel s (where visible).
    pub colors: Vec<[f32; 3]>,
}

/// Rendering options.
#[derive(Clone, Copy, Debug)]
pub struct RenderOptions {
    /// Views blended per surfel (the paper: 4).
    pub k: usize,
    /// Smallest splat radius in pixels (fills gaps between surfels).
    pub min_radius_px: f32,
    /// Depth tolerance of the blending pass, in surfel radii.
    pub depth_tolerance: f32,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            k: 4,
            min_radius_px: 0.8,
            depth_tolerance: 3.0,
        }
    }
}

/// Eq. 4 weights for one surfel: `(view, weight)` pairs summing to 1, empty if no view sees it.
pub fn blend_weights(
    p: DVec3,
    target: DVec3,
    centres: &[DVec3],
    visible: &[bool],
    k: usize,
) -> Vec<(usize, f64)> {
    let dt = (target - p).normalize_or_zero();
    let mut cand: Vec<(f64, usize)> = (0..centres.len())
        .filter(|&v| visible[v])
        .map(|v| (1.0 - (centres[v] - p).normalize_or_zero().dot(dt), v))
        .collect();
    if cand.is_empty() {
        return vec![];
    }
    cand.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    if cand[0].0 <= 1e-12 {
        return vec![(cand[0].1, 1.0)];
    }
    cand.truncate(k.max(1));
    let cos_t = 1.0 - cand.last().map_or(0.0, |c| c.0);
    let mut w: Vec<(usize, f64)> = cand
        .iter()
        .map(|&(pen, v)| {
            let cos_i = 1.0 - pen;
            let r = if cos_t < 1.0 {
                (cos_i - cos_t) / (1.0 - cos_t)
            } else {
                1.0
            };
            (v, r.max(0.0) / pen)
        })
        .collect();
    let sum: f64 = w.iter().map(|x| x.1).sum();
    if !(sum > 0.0) {
        // all kept views equally far: equal weights
        let n = w.len() as f64;
        return w.into_iter().map(|(v, _)| (v, 1.0 / n)).collect();
    }
    for x in &mut w {
        x.1 /= sum;
    }
    w.retain(|x| x.1 > 0.0);
    w
}

/// One projected splat.
#[derive(Clone, Copy)]
struct Splat {
    x: f32,
    y: f32,
    z: f32,
    r: f32,
    color: Vec3,
    alpha: f32,
}

/// Render the model from `camera`: (premultiplied colour, alpha).
pub fn render(model: &HullModel, camera: &Camera, opts: RenderOptions) -> (HdrImage, Vec<f32>) {
    let target = camera.center_world();
    let s = &model.surfels;
    let nv = s.views;
    let fx = camera.intrinsics.fx.max(camera.intrinsics.fy) as f32;
    let splats: Vec<Option<Splat>> = (0..s.len())
        .into_par_iter()
        .map(|i| {
            let p = DVec3::from_array(s.positions[i].map(f64::from));
            let n = DVec3::from_array(s.normals[i].map(f64::from));
            if n.dot(target - p) <= 0.0 {
                return None;
            }
            let z = camera.pose.apply(p).z;
            let px = camera.project(p)?;
            let w = blend_weights(
                p,
                target,
                &model.centres,
                &s.visible[i * nv..(i + 1) * nv],
                opts.k,
            );
            if w.is_empty() {
                return None;
            }
            let (mut color, mut alpha) = (Vec3::ZERO, 0.0f32);
            for (v, wt) in w {
                color += Vec3::from_array(model.colors[i * nv + v]) * wt as f32;
                alpha += s.opacity[i * nv + v] * wt as f32;
            }
            let r = (s.radius[i] * fx / z as f32).max(opts.min_radius_px);
            Some(Splat {
                x: px.x as f32,
                y: px.y as f32,
                z: z as f32,
                r,
                color,
                alpha,
            })
        })
        .collect();
    splat(
        &splats,
        camera.width as usize,
        camera.height as usize,
        opts.depth_tolerance,
        &s.radius,
    )
}

fn footprint(sp: &Splat, w: usize, h: usize) -> Option<(usize, usize, usize, usize)> {
    let r = sp.r.min(32.0);
    let (x0, x1) = (
        (sp.x - r).ceil().max(0.0),
        (sp.x + r).floor().min(w as f32 - 1.0),
    );
    let (y0, y1) = (
        (sp.y - r).ceil().max(0.0),
        (sp.y + r).floor().min(h as f32 - 1.0),
    );
    (x0 <= x1 && y0 <= y1).then_some((x0 as usize, x1 as usize, y0 as usize, y1 as usize))
}

fn splat(
    splats: &[Option<Splat>],
    w: usize,
    h: usize,
    tol: f32,
    radius: &[f32],
) -> (HdrImage, Vec<f32>) {
    let mut zbuf = vec![f32::INFINITY; w * h];
    for sp in splats.iter().flatten() {
        let Some((x0, x1, y0, y1)) = footprint(sp, w, h) else {
            continue;
        };
        for y in y0..=y1 {
            for x in x0..=x1 {
                let d2 = (x as f32 - sp.x).powi(2) + (y as f32 - sp.y).powi(2);
                if d2 <= sp.r * sp.r {
                    let z = &mut zbuf[y * w + x];
                    *z = z.min(sp.z);
                }
            }
        }
    }
    let mut acc = vec![[0.0f32; 5]; w * h];
    for (i, sp) in splats.iter().enumerate() {
        let Some(sp) = sp else { continue };
        let Some((x0, x1, y0, y1)) = footprint(sp, w, h) else {
            continue;
        };
        let ztol = tol * radius[i];
        for y in y0..=y1 {
            for x in x0..=x1 {
                let d2 = (x as f32 - sp.x).powi(2) + (y as f32 - sp.y).powi(2);
                let j = y * w + x;
                if d2 > sp.r * sp.r || sp.z > zbuf[j] + ztol {
                    continue;
                }
                let k = 1.0 - d2 / (sp.r * sp.r) + 1e-3;
                let a = &mut acc[j];
                a[0] += k * sp.color.x;
                a[1] += k * sp.color.y;
                a[2] += k * sp.color.z;
                a[3] += k * sp.alpha;
                a[4] += k;
            }
        }
    }
    let mut img = HdrImage::new(w, h);
    let mut alpha = vec![0.0f32; w * h];
    for (j, a) in acc.iter().enumerate() {
        if a[4] > 0.0 {
            let al = (a[3] / a[4]).clamp(0.0, 1.0);
            alpha[j] = al;
            img.pixels[j] = [a[0] / a[4] * al, a[1] / a[4] * al, a[2] / a[4] * al];
        }
    }
    (img, alpha)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eq4_weights() {
        let p = DVec3::ZERO;
        let centres: Vec<DVec3> = (0..6)
            .map(|i| DVec3::new((i as f64 * 0.3).cos(), (i as f64 * 0.3).sin(), 0.0) * 2.0)
            .collect();
        let vis = vec![true; 6];
        // the new camera is view 2: all weight there
        assert_eq!(
            blend_weights(p, centres[2], &centres, &vis, 4),
            vec![(2, 1.0)]
        );
        // between views 1 and 2: the two nearest dominate, weights sum to 1, the 4th gets 0
        let t = DVec3::new((0.4f64).cos(), (0.4f64).sin(), 0.0) * 3.0;
        let w = blend_weights(p, t, &centres, &vis, 4);
        let sum: f64 = w.iter().map(|x| x.1).sum();
        assert!((sum - 1.0).abs() < 1e-12);
        assert_eq!(w.len(), 3, "{w:?}");
        let w1 = w.iter().find(|x| x.0 == 1).unwrap().1;
        let w2 = w.iter().find(|x| x.0 == 2).unwrap().1;
        assert!(w1 > w2 && w2 > 0.0 && w1 < 1.0, "{w:?}");
        // invisible views are never used
        let mut vis = vis;
        vis[1] = false;
        assert!(blend_weights(p, t, &centres, &vis, 4)
            .iter()
            .all(|x| x.0 != 1));
    }
}
