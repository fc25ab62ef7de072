//! Sphere centres refined from their outlines in the photograph.
//!
//! A sphere placed by the board's fiducial pose inherits the pose's error, and the sun's
//! direction turns by about `2 dc / r` for a black-sphere centre off by `dc` across the line of
//! sight (0.3 degrees for 0.17 mm on a 6 cm sphere). The sphere's own silhouette pins its centre
//! across the line of sight far better: [`refine_center`] measures the silhouette edge to
//! sub-pixel precision along the normals of the pose-predicted outline and moves the centre
//! across the line of sight (its distance from the camera is kept) until the sphere's tangent
//! cone passes through the measured edge points.
//!
//! Edge position along a normal: the image profile across the predicted edge (bilinear, from
//! `-L` inside to `+L` outside) smoothed by a Gaussian of 0.5 px, and the steepest point of the
//! step (sign from the median levels of the profile's ends), refined by a parabola. Normals whose
//! contrast between the two ends is under [`MIN_CONTRAST`] of the brighter level are left out.
//!
//! Only the mirror and black spheres are refined ([`refine_board`]): the diffuse sphere's shading
//! falls toward its terminator right at the outline and moved its measured edge by 1-2 px.
//! The glossy spheres' rims brighten toward grazing incidence and show what they reflect there.
//! On a real board that is mostly the board behind them, alike all around the outline, and the
//! pull on the edge is the common offset below (fiducial test: the black centre 0.142 -> 0.024
//! mm). Where the rim reflects something other than its background (a synthetic board with no
//! panel whose rims show a sky with a horizon step) the edge moves by a few tenths of a pixel
//! around the outline (-0.05 to -0.35 px measured) and about 0.1 px of centre error remains.
//!
//! The fit: each edge point's ray must make the cone's half-angle `asin(R / |c|)` with the
//! direction to the centre `c`, up to one constant angular offset `b` shared by all points (it
//! absorbs what moves every edge point alike: the lens blur on a curved edge, a black sphere's
//! rim brightening toward grazing incidence). Unknowns: two angles of `c` across the line of
//! sight and `b`; Gauss-Newton, then again without the points beyond 3 robust standard
//! deviations.

use crate::board::{BoardSphere, SphereKind};
use glam::{DVec2, DVec3};
use igi_camera::Camera;
use igi_capture::sphere::SphereView;
use igi_imaging::HdrImage;
use nalgebra::{Matrix3, Vector3};

/// Half-length (pixels) of the profile sampled across the predicted edge, beyond the lens blur.
pub const PROFILE_HALF_PX: f64 = 4.0;
/// Minimum edge contrast, as a fraction of the brighter of the two levels.
pub const MIN_CONTRAST: f64 = 0.15;
/// Fewest usable edge points for a fit.
pub const MIN_EDGE_POINTS: usize = 24;

/// What [`refine_center`] did.
#[derive(Clone, Debug, serde::Serialize)]
pub struct OutlineFit {
    pub kind: String,
    /// The centre before and after, camera frame (metres).
    pub center_before: [f64; 3],
    pub center_after: [f64; 3],
    /// How far the centre's image moved (pixels).
    pub shift_px: f64,
    /// Edge points measured, and used in the final fit.
    pub edge_points: usize,
    pub edge_points_used: usize,
    /// RMS distance of the used edge points from the fitted outline (pixels).
    pub rms_px: f64,
    /// The fitted common offset of the edge (pixels, positive outward).
    pub edge_offset_px: f64,
}

/// Luminance along the segment `p + s n`, `s` in `[-half, half]` in `k + 1` steps.
fn profile(img: &HdrImage, p: DVec2, n: DVec2, half: f64, k: usize) -> Option<Vec<f64>> {
    (0..=k)
        .map(|i| {
            let s = -half + 2.0 * half * i as f64 / k as f64;
            let q = p + s * n;
            img.bilinear(q.x as f32, q.y as f32)
                .map(|p| igi_imaging::color::luminance_f64(p.map(f64::from)))
        })
        .collect()
}

fn median_of(v: &[f64]) -> f64 {
    igi_imaging::color::median_in_place(&mut v.to_vec())
}

/// The edge's offset along `n` from `p` (pixels, positive outward), or `None` without a clean step.
fn edge_offset(img: &HdrImage, p: DVec2, n: DVec2, half: f64) -> Option<f64> {
    const STEPS_PER_PX: f64 = 8.0;
    let k = (2.0 * half * STEPS_PER_PX).round() as usize;
    let prof = profile(img, p, n, half, k)?;
    let band = (1.5 * STEPS_PER_PX) as usize;
    let (inside, outside) = (&prof[..=band], &prof[k - band..]);
    let (lev_i, lev_o) = (median_of(inside), median_of(outside));
    let contrast = (lev_i - lev_o).abs();
    if !(contrast > MIN_CONTRAST * lev_i.abs().max(lev_o.abs())) {
        return None;
    }
    // smooth (Gaussian of 0.5 px: bilinear interpolation's kinks), differentiate, and take the
    // steepest point of the step's sign, refined by a parabola through its neighbours
    let sig = 0.5 * STEPS_PER_PX;
    let rad = (3.0 * sig) as i64;
    let ker: Vec<f64> = (-rad..=rad)
        .map(|i| (-((i * i) as f64) / (2.0 * sig * sig)).exp())
        .collect();
    let sm: Vec<f64> = (0..=k as i64)
        .map(|i| {
            let (mut a, mut w) = (0.0, 0.0);
            for (j, kv) in ker.iter().enumerate() {
                let q = i + j as i64 - rad;
                if q >= 0 && q <= k as i64 {
                    a += kv * prof[q as usize];
                    w += kv;
                }
            }
            a / w
        })
        .collect();
    let sign = if lev_o > lev_i { 1.0 } else { -1.0 };
    let g: Vec<f64> = (1..k).map(|i| sign * (sm[i + 1] - sm[i - 1])).collect();
    let (im, gm) = g.iter().enumerate().fold(
        (0, f64::MIN),
        |a, (i, v)| if *v > a.1 { (i, *v) } else { a },
    );
    if im == 0 || im + 1 >= g.len() || !(gm > 0.0) {
        return None;
    }
    let (a, b, c) = (g[im - 1], g[im], g[im + 1]);
    let den = a - 2.0 * b + c;
    let frac = if den < 0.0 { 0.5 * (a - c) / den } else { 0.0 };
    let s = -half + (im as f64 + 1.0 + frac) / STEPS_PER_PX;
    (s.abs() < half - 1.5).then_some(s)
}

/// Measured silhouette edge points (pixels) along the normals of the predicted outline.
fn edge_points(img: &HdrImage, view: &SphereView, half: f64) -> Vec<DVec2> {
    let r_px = view.pixel_radius();
    let n = ((std::f64::consts::TAU * r_px / 2.0).round() as usize).clamp(64, 1440);
    let pts = view.outline(n);
    if pts.len() < n {
        return Vec::new();
    }
    let centre = pts.iter().fold(DVec2::ZERO, |a, p| a + *p) / n as f64;
    (0..n)
        .filter_map(|i| {
            let t = pts[(i + 1) % n] - pts[(i + n - 1) % n];
            let mut nrm = DVec2::new(t.y, -t.x).normalize();
            if nrm.dot(pts[i] - centre) < 0.0 {
                nrm = -nrm;
            }
            edge_offset(img, pts[i], nrm, half).map(|s| pts[i] + s * nrm)
        })
        .collect()
}

/// Centre `c0` turned across the line of sight by angles `(a, b)` about the camera centre.
fn moved(c0: DVec3, e1: DVec3, e2: DVec3, a: f64, b: f64) -> DVec3 {
    let d = c0.length();
    let dir = (c0 / d + a * e1 + b * e2).normalize();
    d * dir
}

/// Residuals (radians) of the camera-frame rays against the cone of centre `c`, offset `off`.
fn residuals(rays: &[DVec3], c: DVec3, radius: f64, off: f64) -> Vec<f64> {
    let axis = c.normalize();
    let half = (radius / c.length()).asin();
    rays.iter()
        .map(|r| r.dot(axis).clamp(-1.0, 1.0).acos() - half - off)
        .collect()
}

/// Gauss-Newton over (a, b, off) with numeric derivatives; returns the parameters.
fn solve(rays: &[DVec3], c0: DVec3, radius: f64, e: (DVec3, DVec3)) -> [f64; 3] {
    let mut x = [0.0f64; 3];
    let model = |x: &[f64; 3]| residuals(rays, moved(c0, e.0, e.1, x[0], x[1]), radius, x[2]);
    for _ in 0..10 {
        let r0 = model(&x);
        let h = 1e-7;
        let jac: Vec<Vec<f64>> = (0..3)
            .map(|k| {
                let mut xp = x;
                xp[k] += h;
                model(&xp)
                    .iter()
                    .zip(&r0)
                    .map(|(a, b)| (a - b) / h)
                    .collect()
            })
            .collect();
        let (mut jtj, mut jtr) = (Matrix3::<f64>::zeros(), Vector3::<f64>::zeros());
        for i in 0..r0.len() {
            for a in 0..3 {
                jtr[a] += jac[a][i] * r0[i];
                for b in 0..3 {
                    jtj[(a, b)] += jac[a][i] * jac[b][i];
                }
            }
        }
        let Some(step) = jtj.lu().solve(&(-jtr)) else {
            break;
        };
        for k in 0..3 {
            x[k] += step[k];
        }
        if step.norm() < 1e-12 {
            break;
        }
    }
    x
}

/// The sphere's centre moved across the line of sight to fit its silhouette in `img` (see the
/// module doc). `None` when fewer than [`MIN_EDGE_POINTS`] edge points could be measured
/// (the caller keeps the given centre).
pub fn refine_center(
    img: &HdrImage,
    camera: &Camera,
    kind: SphereKind,
    sphere: &BoardSphere,
    blur_px: f64,
) -> Option<(BoardSphere, OutlineFit)> {
    let view = SphereView::new(camera, kind, sphere);
    let half = PROFILE_HALF_PX + 2.0 * blur_px.max(0.0);
    let pts = edge_points(img, &view, half);
    if pts.len() < MIN_EDGE_POINTS {
        return None;
    }
    // rays in the camera frame
    let rot = camera.pose.r;
    let mut rays: Vec<DVec3> = pts
        .iter()
        .map(|p| rot * camera.pixel_ray(p.x, p.y).1)
        .collect();
    let c0 = sphere.center_cam;
    let e = c0.normalize().any_orthonormal_pair();
    let mut x = solve(&rays, c0, sphere.radius, e);
    let f = camera.intrinsics.fx;
    let res = residuals(&rays, moved(c0, e.0, e.1, x[0], x[1]), sphere.radius, x[2]);
    let abs: Vec<f64> = res.iter().map(|r| r.abs()).collect();
    let cut = (3.0 * 1.4826 * median_of(&abs)).max(0.05 / f);
    rays = rays
        .into_iter()
        .zip(&res)
        .filter(|(_, r)| r.abs() <= cut)
        .map(|(v, _)| v)
        .collect();
    if rays.len() < MIN_EDGE_POINTS {
        return None;
    }
    x = solve(&rays, c0, sphere.radius, e);
    let c = moved(c0, e.0, e.1, x[0], x[1]);
    let res = residuals(&rays, c, sphere.radius, x[2]);
    let rms = (res.iter().map(|r| r * r).sum::<f64>() / res.len() as f64).sqrt() * f;
    let project = |p: DVec3| camera.intrinsics.to_pixel(DVec2::new(p.x / p.z, p.y / p.z));
    let fit = OutlineFit {
        kind: kind.name().to_string(),
        center_before: c0.to_array(),
        center_after: c.to_array(),
        shift_px: project(c).distance(project(c0)),
        edge_points: pts.len(),
        edge_points_used: rays.len(),
        rms_px: rms,
        edge_offset_px: x[2] * f,
    };
    let refined = BoardSphere {
        center_cam: c,
        radius: sphere.radius,
    };
    Some((refined, fit))
}

/// The mirror and black spheres of `board` refined by [`refine_center`] (a sphere whose
/// silhouette gives too few edge points keeps its centre, with a warning; the diffuse sphere is
/// kept, see the module doc). Returns the board, the fits and the warnings.
pub fn refine_board(
    img: &HdrImage,
    camera: &Camera,
    board: &crate::Board,
    blur_px: f64,
) -> (crate::Board, Vec<OutlineFit>, Vec<String>) {
    let mut out = board.clone();
    let (mut fits, mut warnings) = (Vec::new(), Vec::new());
    let spheres: [(SphereKind, Option<&mut BoardSphere>); 2] = [
        (SphereKind::Mirror, Some(&mut out.mirror)),
        (SphereKind::Black, out.black.as_mut()),
    ];
    for (kind, s) in spheres {
        let Some(s) = s else { continue };
        match refine_center(img, camera, kind, s, blur_px) {
            Some((refined, fit)) => {
                *s = refined;
                fits.push(fit);
            }
            None => warnings.push(format!(
                "the {} sphere's outline gave fewer than {MIN_EDGE_POINTS} clean edge points: its centre is not refined",
                kind.name()
            )),
        }
    }
    (out, fits, warnings)
}
