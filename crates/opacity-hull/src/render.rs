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
//!
//! Coverage: each surfel stands for an area of the hull ([`Surfels::area`]); its kernel, scaled
//! to sum to that area's projection in pixels over the pixel centres it reaches, adds the share
//! of each pixel it covers. Where nothing lies behind the nearest surface, a pixel whose shares
//! sum below [`FULL_COVER`] is covered only in part: the alpha is scaled by the sum over
//! [`FULL_COVER`]. So a splat reaching past the hull's rim, or past a thin part, adds a little
//! of itself there, not its whole alpha. Where a farther surface lies behind (an edge inside the
//! silhouette), the pixel stays covered: one layer cannot show what is behind it.

use crate::surfel::Surfels;
use glam::{DVec3, Vec3};
use igi_camera::Camera;
use igi_imaging::HdrImage;
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

/// The most views blended per surfel ([`RenderOptions::k`] is clamped to it).
pub const MAX_K: usize = 16;

/// Eq. 4 weights for one surfel: `(view, weight)` pairs summing to 1, empty if no view sees it.
pub fn blend_weights(
    p: DVec3,
    target: DVec3,
    centres: &[DVec3],
    visible: &[bool],
    k: usize,
) -> Vec<(usize, f64)> {
    let mut out = [(0, 0.0); MAX_K];
    let n = blend_weights_into(p, target, centres, visible, k, &mut out);
    out[..n].to_vec()
}

/// [`blend_weights`] without allocating: fills `out` and returns how many pairs it holds.
pub fn blend_weights_into(
    p: DVec3,
    target: DVec3,
    centres: &[DVec3],
    visible: &[bool],
    k: usize,
    out: &mut [(usize, f64); MAX_K],
) -> usize {
    let k = k.clamp(1, MAX_K);
    let n = nearest_views(p, target, centres, visible, k, out);
    if n == 0 {
        return 0;
    }
    if out[0].1 <= 1e-12 {
        out[0].1 = 1.0;
        return 1;
    }
    let cos_t = 1.0 - out[n - 1].1;
    let mut sum = 0.0;
    for x in &mut out[..n] {
        let (pen, cos_i) = (x.1, 1.0 - x.1);
        let r = if cos_t < 1.0 {
            (cos_i - cos_t) / (1.0 - cos_t)
        } else {
            1.0
        };
        x.1 = r.max(0.0) / pen;
        sum += x.1;
    }
    if !(sum > 0.0) {
        // all kept views equally far: equal weights
        out[..n].iter_mut().for_each(|x| x.1 = 1.0 / n as f64);
        return n;
    }
    let mut kept = 0;
    for i in 0..n {
        if out[i].1 > 0.0 {
            out[kept] = (out[i].0, out[i].1 / sum);
            kept += 1;
        }
    }
    kept
}

/// The `k` visible views of smallest penalty `1 - cos theta` as `(view, penalty)`, ascending
/// (ties: the lower view index first); returns how many.
fn nearest_views(
    p: DVec3,
    target: DVec3,
    centres: &[DVec3],
    visible: &[bool],
    k: usize,
    out: &mut [(usize, f64); MAX_K],
) -> usize {
    let dt = (target - p).normalize_or_zero();
    let mut n = 0;
    for (v, c) in centres.iter().enumerate().filter(|(v, _)| visible[*v]) {
        let pen = 1.0 - (*c - p).normalize_or_zero().dot(dt);
        if n == k && pen >= out[k - 1].1 {
            continue;
        }
        // insert after every kept entry with a penalty <= pen
        let mut j = n.min(k - 1);
        while j > 0 && out[j - 1].1 > pen {
            out[j] = out[j - 1];
            j -= 1;
        }
        out[j] = (v, pen);
        n = (n + 1).min(k);
    }
    n
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
    /// The surfel's projected area (pixels) over its kernel's sum over the pixel centres it
    /// reaches ([`kernel_sum`]): a pixel's sum of kernel weight times `cover` is the share of it
    /// the surface covers.
    cover: f32,
}

/// The summed coverage at which a pixel counts as fully covered. Inside a surface the sums
/// scatter about 1 (the dino: 10 % of pixels below 0.76, 10 % above 1.35), so a pixel is
/// partly covered only well below that (docs/OPACITY_HULL.md, "Splat coverage").
pub const FULL_COVER: f32 = 0.5;

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
            let mut w = [(0, 0.0); MAX_K];
            let nw = blend_weights_into(
                p,
                target,
                &model.centres,
                &s.visible[i * nv..(i + 1) * nv],
                opts.k,
                &mut w,
            );
            if nw == 0 {
                return None;
            }
            let (mut color, mut alpha) = (Vec3::ZERO, 0.0f32);
            for &(v, wt) in &w[..nw] {
                color += Vec3::from_array(model.colors[i * nv + v]) * wt as f32;
                alpha += s.opacity[i * nv + v] * wt as f32;
            }
            let r = (s.radius[i] * fx / z as f32).max(opts.min_radius_px);
            let cover = match s.area.get(i) {
                Some(&a) => {
                    let cos = n.dot((target - p).normalize()).abs() as f32;
                    let px_per_m = fx / z as f32;
                    a * cos * px_per_m * px_per_m / kernel_sum(px.x as f32, px.y as f32, r)
                }
                None => f32::INFINITY,
            };
            Some(Splat {
                x: px.x as f32,
                y: px.y as f32,
                z: z as f32,
                r,
                color,
                alpha,
                cover,
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

/// A splat's weight at squared distance `d2` from its centre (within its radius `r`).
#[inline]
fn kernel(d2: f32, r: f32) -> f32 {
    1.0 - d2 / (r * r) + 1e-3
}

/// [`kernel`] summed over the pixel centres within `r` of (x, y), as the band passes weigh
/// them (the image's edges aside).
fn kernel_sum(x: f32, y: f32, r: f32) -> f32 {
    let r = r.min(32.0);
    let mut sum = 0.0;
    for py in (y - r).ceil() as i64..=(y + r).floor() as i64 {
        let dy2 = (py as f32 - y).powi(2);
        for px in (x - r).ceil() as i64..=(x + r).floor() as i64 {
            let d2 = (px as f32 - x).powi(2) + dy2;
            if d2 <= r * r {
                sum += kernel(d2, r);
            }
        }
    }
    sum.max(1e-3)
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

/// Rows per band: bands are splatted in parallel, each from the splats overlapping it in
/// surfel order, so the image does not depend on the thread count either.
const BAND: usize = 8;

/// The splats with their pixel boxes, for the band passes.
struct Splatter<'a> {
    splats: &'a [Option<Splat>],
    boxes: Vec<Option<(usize, usize, usize, usize)>>,
    width: usize,
    /// Depth tolerance in surfel radii, and the surfels' radii.
    tol: f32,
    radius: &'a [f32],
}

fn splat(
    splats: &[Option<Splat>],
    w: usize,
    h: usize,
    tol: f32,
    radius: &[f32],
) -> (HdrImage, Vec<f32>) {
    let boxes: Vec<_> = splats
        .iter()
        .map(|sp| sp.as_ref().and_then(|sp| footprint(sp, w, h)))
        .collect();
    let mut bands: Vec<Vec<u32>> = vec![Vec::new(); h.div_ceil(BAND)];
    for (i, b) in boxes.iter().enumerate() {
        if let Some((_, _, y0, y1)) = *b {
            for band in &mut bands[y0 / BAND..=y1 / BAND] {
                band.push(i as u32);
            }
        }
    }
    let sp = Splatter {
        splats,
        boxes,
        width: w,
        tol,
        radius,
    };
    let mut img = HdrImage::new(w, h);
    let mut alpha = vec![0.0f32; w * h];
    img.pixels
        .par_chunks_mut(BAND * w)
        .zip(alpha.par_chunks_mut(BAND * w))
        .zip(bands.par_iter())
        .enumerate()
        .for_each(|(b, ((px, al), ids))| sp.band(b * BAND, ids, px, al));
    (img, alpha)
}

impl Splatter<'_> {
    /// Splat rows `y_start..` (as many as `alpha` holds) from the splats `ids`: the nearest depth
    /// per pixel, then the weighted mean of the splats within the tolerance of it.
    fn band(&self, y_start: usize, ids: &[u32], pixels: &mut [[f32; 3]], alpha: &mut [f32]) {
        let w = self.width;
        let y_end = y_start + alpha.len() / w - 1;
        let mut zbuf = vec![f32::INFINITY; alpha.len()];
        self.cover(ids, y_start, y_end, |_, j, sp, _| {
            zbuf[j] = zbuf[j].min(sp.z)
        });
        let mut acc = vec![[0.0f32; 6]; alpha.len()];
        // pixels with a surface behind the nearest: their coverage is not partial
        let mut behind = vec![false; alpha.len()];
        self.cover(ids, y_start, y_end, |i, j, sp, d2| {
            if sp.z > zbuf[j] + self.tol * self.radius[i] {
                behind[j] = true;
                return;
            }
            let k = kernel(d2, sp.r);
            let a = &mut acc[j];
            a[0] += k * sp.color.x;
            a[1] += k * sp.color.y;
            a[2] += k * sp.color.z;
            a[3] += k * sp.alpha;
            a[4] += k;
            a[5] += k * sp.cover;
        });
        for (j, a) in acc.iter().enumerate() {
            if a[4] > 0.0 {
                let cover = if behind[j] {
                    1.0
                } else {
                    (a[5] / FULL_COVER).min(1.0)
                };
                let al = (a[3] / a[4]).clamp(0.0, 1.0) * cover;
                alpha[j] = al;
                pixels[j] = [a[0] / a[4] * al, a[1] / a[4] * al, a[2] / a[4] * al];
            }
        }
    }

    /// Call `f(surfel, pixel index in the band, splat, squared distance)` for every pixel of rows
    /// `y0..=y1` inside a splat's disk, splats in the order of `ids`.
    fn cover(
        &self,
        ids: &[u32],
        y0: usize,
        y1: usize,
        mut f: impl FnMut(usize, usize, &Splat, f32),
    ) {
        let w = self.width;
        for &i in ids {
            let i = i as usize;
            let (Some(sp), Some((x0, x1, sy0, sy1))) = (&self.splats[i], self.boxes[i]) else {
                continue;
            };
            for y in sy0.max(y0)..=sy1.min(y1) {
                let dy2 = (y as f32 - sp.y).powi(2);
                for x in x0..=x1 {
                    let d2 = (x as f32 - sp.x).powi(2) + dy2;
                    if d2 <= sp.r * sp.r {
                        f(i, (y - y0) * w + x, sp, d2);
                    }
                }
            }
        }
    }
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

    /// The insertion selection keeps what sorting all candidates by (penalty, view) and taking
    /// the first k keeps, ties included.
    #[test]
    fn nearest_views_match_a_full_sort() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
        for case in 0..500 {
            let nv = rng.gen_range(1..40);
            // few distinct directions, so that ties occur
            let centres: Vec<DVec3> = (0..nv)
                .map(|_| {
                    let a = rng.gen_range(0..6) as f64;
                    DVec3::new(a.cos(), a.sin(), 0.3)
                })
                .collect();
            let vis: Vec<bool> = (0..nv).map(|_| rng.gen_bool(0.8)).collect();
            let target = DVec3::new(2.0, 1.0, 0.5);
            let k = rng.gen_range(1..=MAX_K);
            let mut out = [(0, 0.0); MAX_K];
            let n = nearest_views(DVec3::ZERO, target, &centres, &vis, k, &mut out);
            let dt = target.normalize();
            let mut all: Vec<(usize, f64)> = (0..nv)
                .filter(|&v| vis[v])
                .map(|v| (v, 1.0 - centres[v].normalize().dot(dt)))
                .collect();
            all.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
            all.truncate(k);
            assert_eq!(&out[..n], &all[..], "case {case}");
        }
    }

    /// A square of surfels facing the camera, 40 x 40 on a 1 mm grid, each standing for 1 mm^2:
    /// inside, every pixel is covered; over the image the alphas sum to the square's projected
    /// area within 3 % (without the areas, the splats reaching past the rim add a ring).
    #[test]
    fn coverage_sums_to_the_projected_area() {
        let mut cam = Camera::pinhole(64, 64, 500.0, 500.0, 31.5, 31.5);
        cam.pose =
            igi_camera::WorldToCamera::look_at(DVec3::new(0.0, 0.0, 1.0), DVec3::ZERO, DVec3::Y)
                .unwrap();
        let n = 40;
        let step = 1e-3f32;
        let positions: Vec<[f32; 3]> = (0..n * n)
            .map(|i| {
                let (x, y) = ((i % n) as f32 + 0.5, (i / n) as f32 + 0.5);
                [
                    (x - n as f32 / 2.0) * step,
                    (y - n as f32 / 2.0) * step,
                    0.0,
                ]
            })
            .collect();
        let k = positions.len();
        let mut model = HullModel {
            surfels: Surfels {
                positions,
                normals: vec![[0.0, 0.0, 1.0]; k],
                radius: vec![0.7 * step; k],
                area: vec![step * step; k],
                views: 1,
                visible: vec![true; k],
                opacity: vec![1.0; k],
            },
            centres: vec![DVec3::new(0.0, 0.0, 1.0)],
            colors: vec![[0.5, 0.5, 0.5]; k],
        };
        let (_, alpha) = render(&model, &cam, RenderOptions::default());
        // the square is 40 mm at 1 m and 500 px per unit: 20 x 20 pixels, centred
        let projected = (n as f32 * step * 500.0).powi(2);
        let sum: f32 = alpha.iter().sum();
        assert!(
            (sum / projected - 1.0).abs() < 0.03,
            "{sum} against {projected}"
        );
        for y in 24..40 {
            for x in 24..40 {
                assert_eq!(alpha[y * 64 + x], 1.0, "({x}, {y})");
            }
        }
        model.surfels.area.clear();
        let (_, alpha) = render(&model, &cam, RenderOptions::default());
        let sum_old: f32 = alpha.iter().sum();
        eprintln!("alpha sums: {sum} with the areas, {sum_old} without, {projected} projected");
        assert!(sum_old > 1.05 * projected, "{sum_old} against {projected}");
    }
}
