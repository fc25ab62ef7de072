//! A small reference renderer of board photographs from a known lat-long sky (and sun), for
//! round-trip tests and benchmarks. Independent of the unwarping code: it traces camera rays
//! forward (pixel -> sphere -> reflected direction), with `ss` x `ss` supersampling.

use crate::board::Board;
use crate::envmap::{latlong_lookup, Integrator};
use crate::sphere::{reflect, SphereView};
use crate::board::SphereKind;
use glam::DVec3;
use igi_imaging::{Camera, HdrImage};
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
pub fn render_board(camera: &Camera, board: &Board, sky: &HdrImage, sun: Option<SynthSun>, ss: usize) -> HdrImage {
    let ss = ss.max(1);
    let views: Vec<SphereView> = std::iter::once(SphereView::new(camera, SphereKind::Mirror, &board.mirror))
        .chain(board.black.iter().map(|b| SphereView::new(camera, SphereKind::Black, b)))
        .chain(board.diffuse.iter().map(|b| SphereView::new(camera, SphereKind::Diffuse, b)))
        .collect();
    let integ = if board.diffuse.is_some() { Some(Integrator::new(sky)) } else { None };
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
                                            [r[0] * l[0] as f64, r[1] * l[1] as f64, r[2] * l[2] as f64]
                                        }
                                        SphereKind::Diffuse => {
                                            let e = integ.as_ref().map(|i| i.irradiance(n.as_vec3())).unwrap_or([0.0; 3]);
                                            let mut e = e.map(|v| v as f64);
                                            if let Some(s) = sun {
                                                let k = crate::envmap::disk_cosine_solid_angle(s.diameter_deg) * n.dot(s.direction).max(0.0);
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

