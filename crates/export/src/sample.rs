//! `igi sample`: the recovered albedo and its standard error at surface points (for
//! colour-checker comparisons).

use crate::ExportError;
use glam::Vec3;
use igi_formats::points::AlbedoRow;
use igi_reflect::{SolveResult, UNKNOWN_STDERR};
use std::path::Path;

/// The albedo of a result at one query point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AlbedoSample {
    /// Diffuse albedo (bilinear in the atlas).
    pub rho: Vec3,
    /// Its standard error per channel, at the nearest texel; [`UNKNOWN_STDERR`] where unknown.
    pub stderr: Vec3,
}

/// The standard error at `uv` of an `r` x `r` atlas: the nearest texel's (not interpolated:
/// an unknown texel must not blend into a known one).
fn stderr_at(stderr: &[Vec3], r: usize, uv: glam::Vec2) -> Vec3 {
    stderr[igi_geometry::texels::texel_at(uv, r, r)]
}

/// The recovered diffuse albedo (and its standard error) of the surface nearest each query
/// point: a short ray along the point's normal (both ways) finds the surface; when it misses,
/// the nearest covered texel.
pub fn sample_albedo(
    result_dir: &Path,
    points: &[(Vec3, Vec3)],
) -> Result<Vec<AlbedoSample>, ExportError> {
    let res = SolveResult::load(result_dir)?;
    let scene = res.albedo_scene()?;
    // how far off the surface a query point may lie: half the finest texel, 1 mm to 5 cm
    let reach = (res
        .parts
        .iter()
        .map(|p| p.part.texel_size as f32)
        .fold(f32::INFINITY, f32::min)
        * 0.5)
        .clamp(1e-3, 0.05);
    // a point farther than this from every texel has no albedo that could mean anything
    let far = res
        .parts
        .iter()
        .map(|p| 20.0 * p.part.texel_size as f32)
        .fold(0.5f32, f32::max);
    let texels = std::sync::OnceLock::new();
    points
        .iter()
        .enumerate()
        .map(|(k, &(p, n))| {
            let n = n.normalize_or(Vec3::Z);
            if let Some(sp) = scene.surface_near(p, n, reach) {
                let o = sp.object as usize;
                return Ok(AlbedoSample {
                    rho: scene.objects[o].material.brdf_at(sp.uv).rho_d,
                    stderr: stderr_at(&res.parts[o].stderr, res.parts[o].resolution(), sp.uv),
                });
            }
            // the nearest covered texel (the index is built at the first miss)
            let index = texels.get_or_init(|| TexelIndex::new(&res));
            let best = index.nearest(&res, p);
            if !(best.0.sqrt() <= far) {
                return Err(ExportError::FarPoint {
                    index: k + 1,
                    point: p,
                    distance: best.0.sqrt(),
                    far,
                });
            }
            Ok(AlbedoSample {
                rho: best.1,
                stderr: best.2,
            })
        })
        .collect()
}

/// Every part's covered texels in one k-d tree, by position.
struct TexelIndex {
    tree: kiddo::ImmutableKdTree<f32, 3>,
    /// (part, atlas index) of each point of the tree.
    items: Vec<(usize, usize)>,
}

impl TexelIndex {
    fn new(res: &SolveResult) -> TexelIndex {
        let mut points = Vec::new();
        let mut items = Vec::new();
        for (i, part) in res.parts.iter().enumerate() {
            for t in &part.part.cache.texels {
                points.push(t.position.to_array());
                items.push((i, t.index as usize));
            }
        }
        TexelIndex {
            tree: kiddo::ImmutableKdTree::new_from_slice(&points),
            items,
        }
    }

    /// Squared distance, albedo and standard error of the covered texel nearest `p`
    /// (infinitely far when the result has no covered texel).
    fn nearest(&self, res: &SolveResult, p: Vec3) -> (f32, Vec3, Vec3) {
        if self.items.is_empty() || !p.is_finite() {
            return (f32::INFINITY, Vec3::ZERO, UNKNOWN_STDERR);
        }
        let hit = self
            .tree
            .nearest_one::<kiddo::SquaredEuclidean>(&p.to_array());
        let (i, k) = self.items[hit.item as usize];
        (hit.distance, res.parts[i].rho[k], res.parts[i].stderr[k])
    }
}

/// `igi sample`: reads the points of `points_csv`, samples the result in `result_dir` at each
/// and writes the values table to `out_csv` (nothing is written when a point fails); returns
/// how many points were sampled.
pub fn sample_file(
    result_dir: &Path,
    points_csv: &Path,
    out_csv: &Path,
) -> Result<usize, ExportError> {
    let points = igi_formats::points::read_points(points_csv)?;
    let samples = sample_albedo(result_dir, &points)?;
    let rows: Vec<AlbedoRow> = points
        .iter()
        .zip(&samples)
        .map(|(&(point, normal), s)| AlbedoRow {
            point,
            normal,
            rho: s.rho,
            stderr: (s.stderr.min_element() >= 0.0).then_some(s.stderr),
        })
        .collect();
    igi_formats::points::write_albedo_rows(out_csv, &rows)?;
    Ok(rows.len())
}
