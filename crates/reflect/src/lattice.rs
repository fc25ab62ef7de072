//! Shading on a lattice: in the fine iteration of a coarse-to-fine solve (`crate::coarse`),
//! the radiance toward each photograph is path-traced only at every [`LATTICE_STEP`]-th texel
//! of each atlas row and column, and read bilinearly from those at the texels between them.
//!
//! A texel's proposal divides its photograph by its *shading*, the radiance per unit albedo
//! toward the camera (`L / rho_eval`). The shading varies at the scale of the geometry and the
//! light, not of the albedo's detail (the smoothing of `crate::smooth` rests on the same fact),
//! so the fine iteration, whose albedo comes from the settled coarse stage, needs it only
//! sparsely. A texel takes the bilinear blend of the four lattice texels around it
//! only when every corner with a weight stands for it: a traced estimate, not at a shadow
//! edge, in the same sunlight, a normal within [`MIN_NORMAL_DOT`] and at most [`reach`] away
//! (one surface). Otherwise it is traced itself, so shadow edges, creases and chart borders
//! keep their own estimates. A corner at an occlusion boundary of the photograph still stands
//! for its neighbours: the boundary lowers the weight of its pixel, while its shading is traced
//! at the texel itself like any other.

use crate::parts::Part;
use glam::Vec3;
use igi_geometry::texels::number_table;

/// The lattice's spacing in texels. Measured on the large survey of docs/BENCHMARKS.md (4.4 cm
/// texels) and the survey fixture (8-9 cm) with the default iterations: spacings of 3 (the
/// coarse stage's factor, used until 2026-11-29), 5, 6 and 8 give the same texel MAE to
/// 0.0001, and 5 takes the fine iteration 18 % less time than 3 (8 no less than 5: the texels
/// traced one by one and the observations' geometry are the rest).
pub const LATTICE_STEP: u32 = 5;

/// Smallest cosine between a texel's normal and a corner's it borrows from (8 degrees).
pub const MIN_NORMAL_DOT: f32 = 0.99;

/// The lattice of a group's texels.
pub(crate) struct Lattice {
    step: i64,
    /// Per part of the group (empty for other parts): atlas index -> the texel's number in the
    /// group, or `u32::MAX`.
    number: Vec<Vec<u32>>,
}

/// One corner a texel borrows its shading from: its number in the group and bilinear weight.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Corner {
    pub number: u32,
    pub weight: f32,
}

impl Lattice {
    /// The lattice of spacing `step` over the group's texels, given as (part, texel) in group
    /// order.
    pub fn new(
        parts: &[impl AsRef<Part>],
        texels: impl Iterator<Item = (u32, u32)>,
        step: u32,
    ) -> Lattice {
        let mut entries: Vec<Vec<(u32, u32)>> = parts.iter().map(|_| Vec::new()).collect();
        for (gi, (part, texel)) in texels.enumerate() {
            let index = parts[part as usize].as_ref().cache.texels[texel as usize].index;
            entries[part as usize].push((index, gi as u32));
        }
        let number = parts
            .iter()
            .zip(entries)
            .map(|(p, e)| {
                if e.is_empty() {
                    Vec::new()
                } else {
                    number_table(p.as_ref().resolution(), e)
                }
            })
            .collect();
        Lattice {
            step: step.max(1) as i64,
            number,
        }
    }

    /// Whether the texel is traced: on the lattice (every texel when the step is 1).
    pub fn traced(&self, parts: &[impl AsRef<Part>], part: u32, texel: u32) -> bool {
        let (x, y) = self.xy(parts, part, texel);
        x % self.step == 0 && y % self.step == 0
    }

    /// The lattice corners around a texel off the lattice, with their weights (only those
    /// with a positive weight), or `None` when one of them is not a texel of the group.
    pub fn corners(
        &self,
        parts: &[impl AsRef<Part>],
        part: u32,
        texel: u32,
    ) -> Option<Vec<Corner>> {
        let (x, y) = self.xy(parts, part, texel);
        let r = parts[part as usize].as_ref().resolution() as i64;
        let (x0, y0) = (x - x % self.step, y - y % self.step);
        let (fx, fy) = (
            (x - x0) as f32 / self.step as f32,
            (y - y0) as f32 / self.step as f32,
        );
        let mut out = Vec::with_capacity(4);
        for (dx, wx) in [(0, 1.0 - fx), (self.step, fx)] {
            for (dy, wy) in [(0, 1.0 - fy), (self.step, fy)] {
                let w = wx * wy;
                if w <= 0.0 {
                    continue;
                }
                let (cx, cy) = (x0 + dx, y0 + dy);
                if cx >= r || cy >= r {
                    return None;
                }
                let n = self.number[part as usize][(cy * r + cx) as usize];
                if n == u32::MAX {
                    return None;
                }
                out.push(Corner {
                    number: n,
                    weight: w,
                });
            }
        }
        Some(out)
    }

    fn xy(&self, parts: &[impl AsRef<Part>], part: u32, texel: u32) -> (i64, i64) {
        let p = parts[part as usize].as_ref();
        let r = p.resolution() as i64;
        let i = p.cache.texels[texel as usize].index as i64;
        (i % r, i / r)
    }
}

/// How far a corner may lie from the texel that borrows from it: the lattice diagonal and one
/// texel more, in metres.
pub fn reach(step: u32, texel_size: f64) -> f32 {
    ((step as f64 * std::f64::consts::SQRT_2 + 1.0) * texel_size) as f32
}

/// The bilinear blend of the corners' shading and its standard error, when every corner gives
/// one (`of`: a corner's shading and standard error per unit albedo, or `None` when it cannot
/// stand for the texel).
pub(crate) fn blend(
    corners: &[Corner],
    of: impl Fn(u32) -> Option<(Vec3, Vec3)>,
) -> Option<(Vec3, Vec3)> {
    let (mut s, mut var) = (Vec3::ZERO, Vec3::ZERO);
    for c in corners {
        let (shading, se) = of(c.number)?;
        s += c.weight * shading;
        var += (c.weight * se) * (c.weight * se);
    }
    Some((s, var.map(f32::sqrt)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ground(res: u32) -> Vec<Part> {
        crate::parts::square_part(res)
    }

    /// A shading linear in position is read back exactly between the lattice texels, about a
    /// ninth of the texels are traced at step 3, and a corner that cannot stand for the texel
    /// makes it traced.
    #[test]
    fn a_linear_shading_is_read_back_exactly_between_the_lattice_texels() {
        let parts = ground(64);
        let texels = &parts[0].cache.texels;
        let lattice = Lattice::new(&parts, (0..texels.len() as u32).map(|k| (0, k)), 3);
        let shading = |k: u32| {
            let p = texels[k as usize].position;
            Vec3::new(1.0 + 0.2 * p.x, 2.0 - 0.1 * p.y, 0.5 + 0.05 * (p.x + p.y))
        };
        let traced: Vec<bool> = (0..texels.len() as u32)
            .map(|k| lattice.traced(&parts, 0, k))
            .collect();
        let share = traced.iter().filter(|t| **t).count() as f64 / texels.len() as f64;
        assert!((share - 1.0 / 9.0).abs() < 0.03, "traced share {share}");
        let (mut blended, mut worst) = (0, 0.0f32);
        for k in 0..texels.len() as u32 {
            if traced[k as usize] {
                continue;
            }
            let Some(corners) = lattice.corners(&parts, 0, k) else {
                continue;
            };
            let w: f32 = corners.iter().map(|c| c.weight).sum();
            assert!((w - 1.0).abs() < 1e-5, "weights sum to {w}");
            let of = |n: u32| traced[n as usize].then(|| (shading(n), Vec3::splat(0.1)));
            let (s, se) = blend(&corners, of).expect("every corner is traced");
            worst = worst.max((s - shading(k)).abs().max_element());
            assert!(se.max_element() <= 0.1 + 1e-6);
            blended += 1;
        }
        assert!(worst < 1e-4, "largest error {worst}");
        // texels within a step of a chart's border are traced (their corner is off the chart)
        let share = blended as f64 / texels.len() as f64;
        assert!(share > 0.6, "{blended} of {} blended", texels.len());
        // a corner refused: no blend
        let k = (0..texels.len() as u32)
            .find(|&k| !traced[k as usize] && lattice.corners(&parts, 0, k).is_some())
            .unwrap();
        let corners = lattice.corners(&parts, 0, k).unwrap();
        let refused = corners[0].number;
        assert!(blend(&corners, |n| (n != refused)
            .then(|| (shading(n), Vec3::ZERO)))
        .is_none());
    }
}
