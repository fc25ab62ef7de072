//! Light weights for relighting (Matusik et al. 2002, Eq. 3): the environment's radiance
//! integrated over each light's Voronoi cell of directions.
//!
//! A light image shows the object under a distant light of unit irradiance (FORMATS.md,
//! "Multi-view capture"), so under an environment `L(w)` the view's image is
//! `sum_i weight_i * image_i` with `weight_i = integral of L(w) dw over the directions nearer to
//! light i than to any other` (RGB). The environment is the lighting file's map times `scale`
//! as `igi_formats::lighting::LightingRadiance` reads it (the lat-long mapping of FORMATS.md,
//! the one `igi-render` uses), taken as constant over each pixel. Each pixel's (u, v) rectangle
//! goes to the light nearest its centre when its four corners and centre share that light;
//! otherwise it is split in four, down to [`MAX_DEPTH`] levels (1/64 of a pixel), where the
//! centre decides. The sun, `radiance * solid angle of its disk`, goes to the light nearest its
//! direction. Nearest lights come from a kiddo k-d tree over the unit directions (the nearest
//! by chord is the nearest by angle).

use crate::HullError;
use igi_formats::lighting::LightingRadiance;
use igi_imaging::latlong;
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use std::f64::consts::PI;

/// Levels of splitting of a pixel that straddles a cell boundary (2^6 = 64 per side at most).
pub const MAX_DEPTH: u32 = 6;

/// The Voronoi cells of a set of unit directions.
struct Cells {
    tree: ImmutableKdTree<f64, 3>,
}

impl Cells {
    fn nearest(&self, d: [f64; 3]) -> usize {
        self.tree.nearest_one::<SquaredEuclidean>(&d).item as usize
    }

    fn nearest_uv(&self, u: f64, v: f64) -> usize {
        let d = latlong::uv_to_direction(u as f32, v as f32);
        self.nearest([d.x as f64, d.y as f64, d.z as f64])
    }
}

/// Solid angle of the lat-long rectangle `[u0, u1] x [v0, v1]` (exact for the band).
fn rect_solid_angle(u0: f64, u1: f64, v0: f64, v1: f64) -> f64 {
    2.0 * PI * (u1 - u0) * ((PI * v0).cos() - (PI * v1).cos())
}

/// Weights (RGB) of the lights at unit `directions` under `light` (see the module docs).
/// Every weight is finite and non-negative; a black environment gives zeros.
pub fn light_weights(
    light: &LightingRadiance,
    directions: &[[f64; 3]],
) -> Result<Vec<[f64; 3]>, HullError> {
    if directions.is_empty() {
        return Err(HullError::NoLights);
    }
    let cells = Cells {
        tree: ImmutableKdTree::new_from_slice(directions),
    };
    let mut weights = vec![[0.0f64; 3]; directions.len()];
    if let Some((w, h, texels)) = &light.environment {
        for row in 0..*h {
            for col in 0..*w {
                let r = texels[row * w + col];
                if r == [0.0; 3] {
                    continue;
                }
                let (u0, u1) = (col as f64 / *w as f64, (col + 1) as f64 / *w as f64);
                let (v0, v1) = (row as f64 / *h as f64, (row + 1) as f64 / *h as f64);
                split_pixel(&cells, (u0, u1, v0, v1), 0, &mut |i, sa| {
                    for c in 0..3 {
                        weights[i][c] += r[c] as f64 * sa;
                    }
                });
            }
        }
    }
    if let Some(sun) = &light.sun {
        let i = cells.nearest(sun.unit_direction().map(f64::from));
        for c in 0..3 {
            weights[i][c] += sun.radiance[c] as f64 * sun.solid_angle;
        }
    }
    Ok(weights)
}

/// Hand the rectangle (or its pieces) to the nearest light: `add(light, solid angle)`.
fn split_pixel(
    cells: &Cells,
    (u0, u1, v0, v1): (f64, f64, f64, f64),
    depth: u32,
    add: &mut dyn FnMut(usize, f64),
) {
    let (um, vm) = ((u0 + u1) / 2.0, (v0 + v1) / 2.0);
    let centre = cells.nearest_uv(um, vm);
    let uniform = depth >= MAX_DEPTH
        || [(u0, v0), (u1, v0), (u0, v1), (u1, v1)]
            .iter()
            .all(|&(u, v)| cells.nearest_uv(u, v) == centre);
    if uniform {
        add(centre, rect_solid_angle(u0, u1, v0, v1));
        return;
    }
    for (a, b) in [(u0, um), (um, u1)] {
        for (c, d) in [(v0, vm), (vm, v1)] {
            split_pixel(cells, (a, b, c, d), depth + 1, add);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use igi_formats::lighting::SunRadiance;

    fn constant(l: [f32; 3], w: usize, h: usize) -> LightingRadiance {
        LightingRadiance {
            environment: Some((w, h, vec![l; w * h])),
            sun: None,
        }
    }

    const AXES: [[f64; 3]; 6] = [
        [1.0, 0.0, 0.0],
        [-1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.0, 0.0, -1.0],
    ];

    #[test]
    fn a_constant_environment_splits_evenly_over_the_six_axes() {
        let l = [0.7f32, 1.3, 2.0];
        for (w, h) in [(64, 32), (37, 19)] {
            let wts = light_weights(&constant(l, w, h), &AXES).unwrap();
            let mut worst = 0.0f64;
            for wt in &wts {
                for c in 0..3 {
                    let expect = l[c] as f64 * 4.0 * PI / 6.0;
                    worst = worst.max((wt[c] - expect).abs() / expect);
                }
            }
            // measured 1.1e-5 (64 x 32) and 2.3e-5 (37 x 19): the 1/64-pixel boundary cells
            // measured 6.0e-6 (64 x 32) and 6.9e-6 (37 x 19): the 1/64-pixel boundary pieces
            assert!(worst < 2e-5, "{w}x{h}: worst relative error {worst:e}");
            let total: f64 = wts.iter().map(|w| w[0]).sum();
            assert!((total - l[0] as f64 * 4.0 * PI).abs() < 1e-4 * total);
        }
    }

    #[test]
    fn the_sun_lands_on_its_nearest_light_and_black_gives_zero() {
        let dir = [0.3f32, -0.2, 0.93];
        let sun = SunRadiance {
            direction: dir.map(|c| c * 3.0),
            radiance: [1e5, 2e5, 0.0],
            angular_diameter_deg: 0.53,
            solid_angle: 6.72e-5,
        };
        let light = LightingRadiance {
            environment: Some((8, 4, vec![[0.0; 3]; 32])),
            sun: Some(sun),
        };
        let wts = light_weights(&light, &AXES).unwrap();
        for (i, w) in wts.iter().enumerate() {
            let expect = if i == 4 {
                [1e5 * 6.72e-5, 2e5 * 6.72e-5, 0.0]
            } else {
                [0.0; 3]
            };
            for c in 0..3 {
                assert!((w[c] - expect[c]).abs() < 1e-9, "light {i}: {w:?}");
            }
        }
        assert!(light_weights(&light, &[]).is_err());
    }
}
