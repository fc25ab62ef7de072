//! A sphere as seen by a calibrated camera: ray hits, the mirror reflection, the point that
//! reflects a given direction (Newton's method, exact for a camera at finite distance), the
//! image outline and the pixels the sphere covers. Shared by the lighting board's three spheres
//! (igi-probe) and the sample frame's two black spheres ([`crate::sample_frame`]).

use crate::SphereError;
use glam::{DVec2, DVec3};
use igi_camera::Camera;

/// What a sphere is made of (the board file's vocabulary, `igi_formats::board`).
pub use igi_formats::board::SphereKind;

/// Position of one sphere of a photographed rig in the camera frame of the photograph (OpenCV
/// convention).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoardSphere {
    pub center_cam: DVec3,
    pub radius: f64,
}

/// The two ray parameters `s_near <= s_far` where the ray `o + s d` (unit `d`) meets the sphere
/// of centre `c` and radius `r`; `None` where it misses.
pub fn ray_sphere(o: DVec3, d: DVec3, c: DVec3, r: f64) -> Option<(f64, f64)> {
    let oc = o - c;
    let b = oc.dot(d);
    let disc = b * b - (oc.length_squared() - r * r);
    if disc < 0.0 {
        return None;
    }
    let sq = disc.sqrt();
    Some((-b - sq, -b + sq))
}

/// A pixel of a sphere's image with its geometry ([`SphereView::pixels`]).
#[derive(Clone, Copy, Debug)]
pub struct SpherePixel {
    pub x: usize,
    pub y: usize,
    /// Unit surface normal where the pixel's ray hits.
    pub normal: DVec3,
    /// Cosine of the incidence angle of that ray.
    pub cos_i: f64,
}

/// A sphere in world coordinates together with the camera that photographs it.
#[derive(Clone, Debug)]
pub struct SphereView<'a> {
    pub camera: &'a Camera,
    pub kind: SphereKind,
    /// Centre in world coordinates.
    pub center: DVec3,
    pub radius: f64,
    /// Camera centre in world coordinates.
    pub eye: DVec3,
}

/// Where a reflected direction comes from on the sphere.
#[derive(Clone, Copy, Debug)]
pub struct ReflectionPoint {
    pub point: DVec3,
    pub normal: DVec3,
    /// Cosine of the incidence angle (normal . direction to the eye).
    pub cos_i: f64,
    /// Pixel coordinates of the point.
    pub pixel: DVec2,
}

impl<'a> SphereView<'a> {
    /// `s` is given in the camera frame (as in the board file).
    pub fn new(camera: &'a Camera, kind: SphereKind, s: &BoardSphere) -> Self {
        Self::in_world(
            camera,
            kind,
            camera.pose.inverse().apply(s.center_cam),
            s.radius,
        )
    }

    /// A sphere whose centre is given in world coordinates.
    pub fn in_world(camera: &'a Camera, kind: SphereKind, center: DVec3, radius: f64) -> Self {
        SphereView {
            camera,
            kind,
            center,
            radius,
            eye: camera.center_world(),
        }
    }

    /// Unit vector from the sphere's centre toward the camera.
    pub fn to_eye(&self) -> DVec3 {
        (self.eye - self.center).normalize()
    }

    /// Nearest hit of the ray `o + t d` (unit `d`) with the sphere, `t > 0`.
    pub fn intersect(&self, o: DVec3, d: DVec3) -> Option<DVec3> {
        let (near, far) = ray_sphere(o, d, self.center, self.radius)?;
        let t = if near > 0.0 { near } else { far };
        (t > 0.0).then(|| o + t * d)
    }

    /// Surface point, normal and incidence of the camera ray through pixel (u, v), if it hits.
    pub fn hit_pixel(&self, u: f64, v: f64) -> Option<(DVec3, DVec3, DVec3)> {
        let (o, d) = self.camera.pixel_ray(u, v);
        let p = self.intersect(o, d)?;
        let n = (p - self.center) / self.radius;
        Some((p, n, d))
    }

    /// The pixels of the sphere's image (row by row) whose rays hit it with incidence cosine at
    /// least `min_cos`.
    pub fn pixels(&self, min_cos: f64) -> Vec<SpherePixel> {
        let (x0, y0, x1, y1) = self.pixel_bbox();
        let mut out = Vec::new();
        for y in y0..=y1 {
            for x in x0..=x1 {
                if let Some((_, n, d)) = self.hit_pixel(x as f64, y as f64) {
                    let cos_i = n.dot(-d);
                    if cos_i >= min_cos {
                        out.push(SpherePixel {
                            x,
                            y,
                            normal: n,
                            cos_i,
                        });
                    }
                }
            }
        }
        out
    }

    /// The point whose mirror reflection of the camera ray leaves along unit direction `w`
    /// (exact for a camera at finite distance, not the orthographic approximation). `None` in
    /// the blind spot straight behind.
    ///
    /// The normal lies in the plane of the eye, the centre and `w`; with `e1` toward the eye and
    /// `e2` toward `w` in that plane, `n = (cos a, sin a)` must bisect `w` (at angle `psi_w`)
    /// and the direction to the eye from the surface point (at angle `psi_v(a)`): `g(a) = 2a -
    /// psi_w - psi_v(a) = 0`. `g' = 2 - psi_v' >= 1 + D/(D + r) > 1`, so `g` is monotone and
    /// Newton's method from the orthographic answer `psi_w / 2` converges in a few steps.
    pub fn reflection_point(&self, w: DVec3) -> Option<ReflectionPoint> {
        let e = self.eye - self.center;
        let dist = e.length();
        let e1 = e / dist;
        let w = w.normalize();
        let wa = w.dot(e1);
        let wp = w - wa * e1;
        let wb = wp.length();
        let r = self.radius;
        let n = if wb < 1e-12 {
            if wa <= 0.0 {
                return None;
            }
            e1
        } else {
            let e2 = wp / wb;
            let psi_w = wb.atan2(wa);
            let psi_v = |a: f64| (-r * a.sin()).atan2(dist - r * a.cos());
            let mut a = 0.5 * psi_w;
            for _ in 0..30 {
                let c = a.cos();
                let g = 2.0 * a - psi_w - psi_v(a);
                let dpsi = r * (r - dist * c) / (dist * dist - 2.0 * r * dist * c + r * r);
                let step = g / (2.0 - dpsi);
                a -= step;
                if step.abs() < 1e-14 {
                    break;
                }
            }
            let (s, c) = a.sin_cos();
            c * e1 + s * e2
        };
        let point = self.center + self.radius * n;
        let v = (self.eye - point).normalize();
        let cos_i = n.dot(v);
        if cos_i <= 0.0 || cos_i.is_nan() {
            return None;
        }
        let pixel = self.camera.project(point)?;
        Some(ReflectionPoint {
            point,
            normal: n,
            cos_i,
            pixel,
        })
    }

    /// Apparent radius in pixels (mean focal length times the angular radius).
    pub fn pixel_radius(&self) -> f64 {
        let d = self.center.distance(self.eye);
        let f = (self.camera.intrinsics.fx * self.camera.intrinsics.fy).sqrt();
        f * (self.radius / d).asin().tan()
    }

    /// Points of the sphere's outline (the contour circle seen from the eye) in pixels.
    pub fn outline(&self, n: usize) -> Vec<DVec2> {
        let axis = self.center - self.eye;
        let d = axis.length();
        let a = axis / d;
        let rc = self.radius * (d * d - self.radius * self.radius).sqrt() / d;
        let cc = self.center - a * (self.radius * self.radius / d);
        let e1 = a.any_orthonormal_vector();
        let e2 = a.cross(e1);
        (0..n)
            .filter_map(|i| {
                let t = i as f64 / n as f64 * std::f64::consts::TAU;
                self.camera.project(cc + rc * (t.cos() * e1 + t.sin() * e2))
            })
            .collect()
    }

    /// Pixel bounding box (x0, y0, x1, y1) of the outline, clamped to the image (inclusive).
    pub fn pixel_bbox(&self) -> (usize, usize, usize, usize) {
        let pts = self.outline(128);
        let (w, h) = (self.camera.width as f64, self.camera.height as f64);
        let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
        for p in pts {
            x0 = x0.min(p.x);
            y0 = y0.min(p.y);
            x1 = x1.max(p.x);
            y1 = y1.max(p.y);
        }
        let cl = |v: f64, m: f64| v.clamp(0.0, m - 1.0) as usize;
        (
            cl(x0.floor() - 1.0, w),
            cl(y0.floor() - 1.0, h),
            cl(x1.ceil() + 1.0, w),
            cl(y1.ceil() + 1.0, h),
        )
    }

    /// Error if the sphere does not lie fully inside the image; its apparent radius otherwise.
    pub fn check_in_image(&self) -> Result<f64, SphereError> {
        let kind = self.kind.name().to_string();
        if self.center.distance(self.eye) <= self.radius * 1.0001 {
            return Err(SphereError::BadSphere {
                kind,
                center: self.center.to_array(),
                radius: self.radius,
            });
        }
        let pts = self.outline(256);
        if pts.len() < 256 {
            return Err(SphereError::BadSphere {
                kind,
                center: self.center.to_array(),
                radius: self.radius,
            });
        }
        let (w, h) = (self.camera.width, self.camera.height);
        for p in pts {
            if !(p.x >= -0.5 && p.y >= -0.5 && p.x <= w as f64 - 0.5 && p.y <= h as f64 - 0.5) {
                return Err(SphereError::OutsideImage {
                    kind,
                    width: w,
                    height: h,
                    x: p.x,
                    y: p.y,
                });
            }
        }
        Ok(self.pixel_radius())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DMat3;
    use igi_camera::WorldToCamera;

    fn camera() -> Camera {
        let mut c = Camera::pinhole(256, 256, 400.0, 400.0, 127.5, 127.5);
        // camera x right = world -Y, y down = world -Z, z forward = world +X, centre at (1, 2, 3)
        let r = DMat3::from_cols_array_2d(&[[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
            .transpose();
        let eye = DVec3::new(1.0, 2.0, 3.0);
        c.pose = WorldToCamera { r, t: -(r * eye) };
        c
    }

    #[test]
    fn ray_sphere_roots_are_the_entry_and_exit() {
        let c = DVec3::new(0.0, 0.0, 5.0);
        let (near, far) = ray_sphere(DVec3::ZERO, DVec3::Z, c, 1.0).unwrap();
        assert!((near - 4.0).abs() < 1e-12 && (far - 6.0).abs() < 1e-12);
        // from inside: the entry is behind the origin
        let (near, far) = ray_sphere(c, DVec3::X, c, 1.0).unwrap();
        assert!((near + 1.0).abs() < 1e-12 && (far - 1.0).abs() < 1e-12);
        // a ray passing 1.5 radii from the centre misses
        assert!(ray_sphere(DVec3::new(1.5, 0.0, 0.0), DVec3::Z, c, 1.0).is_none());
        // a grazing ray touches once
        let (near, far) = ray_sphere(DVec3::new(1.0, 0.0, 0.0), DVec3::Z, c, 1.0).unwrap();
        assert!((near - 5.0).abs() < 1e-12 && (far - 5.0).abs() < 1e-12);
    }

    #[test]
    fn reflection_point_inverts_ray_tracing() {
        let cam = camera();
        let s = BoardSphere {
            center_cam: DVec3::new(-0.1, 0.05, 0.6),
            radius: 0.07,
        };
        let view = SphereView::new(&cam, SphereKind::Mirror, &s);
        // world centre = eye + R^T c_cam
        let want = DVec3::new(1.0 + 0.6, 2.0 + 0.1, 3.0 - 0.05);
        assert!(view.center.distance(want) < 1e-12);
        let mut checked = 0;
        for y in (60..200).step_by(7) {
            for x in (0..130).step_by(7) {
                let Some((_, n, d)) = view.hit_pixel(x as f64, y as f64) else {
                    continue;
                };
                if n.dot(-d) < 0.2 {
                    continue;
                }
                let w = d.reflect(n);
                let rp = view.reflection_point(w).expect("visible direction");
                assert!(
                    rp.pixel.distance(DVec2::new(x as f64, y as f64)) < 1e-6,
                    "{x} {y} -> {:?}",
                    rp.pixel
                );
                assert!((rp.cos_i - n.dot(-d)).abs() < 1e-9);
                checked += 1;
            }
        }
        assert!(checked > 50);
        // the direction straight behind the sphere is blind
        assert!(view.reflection_point(-view.to_eye()).is_none());
    }

    #[test]
    fn outline_and_image_checks() {
        let cam = camera();
        let s = BoardSphere {
            center_cam: DVec3::new(0.0, 0.0, 0.6),
            radius: 0.07,
        };
        let v = SphereView::new(&cam, SphereKind::Diffuse, &s);
        let r = v.check_in_image().unwrap();
        // on axis: f tan(asin(r/d))
        assert!((r - 400.0 * (0.07f64 / 0.6).asin().tan()).abs() < 1e-9);
        for p in v.outline(64) {
            assert!((p.distance(DVec2::new(127.5, 127.5)) - r).abs() < 1e-6);
        }
        let off = BoardSphere {
            center_cam: DVec3::new(0.35, 0.0, 0.6),
            radius: 0.07,
        };
        let e = SphereView::new(&cam, SphereKind::Black, &off)
            .check_in_image()
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("black sphere is partly outside the 256x256 image"),
            "{e}"
        );
    }
}
