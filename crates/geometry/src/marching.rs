//! Marching cubes: the iso-surface of a scalar field on a regular grid as a [`TriMesh`].
//!
//! The inside is where the value is **greater** than the iso level (an occupancy or density
//! convention; pass `-sdf` for a signed distance that is negative inside). Triangles are wound
//! counter-clockwise seen from outside, so face normals point from inside to outside; vertex
//! normals are the area-weighted average of the faces around each vertex.
//!
//! The 256-case triangle table is derived on first use rather than typed in: on each cube face
//! the crossings of the iso level are paired (each crossing entering the inside with the next
//! one leaving it, walking the face counter-clockwise from outside), which separates the inside
//! corners on ambiguous faces. The rule depends only on the face's own corners, so neighbouring
//! cubes agree and the surface is closed wherever it does not meet the grid's border. The
//! segments of the six faces chain into loops, which are fan-triangulated.

use crate::error::GeometryError;
use crate::mesh::TriMesh;
use std::collections::HashMap;
use std::sync::OnceLock;

/// A scalar field sampled on a regular grid: `values[x + nx * (y + ny * z)]` is the value at
/// `origin + (x, y, z) * spacing`.
#[derive(Clone, Copy, Debug)]
pub struct Grid<'a> {
    pub values: &'a [f32],
    pub dims: [usize; 3],
    pub origin: [f32; 3],
    pub spacing: [f32; 3],
}

/// Corner `c` of a cube sits at offset (c & 1, c >> 1 & 1, c >> 2 & 1).
const fn corner_offset(c: usize) -> [usize; 3] {
    [c & 1, (c >> 1) & 1, (c >> 2) & 1]
}

/// The 12 cube edges as (lower corner, axis); the upper corner is `lower | 1 << axis`.
fn edges() -> Vec<(usize, usize)> {
    let mut e = Vec::with_capacity(12);
    for axis in 0..3 {
        for c in 0..8 {
            if c & (1 << axis) == 0 {
                e.push((c, axis));
            }
        }
    }
    e
}

fn edge_index(a: usize, b: usize) -> usize {
    let (lo, hi) = (a.min(b), a.max(b));
    let axis = (lo ^ hi).trailing_zeros() as usize;
    edges()
        .iter()
        .position(|&(c, k)| c == lo && k == axis)
        .expect("corners share an edge")
}

/// The four corners of each face in counter-clockwise order seen from outside the cube.
fn faces() -> Vec<[usize; 4]> {
    let mut f = Vec::with_capacity(6);
    for k in 0..3 {
        let (u, v) = ((k + 1) % 3, (k + 2) % 3);
        for side in 0..2 {
            let c = |a: usize, b: usize| (side << k) | (a << u) | (b << v);
            let ring = [c(0, 0), c(1, 0), c(1, 1), c(0, 1)];
            f.push(if side == 1 {
                ring
            } else {
                [ring[3], ring[2], ring[1], ring[0]]
            });
        }
    }
    f
}

/// Triangles (as edge-index triples) for one of the 256 cases (bit c set = corner c inside).
fn triangulate_case(case: usize) -> Vec<[u8; 3]> {
    let inside = |c: usize| case & (1 << c) != 0;
    let mut next: HashMap<usize, usize> = HashMap::new();
    for ring in faces() {
        let mut crossings = Vec::new(); // (edge, entering the inside)
        for i in 0..4 {
            let (a, b) = (ring[i], ring[(i + 1) % 4]);
            if inside(a) != inside(b) {
                crossings.push((edge_index(a, b), inside(b)));
            }
        }
        for (i, &(e, entering)) in crossings.iter().enumerate() {
            if entering {
                let exit = crossings[(i + 1) % crossings.len()].0;
                next.insert(e, exit);
            }
        }
    }
    let mut tris = Vec::new();
    let mut starts: Vec<usize> = next.keys().copied().collect();
    starts.sort_unstable();
    let mut used = [false; 12];
    for s in starts {
        if used[s] {
            continue;
        }
        let mut lp = vec![s];
        used[s] = true;
        let mut e = next[&s];
        while e != s {
            used[e] = true;
            lp.push(e);
            e = next[&e];
        }
        for j in 1..lp.len() - 1 {
            tris.push([lp[0] as u8, lp[j] as u8, lp[j + 1] as u8]);
        }
    }
    tris
}

fn case_table() -> &'static Vec<Vec<[u8; 3]>> {
    static TABLE: OnceLock<Vec<Vec<[u8; 3]>>> = OnceLock::new();
    TABLE.get_or_init(|| (0..256).map(triangulate_case).collect())
}

/// Extract the iso-surface `value = iso` (inside: `value > iso`). Returns a mesh without
/// triangles when the level is not crossed. Errors on a grid smaller than 2 x 2 x 2, a value
/// count that does not match the dimensions, a non-finite value or a non-positive spacing.
pub fn marching_cubes(grid: &Grid, iso: f32) -> Result<TriMesh, GeometryError> {
    check_grid(grid)?;
    let [nx, ny, nz] = grid.dims;
    let table = case_table();
    let cube_edges = edges();
    let idx = |x: usize, y: usize, z: usize| x + nx * (y + ny * z);
    let mut mesh = TriMesh::default();
    let mut vertex_of: HashMap<(usize, usize), u32> = HashMap::new();
    for z in 0..nz - 1 {
        for y in 0..ny - 1 {
            for x in 0..nx - 1 {
                let corner = |c: usize| {
                    let o = corner_offset(c);
                    idx(x + o[0], y + o[1], z + o[2])
                };
                let case = (0..8).fold(0, |acc, c| {
                    acc | (((grid.values[corner(c)] > iso) as usize) << c)
                });
                if case == 0 || case == 255 {
                    continue;
                }
                for tri in &table[case] {
                    let mut t = [0u32; 3];
                    for (slot, &e) in t.iter_mut().zip(tri) {
                        let (lo, axis) = cube_edges[e as usize];
                        let (a, b) = (corner(lo), corner(lo | 1 << axis));
                        *slot = *vertex_of.entry((a, axis)).or_insert_with(|| {
                            mesh.positions.push(edge_point(grid, a, b, iso));
                            (mesh.positions.len() - 1) as u32
                        });
                    }
                    mesh.indices.push(t);
                }
            }
        }
    }
    mesh.compute_vertex_normals();
    Ok(mesh)
}

fn check_grid(g: &Grid) -> Result<(), GeometryError> {
    let bad = |m: String| Err(GeometryError::InvalidArgument(m));
    if g.dims.iter().any(|&d| d < 2) {
        return bad(format!(
            "marching cubes needs at least 2 samples per axis, got {:?}",
            g.dims
        ));
    }
    if g.values.len() != g.dims.iter().product::<usize>() {
        return bad(format!(
            "grid {:?} needs {} values, got {}",
            g.dims,
            g.dims.iter().product::<usize>(),
            g.values.len()
        ));
    }
    if !g.spacing.iter().all(|s| *s > 0.0 && s.is_finite())
        || !g.origin.iter().all(|o| o.is_finite())
    {
        return bad(format!(
            "grid spacing {:?} must be positive and origin {:?} finite",
            g.spacing, g.origin
        ));
    }
    if let Some(i) = g.values.iter().position(|v| !v.is_finite()) {
        return bad(format!("grid value {i} is not finite"));
    }
    Ok(())
}

/// The point on the grid edge between flat indices `a` and `b` where the field crosses `iso`.
fn edge_point(g: &Grid, a: usize, b: usize, iso: f32) -> [f32; 3] {
    let pos = |i: usize| {
        let [nx, ny, _] = g.dims;
        let c = [i % nx, (i / nx) % ny, i / (nx * ny)];
        [0, 1, 2].map(|k| g.origin[k] + c[k] as f32 * g.spacing[k])
    };
    let (va, vb) = (g.values[a], g.values[b]);
    let t = if (vb - va).abs() > 0.0 {
        ((iso - va) / (vb - va)).clamp(0.0, 1.0)
    } else {
        0.5
    };
    let (pa, pb) = (pos(a), pos(b));
    [0, 1, 2].map(|k| pa[k] + t * (pb[k] - pa[k]))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sphere_grid(n: usize, r: f32) -> (Vec<f32>, Grid<'static>) {
        let h = 2.0 / (n - 1) as f32;
        let mut v = Vec::with_capacity(n * n * n);
        for z in 0..n {
            for y in 0..n {
                for x in 0..n {
                    let p = glam::Vec3::new(x as f32, y as f32, z as f32) * h - glam::Vec3::ONE;
                    v.push(r - p.length());
                }
            }
        }
        let g = Grid {
            values: &[],
            dims: [n; 3],
            origin: [-1.0; 3],
            spacing: [h; 3],
        };
        (v, g)
    }

    fn signed_volume(m: &TriMesh) -> f64 {
        m.indices
            .iter()
            .map(|t| {
                let p = t.map(|i| glam::DVec3::from_array(m.positions[i as usize].map(f64::from)));
                p[0].dot(p[1].cross(p[2])) / 6.0
            })
            .sum()
    }

    #[test]
    fn sphere_is_closed_outward_and_has_the_right_volume_and_area() {
        let (v, mut g) = sphere_grid(41, 0.7);
        g.values = &v;
        let m = marching_cubes(&g, 0.0).unwrap();
        m.validate().unwrap();
        // closed: every undirected edge is used by exactly two triangles, once each way
        let mut directed: HashMap<(u32, u32), usize> = HashMap::new();
        for t in &m.indices {
            for k in 0..3 {
                *directed.entry((t[k], t[(k + 1) % 3])).or_default() += 1;
            }
        }
        for (&(a, b), &c) in &directed {
            assert_eq!(c, 1, "edge {a}-{b} used {c} times in one direction");
            assert_eq!(directed.get(&(b, a)), Some(&1), "edge {a}-{b} has no twin");
        }
        let exact_v = 4.0 / 3.0 * std::f64::consts::PI * 0.343;
        let vol = signed_volume(&m);
        assert!(
            vol > 0.0 && (vol / exact_v - 1.0).abs() < 0.01,
            "volume {vol} vs {exact_v}"
        );
        let area = m.total_area();
        let exact_a = 4.0 * std::f64::consts::PI * 0.49;
        assert!(
            (area / exact_a - 1.0).abs() < 0.02,
            "area {area} vs {exact_a}"
        );
        // vertices on the sphere, normals radial
        for (p, n) in m.positions.iter().zip(m.normals.as_ref().unwrap()) {
            let p = glam::Vec3::from_array(*p);
            assert!((p.length() - 0.7).abs() < 2e-3, "{p}");
            assert!(p.normalize().dot(glam::Vec3::from_array(*n)) > 0.99);
        }
    }

    #[test]
    fn every_case_closes_its_loops() {
        // In each case, every crossing edge belongs to exactly one loop, so the triangles of
        // all 256 cases use each crossing edge and only those.
        for case in 0..256usize {
            let tris = triangulate_case(case);
            let mut used = [false; 12];
            for t in &tris {
                for &e in t {
                    used[e as usize] = true;
                }
            }
            for (e, &(lo, axis)) in edges().iter().enumerate() {
                let hi = lo | 1 << axis;
                let crosses = (case >> lo & 1) != (case >> hi & 1);
                assert_eq!(used[e], crosses, "case {case} edge {e}");
            }
        }
        assert!(triangulate_case(0).is_empty() && triangulate_case(255).is_empty());
        assert_eq!(triangulate_case(1).len(), 1);
    }

    #[test]
    fn bad_grids_are_refused_and_uncrossed_levels_give_no_triangles() {
        let v = vec![0.0f32; 8];
        let g = Grid {
            values: &v,
            dims: [2, 2, 2],
            origin: [0.0; 3],
            spacing: [1.0; 3],
        };
        assert_eq!(marching_cubes(&g, 0.5).unwrap().triangle_count(), 0);
        let g2 = Grid {
            dims: [2, 2, 3],
            ..g
        };
        assert!(marching_cubes(&g2, 0.5)
            .unwrap_err()
            .to_string()
            .contains("needs 12 values"));
        let g3 = Grid {
            spacing: [1.0, 0.0, 1.0],
            ..g
        };
        assert!(marching_cubes(&g3, 0.5).is_err());
        let nan = vec![f32::NAN; 8];
        assert!(marching_cubes(&Grid { values: &nan, ..g }, 0.5)
            .unwrap_err()
            .to_string()
            .contains("not finite"));
    }
}
