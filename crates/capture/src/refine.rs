//! Pose refinement by edges and silhouettes (Debevec et al. 2004: after PnP, the camera pose is
//! refined by matching the model's silhouette to the photograph's).
//!
//! The model is ray cast through every pixel of the current camera with Embree. Where two
//! neighbouring pixels see different things (one misses the model: silhouette; one surface
//! occludes another: occlusion boundary; two faces meet at an angle: crease, used only with
//! [`RefineOptions::creases`]) the boundary is located to 1/4096 px by bisection, giving a 3D
//! point on the model's edge and the edge's 2D normal (principal direction of the neighbouring
//! edge points). Each edge point is matched to the strongest log-luminance step in the
//! photograph along its normal (within a search range that shrinks as the fit converges), located
//! to sub-pixel by the first moment of the linear-luminance step, and the pose is updated by damped
//! Gauss-Newton on the point-to-edge distances with Huber weights. The edge points are re-cast
//! every few iterations. See docs/IMAGING.md ("Pose refinement").

use crate::CaptureError;
use glam::{DMat3, DVec2, DVec3};
use igi_camera::{Camera, WorldToCamera};
use igi_imaging::HdrImage;
use igi_raycast::RtScene;
use nalgebra::{Matrix6, Vector6};
use rayon::prelude::*;

/// Settings of [`refine_pose`].
#[derive(Clone, Debug)]
pub struct RefineOptions {
    /// Outer iterations (match, then one Gauss-Newton step) at most.
    pub max_iterations: usize,
    /// Initial search range along each edge normal, pixels (about twice the expected error).
    pub search_px: f64,
    /// Smallest search range the schedule shrinks to, pixels.
    pub min_search_px: f64,
    /// Smallest log-luminance step (over one pixel) accepted as a photo edge.
    pub min_contrast: f32,
    /// Faces meeting at more than this angle form a crease edge, degrees.
    pub crease_deg: f64,
    /// Whether creases (faces meeting at an angle, no depth jump) are matched too; otherwise
    /// only silhouettes and occlusion boundaries are. Off by default: the shading at a crease
    /// (ambient occlusion in a concave corner, a shadow starting at a contact line) moves its
    /// photographed step off the geometric edge; on the ground-and-block test site matching
    /// creases left 0.52-0.64 px of pose error from one view where silhouettes alone reach
    /// 0.07-0.1 px.
    pub creases: bool,
}

impl Default for RefineOptions {
    fn default() -> Self {
        RefineOptions {
            max_iterations: 40,
            search_px: 10.0,
            min_search_px: 3.0,
            min_contrast: 0.04,
            crease_deg: 25.0,
            creases: false,
        }
    }
}

/// What a refinement did.
#[derive(Clone, Debug, serde::Serialize)]
pub struct RefineReport {
    pub iterations: usize,
    /// Model edge points found at the final pose.
    pub edge_points: usize,
    /// Edge points matched to a photo edge in the last iteration.
    pub matched: usize,
    /// RMS point-to-edge distance of the matched points before and after, pixels.
    pub rms_before_px: f64,
    pub rms_after_px: f64,
    /// RMS movement of the edge points' projections from the initial to the refined pose, pixels.
    pub moved_px: f64,
}

/// A point on a model edge and the edge's unit normal in the image (at the pose it was cast at).
#[derive(Clone, Copy, Debug)]
struct EdgePoint {
    world: DVec3,
    normal: DVec2,
}

/// A primary-ray hit: distance, point, unit geometric normal.
#[derive(Clone, Copy)]
struct Surf {
    t: f64,
    p: DVec3,
    n: DVec3,
}

fn cast(rt: &RtScene, cam: &Camera, px: DVec2) -> Option<Surf> {
    let (o, d) = cam.pixel_ray(px.x, px.y);
    let h = rt.intersect(o.as_vec3(), d.as_vec3(), 0.0, f32::INFINITY)?;
    let n = h.ng.as_dvec3().normalize_or_zero();
    (n != DVec3::ZERO).then(|| Surf {
        t: h.t as f64,
        p: o + d * h.t as f64,
        n,
    })
}

/// Whether `b` lies on the same smooth surface as `a` (same plane within a small tolerance,
/// normals within the crease angle).
fn same_surface(a: &Surf, b: &Surf, crease_cos: f64) -> bool {
    let d = b.p - a.p;
    a.n.dot(b.n).abs() > crease_cos && a.n.dot(d).abs() <= 0.05 * d.length() + 1e-5 * a.t
}

/// Ray casting of the model through one camera, for locating its edges.
struct EdgeCaster<'a> {
    rt: &'a RtScene,
    cam: &'a Camera,
    crease_cos: f64,
    creases: bool,
}

impl EdgeCaster<'_> {
    /// The edge between pixel centres `pa` and `pb` (which see `a` and `b`), located by
    /// bisection: the 2D boundary position and the 3D point on the front surface next to it;
    /// `None` where there is no edge (or a crease, unless creases are wanted).
    fn locate(
        &self,
        (pa, a): (DVec2, Option<Surf>),
        (pb, b): (DVec2, Option<Surf>),
    ) -> Option<(DVec2, DVec3)> {
        let crease_cos = self.crease_cos;
        let (front, p0, p1) = match (a, b) {
            (None, None) => return None,
            (Some(a), None) => (a, pa, pb),
            (None, Some(b)) => (b, pb, pa),
            (Some(a), Some(b)) => {
                if same_surface(&a, &b, crease_cos) && same_surface(&b, &a, crease_cos) {
                    return None;
                }
                if b.t < a.t * (1.0 - 1e-3) {
                    (b, pb, pa)
                } else {
                    (a, pa, pb)
                }
            }
        };
        let (mut lo, mut hi, mut last, mut beyond) = (0.0f64, 1.0f64, front, None);
        for _ in 0..12 {
            let m = 0.5 * (lo + hi);
            match cast(self.rt, self.cam, p0 + (p1 - p0) * m) {
                Some(s) if same_surface(&front, &s, crease_cos) => {
                    lo = m;
                    last = s;
                }
                s => {
                    hi = m;
                    beyond = s;
                }
            }
        }
        // a crease: the surface beyond the boundary starts where the front one ends (no
        // depth jump)
        let crease = beyond.is_some_and(|s| (s.t - last.t).abs() <= 0.01 * last.t);
        if crease && !self.creases {
            return None;
        }
        Some((p0 + (p1 - p0) * (0.5 * (lo + hi)), last.p))
    }
}

/// All model edge points seen by `cam`, with their image normals.
fn model_edges(rt: &RtScene, cam: &Camera, opts: &RefineOptions) -> Vec<EdgePoint> {
    let (w, h) = (cam.width as usize, cam.height as usize);
    let caster = EdgeCaster {
        rt,
        cam,
        crease_cos: opts.crease_deg.to_radians().cos(),
        creases: opts.creases,
    };
    let surf: Vec<Option<Surf>> = (0..w * h)
        .into_par_iter()
        .map(|i| cast(rt, cam, DVec2::new((i % w) as f64, (i / w) as f64)))
        .collect();
    let (surf, caster) = (&surf, &caster);
    let found: Vec<(DVec2, DVec3)> = (0..w * h)
        .into_par_iter()
        .flat_map_iter(|i| {
            let (x, y) = (i % w, i / w);
            let pa = DVec2::new(x as f64, y as f64);
            let right = (x + 1 < w).then(|| (pa + DVec2::X, surf[i + 1]));
            let down = (y + 1 < h).then(|| (pa + DVec2::Y, surf[i + w]));
            [right, down]
                .into_iter()
                .flatten()
                .filter_map(move |b| caster.locate((pa, surf[i]), b))
                .collect::<Vec<_>>()
        })
        .collect();
    with_normals(&found, w, h)
}

/// Edge normals from the principal direction of the edge points within 2.5 px (a pixel grid
/// indexes them); points at corners or in clutter (no clear line) are dropped.
fn with_normals(found: &[(DVec2, DVec3)], w: usize, h: usize) -> Vec<EdgePoint> {
    let mut grid: Vec<Vec<u32>> = vec![Vec::new(); w * h];
    let cell = |p: DVec2| {
        (
            p.x.round().clamp(0.0, (w - 1) as f64) as usize,
            p.y.round().clamp(0.0, (h - 1) as f64) as usize,
        )
    };
    for (k, (p, _)) in found.iter().enumerate() {
        let (x, y) = cell(*p);
        grid[y * w + x].push(k as u32);
    }
    found
        .par_iter()
        .filter_map(|(p, world)| {
            let (cx, cy) = cell(*p);
            let mut near = Vec::new();
            for y in cy.saturating_sub(3)..(cy + 4).min(h) {
                for x in cx.saturating_sub(3)..(cx + 4).min(w) {
                    near.extend(
                        grid[y * w + x]
                            .iter()
                            .map(|&k| found[k as usize].0)
                            .filter(|q| q.distance(*p) <= 2.5),
                    );
                }
            }
            if near.len() < 4 {
                return None;
            }
            let mean = near.iter().fold(DVec2::ZERO, |a, q| a + *q) / near.len() as f64;
            let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
            for q in &near {
                let d = *q - mean;
                sxx += d.x * d.x;
                sxy += d.x * d.y;
                syy += d.y * d.y;
            }
            // eigenvalues of the 2x2 scatter; the tangent is the major axis
            let tr = sxx + syy;
            let disc = ((sxx - syy).powi(2) + 4.0 * sxy * sxy).sqrt();
            let (l1, l2) = (0.5 * (tr + disc), 0.5 * (tr - disc));
            if !(l1 > 0.0) || l2 > 0.02 * l1 {
                return None;
            }
            let angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
            Some(EdgePoint {
                world: *world,
                normal: DVec2::new(-angle.sin(), angle.cos()),
            })
        })
        .collect()
}

/// The photograph's luminance planes for edge matching (invalid pixels stay invalid): channel 0
/// is the log-luminance, with an offset of 1 % of the mean luminance so that dark noise does not
/// make edges, channels 1 and 2 the linear luminance (bilinear sampling of the linear plane keeps
/// a blurred step symmetric, which the log plane does not).
fn luminance_planes(photo: &HdrImage) -> HdrImage {
    let lum = |p: &[f32; 3]| igi_imaging::color::luminance(*p);
    let mean = photo.pixels.iter().map(lum).sum::<f32>() / photo.pixels.len().max(1) as f32;
    let eps = (0.01 * mean).max(1e-12);
    let mut out = photo.clone();
    for p in &mut out.pixels {
        let l = lum(p).max(0.0);
        *p = [(l + eps).ln(), l, l];
    }
    out
}

/// The strongest log-luminance step along `n` from `p` within `range` px, as a signed offset
/// along `n`. The step is chosen on the log-luminance derivative (so that contrast, not
/// brightness, decides) and located to sub-pixel by [`step_position`] on linear luminance.
fn match_edge(g: &HdrImage, p: DVec2, n: DVec2, range: f64, min_contrast: f32) -> Option<f64> {
    let steps = (2.0 * range).ceil() as i32; // half-pixel samples each side
    let sample = |k: i32| {
        let q = p + n * (0.5 * k as f64);
        g.bilinear(q.x as f32, q.y as f32)
    };
    let vals: Vec<f32> = (-steps - 1..=steps + 1)
        .map(|k| sample(k).map(|v| v[0]))
        .collect::<Option<_>>()?;
    // derivative over one pixel, centred on sample k - steps (index k + 1 in vals)
    let d: Vec<f32> = (1..vals.len() - 1)
        .map(|i| (vals[i + 1] - vals[i - 1]).abs())
        .collect();
    let (k, &peak) = d.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1))?;
    if peak < min_contrast || k == 0 || k + 1 == d.len() {
        return None;
    }
    let centre = k as i32 - steps;
    let linear: Vec<f64> = (centre - STEP_HALF_WINDOW..=centre + STEP_HALF_WINDOW)
        .map(|j| sample(j).map(|v| v[1] as f64))
        .collect::<Option<_>>()?;
    let s = 0.5 * centre as f64 + step_position(&linear)?;
    // the moment must agree with the derivative peak; otherwise the window held a second edge
    ((s - 0.5 * centre as f64).abs() <= 1.0).then_some(s)
}

/// Half-pixel samples each side of a derivative peak used to locate the step (2 px: wide
/// enough for a box-filtered pixel plus bilinear interpolation at any angle).
const STEP_HALF_WINDOW: i32 = 4;

/// Position of a blurred step in `u` (samples 0.5 px apart, centred on the window's middle),
/// relative to the middle, in pixels: for any symmetric blur of a step from `u[0]` to
/// `u[last]`, the area under the normalised profile is the distance from the step to the window
/// end (first moment of the derivative; trapezoidal rule, exact for the bilinear profile of a
/// box-filtered axis-aligned step).
fn step_position(u: &[f64]) -> Option<f64> {
    let (lo, hi) = (u[0], u[u.len() - 1]);
    if !((hi - lo).abs() > 1e-12) {
        return None;
    }
    let f: Vec<f64> = u.iter().map(|v| (v - lo) / (hi - lo)).collect();
    let area = 0.5 * (f.iter().sum::<f64>() - 0.5 * (f[0] + f[f.len() - 1]));
    let half_len = 0.25 * (u.len() - 1) as f64;
    Some(half_len - area)
}

/// The pose after a small motion in the camera frame: `x' = exp(w) x_cam + v`.
fn moved(pose: &WorldToCamera, d: &Vector6<f64>) -> WorldToCamera {
    let w = DVec3::new(d[0], d[1], d[2]);
    let r = if w.length() > 0.0 {
        DMat3::from_axis_angle(w.normalize(), w.length())
    } else {
        DMat3::IDENTITY
    };
    WorldToCamera {
        r: r * pose.r,
        t: r * pose.t + DVec3::new(d[3], d[4], d[5]),
    }
}

/// A matched edge point: where it projects must move along `normal` onto `target`.
struct Match {
    world: DVec3,
    normal: DVec2,
    target: DVec2,
}

/// One damped Gauss-Newton step on the point-to-edge distances with Huber weights. Returns the
/// new camera and the RMS residual before the step.
fn gauss_newton_step(cam: &Camera, matches: &[Match]) -> (Camera, f64) {
    let residual = |c: &Camera, m: &Match| c.project(m.world).map(|p| m.normal.dot(p - m.target));
    let r0: Vec<f64> = matches
        .iter()
        .map(|m| residual(cam, m).unwrap_or(0.0))
        .collect();
    let mut abs: Vec<f64> = r0.iter().map(|r| r.abs()).collect();
    abs.sort_by(f64::total_cmp);
    let huber = (1.5 * 1.4826 * abs[abs.len() / 2]).max(0.5);
    let (mut jtj, mut jtr) = (Matrix6::<f64>::zeros(), Vector6::<f64>::zeros());
    for (m, r) in matches.iter().zip(&r0) {
        let mut j = Vector6::<f64>::zeros();
        for k in 0..6 {
            let eps = 1e-6;
            let mut d = Vector6::<f64>::zeros();
            d[k] = eps;
            let plus = residual(
                &Camera {
                    pose: moved(&cam.pose, &d),
                    ..cam.clone()
                },
                m,
            );
            d[k] = -eps;
            let minus = residual(
                &Camera {
                    pose: moved(&cam.pose, &d),
                    ..cam.clone()
                },
                m,
            );
            if let (Some(a), Some(b)) = (plus, minus) {
                j[k] = (a - b) / (2.0 * eps);
            }
        }
        let w = if r.abs() <= huber {
            1.0
        } else {
            huber / r.abs()
        };
        jtj += j * j.transpose() * w;
        jtr += j * (*r * w);
    }
    let damped = jtj + Matrix6::from_diagonal(&jtj.diagonal().map(|v| 1e-3 * v + 1e-12));
    let step = damped
        .cholesky()
        .map(|c| -c.solve(&jtr))
        .unwrap_or_else(Vector6::zeros);
    let rms = (r0.iter().map(|r| r * r).sum::<f64>() / r0.len() as f64).sqrt();
    (
        Camera {
            pose: moved(&cam.pose, &step),
            ..cam.clone()
        },
        rms,
    )
}

/// Refines `camera`'s pose so that the edges and silhouette of the model in `rt` fall on the
/// edges of `photo` (linear radiance, the camera's size). The intrinsics are kept.
pub fn refine_pose(
    photo: &HdrImage,
    camera: &Camera,
    rt: &RtScene,
    opts: &RefineOptions,
) -> Result<(Camera, RefineReport), CaptureError> {
    if photo.width != camera.width as usize || photo.height != camera.height as usize {
        return Err(CaptureError::PhotoSize {
            photo: (photo.width, photo.height),
            camera: (camera.width, camera.height),
        });
    }
    let g = luminance_planes(photo);
    let mut cam = camera.clone();
    let mut edges = model_edges(rt, &cam, opts);
    let initial: Vec<DVec3> = edges.iter().map(|e| e.world).collect();
    let (mut rms_before, mut rms_after, mut matched, mut iterations) = (None, 0.0, 0, 0);
    let mut range = opts.search_px;
    for it in 0..opts.max_iterations {
        if it > 0 && it % 4 == 0 {
            edges = model_edges(rt, &cam, opts);
        }
        let matches: Vec<Match> = edges
            .iter()
            .filter_map(|e| {
                let p = cam.project(e.world)?;
                let s = match_edge(&g, p, e.normal, range, opts.min_contrast)?;
                Some(Match {
                    world: e.world,
                    normal: e.normal,
                    target: p + e.normal * s,
                })
            })
            .collect();
        if matches.len() < 12 {
            return Err(CaptureError::TooFewEdgeMatches {
                matched: matches.len(),
                found: edges.len(),
                search_px: opts.search_px,
            });
        }
        let (next, rms) = gauss_newton_step(&cam, &matches);
        rms_before.get_or_insert(rms);
        rms_after = rms;
        matched = matches.len();
        iterations = it + 1;
        let shift = matches
            .iter()
            .filter_map(|m| Some(next.project(m.world)?.distance(cam.project(m.world)?)))
            .fold(0.0f64, f64::max);
        cam = next;
        range = (range * 0.8).max(opts.min_search_px);
        if shift < 1e-3 && range <= opts.min_search_px {
            break;
        }
    }
    let moved_px = igi_camera::camera::reprojection_rms(camera, &cam, &initial).unwrap_or(0.0);
    let report = RefineReport {
        iterations,
        edge_points: edges.len(),
        matched,
        rms_before_px: rms_before.unwrap_or(0.0),
        rms_after_px: rms_after,
        moved_px,
    };
    Ok((cam, report))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A box-filtered step edge at a known sub-pixel position is located to 0.05 px along any
    /// direction, and a flat image has no edge.
    #[test]
    fn match_edge_finds_a_sub_pixel_step() {
        let (w, h) = (40, 40);
        for edge_x in [17.5f64, 18.0, 18.3, 18.77] {
            let mut img = HdrImage::new(w, h);
            for y in 0..h {
                for x in 0..w {
                    // pixel x covers [x - 0.5, x + 0.5]: coverage of the bright side x > edge_x
                    let cover = ((x as f64 + 0.5 - edge_x).clamp(0.0, 1.0)) as f32;
                    img.set(x, y, [0.2 + 0.8 * cover; 3]);
                }
            }
            let g = luminance_planes(&img);
            for (p, n) in [
                (DVec2::new(15.0, 20.0), DVec2::X),
                (DVec2::new(21.0, 20.0), -DVec2::X),
                (DVec2::new(16.0, 18.0), DVec2::new(1.0, 0.3).normalize()),
            ] {
                let s = match_edge(&g, p, n, 6.0, 0.04).expect("edge found");
                let hit = p + n * s;
                assert!(
                    (hit.x - edge_x).abs() < 0.05,
                    "edge at {edge_x}: found x = {} from {p} along {n}",
                    hit.x
                );
            }
        }
        let flat = luminance_planes(&HdrImage::new(w, h));
        assert!(match_edge(&flat, DVec2::new(20.0, 20.0), DVec2::X, 6.0, 0.04).is_none());
    }
}
