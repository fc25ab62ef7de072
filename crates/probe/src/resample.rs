//! Area-preserving resampling of a reflective sphere's photograph into direction maps.
//!
//! A camera pixel records the mean radiance over its footprint, so the photograph is read as
//! piecewise constant (box reconstruction): the value of a direction is the value of the pixel
//! its reflection point falls in, divided by the sphere's reflectance there. A map texel is the
//! solid-angle-weighted mean of that function over the texel, by `n_u x n_v` sub-directions
//! with `n` chosen per texel from the texel's footprint in the photograph (two sub-directions
//! per pixel across the footprint, the Nyquist rate of the pixel grid), so every pixel's light
//! lands in the texels it covers, in proportion to the overlap. Bilinear interpolation of the
//! photograph would instead blur each pixel over a 2-pixel tent and move light from a small
//! bright source into the neighbouring texels (see docs/PROBE.md, "Resolution").

use glam::{DVec2, DVec3};
use igi_capture::sphere::SphereView;
use igi_imaging::HdrImage;
use rayon::prelude::*;

/// Most sub-directions per texel side (a texel covering more than 8 pixels across is averaged
/// from 16 sub-directions per side, still at least one per pixel).
pub const MAX_SUBSAMPLES: usize = 16;

/// Reads one reflective sphere of a photograph as a function of the reflected direction.
pub struct Reflector<'a> {
    pub img: &'a HdrImage,
    pub view: &'a SphereView<'a>,
    /// Reflectance per channel at an incidence cosine.
    pub refl: &'a (dyn Fn(f64) -> [f64; 3] + Sync),
    /// Directions seen at an incidence cosine below this are not used (grazing, blind spot).
    pub min_cos: f64,
    /// Directions within this cosine of the direction toward the camera are not used.
    pub cam_cos: f64,
}

impl Reflector<'_> {
    /// Pixel coordinates and incidence cosine of the point reflecting unit direction `w`,
    /// `None` where the sphere cannot see `w` or it is masked geometrically.
    pub fn locate(&self, w: DVec3) -> Option<(DVec2, f64)> {
        if w.dot(self.view.to_eye()) > self.cam_cos {
            return None;
        }
        let rp = self.view.reflection_point(w)?;
        (rp.cos_i >= self.min_cos).then_some((rp.pixel, rp.cos_i))
    }

    /// Radiance arriving from `w`: the pixel containing its reflection point (box
    /// reconstruction) over the reflectance; `None` if masked or the pixel is invalid.
    pub fn radiance(&self, w: DVec3) -> Option<[f64; 3]> {
        let (p, cos_i) = self.locate(w)?;
        let (x, y) = (p.x.round(), p.y.round());
        if !(x >= 0.0 && y >= 0.0 && x < self.img.width as f64 && y < self.img.height as f64) {
            return None;
        }
        let k = y as usize * self.img.width + x as usize;
        if !self.img.valid[k] {
            return None;
        }
        let v = self.img.pixels[k];
        let r = (self.refl)(cos_i);
        Some([v[0] as f64 / r[0], v[1] as f64 / r[1], v[2] as f64 / r[2]])
    }
}

/// A direction map's layout: continuous map coordinates `(x, y)` (texel `(j, i)` spans
/// `[j, j+1] x [i, i+1]`) to a unit direction and the solid angle per unit map area there (up
/// to a constant), `None` outside the map's domain.
pub type Layout<'a> = dyn Fn(f64, f64) -> Option<(DVec3, f64)> + Sync + 'a;

/// Pixel positions of the texel corners of a `w` x `h` map, `(w + 1) x (h + 1)` row-major
/// (`None` where the corner's direction is outside the layout or masked).
fn corner_pixels(r: &Reflector, layout: &Layout, w: usize, h: usize) -> Vec<Option<DVec2>> {
    (0..=h)
        .into_par_iter()
        .flat_map_iter(|i| {
            (0..=w).map(move |j| {
                layout(j as f64, i as f64)
                    .and_then(|(d, _)| r.locate(d))
                    .map(|(p, _)| p)
            })
        })
        .collect()
}

/// Number of sub-directions along each side of the texel with the given corner pixels
/// (00, 10, 01, 11): twice the texel's longest footprint in pixels along that side, between
/// `min_sub` and [`MAX_SUBSAMPLES`]; `min_sub` where no side is known (masked corners).
fn subsamples(c: [Option<DVec2>; 4], min_sub: usize) -> (usize, usize) {
    let len = |a: Option<DVec2>, b: Option<DVec2>| a.zip(b).map_or(0.0, |(a, b)| a.distance(b));
    let eu = len(c[0], c[1]).max(len(c[2], c[3]));
    let ev = len(c[0], c[2]).max(len(c[1], c[3]));
    let lo = min_sub.max(1);
    let n = |e: f64| ((2.0 * e).ceil() as usize).clamp(lo, MAX_SUBSAMPLES.max(lo));
    (n(eu), n(ev))
}

/// The solid-angle-weighted mean of [`Reflector::radiance`] over texel `(j, i)` by `nu` x `nv`
/// sub-directions; `None` if the texel's centre is outside the layout or any sub-direction
/// inside it is masked.
pub fn texel(
    r: &Reflector,
    layout: &Layout,
    j: usize,
    i: usize,
    (nu, nv): (usize, usize),
) -> Option<[f32; 3]> {
    let (x, y) = (j as f64, i as f64);
    layout(x + 0.5, y + 0.5)?;
    let (mut acc, mut wsum) = ([0.0f64; 3], 0.0f64);
    for sy in 0..nv {
        for sx in 0..nu {
            let Some((d, wt)) = layout(
                x + (sx as f64 + 0.5) / nu as f64,
                y + (sy as f64 + 0.5) / nv as f64,
            ) else {
                continue;
            };
            let v = r.radiance(d)?;
            for c in 0..3 {
                acc[c] += wt * v[c];
            }
            wsum += wt;
        }
    }
    (wsum > 0.0).then(|| acc.map(|v| (v / wsum) as f32))
}

/// Resample a whole `w` x `h` map (at least `min_sub` x `min_sub` sub-directions per texel,
/// more where the texel covers more than half a pixel); texels that [`texel`] rejects are
/// marked invalid.
pub fn resample(r: &Reflector, layout: &Layout, w: usize, h: usize, min_sub: usize) -> HdrImage {
    let corners = corner_pixels(r, layout, w, h);
    let rows: Vec<Vec<Option<[f32; 3]>>> = (0..h)
        .into_par_iter()
        .map(|i| {
            (0..w)
                .map(|j| {
                    let k = i * (w + 1) + j;
                    let c = [
                        corners[k],
                        corners[k + 1],
                        corners[k + w + 1],
                        corners[k + w + 2],
                    ];
                    texel(r, layout, j, i, subsamples(c, min_sub))
                })
                .collect()
        })
        .collect();
    let mut out = HdrImage::new(w, h);
    for (i, row) in rows.into_iter().enumerate() {
        for (j, v) in row.into_iter().enumerate() {
            let k = i * w + j;
            match v {
                Some(p) => out.pixels[k] = p,
                None => out.valid[k] = false,
            }
        }
    }
    out
}

/// The FORMATS.md lat-long layout of a `w` x `h` map (solid angle density `sin theta`).
pub fn latlong_layout(w: usize, h: usize) -> impl Fn(f64, f64) -> Option<(DVec3, f64)> + Sync {
    move |x, y| {
        let (u, v) = (x / w as f64, y / h as f64);
        let d = igi_imaging::latlong::uv_to_direction(u as f32, v as f32)
            .as_dvec3()
            .normalize();
        Some((d, (std::f64::consts::PI * v).sin()))
    }
}

/// The upper-hemisphere layout of [`crate::envmap::hemisphere_direction`] for a `size` x
/// `size` map (equal-angle polar: solid angle density `sin theta / theta`).
pub fn hemisphere_layout(size: usize) -> impl Fn(f64, f64) -> Option<(DVec3, f64)> + Sync {
    move |x, y| {
        let d = crate::envmap::hemisphere_direction_at(x as f32 - 0.5, y as f32 - 0.5, size)?
            .as_dvec3()
            .normalize();
        let theta = d.z.clamp(-1.0, 1.0).acos();
        Some((
            d,
            if theta > 1e-9 {
                theta.sin() / theta
            } else {
                1.0
            },
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::board::{BoardSphere, SphereKind};
    use glam::DMat3;
    use igi_camera::{Camera, WorldToCamera};
    use igi_imaging::latlong;

    /// Solid angle of the spherical triangle (a, b, c) (Van Oosterom and Strackee).
    fn triangle(a: DVec3, b: DVec3, c: DVec3) -> f64 {
        2.0 * a
            .dot(b.cross(c))
            .abs()
            .atan2(1.0 + a.dot(b) + b.dot(c) + c.dot(a))
    }

    #[test]
    fn one_bright_pixel_keeps_its_light_and_its_footprint() {
        let mut cam = Camera::pinhole(200, 200, 600.0, 600.0, 99.5, 99.5);
        cam.pose = WorldToCamera {
            r: DMat3::from_cols_array_2d(&[[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
                .transpose(),
            t: DVec3::ZERO,
        };
        let s = BoardSphere {
            center_cam: DVec3::new(0.0, 0.0, 1.0),
            radius: 0.1,
        };
        let view = SphereView::new(&cam, SphereKind::Mirror, &s);
        let mut img = HdrImage::new(200, 200);
        let (px, py) = (125usize, 80usize);
        img.set(px, py, [1.0, 2.0, 3.0]);
        let unit = |_: f64| [1.0; 3];
        let r = Reflector {
            img: &img,
            view: &view,
            refl: &unit,
            min_cos: 0.0,
            cam_cos: 1.0,
        };
        let (w, h) = (512, 256);
        let map = resample(&r, &latlong_layout(w, h), w, h, 2);
        // the pixel's footprint in directions: its four corners traced and reflected
        let dir = |u: f64, v: f64| {
            let (_, n, d) = view.hit_pixel(u, v).unwrap();
            d.reflect(n).normalize()
        };
        let (x, y) = (px as f64, py as f64);
        let c = [
            dir(x - 0.5, y - 0.5),
            dir(x + 0.5, y - 0.5),
            dir(x + 0.5, y + 0.5),
            dir(x - 0.5, y + 0.5),
        ];
        let omega = triangle(c[0], c[1], c[2]) + triangle(c[0], c[2], c[3]);
        let (mut energy, mut far, mut inner) = (0.0f64, 0.0f64, 0usize);
        for i in 0..h {
            let sa = latlong::pixel_solid_angle(i, w, h) as f64;
            for j in 0..w {
                let v = map.pixels[i * w + j];
                let at = r
                    .locate(latlong::pixel_center_direction(i, j, w, h).as_dvec3())
                    .map(|(p, _)| p);
                let cheb = at.map_or(f64::MAX, |p| (p.x - x).abs().max((p.y - y).abs()));
                if v[0] > 0.0 {
                    energy += sa * v[0] as f64;
                    far = far.max(cheb);
                    assert!((v[1] / v[0] - 2.0).abs() < 1e-5 && (v[2] / v[0] - 3.0).abs() < 1e-5);
                }
                if cheb < 0.3 {
                    // texels well inside the pixel's footprint see exactly its value
                    assert!(
                        (v[0] - 1.0).abs() < 1e-6,
                        "texel {i},{j} at {cheb:.2} px: {v:?}"
                    );
                    inner += 1;
                }
            }
        }
        // light lands only on texels overlapping the footprint (bilinear interpolation would
        // spread it to texels whose centres are up to 1 px away) and its total is preserved
        eprintln!(
            "{inner} texels inside, farthest lit texel {far:.3} px, energy / footprint {:.4}",
            energy / omega
        );
        assert!(inner >= 2, "{inner}");
        assert!(
            far < 0.8,
            "light reached a texel {far:.2} px from the pixel"
        );
        assert!(
            (energy / omega - 1.0).abs() < 0.03,
            "energy {energy:.4e} vs footprint {omega:.4e}"
        );
    }
}
