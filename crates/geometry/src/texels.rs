//! The covered texels of an atlas (texel centres that lie on the surface, with their world
//! position and normal), the atlas-sized table that numbers a list of texels, and the dilation
//! that grows known texel values into neighbouring texels (hole filling, atlas gutters). Shared by the inverse solver and the surface light field.

use glam::{Vec2, Vec3};
use igi_imaging::HdrImage;

/// A texel whose centre lies on the surface.
#[derive(Clone, Copy, Debug)]
pub struct Texel {
    /// Index into the atlas image: `row * resolution + column`.
    pub index: u32,
    pub position: Vec3,
    pub normal: Vec3,
}

/// The covered texels of one atlas.
#[derive(Clone, Debug)]
pub struct TexelCache {
    pub resolution: usize,
    pub texels: Vec<Texel>,
}

/// `n` normalised, unless it already is a unit vector to f32 precision: normalising a
/// normalised vector again can change its last bit, and a texel cache written and read back
/// (a resumed or distributed solve) must give the very same normals.
fn unit(n: Vec3) -> Vec3 {
    if (n.length_squared() - 1.0).abs() < 1e-6 {
        n
    } else {
        n.normalize_or(Vec3::Z)
    }
}

impl TexelCache {
    /// The covered texels (coverage 1) of same-size position, normal and coverage caches.
    pub fn covered_texels(pos: &HdrImage, nrm: &HdrImage, coverage: &HdrImage) -> Vec<Texel> {
        (0..coverage.width * coverage.height)
            .filter(|&i| coverage.pixels[i][0] == 1.0)
            .map(|i| Texel {
                index: i as u32,
                position: Vec3::from_array(pos.pixels[i]),
                normal: unit(Vec3::from_array(nrm.pixels[i])),
            })
            .collect()
    }

    /// Texture coordinate of a texel centre (FORMATS.md: row 0 at the top, v up).
    pub fn uv(&self, index: u32) -> Vec2 {
        let r = self.resolution;
        let (x, y) = (index as usize % r, index as usize / r);
        Vec2::new(
            (x as f32 + 0.5) / r as f32,
            1.0 - (y as f32 + 0.5) / r as f32,
        )
    }

    /// [`number_table`] of the cache's texels: atlas index -> position in `texels`.
    pub fn numbers(&self) -> Vec<u32> {
        number_table(
            self.resolution,
            self.texels
                .iter()
                .enumerate()
                .map(|(k, t)| (t.index, k as u32)),
        )
    }
}

/// An atlas-sized table (`resolution` x `resolution`, row-major like [`Texel::index`]) holding
/// each entry's number at its atlas index and `u32::MAX` elsewhere: from a texel's place in the
/// atlas back to its place in a list (a cache's texels, a solve group, a field's grid points).
/// A later entry at the same index wins.
pub fn number_table(resolution: usize, entries: impl IntoIterator<Item = (u32, u32)>) -> Vec<u32> {
    let mut table = vec![u32::MAX; resolution * resolution];
    for (index, number) in entries {
        table[index as usize] = number;
    }
    table
}

/// Index (`row * width + column`) of the texel of a `width` x `height` texture whose square
/// holds `uv` (FORMATS.md: row 0 at the top, v up): the nearest texel, clamped to the edge; a
/// non-finite coordinate reads the centre.
#[inline]
pub fn texel_at(uv: Vec2, width: usize, height: usize) -> usize {
    let (u, v) = clamp_uv(uv);
    let x = ((u * width as f32) as usize).min(width - 1);
    let y = (((1.0 - v) * height as f32) as usize).min(height - 1);
    y * width + x
}

/// A UV clamped to [0, 1] (a non-finite coordinate reads the centre, 0.5).
#[inline]
pub fn clamp_uv(uv: Vec2) -> (f32, f32) {
    let c = |x: f32| {
        if x.is_finite() {
            x.clamp(0.0, 1.0)
        } else {
            0.5
        }
    };
    (c(uv.x), c(uv.y))
}

/// Grows `known` values into `target` texels that are not yet known, ring by ring (8-neighbour
/// mean of known texels). Returns how many texels were filled.
pub fn dilate(
    values: &mut [Vec3],
    known: &mut [bool],
    target: &[bool],
    res: usize,
    rings: usize,
) -> usize {
    let mut filled = 0;
    for _ in 0..rings {
        let prev = known.to_vec();
        let mut changed = false;
        for y in 0..res {
            for x in 0..res {
                let i = y * res + x;
                if prev[i] || !target[i] {
                    continue;
                }
                if let Some(mean) = known_neighbour_mean(values, &prev, res, x, y) {
                    values[i] = mean;
                    known[i] = true;
                    filled += 1;
                    changed = true;
                }
            }
        }
        if !changed {
            break;
        }
    }
    filled
}

/// Mean of the known 8-neighbours of texel (x, y), if any.
fn known_neighbour_mean(
    values: &[Vec3],
    known: &[bool],
    res: usize,
    x: usize,
    y: usize,
) -> Option<Vec3> {
    let (mut s, mut n) = (Vec3::ZERO, 0.0f32);
    for j in window3x3(x, y, res) {
        if known[j] {
            s += values[j];
            n += 1.0;
        }
    }
    (n > 0.0).then(|| s / n)
}

/// Indices of the texels of the 3x3 window around texel (x, y) of a `res` x `res` grid that lie
/// inside it (the centre included), row by row from the top left.
pub(crate) fn window3x3(x: usize, y: usize, res: usize) -> impl Iterator<Item = usize> {
    (-1i64..=1).flat_map(move |dy| {
        (-1i64..=1).filter_map(move |dx| {
            let (xx, yy) = (x as i64 + dx, y as i64 + dy);
            if xx < 0 || yy < 0 || xx >= res as i64 || yy >= res as i64 {
                None
            } else {
                Some(yy as usize * res + xx as usize)
            }
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `texel_at` inverts `TexelCache::uv` at every texel centre of a 4 x 3 texture's rows and
    /// columns, clamps outside [0, 1] and reads the centre for a non-finite coordinate.
    #[test]
    fn texel_at_finds_the_texel_of_its_centre_and_clamps() {
        let cache = TexelCache {
            resolution: 4,
            texels: Vec::new(),
        };
        for i in 0..16 {
            assert_eq!(texel_at(cache.uv(i), 4, 4), i as usize);
        }
        // 4 wide, 3 high: v = 1 is row 0 (the top), u = 1 the last column
        assert_eq!(texel_at(Vec2::new(0.0, 1.0), 4, 3), 0);
        assert_eq!(texel_at(Vec2::new(1.0, 0.0), 4, 3), 2 * 4 + 3);
        assert_eq!(texel_at(Vec2::new(-3.0, 7.0), 4, 3), 0);
        assert_eq!(texel_at(Vec2::new(f32::NAN, f32::INFINITY), 4, 3), 4 + 2);
    }

    #[test]
    fn normals_read_back_are_bit_identical_and_others_are_normalised() {
        let mut worst_changed = 0;
        for k in 0..1000 {
            let a = k as f32 * 0.731;
            let n = Vec3::new(a.cos() * 0.3, a.sin(), 0.01 + (a * 3.1).sin() * 0.2).normalize();
            worst_changed += (unit(n) != n) as usize;
        }
        assert_eq!(worst_changed, 0, "unit normals are kept bit for bit");
        assert_eq!(unit(Vec3::new(0.0, 0.0, 2.0)), Vec3::Z);
        assert_eq!(unit(Vec3::ZERO), Vec3::Z);
        let n = Vec3::new(0.7774881, -0.62880355, 0.010888989);
        assert_eq!(
            unit(n),
            n,
            "the normal found changing by an ulp on a round trip"
        );
    }

    #[test]
    fn dilation_grows_one_ring_per_step_with_the_neighbour_mean() {
        let res = 5;
        let mut v = vec![Vec3::ZERO; res * res];
        let mut known = vec![false; res * res];
        v[12] = Vec3::splat(2.0);
        known[12] = true;
        let target = vec![true; res * res];
        assert_eq!(dilate(&mut v, &mut known, &target, res, 1), 8);
        assert!(known[6] && !known[0]);
        assert!((v[6].x - 2.0).abs() < 1e-6);
        assert_eq!(
            dilate(&mut v, &mut known, &target, res, 3),
            16,
            "the rest in one more ring"
        );
    }

    #[test]
    fn covered_texels_keep_coverage_one_and_normalise_normals() {
        let mut cov = HdrImage::new(2, 2);
        let mut pos = HdrImage::new(2, 2);
        let mut nrm = HdrImage::new(2, 2);
        cov.pixels[3] = [1.0; 3];
        cov.pixels[1] = [0.5; 3];
        pos.pixels[3] = [1.0, 2.0, 3.0];
        nrm.pixels[3] = [0.0, 0.0, 2.0];
        let t = TexelCache::covered_texels(&pos, &nrm, &cov);
        assert_eq!(t.len(), 1);
        assert_eq!(t[0].index, 3);
        assert_eq!(t[0].normal, Vec3::Z);
        let cache = TexelCache {
            resolution: 2,
            texels: t,
        };
        assert_eq!(cache.uv(3), Vec2::new(0.75, 0.25));
    }

    #[test]
    fn the_number_table_finds_each_texel_in_its_list() {
        let cache = TexelCache {
            resolution: 3,
            texels: [7u32, 0, 4]
                .iter()
                .map(|&index| Texel {
                    index,
                    position: Vec3::ZERO,
                    normal: Vec3::Z,
                })
                .collect(),
        };
        let m = cache.numbers();
        assert_eq!(m.len(), 9);
        assert_eq!((m[7], m[0], m[4]), (0, 1, 2));
        assert_eq!(m.iter().filter(|&&v| v == u32::MAX).count(), 6);
        assert_eq!(
            number_table(2, [(3, 5), (3, 9)]),
            vec![u32::MAX, u32::MAX, u32::MAX, 9]
        );
    }
}
