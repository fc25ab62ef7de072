//! Direction maps: lookups in FORMATS.md lat-long maps (wrapping in azimuth), the 512x512
//! upper-hemisphere layout, hole filling, downsampling and the diffuse convolution
//! (irradiance) of a lat-long map by direct integration.

use glam::Vec3;
use igi_imaging::latlong::{direction_to_pixel, pixel_center_direction, pixel_solid_angle};
use igi_imaging::HdrImage;
use rayon::prelude::*;

/// Bilinear lookup in a lat-long map in direction `d` (FORMATS.md pixel centres; wraps in
/// azimuth, clamps at the poles). `None` if a tap with non-zero weight is invalid.
pub fn latlong_lookup(map: &HdrImage, d: Vec3) -> Option<[f32; 3]> {
    let (w, h) = (map.width, map.height);
    let (x, y) = direction_to_pixel(d, w, h);
    let y = y.clamp(0.0, (h - 1) as f32);
    let (x0f, y0f) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0f, y - y0f);
    let x0 = (x0f as i64).rem_euclid(w as i64) as usize;
    let x1 = (x0 + 1) % w;
    let y0 = y0f as usize;
    let y1 = (y0 + 1).min(h - 1);
    let mut out = [0.0f32; 3];
    for (xx, yy, wt) in [
        (x0, y0, (1.0 - fx) * (1.0 - fy)),
        (x1, y0, fx * (1.0 - fy)),
        (x0, y1, (1.0 - fx) * fy),
        (x1, y1, fx * fy),
    ] {
        if wt <= 0.0 {
            continue;
        }
        let i = yy * w + xx;
        if !map.valid[i] {
            return None;
        }
        for c in 0..3 {
            out[c] += wt * map.pixels[i][c];
        }
    }
    Some(out)
}

/// Direction of pixel (x, y) of a `size` x `size` upper-hemisphere map: an equal-angle
/// (polar) projection looking down from the zenith; image right is world +X, image up is
/// world +Y, the zenith at the centre and the horizon on the inscribed circle. `None` outside.
pub fn hemisphere_direction(x: usize, y: usize, size: usize) -> Option<Vec3> {
    hemisphere_direction_at(x as f32, y as f32, size)
}

/// [`hemisphere_direction`] at continuous pixel coordinates (pixel centres at integers).
pub fn hemisphere_direction_at(x: f32, y: f32, size: usize) -> Option<Vec3> {
    let a = (x + 0.5) / size as f32 * 2.0 - 1.0;
    let b = 1.0 - (y + 0.5) / size as f32 * 2.0;
    let r = (a * a + b * b).sqrt();
    if r > 1.0 {
        return None;
    }
    let theta = r * std::f32::consts::FRAC_PI_2;
    let phi = b.atan2(a);
    Some(Vec3::new(
        theta.sin() * phi.cos(),
        theta.sin() * phi.sin(),
        theta.cos(),
    ))
}

/// Continuous pixel coordinates of direction `d` (z >= 0) in the hemisphere map.
pub fn hemisphere_pixel(d: Vec3, size: usize) -> Option<(f32, f32)> {
    let d = d.normalize_or_zero();
    if d.z < 0.0 {
        return None;
    }
    let theta = d.z.clamp(-1.0, 1.0).acos();
    let r = theta / std::f32::consts::FRAC_PI_2;
    let phi = d.y.atan2(d.x);
    let (a, b) = (r * phi.cos(), r * phi.sin());
    Some((
        (a + 1.0) * 0.5 * size as f32 - 0.5,
        (1.0 - b) * 0.5 * size as f32 - 0.5,
    ))
}

/// Fill invalid pixels of a lat-long map from their valid neighbours, ring by ring (onion
/// peeling, wrapping in azimuth), then relax the filled pixels by a few Jacobi sweeps so the
/// fill is smooth. The `valid` mask is left unchanged. A map without any valid pixel is set to 0.
pub fn fill_invalid_latlong(map: &mut HdrImage) {
    let (w, h) = (map.width, map.height);
    let mut known = map.valid.clone();
    if !known.iter().any(|k| *k) {
        map.pixels.iter_mut().for_each(|p| *p = [0.0; 3]);
        return;
    }
    let holes: Vec<usize> = (0..w * h).filter(|&i| !known[i]).collect();
    let neighbours = |i: usize| {
        let (x, y) = (i % w, i / w);
        let mut n = vec![y * w + (x + 1) % w, y * w + (x + w - 1) % w];
        if y > 0 {
            n.push((y - 1) * w + x);
        }
        if y + 1 < h {
            n.push((y + 1) * w + x);
        }
        n
    };
    let mut remaining = holes.clone();
    while !remaining.is_empty() {
        let mut updates = Vec::new();
        for &i in &remaining {
            let (mut s, mut n) = ([0.0f32; 3], 0);
            for j in neighbours(i) {
                if known[j] {
                    for c in 0..3 {
                        s[c] += map.pixels[j][c];
                    }
                    n += 1;
                }
            }
            if n > 0 {
                updates.push((i, s.map(|v| v / n as f32)));
            }
        }
        if updates.is_empty() {
            break;
        }
        for (i, v) in &updates {
            map.pixels[*i] = *v;
            known[*i] = true;
        }
        remaining.retain(|&i| !known[i]);
    }
    for _ in 0..20 {
        let snapshot = map.pixels.clone();
        for &i in &holes {
            let ns = neighbours(i);
            let mut s = [0.0f32; 3];
            for &j in &ns {
                for c in 0..3 {
                    s[c] += snapshot[j][c];
                }
            }
            map.pixels[i] = s.map(|v| v / ns.len() as f32);
        }
    }
}

/// Box-downsample a lat-long map by an integer factor, weighting by pixel solid angle.
/// A coarse pixel is valid only if all its fine pixels are.
pub fn downsample_latlong(map: &HdrImage, factor: usize) -> HdrImage {
    let f = factor.max(1);
    let (w, h) = (map.width / f, map.height / f);
    let mut out = HdrImage::new(w, h);
    for y in 0..h {
        for x in 0..w {
            let (mut s, mut wsum, mut ok) = ([0.0f64; 3], 0.0f64, true);
            for yy in y * f..(y + 1) * f {
                let sa = pixel_solid_angle(yy, map.width, map.height) as f64;
                for xx in x * f..(x + 1) * f {
                    let i = yy * map.width + xx;
                    ok &= map.valid[i];
                    for c in 0..3 {
                        s[c] += sa * map.pixels[i][c] as f64;
                    }
                    wsum += sa;
                }
            }
            let i = y * w + x;
            out.pixels[i] = s.map(|v| (v / wsum) as f32);
            out.valid[i] = ok;
        }
    }
    out
}

/// Precomputed texel directions and solid angles of a lat-long map for integration, stored as
/// separate arrays (structure of arrays) so the sum over texels runs in SIMD lanes.
pub struct Integrator {
    /// Texel directions' x, y, z.
    dirs: [Vec<f32>; 3],
    /// Texel radiance times solid angle, per channel.
    weighted: [Vec<f32>; 3],
}

/// Texels summed in f32 before the block's sum joins the f64 total: 32 terms a SIMD lane, so
/// the f32 rounding stays near 1e-7 relative, as the f64 sum of f32 products before it.
const BLOCK: usize = 256;

impl Integrator {
    /// Every texel's radiance times its solid angle (the map must be fully filled).
    pub fn new(map: &HdrImage) -> Self {
        let (w, h) = (map.width, map.height);
        let mut dirs: [Vec<f32>; 3] = Default::default();
        let mut weighted: [Vec<f32>; 3] = Default::default();
        for i in 0..h {
            let sa = pixel_solid_angle(i, w, h);
            for j in 0..w {
                let p = map.pixels[i * w + j];
                if p.iter().all(|v| *v == 0.0) {
                    continue;
                }
                let d = pixel_center_direction(i, j, w, h);
                for k in 0..3 {
                    dirs[k].push(d[k]);
                    weighted[k].push(p[k] * sa);
                }
            }
        }
        Integrator { dirs, weighted }
    }

    /// Irradiance on a surface with unit normal `n`: the integral of L max(0, n . w) dw.
    pub fn irradiance(&self, n: Vec3) -> [f32; 3] {
        let mut e = [0.0f64; 3];
        let [x, y, z] = &self.dirs;
        let [r, g, b] = &self.weighted;
        for start in (0..x.len()).step_by(BLOCK) {
            let end = (start + BLOCK).min(x.len());
            let block = block_irradiance(
                n,
                [&x[start..end], &y[start..end], &z[start..end]],
                [&r[start..end], &g[start..end], &b[start..end]],
            );
            for k in 0..3 {
                e[k] += block[k] as f64;
            }
        }
        e.map(|v| v as f32)
    }

    /// Irradiance for many normals in parallel.
    pub fn irradiance_many(&self, normals: &[Vec3]) -> Vec<[f32; 3]> {
        normals.par_iter().map(|n| self.irradiance(*n)).collect()
    }
}

/// SIMD lanes of [`block_irradiance`].
const LANES: usize = 8;

/// `v` in whole groups of [`LANES`] (the remainder left out).
fn lanes(v: &[f32]) -> impl Iterator<Item = &[f32; LANES]> {
    v.chunks_exact(LANES)
        .map(|c| c.try_into().expect("chunks_exact gives LANES"))
}

/// One block's irradiance in f32: eight independent partial sums a channel (the SIMD lanes),
/// then the remainder.
fn block_irradiance(n: Vec3, dirs: [&[f32]; 3], weighted: [&[f32]; 3]) -> [f32; 3] {
    let mut acc = [[0.0f32; LANES]; 3];
    let texels = lanes(dirs[0]).zip(lanes(dirs[1])).zip(lanes(dirs[2]));
    let radiance = lanes(weighted[0])
        .zip(lanes(weighted[1]))
        .zip(lanes(weighted[2]));
    for (((x, y), z), ((r, g), b)) in texels.zip(radiance) {
        for l in 0..LANES {
            let c = (n.x * x[l] + n.y * y[l] + n.z * z[l]).max(0.0);
            acc[0][l] += c * r[l];
            acc[1][l] += c * g[l];
            acc[2][l] += c * b[l];
        }
    }
    let mut out = acc.map(|a| a.iter().sum::<f32>());
    for i in dirs[0].len() / LANES * LANES..dirs[0].len() {
        let c = (n.x * dirs[0][i] + n.y * dirs[1][i] + n.z * dirs[2][i]).max(0.0);
        for k in 0..3 {
            out[k] += c * weighted[k][i];
        }
    }
    out
}

/// Cosine-weighted solid angle of a uniform disk of angular diameter `diam_deg` seen head-on:
/// the integral over the disk of (s . w) dw = pi sin^2(alpha), alpha the angular radius.
/// Irradiance from a disk of unit radiance in direction s on a normal n is this times n . s
/// (exact while the whole disk is above the surface's horizon).
pub fn disk_cosine_solid_angle(diam_deg: f64) -> f64 {
    let a = (diam_deg * 0.5).to_radians();
    std::f64::consts::PI * a.sin() * a.sin()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f32::consts::PI;

    #[test]
    fn hemisphere_layout_round_trips() {
        let s = 512;
        assert!((hemisphere_direction(255, 255, s).unwrap().z - 1.0).abs() < 1e-4);
        // right edge middle -> +X horizon; top middle -> +Y horizon
        let r = hemisphere_direction(511, 256, s).unwrap();
        assert!(r.x > 0.99 && r.z.abs() < 0.01, "{r}");
        let t = hemisphere_direction(256, 0, s).unwrap();
        assert!(t.y > 0.99 && t.z.abs() < 0.01, "{t}");
        assert!(hemisphere_direction(0, 0, s).is_none());
        for (x, y) in [(100, 200), (300, 50), (256, 256), (20, 260)] {
            let d = hemisphere_direction(x, y, s).unwrap();
            let (px, py) = hemisphere_pixel(d, s).unwrap();
            assert!((px - x as f32).abs() < 1e-2 && (py - y as f32).abs() < 1e-2);
        }
    }

    #[test]
    fn irradiance_of_constant_and_linear_skies() {
        // constant L over the sphere: E = pi L for every normal
        let (w, h) = (128, 64);
        let mut m = HdrImage::new(w, h);
        m.pixels.iter_mut().for_each(|p| *p = [1.0, 2.0, 0.5]);
        let int = Integrator::new(&m);
        for n in [
            Vec3::Z,
            Vec3::X,
            Vec3::new(0.3, -0.5, 0.8).normalize(),
            -Vec3::Z,
        ] {
            let e = int.irradiance(n);
            for (c, want) in [1.0, 2.0, 0.5].iter().enumerate() {
                assert!((e[c] / (PI * want) - 1.0).abs() < 2e-3, "{n} {e:?}");
            }
        }
        // upper hemisphere only, L = 1: E(n) = pi (1 + n_z) / 2
        for (i, p) in m.pixels.iter_mut().enumerate() {
            *p = if i / w < h / 2 { [1.0; 3] } else { [0.0; 3] };
        }
        let int = Integrator::new(&m);
        for n in [
            Vec3::Z,
            Vec3::X,
            Vec3::new(0.6, 0.0, -0.8),
            Vec3::new(0.0, 0.6, 0.8),
        ] {
            let want = PI * (1.0 + n.z) / 2.0;
            let e = int.irradiance(n)[0];
            assert!((e - want).abs() < 4e-3 * PI, "{n}: {e} vs {want}");
        }
    }

    #[test]
    fn fill_is_smooth_and_keeps_mask() {
        let (w, h) = (64, 32);
        let mut m = igi_imaging::latlong::map_from_fn(w, h, |d| [1.0 + d.z, 2.0, 0.5 + 0.5 * d.x]);
        let truth = m.clone();
        for i in 10..16 {
            for j in 20..30 {
                let k = i * w + j;
                m.valid[k] = false;
                m.pixels[k] = [0.0; 3];
            }
        }
        fill_invalid_latlong(&mut m);
        assert_eq!(m.valid.iter().filter(|v| !**v).count(), 60);
        for k in 0..w * h {
            for c in 0..3 {
                assert!((m.pixels[k][c] - truth.pixels[k][c]).abs() < 0.06, "{k}");
            }
        }
        // downsampling keeps the mean of a constant and marks mixed pixels invalid
        let d = downsample_latlong(&m, 4);
        assert_eq!((d.width, d.height), (16, 8));
        assert!(!d.valid[3 * 16 + 6] && d.valid[0]);
        assert!((d.pixels[5][1] - 2.0).abs() < 1e-6);
    }

    #[test]
    fn lookup_wraps_and_respects_mask() {
        let mut m = HdrImage::new(8, 4);
        for j in 0..8 {
            for i in 0..4 {
                m.set(j, i, [j as f32, 0.0, 0.0]);
            }
        }
        // between the last and the first column (phi ~ 2pi - small): 50/50 of columns 7 and 0
        let d = igi_imaging::latlong::uv_to_direction(0.9999, 0.5);
        let v = latlong_lookup(&m, d).unwrap()[0];
        assert!((v - 3.5).abs() < 0.01, "{v}");
        m.valid[2 * 8] = false;
        assert!(latlong_lookup(&m, d).is_none());
        let a = disk_cosine_solid_angle(0.53);
        let cap = 2.0 * std::f64::consts::PI * (1.0 - 0.265f64.to_radians().cos());
        assert!((a / cap - 1.0).abs() < 1e-4);
    }
}
