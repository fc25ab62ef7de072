//! Where between two cell centres the hull's surface lies: signed distances to the mattes'
//! half-coverage contours.
//!
//! Carving decides which cells are kept; marching cubes on that binary occupancy would put
//! every surface vertex half-way between a kept and a carved centre, anywhere within half a
//! cell of the silhouettes' edges (RMS 0.26 cell on a sphere; 0.09 as placed here, test
//! `the_hull_surface_follows_the_mattes_contours`). [`occupancy_values`] gives each cell next
//! to the surface the signed distance (metres, positive inside) of its centre to the nearest
//! view's matte contour at alpha 0.5, the edge of the object in a box-filtered photograph: the
//! smallest over the views that see the centre on pixels that may carve (known, outside the
//! frame band: the band is weak evidence, weighed by votes), each view's distance in pixels
//! times the pixel's size at the centre's depth. As marching-cubes values `0.5 + 0.5 * d /
//! cell` (clamped) they put each vertex where the distance crosses zero along its cell edge.
//! Kept cells stay above 0.5 and carved ones below, so the carving's topology is untouched: a
//! thin part whose matte never reaches 0.5 (a straw under a pixel wide) keeps its cells, and
//! its surface is drawn in toward the kept centres.
//!
//! Per pixel, the distance is estimated from the alphas around it (within [`REACH`] pixels):
//! in a box-filtered image an edge at signed distance `s` from a pixel centre gives it alpha
//! `0.5 + s` for `|s| <= 0.5`. So a pixel of the other class, at distance `r` with alpha `b`,
//! bounds the distance by `r - |0.5 - b|`, and one of the same class whose alpha is in the
//! ramp (`0 < b < 1`, the pixel itself included) by `r + |b - 0.5|`; the smallest bound wins.
//! Both are exact along the edge's normal for an unsaturated alpha. A binary mask puts the
//! contour half-way between centres.

use crate::carve::{CellGrid, ViewIndex, KEPT};
use crate::views::View;
use glam::DVec3;
use igi_imaging::HdrImage;
use rayon::prelude::*;

/// How far (pixels) around a pixel its contour distance is looked for; farther is [`REACH`].
pub const REACH: i64 = 3;

/// The least margin (as a marching-cubes value) a kept or carved cell keeps from the iso level
/// 0.5, so no vertex lands on a cell centre (no degenerate triangles).
const MARGIN: f32 = 0.05;

/// Per pixel of `view`, its signed distance in pixels to the matte's alpha-0.5 contour
/// (positive inside, within +-[`REACH`]), in every channel of an image that is valid where the
/// pixel carves: invalid matte pixels and the frame band give no evidence.
pub fn contour_distance(view: &View) -> HdrImage {
    let m = &view.matte;
    let (w, h) = (m.width as i64, m.height as i64);
    let alpha = |x: i64, y: i64| {
        let i = (y * w + x) as usize;
        view.carves.data[i].then(|| m.alpha[i])
    };
    let pixels = (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let Some(a) = alpha(x, y) else {
                return [REACH as f32; 3];
            };
            let inside = a > 0.5;
            let sign = if inside { 1.0 } else { -1.0 };
            let mut best = REACH as f32;
            for qy in (y - REACH).max(0)..=(y + REACH).min(h - 1) {
                for qx in (x - REACH).max(0)..=(x + REACH).min(w - 1) {
                    let Some(b) = alpha(qx, qy) else { continue };
                    let r = (((qx - x).pow(2) + (qy - y).pow(2)) as f32).sqrt();
                    // every estimate is an upper bound (triangle inequality): the contour lies
                    // |0.5 - b| beyond a pixel of the same class in the ramp, or before one of
                    // the other class (exactly there when b is in the ramp, farther otherwise)
                    if (b > 0.5) != inside {
                        best = best.min(r - (0.5 - b).abs());
                    } else if b > 0.0 && b < 1.0 {
                        best = best.min(r + (b - 0.5).abs());
                    }
                }
            }
            [sign * best.max(0.0); 3]
        })
        .collect();
    HdrImage {
        width: m.width,
        height: m.height,
        pixels,
        valid: view.carves.data.clone(),
    }
}

/// The signed distance (metres) of `p` to the nearest contour over `views` (with their
/// [`contour_distance`] images), or `None` when no view sees it on pixels that carve.
fn cell_distance(p: DVec3, views: &[&View], dist: &[HdrImage]) -> Option<f64> {
    let metres = |(v, d): (&&View, &HdrImage)| {
        let px = v.camera.project(p)?;
        let pixels = d.bilinear(px.x as f32, px.y as f32)?[0] as f64;
        Some(pixels * v.camera.pose.apply(p).z / v.camera.intrinsics.fx)
    };
    views.iter().zip(dist).filter_map(metres).reduce(f64::min)
}

/// The marching-cubes value of a cell on the surface (a neighbour of the other class) from
/// the contour distance `d` of its centre, `0.5 + 0.5 * d / cell`, kept at least [`MARGIN`] on
/// its own side of 0.5; 1 or 0 when no view sees it on pixels that carve.
fn surface_value(d: Option<f64>, kept: bool, cell: f64) -> f32 {
    let Some(d) = d else {
        return if kept { 1.0 } else { 0.0 };
    };
    let v = (0.5 + 0.5 * d / cell).clamp(0.0, 1.0) as f32;
    if kept {
        v.max(0.5 + MARGIN)
    } else {
        v.min(0.5 - MARGIN)
    }
}

/// The values for marching cubes at 0.5 on the kept cells, padded with one empty layer (the
/// padded grid's node `n` is the centre of cell `n - 1`): 1 inside and 0 outside, and on the
/// surface (a cell with a 6-neighbour of the other class) `0.5 + 0.5 * d / cell` from its centre's
/// contour distance `d`, kept at least 0.05 on its own side of 0.5, so that each vertex lands
/// where the contour distance crosses zero between the two centres.
pub fn occupancy_values(
    grid: &CellGrid,
    carver: &[ViewIndex],
    views: &[&View],
) -> (Vec<f32>, [usize; 3]) {
    let dims = grid.dims;
    let padded = dims.map(|n| n + 2);
    let dist: Vec<HdrImage> = views.iter().map(|v| contour_distance(v)).collect();
    let cell = grid.cell_size().max_element();
    let kept = |c: [i64; 3]| {
        (0..3).all(|k| c[k] >= 0 && c[k] < dims[k] as i64)
            && carver[grid.index(c.map(|x| x as usize))] == KEPT
    };
    let values = (0..padded.iter().product::<usize>())
        .into_par_iter()
        .map(|i| {
            let n = [
                i % padded[0],
                i / padded[0] % padded[1],
                i / (padded[0] * padded[1]),
            ];
            let c = n.map(|x| x as i64 - 1);
            let inside = kept(c);
            let surface = (0..6).any(|s| {
                let mut q = c;
                q[s / 2] += if s % 2 == 0 { -1 } else { 1 };
                kept(q) != inside
            });
            let outer = (0..3).any(|k| c[k] < 0 || c[k] >= dims[k] as i64);
            if outer || !surface {
                return if inside { 1.0 } else { 0.0 };
            }
            let centre = grid.center(c.map(|x| x as usize));
            surface_value(cell_distance(centre, views, &dist), inside, cell)
        })
        .collect();
    (values, padded)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backdrop::Matte;
    use crate::hull::carve_hull;
    use igi_camera::Camera;
    use igi_imaging::Mask;
    use std::path::Path;

    /// A view of `camera` whose matte is `alpha` (every pixel known, silhouette at 0.05).
    fn view(camera: Camera, alpha: Vec<f32>) -> View {
        let (w, h) = (camera.width as usize, camera.height as usize);
        let all = Mask {
            width: w,
            height: h,
            data: vec![true; w * h],
        };
        let silhouette = Mask {
            width: w,
            height: h,
            data: alpha.iter().map(|&a| a > 0.05).collect(),
        };
        View {
            id: "v".into(),
            photo: HdrImage::new(w, h),
            matte: Matte {
                width: w,
                height: h,
                alpha,
                valid: vec![true; w * h],
            },
            silhouette,
            known: all.clone(),
            carves: all,
            camera,
        }
    }

    fn camera(eye: DVec3, w: u32, h: u32) -> Camera {
        Camera::look_at(eye, DVec3::ZERO, w, h, 30.0).unwrap()
    }

    /// A box-filtered vertical edge at x = 10.3 (alpha 0.5 + 10.3 - x in the ramp): every pixel
    /// within reach gets its signed distance 10.3 - x; a binary edge between columns 9 and 10
    /// puts the contour half-way.
    #[test]
    fn edges_give_their_signed_distances() {
        let (w, h) = (24u32, 8u32);
        let cam = camera(DVec3::new(1.0, 0.0, 0.0), w, h);
        let ramp = |x: usize| (0.5 + 10.3 - x as f32).clamp(0.0, 1.0);
        let d = contour_distance(&view(
            cam.clone(),
            (0..w * h).map(|i| ramp(i as usize % 24)).collect(),
        ));
        for x in 8..=13 {
            let got = d.pixels[4 * 24 + x][0];
            assert!((got - (10.3 - x as f32)).abs() < 1e-5, "x {x}: {got}");
        }
        let step = |x: usize| if x <= 9 { 1.0 } else { 0.0 };
        let d = contour_distance(&view(
            cam,
            (0..w * h).map(|i| step(i as usize % 24)).collect(),
        ));
        for (x, want) in [(7, 2.5), (8, 1.5), (9, 0.5), (10, -0.5), (11, -1.5)] {
            assert!(
                (d.pixels[4 * 24 + x][0] - want).abs() < 1e-6,
                "x {x}: {}",
                d.pixels[4 * 24 + x][0]
            );
        }
        assert_eq!(d.pixels[4 * 24 + 20][0], -(REACH as f32), "beyond reach");
    }

    /// A sphere of radius 5 cm seen by 3 x 24 cameras at 64 x 48 pixels, each matte its exact
    /// pixel coverage (8 x 8 rays a pixel): the hull's vertices lie on the sphere within a
    /// small fraction of a cell on average.
    #[test]
    fn the_hull_surface_follows_the_mattes_contours() {
        const R: f64 = 0.05;
        let mut views = Vec::new();
        for e in [-20.0f64, 10.0, 40.0] {
            for p in 0..24 {
                let (e, a) = (e.to_radians(), (15.0 * p as f64).to_radians());
                let eye = 0.4 * DVec3::new(e.cos() * a.cos(), e.cos() * a.sin(), e.sin());
                let cam = camera(eye, 64, 48);
                let hits = |u: f64, v: f64| {
                    let (o, d) = cam.pixel_ray(u, v);
                    let b = o.dot(d);
                    b * b - (o.length_squared() - R * R) >= 0.0
                };
                let alpha = (0..64 * 48)
                    .map(|i| {
                        let (x, y) = ((i % 64) as f64, (i / 64) as f64);
                        let n = (0..64)
                            .filter(|k| {
                                hits(
                                    x - 0.5 + (k % 8) as f64 / 8.0 + 1.0 / 16.0,
                                    y - 0.5 + (k / 8) as f64 / 8.0 + 1.0 / 16.0,
                                )
                            })
                            .count();
                        n as f32 / 64.0
                    })
                    .collect();
                views.push(view(cam, alpha));
            }
        }
        let refs: Vec<&View> = views.iter().collect();
        let (min, max) = (DVec3::splat(-0.08), DVec3::splat(0.08));
        let hull = carve_hull(Path::new("rig.toml"), &refs, min, max, 64).unwrap();
        let cell = 0.16 / 64.0;
        let err: Vec<f64> = hull
            .mesh
            .positions
            .iter()
            .map(|p| (DVec3::from_array(p.map(f64::from)).length() - R) / cell)
            .collect();
        let mean = err.iter().sum::<f64>() / err.len() as f64;
        let rms = (err.iter().map(|e| e * e).sum::<f64>() / err.len() as f64).sqrt();
        eprintln!(
            "{} vertices: radial error mean {mean:.3} cell, rms {rms:.3} cell",
            err.len()
        );
        assert!(
            mean.abs() < 0.1 && rms < 0.2,
            "mean {mean:.3}, rms {rms:.3} cells"
        );
    }
}
