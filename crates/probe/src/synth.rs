//! A small reference renderer of board photographs from a known lat-long sky (and sun), for
//! round-trip tests and benchmarks. Independent of the unwarping code: it traces camera rays
//! forward (pixel -> sphere -> reflected direction), with `ss` x `ss` supersampling.

use crate::board::Board;
use crate::board::SphereKind;
use crate::envmap::{latlong_lookup, Integrator};
use crate::sphere::{reflect, SphereView};
use glam::DVec3;
use igi_imaging::{Camera, HdrImage, WorldToCamera};
use rayon::prelude::*;

/// A sun for [`render_board`]: direction (unit, toward the sun), radiance, angular diameter.
#[derive(Clone, Copy, Debug)]
pub struct SynthSun {
    pub direction: DVec3,
    pub radiance: [f32; 3],
    pub diameter_deg: f64,
}

/// Render the board's spheres (and the sky behind them) as the camera sees them. Mirror and
/// black spheres reflect the sky (and the sun disk where reflected rays hit it) times their
/// Fresnel reflectance; the diffuse sphere shows reflectance * irradiance / pi (irradiance
/// from the integrated sky plus the sun disk, evaluated at each sub-sample's normal).
/// `sky` must be fully valid.
pub fn render_board(
    camera: &Camera,
    board: &Board,
    sky: &HdrImage,
    sun: Option<SynthSun>,
    ss: usize,
) -> HdrImage {
    render_board_with_panel(camera, board, sky, sun, ss, None)
}

/// The flat board behind the spheres, printed with fiducials, for [`render_board_with_panel`]:
/// a rectangle of the board plane `z = 0` (board frame) of constant radiance `white`, with
/// markers of radiance `black` where their images are 0 (and `white` where 255).
#[derive(Clone, Debug)]
pub struct SynthPanel {
    /// Board to camera: `x_cam = r x_board + t`.
    pub board_to_camera: WorldToCamera,
    /// `[x0, y0, x1, y1]` in the board plane.
    pub extent: [f64; 4],
    pub white: f32,
    pub black: f32,
    /// Each marker: its corners in the board frame (the image's top-left, top-right,
    /// bottom-right, bottom-left; in the plane z = 0), and its `side` x `side` image (bytes).
    pub markers: Vec<([DVec3; 4], usize, Vec<u8>)>,
}

impl SynthPanel {
    /// Radiance of board-frame point `q` (in the plane) if it is on the panel.
    fn radiance(&self, q: DVec3) -> Option<f32> {
        let [x0, y0, x1, y1] = self.extent;
        if !(q.x >= x0 && q.x <= x1 && q.y >= y0 && q.y <= y1) {
            return None;
        }
        for (c, side, bits) in &self.markers {
            let (a, b) = (c[1] - c[0], c[3] - c[0]);
            let (s, t) = (
                (q - c[0]).dot(a) / a.length_squared(),
                (q - c[0]).dot(b) / b.length_squared(),
            );
            if (0.0..1.0).contains(&s) && (0.0..1.0).contains(&t) {
                let (col, row) = ((s * *side as f64) as usize, (t * *side as f64) as usize);
                let v = bits[row.min(side - 1) * side + col.min(side - 1)] as f32 / 255.0;
                return Some(self.black + (self.white - self.black) * v);
            }
        }
        Some(self.white)
    }

    /// Nearest hit (distance along the unit world ray, radiance) of the panel.
    fn hit(&self, camera: &Camera, o: DVec3, d: DVec3) -> Option<(f64, f32)> {
        let c2w = camera.pose.inverse();
        let to_world = |p: DVec3| c2w.apply(self.board_to_camera.apply(p));
        let origin = to_world(DVec3::ZERO);
        let (ex, ey) = (to_world(DVec3::X) - origin, to_world(DVec3::Y) - origin);
        let n = ex.cross(ey);
        let den = d.dot(n);
        if den.abs() < 1e-12 {
            return None;
        }
        let t = (origin - o).dot(n) / den;
        if t <= 0.0 || !t.is_finite() {
            return None;
        }
        let q = o + t * d - origin;
        self.radiance(DVec3::new(q.dot(ex), q.dot(ey), 0.0))
            .map(|v| (t, v))
    }
}

/// [`render_board`] with the board itself behind the spheres (an optional textured panel
/// with fiducials, see [`SynthPanel`]); rays that miss spheres and panel show the sky.
pub fn render_board_with_panel(
    camera: &Camera,
    board: &Board,
    sky: &HdrImage,
    sun: Option<SynthSun>,
    ss: usize,
    panel: Option<&SynthPanel>,
) -> HdrImage {
    let ss = ss.max(1);
    let views: Vec<SphereView> =
        std::iter::once(SphereView::new(camera, SphereKind::Mirror, &board.mirror))
            .chain(
                board
                    .black
                    .iter()
                    .map(|b| SphereView::new(camera, SphereKind::Black, b)),
            )
            .chain(
                board
                    .diffuse
                    .iter()
                    .map(|b| SphereView::new(camera, SphereKind::Diffuse, b)),
            )
            .collect();
    let integ = if board.diffuse.is_some() {
        Some(Integrator::new(sky))
    } else {
        None
    };
    let sun_cos = sun.map(|s| (s.diameter_deg * 0.5).to_radians().cos());
    let env = |d: DVec3| -> [f32; 3] {
        let mut v = latlong_lookup(sky, d.as_vec3()).unwrap_or([0.0; 3]);
        if let (Some(s), Some(c)) = (sun, sun_cos) {
            if d.dot(s.direction) >= c {
                for k in 0..3 {
                    v[k] += s.radiance[k];
                }
            }
        }
        v
    };
    let (w, h) = (camera.width as usize, camera.height as usize);
    let rows: Vec<Vec<[f32; 3]>> = (0..h)
        .into_par_iter()
        .map(|y| {
            (0..w)
                .map(|x| {
                    let mut acc = [0.0f64; 3];
                    for sy in 0..ss {
                        for sx in 0..ss {
                            let u = x as f64 - 0.5 + (sx as f64 + 0.5) / ss as f64;
                            let v = y as f64 - 0.5 + (sy as f64 + 0.5) / ss as f64;
                            let (o, d) = camera.pixel_ray(u, v);
                            let mut best: Option<(f64, &SphereView, DVec3)> = None;
                            for view in &views {
                                if let Some(p) = view.intersect(o, d) {
                                    let t = (p - o).length();
                                    if best.is_none_or(|b| t < b.0) {
                                        best = Some((t, view, p));
                                    }
                                }
                            }
                            let panel_hit = panel.and_then(|p| p.hit(camera, o, d));
                            if let Some((t, v)) = panel_hit {
                                if best.is_none_or(|b| t < b.0) {
                                    for a in acc.iter_mut() {
                                        *a += v as f64;
                                    }
                                    continue;
                                }
                            }
                            let val: [f64; 3] = match best {
                                None => env(d).map(|c| c as f64),
                                Some((_, view, p)) => {
                                    let n = (p - view.center) / view.radius;
                                    let cos_i = n.dot(-d).max(0.0);
                                    match view.kind {
                                        SphereKind::Mirror | SphereKind::Black => {
                                            let r = if view.kind == SphereKind::Mirror {
                                                board.mirror_reflectance(cos_i)
                                            } else {
                                                board.black_reflectance(cos_i)
                                            };
                                            let l = env(reflect(d, n));
                                            [
                                                r[0] * l[0] as f64,
                                                r[1] * l[1] as f64,
                                                r[2] * l[2] as f64,
                                            ]
                                        }
                                        SphereKind::Diffuse => {
                                            let e = integ
                                                .as_ref()
                                                .map(|i| i.irradiance(n.as_vec3()))
                                                .unwrap_or([0.0; 3]);
                                            let mut e = e.map(|v| v as f64);
                                            if let Some(s) = sun {
                                                let k = crate::envmap::disk_cosine_solid_angle(
                                                    s.diameter_deg,
                                                ) * n.dot(s.direction).max(0.0);
                                                for c in 0..3 {
                                                    e[c] += k * s.radiance[c] as f64;
                                                }
                                            }
                                            let rho = board.diffuse_reflectance;
                                            [0, 1, 2].map(|c| rho[c] * e[c] / std::f64::consts::PI)
                                        }
                                    }
                                }
                            };
                            for c in 0..3 {
                                acc[c] += val[c];
                            }
                        }
                    }
                    acc.map(|v| (v / (ss * ss) as f64) as f32)
                })
                .collect()
        })
        .collect();
    let mut img = HdrImage::new(w, h);
    for (y, row) in rows.into_iter().enumerate() {
        for (x, p) in row.into_iter().enumerate() {
            img.set(x, y, p);
        }
    }
    img
}

/// Unit vector from elevation and azimuth in degrees (azimuth from +X toward +Y, Z up).
pub fn direction_from_angles(elevation_deg: f64, azimuth_deg: f64) -> DVec3 {
    let (e, a) = (elevation_deg.to_radians(), azimuth_deg.to_radians());
    DVec3::new(e.cos() * a.cos(), e.cos() * a.sin(), e.sin())
}

/// A lens's blur for [`render_board`] output: separable Gaussian of standard deviation `sigma`
/// pixels (truncated at 4 sigma, renormalised at the image border), like Mitsuba's default
/// reconstruction filter (sigma 0.5 px). Sub-pixel suns spread over a few pixels, so their
/// centroids carry sub-pixel information, as in a real photograph.
pub fn gaussian_blur(img: &HdrImage, sigma: f64) -> HdrImage {
    if sigma <= 0.0 {
        return img.clone();
    }
    let r = (4.0 * sigma).ceil() as i64;
    let k: Vec<f64> = (-r..=r)
        .map(|d| (-(d * d) as f64 / (2.0 * sigma * sigma)).exp())
        .collect();
    let (w, h) = (img.width as i64, img.height as i64);
    let pass = |src: &HdrImage, dx: i64, dy: i64| -> HdrImage {
        let rows: Vec<Vec<[f32; 3]>> = (0..h)
            .into_par_iter()
            .map(|y| {
                (0..w)
                    .map(|x| {
                        let (mut acc, mut ws) = ([0.0f64; 3], 0.0);
                        for (i, kv) in k.iter().enumerate() {
                            let o = i as i64 - r;
                            let (sx, sy) = (x + o * dx, y + o * dy);
                            if sx < 0 || sy < 0 || sx >= w || sy >= h {
                                continue;
                            }
                            let p = src.get(sx as usize, sy as usize);
                            for c in 0..3 {
                                acc[c] += kv * p[c] as f64;
                            }
                            ws += kv;
                        }
                        acc.map(|v| (v / ws) as f32)
                    })
                    .collect()
            })
            .collect();
        let mut out = HdrImage::new(w as usize, h as usize);
        for (y, row) in rows.into_iter().enumerate() {
            for (x, p) in row.into_iter().enumerate() {
                out.set(x, y, p);
            }
        }
        out
    };
    pass(&pass(img, 1, 0), 0, 1)
}
