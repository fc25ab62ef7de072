//! Lat-long (equirectangular) mapping of FORMATS.md, world Z up.
//!
//! Polar angle theta from +Z, azimuth phi from +X toward +Y; `u = phi / 2pi` in [0, 1),
//! `v = theta / pi` in [0, 1]. In a W x H image the direction lands at pixel
//! `x = u W - 0.5`, `y = v H - 0.5` (pixel centres at integers, row 0 next to the zenith).

use glam::Vec3;
use std::f32::consts::PI;

/// Texture coordinates (u, v) of a direction (need not be normalised; zero maps to (0, 0)).
pub fn direction_to_uv(d: Vec3) -> (f32, f32) {
    let len = d.length();
    if !(len > 0.0) || !len.is_finite() {
        return (0.0, 0.0);
    }
    let z = (d.z / len).clamp(-1.0, 1.0);
    let theta = z.acos();
    let mut phi = d.y.atan2(d.x);
    if phi < 0.0 {
        phi += 2.0 * PI;
    }
    let mut u = phi / (2.0 * PI);
    if u >= 1.0 {
        u = 0.0;
    }
    (u, (theta / PI).clamp(0.0, 1.0))
}

/// Unit direction of texture coordinates (u, v).
pub fn uv_to_direction(u: f32, v: f32) -> Vec3 {
    let phi = 2.0 * PI * u;
    let theta = PI * v;
    let (st, ct) = theta.sin_cos();
    let (sp, cp) = phi.sin_cos();
    Vec3::new(st * cp, st * sp, ct)
}

/// Direction of the centre of the pixel in row `i_row`, column `j_col` of a `w` x `h` map.
pub fn pixel_center_direction(i_row: usize, j_col: usize, w: usize, h: usize) -> Vec3 {
    uv_to_direction(
        (j_col as f32 + 0.5) / w as f32,
        (i_row as f32 + 0.5) / h as f32,
    )
}

/// Continuous pixel coordinates (x, y) of a direction in a `w` x `h` map.
pub fn direction_to_pixel(d: Vec3, w: usize, h: usize) -> (f32, f32) {
    let (u, v) = direction_to_uv(d);
    (u * w as f32 - 0.5, v * h as f32 - 0.5)
}

/// Solid angle of the pixel in row `i_row` of a `w` x `h` map (exact for the row's band).
pub fn pixel_solid_angle(i_row: usize, w: usize, h: usize) -> f32 {
    let t0 = PI * i_row as f32 / h as f32;
    let t1 = PI * (i_row + 1) as f32 / h as f32;
    (2.0 * PI / w as f32) * (t0.cos() - t1.cos())
}

/// A `w x h` lat-long map whose every pixel is `f` of its centre direction (an analytic sky).
pub fn map_from_fn(w: usize, h: usize, f: impl Fn(Vec3) -> [f32; 3]) -> crate::HdrImage {
    let mut m = crate::HdrImage::new(w, h);
    for i in 0..h {
        for j in 0..w {
            m.set(j, i, f(pixel_center_direction(i, j, w, h)));
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axes_map_as_documented() {
        let (u, v) = direction_to_uv(Vec3::Z);
        assert!(v.abs() < 1e-6 && u == 0.0);
        let (u, v) = direction_to_uv(Vec3::X);
        assert!(u.abs() < 1e-6 && (v - 0.5).abs() < 1e-6);
        let (u, v) = direction_to_uv(Vec3::Y);
        assert!((u - 0.25).abs() < 1e-6 && (v - 0.5).abs() < 1e-6);
        let (u, _) = direction_to_uv(-Vec3::Y);
        assert!((u - 0.75).abs() < 1e-6);
        let (_, v) = direction_to_uv(-Vec3::Z);
        assert!((v - 1.0).abs() < 1e-6);
        // FORMATS.md: pixel row i, column j centre direction
        let d = pixel_center_direction(0, 0, 8, 4);
        let th = PI * 0.5 / 4.0;
        let ph = 2.0 * PI * 0.5 / 8.0;
        assert!(
            (d - Vec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos())).length() < 1e-6
        );
    }

    #[test]
    fn round_trip_and_pixel_coords() {
        for i in 0..16 {
            for j in 0..32 {
                let d = pixel_center_direction(i, j, 32, 16);
                assert!((d.length() - 1.0).abs() < 1e-5);
                let (x, y) = direction_to_pixel(d, 32, 16);
                assert!(
                    (x - j as f32).abs() < 1e-3 && (y - i as f32).abs() < 1e-3,
                    "{i} {j} {x} {y}"
                );
            }
        }
        let total: f32 = (0..16).map(|i| 32.0 * pixel_solid_angle(i, 32, 16)).sum();
        assert!((total - 4.0 * PI).abs() < 1e-4);
    }
}
