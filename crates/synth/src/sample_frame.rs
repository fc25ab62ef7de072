//! A synthetic photograph of the hand-held sample frame with known pose, light and BRDFs: the
//! ground truth of the tests of [`igi_capture::sample_frame`] and of `igi brdf measure`.
//!
//! Each pixel's camera ray (through the distorted lens) is cast against the frame plane z = 0
//! and the two black spheres. A point light of intensity `intensity` at `light` lights the
//! plane (`f I cos(theta_l) / d^2`, no shadows): the sample aperture (`frame.ortho`) has the
//! Lafortune BRDF of the nearest region's material, the white standard is Lambertian
//! `white_rho`, the fiducials are black squares with a white centre (or any pattern), the rest
//! of the board grey. The spheres are a dark Lambertian base plus a mirror coat of reflectance
//! `coat` that reflects the light, a sphere of radius `light_radius` and radiance
//! `light_radiance`. Sphere pixels are supersampled 8x8; pixels within 3 px of a highlight are
//! integrated finely through a Gaussian point spread of 0.8 px (as a lens spreads a small
//! highlight over a few pixels); then optional clipping (saturation).
use glam::{DVec2, DVec3, Vec3};
use igi_brdf::{Lafortune, Lobe};
use igi_camera::{Camera, Distortion, WorldToCamera};
use igi_capture::sample_frame::SampleFrame;
use igi_capture::sphere::ray_sphere;
use igi_imaging::HdrImage;
use std::path::Path;

pub const FRAME_JSON: &str = r#"{
  "fiducials": [
    { "center": [-0.14, -0.10], "aruco_id": 0, "size": 0.03 },
    { "center": [ 0.14, -0.10], "aruco_id": 1, "size": 0.03 },
    { "center": [ 0.14,  0.10], "aruco_id": 2, "size": 0.03 },
    { "center": [-0.14,  0.10], "aruco_id": 3, "size": 0.03 }
  ],
  "aruco_dictionary": "4x4_50",
  "spheres": [
    { "center": [-0.07, 0.125, 0.025], "radius": 0.025 },
    { "center": [ 0.07, 0.125, 0.025], "radius": 0.025 }
  ],
  "white": { "min": [0.05, -0.05], "max": [0.11, 0.05], "reflectance": 0.99 },
  "ortho": { "min": [-0.11, -0.07], "max": [0.03, 0.07], "px_per_m": 2000 },
  "regions": [
    { "material": "stone", "center": [-0.07,  0.035] },
    { "material": "stone", "center": [-0.07, -0.035] },
    { "material": "tile",  "center": [-0.01,  0.035] },
    { "material": "tile",  "center": [-0.01, -0.035], "size_px": 30 }
  ]
}"#;

pub fn frame() -> SampleFrame {
    SampleFrame::from_json_str(FRAME_JSON, Path::new("frame.json")).expect("test frame parses")
}

/// The test stone: a warm diffuse base and a broad off-specular lobe, plus `specular` (the
/// frame's stone, the fit tests' material and the BRDF bench's differ only there).
pub fn stone(specular: Lobe) -> Lafortune {
    Lafortune {
        rho_d: Vec3::new(0.35, 0.3, 0.22),
        lobes: vec![
            Lobe {
                rho: Vec3::new(0.1, 0.09, 0.07),
                cxy: 0.7,
                cz: 1.0,
                n: 5.0,
            },
            specular,
        ],
    }
}

/// A specular (mirror-direction) lobe `rho max(0, -ux vx - uy vy + uz vz)^n`.
pub fn specular_lobe(rho: Vec3, n: f32) -> Lobe {
    Lobe {
        rho,
        cxy: -1.0,
        cz: 1.0,
        n,
    }
}

pub fn materials() -> Vec<(String, Lafortune)> {
    vec![
        (
            "stone".into(),
            stone(specular_lobe(Vec3::new(0.5, 0.5, 0.52), 12.0)),
        ),
        (
            "tile".into(),
            Lafortune {
                rho_d: Vec3::new(0.12, 0.16, 0.22),
                lobes: vec![Lobe {
                    rho: Vec3::new(0.9, 0.9, 0.9),
                    cxy: -1.0,
                    cz: 1.0,
                    n: 25.0,
                }],
            },
        ),
    ]
}

pub struct Synth {
    pub frame: SampleFrame,
    pub materials: Vec<(String, Lafortune)>,
    pub white_rho: f64,
    pub light: DVec3,
    pub light_radius: f64,
    pub intensity: DVec3,
    pub light_radiance: f64,
    pub coat: f64,
    /// Pixels with a channel above this are marked invalid (a sensor's saturation).
    pub saturate_above: Option<f32>,
    /// Albedo of fiducial `i` at local coordinates in [-0.5, 0.5]^2 (x right, y up).
    pub marker: Box<dyn Fn(usize, DVec2) -> f64 + Sync>,
}

/// The nearest hit in front of the ray's origin ([`ray_sphere`]'s near root, when positive).
fn hit_sphere(o: DVec3, d: DVec3, c: DVec3, r: f64) -> Option<f64> {
    ray_sphere(o, d, c, r)
        .map(|(near, _)| near)
        .filter(|s| *s > 0.0)
}

impl Synth {
    pub fn new(light: DVec3) -> Synth {
        Synth {
            frame: frame(),
            materials: materials(),
            white_rho: 0.99,
            light,
            light_radius: 0.015,
            intensity: DVec3::new(1.0, 0.9, 0.8),
            light_radiance: 100.0,
            coat: 0.05,
            saturate_above: None,
            marker: Box::new(|_, p| {
                if p.x.abs() < 0.25 && p.y.abs() < 0.25 {
                    0.8
                } else {
                    0.03
                }
            }),
        }
    }

    /// The material of a point of the sample aperture: the nearest region's.
    fn material_at(&self, p: DVec2) -> &Lafortune {
        let r = self
            .frame
            .regions
            .iter()
            .min_by(|a, b| {
                let da = (DVec2::from_array(a.center) - p).length();
                let db = (DVec2::from_array(b.center) - p).length();
                da.total_cmp(&db)
            })
            .unwrap();
        &self
            .materials
            .iter()
            .find(|(n, _)| *n == r.material)
            .unwrap()
            .1
    }

    /// Radiance along the ray `o + s d` (unit `d`).
    pub fn radiance(&self, o: DVec3, d: DVec3) -> DVec3 {
        let mut best: Option<(f64, usize)> = None;
        for (k, s) in self.frame.spheres.iter().enumerate() {
            if let Some(t) = hit_sphere(o, d, DVec3::from_array(s.center), s.radius) {
                if best.is_none_or(|b| t < b.0) {
                    best = Some((t, k));
                }
            }
        }
        let tp = if d.z < 0.0 { -o.z / d.z } else { f64::INFINITY };
        if let Some((t, k)) = best.filter(|b| b.0 < tp) {
            let s = &self.frame.spheres[k];
            let p = o + d * t;
            let n = (p - DVec3::from_array(s.center)) / s.radius;
            let tl = self.light - p;
            let dl2 = tl.length_squared();
            let cos = (n.dot(tl) / dl2.sqrt()).max(0.0);
            let mut l = self.intensity * (0.01 / std::f64::consts::PI * cos / dl2);
            let r = d - 2.0 * d.dot(n) * n;
            if hit_sphere(p, r, self.light, self.light_radius).is_some() {
                l += DVec3::splat(self.coat * self.light_radiance);
            }
            return l;
        }
        if !tp.is_finite() {
            return DVec3::ZERO;
        }
        let p = o + d * tp;
        let (x, y) = (p.x, p.y);
        let tl = self.light - p;
        let dl2 = tl.length_squared();
        let lu = tl / dl2.sqrt();
        if lu.z <= 0.0 {
            return DVec3::ZERO;
        }
        let e = self.intensity * (lu.z / dl2);
        let f = &self.frame;
        let inside =
            |mn: [f64; 2], mx: [f64; 2]| x >= mn[0] && x <= mx[0] && y >= mn[1] && y <= mx[1];
        if inside(f.ortho.min, f.ortho.max) {
            let m = self.material_at(DVec2::new(x, y));
            let v = -d;
            let fr = m.as_ref().eval(lu.as_vec3(), v.as_vec3()).as_dvec3();
            return fr * e;
        }
        if inside(f.white.min, f.white.max) {
            return e * (self.white_rho / std::f64::consts::PI);
        }
        for (i, fd) in f.fiducials.iter().enumerate() {
            let s = fd.size.unwrap_or(0.03);
            let q = (DVec2::new(x, y) - DVec2::from_array(fd.center)) / s;
            if q.x.abs() <= 0.5 && q.y.abs() <= 0.5 {
                return e * ((self.marker)(i, q) / std::f64::consts::PI);
            }
        }
        if x.abs() < 0.17 && y.abs() < 0.17 {
            e * (0.25 / std::f64::consts::PI)
        } else {
            DVec3::splat(0.02)
        }
    }

    fn supersample(&self, cam: &Camera, x: usize, y: usize, n: usize) -> DVec3 {
        let mut acc = DVec3::ZERO;
        for j in 0..n {
            for i in 0..n {
                let u = x as f64 - 0.5 + (i as f64 + 0.5) / n as f64;
                let v = y as f64 - 0.5 + (j as f64 + 0.5) / n as f64;
                let (o, d) = cam.pixel_ray(u, v);
                acc += self.radiance(o, d);
            }
        }
        acc / (n * n) as f64
    }

    /// Render the photograph seen by `cam`.
    pub fn render(&self, cam: &Camera) -> HdrImage {
        let (w, h) = (cam.width as usize, cam.height as usize);
        let mut img = HdrImage::new(w, h);
        let spheres: Vec<(DVec3, f64)> = self
            .frame
            .spheres
            .iter()
            .map(|s| (DVec3::from_array(s.center), s.radius))
            .collect();
        const SS: usize = 8;
        let mut hot = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let (o, d) = cam.pixel_ray(x as f64, y as f64);
                let near = spheres.iter().any(|&(c, r)| {
                    let tca = (c - o).dot(d);
                    tca > 0.0 && ((c - o).length_squared() - tca * tca).sqrt() < 1.15 * r
                });
                let v = if near {
                    let v = self.supersample(cam, x, y, SS);
                    if v.max_element() > 0.5 * self.coat * self.light_radiance / (SS * SS) as f64
                        && self.coat > 0.0
                    {
                        hot.push((x, y));
                    }
                    v
                } else {
                    self.radiance(o, d)
                };
                let i = img.index(x, y);
                img.pixels[i] = [v.x as f32, v.y as f32, v.z as f32];
            }
        }
        // pixels around the highlights again, through the lens's point spread (a Gaussian of
        // 0.8 px applied before the pixels integrate: a real highlight spreads over a few pixels,
        // which is what makes its centroid sub-pixel accurate), finely sampled
        let mut redo = std::collections::BTreeSet::new();
        for &(x, y) in &hot {
            for dy in -3i64..=3 {
                for dx in -3i64..=3 {
                    let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                    if nx >= 0 && ny >= 0 && (nx as usize) < w && (ny as usize) < h {
                        redo.insert((nx as usize, ny as usize));
                    }
                }
            }
        }
        for (x, y) in redo {
            let v = self.psf_sample(cam, x, y, 0.8);
            let i = img.index(x, y);
            img.pixels[i] = [v.x as f32, v.y as f32, v.z as f32];
        }
        if let Some(s) = self.saturate_above {
            for (p, v) in img.pixels.iter_mut().zip(img.valid.iter_mut()) {
                if p.iter().any(|c| *c > s) {
                    *p = [s; 3];
                    *v = false;
                }
            }
        }
        img
    }

    /// Pixel (x, y) integrated over its box convolved with a Gaussian of `sigma` px.
    fn psf_sample(&self, cam: &Camera, x: usize, y: usize, sigma: f64) -> DVec3 {
        let half = 0.5 + 2.5 * sigma;
        let n = (2.0 * half * 12.0).ceil() as usize;
        let h = 2.0 * half / n as f64;
        // weight of an offset t from the pixel centre: P(|t + noise| <= 0.5), per axis
        let wt = |t: f64| phi((0.5 - t) / sigma) - phi((-0.5 - t) / sigma);
        let (mut acc, mut sw) = (DVec3::ZERO, 0.0);
        for j in 0..n {
            let ty = -half + (j as f64 + 0.5) * h;
            let wy = wt(ty);
            for i in 0..n {
                let tx = -half + (i as f64 + 0.5) * h;
                let wgt = wt(tx) * wy;
                let (o, d) = cam.pixel_ray(x as f64 + tx, y as f64 + ty);
                acc += self.radiance(o, d) * wgt;
                sw += wgt;
            }
        }
        acc / sw
    }
}

/// Standard normal CDF (Abramowitz & Stegun 7.1.26, error < 1.5e-7).
fn phi(x: f64) -> f64 {
    let z = x.abs() / std::f64::consts::SQRT_2;
    let t = 1.0 / (1.0 + 0.3275911 * z);
    let erf = 1.0
        - t * (0.254829592
            + t * (-0.284496736 + t * (1.421413741 + t * (-1.453152027 + t * 1.061405429))))
            * (-z * z).exp();
    if x >= 0.0 {
        0.5 * (1.0 + erf)
    } else {
        0.5 * (1.0 - erf)
    }
}

/// The test camera (1024 x 768, f = 1000 px, some barrel distortion) at `eye`, looking at the
/// frame's origin with the frame's +y up in the image.
pub fn camera(eye: DVec3) -> Camera {
    let mut c = Camera::pinhole(1024, 768, 1000.0, 1002.0, 515.0, 380.0);
    c.intrinsics.dist = Distortion {
        k1: -0.08,
        k2: 0.02,
        p1: 0.0005,
        p2: -0.0003,
        k3: 0.0,
    };
    c.pose = WorldToCamera::look_at(eye, DVec3::new(-0.02, 0.02, 0.0), DVec3::Y)
        .expect("view not along +y");
    c
}

/// A direction at polar angle `theta_deg` from +z and azimuth `phi_deg` from +x.
pub fn dir(theta_deg: f64, phi_deg: f64) -> DVec3 {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
}

/// True pixels of the fiducials' centres.
pub fn true_corners(cam: &Camera, frame: &SampleFrame) -> Vec<DVec2> {
    frame
        .fiducials
        .iter()
        .map(|f| {
            cam.project(DVec3::new(f.center[0], f.center[1], 0.0))
                .unwrap()
        })
        .collect()
}
