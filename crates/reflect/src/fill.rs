//! Filling texels no photo saw, and the gutters of the atlas.
//!
//! Rule (documented in docs/SOLVER.md): a covered texel with no usable observation takes the
//! mean of its seen 8-neighbours in the atlas, grown ring by ring from the seen texels (up to
//! `max_rings` rings, so a small hole borrows from its surroundings); whatever is still unfilled
//! takes the mean of all seen texels of the part, or the initial albedo when the part was not
//! seen at all. Gutter texels (around each chart) are then dilated from the covered texels so
//! bilinear lookups at chart borders never read unrelated values.

use glam::Vec3;

pub use igi_geometry::texels::dilate;

/// Applies the fill rule to one part's albedo atlas. `seen[i]`: texel i got a value from the
/// photos; `covered[i]`: texel centre on the surface; `gutter[i]`: dilated border texel.
/// Returns the number of covered texels that were filled rather than seen.
pub fn fill_unseen(
    values: &mut [Vec3],
    seen: &[bool],
    covered: &[bool],
    gutter: &[bool],
    res: usize,
    fallback: Vec3,
    max_rings: usize,
) -> usize {
    let mut known = seen.to_vec();
    let nseen = seen.iter().filter(|s| **s).count();
    let mean = if nseen > 0 {
        values
            .iter()
            .zip(seen)
            .filter(|(_, s)| **s)
            .fold(Vec3::ZERO, |a, (v, _)| a + *v)
            / nseen as f32
    } else {
        fallback
    };
    let mut filled = dilate(values, &mut known, covered, res, max_rings);
    for i in 0..values.len() {
        if covered[i] && !known[i] {
            values[i] = mean;
            known[i] = true;
            filled += 1;
        }
    }
    let border: Vec<bool> = gutter.iter().zip(covered).map(|(g, c)| *g && !*c).collect();
    dilate(values, &mut known, &border, res, 4);
    filled
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_hole_takes_its_neighbours_and_an_unseen_island_the_mean() {
        let res = 8;
        let mut v = vec![Vec3::ZERO; res * res];
        let mut seen = vec![false; res * res];
        let mut covered = vec![false; res * res];
        // a 3x3 seen block of 0.4 around an unseen centre
        for y in 1..4 {
            for x in 1..4 {
                covered[y * res + x] = true;
                if !(x == 2 && y == 2) {
                    seen[y * res + x] = true;
                    v[y * res + x] = Vec3::splat(0.4);
                }
            }
        }
        // an unseen island far away
        covered[7 * res + 7] = true;
        let gutter = vec![false; res * res];
        let n = fill_unseen(&mut v, &seen, &covered, &gutter, res, Vec3::splat(0.5), 2);
        assert_eq!(n, 2);
        assert!((v[2 * res + 2].x - 0.4).abs() < 1e-6);
        assert!(
            (v[7 * res + 7].x - 0.4).abs() < 1e-6,
            "island gets the part's mean"
        );
    }
}
