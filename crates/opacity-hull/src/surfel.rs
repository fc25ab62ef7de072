//! Surfels by resampling the hull: the vertices of the hull's surface mesh (spaced about one
//! carving cell apart) with their normals, a splat radius (the build's
//! [`crate::build::SPLAT_RADIUS`] cells), per-view visibility
//! (facing the camera, inside the frame, not behind the hull in the view's depth buffer) and
//! per-view opacity (the view's matte at the surfel's projection, Matusik et al. 2002 Sec. 4).

use crate::raster::rasterize_depth;
use crate::views::View;
use glam::DVec3;
use igi_geometry::{PointCloud, TriMesh};
use rayon::prelude::*;

/// Views whose visibility bit fits in one f32 property exactly (integers up to 2^24).
pub const BITS_PER_WORD: usize = 24;

/// Surfels with per-view visibility and opacity.
#[derive(Clone, Debug, PartialEq)]
pub struct Surfels {
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
    pub radius: Vec<f32>,
    /// The surface area each surfel stands for (m^2: a third of the areas of its triangles),
    /// from which a splat's coverage of a pixel follows; empty in a hull folder written before
    /// it was kept (its splats then cover every pixel they touch).
    pub area: Vec<f32>,
    /// Number of views.
    pub views: usize,
    /// `visible[s * views + v]`.
    pub visible: Vec<bool>,
    /// `opacity[s * views + v]` (0 where not visible or the matte is invalid there).
    pub opacity: Vec<f32>,
}

impl Surfels {
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// As a point cloud: `vis0, vis1, ...` hold 24 visibility bits each, `alpha_vN` the
    /// opacity seen from view N.
    pub fn to_cloud(&self) -> PointCloud {
        let n = self.len();
        let words = self.views.div_ceil(BITS_PER_WORD);
        let mut properties = Vec::new();
        for w in 0..words {
            let vals = (0..n)
                .map(|s| {
                    (0..BITS_PER_WORD)
                        .filter(|b| {
                            w * BITS_PER_WORD + b < self.views
                                && self.visible[s * self.views + w * BITS_PER_WORD + b]
                        })
                        .fold(0u32, |acc, b| acc | 1 << b) as f32
                })
                .collect();
            properties.push((format!("vis{w}"), vals));
        }
        if self.area.len() == n {
            properties.push(("area".to_string(), self.area.clone()));
        }
        for v in 0..self.views {
            properties.push((
                format!("alpha_v{v}"),
                (0..n).map(|s| self.opacity[s * self.views + v]).collect(),
            ));
        }
        PointCloud {
            positions: self.positions.clone(),
            normals: Some(self.normals.clone()),
            colors: None,
            radii: Some(self.radius.clone()),
            properties,
        }
    }

    /// Back from [`Surfels::to_cloud`]; `None` when a property is missing.
    pub fn from_cloud(c: &PointCloud, views: usize) -> Option<Surfels> {
        let n = c.len();
        let mut visible = vec![false; n * views];
        let mut opacity = vec![0.0f32; n * views];
        for w in 0..views.div_ceil(BITS_PER_WORD) {
            let vals = c.property(&format!("vis{w}"))?;
            for s in 0..n {
                let bits = vals[s] as u32;
                for b in 0..BITS_PER_WORD.min(views - w * BITS_PER_WORD) {
                    visible[s * views + w * BITS_PER_WORD + b] = bits >> b & 1 == 1;
                }
            }
        }
        for v in 0..views {
            let a = c.property(&format!("alpha_v{v}"))?;
            for s in 0..n {
                opacity[s * views + v] = a[s];
            }
        }
        Some(Surfels {
            positions: c.positions.clone(),
            normals: c.normals.clone()?,
            radius: c.radii.clone()?,
            area: c.property("area").map(<[f32]>::to_vec).unwrap_or_default(),
            views,
            visible,
            opacity,
        })
    }
}

/// Surfels on the vertices of `mesh` with splat radius `radius` (grown where the vertices lie
/// sparser, `spacing_radii`); `depth_tolerance` is how far
/// (metres, along the camera axis) a surfel may lie behind the depth buffer (the farthest of the
/// pixel centres around its projection) and still count as visible.
pub fn make_surfels(mesh: &TriMesh, radius: f32, depth_tolerance: f64, views: &[View]) -> Surfels {
    let n = mesh.positions.len();
    let normals = mesh
        .normals
        .clone()
        .unwrap_or_else(|| vec![[0.0, 0.0, 1.0]; n]);
    let nv = views.len();
    let per_view: Vec<Vec<(bool, f32)>> = views
        .par_iter()
        .map(|view| {
            let depth = rasterize_depth(mesh, &view.camera);
            let centre = view.camera.center_world();
            (0..n)
                .map(|s| {
                    visibility(
                        &mesh.positions[s],
                        &normals[s],
                        view,
                        &depth,
                        centre,
                        depth_tolerance,
                    )
                })
                .collect()
        })
        .collect();
    let mut visible = vec![false; n * nv];
    let mut opacity = vec![0.0f32; n * nv];
    for (v, col) in per_view.iter().enumerate() {
        for (s, &(vis, a)) in col.iter().enumerate() {
            visible[s * nv + v] = vis;
            opacity[s * nv + v] = a;
        }
    }
    let area = vertex_areas(mesh);
    let radius = spacing_radii(&area, radius);
    Surfels {
        positions: mesh.positions.clone(),
        normals,
        radius,
        area,
        views: nv,
        visible,
        opacity,
    }
}

/// Each surfel's splat radius: `radius` where the vertices lie as densely as the median one,
/// grown with the square root of the area a surfel stands for where they lie sparser (up to
/// twice), so that the splats still meet. The vertices placed by the mattes' contours
/// ([`crate::contour`]) are spaced less evenly than the half-way points of the cell edges.
fn spacing_radii(area: &[f32], radius: f32) -> Vec<f32> {
    let mut wide: Vec<f64> = area.iter().map(|&a| a as f64).collect();
    let median = (igi_imaging::color::median_in_place(&mut wide) as f32).max(f32::MIN_POSITIVE);
    area.iter()
        .map(|a| radius * (a / median).sqrt().clamp(1.0, 2.0))
        .collect()
}

/// The largest depth at the (up to four) pixel centres around image point (x, y). A point of
/// a locally planar surface lies within the depths of the centres around it, however grazing
/// the surface; an occluded point lies behind all of them.
fn farthest_around(depth: &crate::raster::DepthBuffer, x: f64, y: f64) -> f32 {
    let (w, h) = (depth.width as i64, depth.height as i64);
    let (x0, y0) = (x.floor() as i64, y.floor() as i64);
    let mut far = f32::NEG_INFINITY;
    for (xi, yi) in [(x0, y0), (x0 + 1, y0), (x0, y0 + 1), (x0 + 1, y0 + 1)] {
        if xi >= 0 && yi >= 0 && xi < w && yi < h {
            far = far.max(depth.depth[(yi * w + xi) as usize]);
        }
    }
    far
}

/// A third of the areas of each vertex's triangles.
fn vertex_areas(mesh: &TriMesh) -> Vec<f32> {
    let mut area = vec![0.0f64; mesh.positions.len()];
    for (k, t) in mesh.indices.iter().enumerate() {
        let a = mesh.triangle_area(k) / 3.0;
        for &i in t {
            area[i as usize] += a;
        }
    }
    area.into_iter().map(|a| a as f32).collect()
}

fn visibility(
    p: &[f32; 3],
    n: &[f32; 3],
    view: &View,
    depth: &crate::raster::DepthBuffer,
    centre: DVec3,
    tol: f64,
) -> (bool, f32) {
    let pw = DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64);
    let nw = DVec3::new(n[0] as f64, n[1] as f64, n[2] as f64);
    if nw.dot(centre - pw) <= 0.0 {
        return (false, 0.0);
    }
    let z = view.camera.pose.apply(pw).z;
    let Some(px) = view.camera.project(pw) else {
        return (false, 0.0);
    };
    let (x, y) = (px.x.round(), px.y.round());
    if !(x >= 0.0 && y >= 0.0 && x < depth.width as f64 && y < depth.height as f64) {
        return (false, 0.0);
    }
    let i = y as usize * depth.width + x as usize;
    if z > farthest_around(depth, px.x, px.y) as f64 + tol {
        return (false, 0.0);
    }
    let a = if view.matte.valid[i] {
        view.matte.alpha[i]
    } else {
        0.0
    };
    (true, a)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Vertices as dense as the median keep the radius; sparser ones grow with the square root
    /// of their area, up to twice; denser ones never shrink.
    #[test]
    fn sparse_vertices_get_larger_splats() {
        let r = spacing_radii(&[0.25, 1.0, 1.0, 1.0, 2.25, 100.0], 0.5);
        assert_eq!(r, vec![0.5, 0.5, 0.5, 0.5, 0.75, 1.0]);
        assert!(spacing_radii(&[], 0.5).is_empty());
    }
}
