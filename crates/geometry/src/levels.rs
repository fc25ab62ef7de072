//! Multiresolution levels by edge collapse (meshoptimizer), keeping UVs and locked vertices.

use crate::mesh::TriMesh;
use meshopt::{SimplifyOptions, VertexDataAdapter};

/// One simplified level.
pub struct Level {
    pub mesh: TriMesh,
    /// Geometric (Hausdorff-like, quadric) error in metres as reported by meshoptimizer.
    pub error: f64,
}

/// Keep only the referenced vertices (attributes follow), in first-use order.
pub fn compact(mesh: &TriMesh, indices: &[u32]) -> TriMesh {
    let mut map = vec![u32::MAX; mesh.positions.len()];
    let mut out = TriMesh {
        normals: mesh.normals.as_ref().map(|_| Vec::new()),
        uvs: mesh.uvs.as_ref().map(|_| Vec::new()),
        colors: mesh.colors.as_ref().map(|_| Vec::new()),
        ..Default::default()
    };
    let mut tri = [0u32; 3];
    for (k, &i) in indices.iter().enumerate() {
        if map[i as usize] == u32::MAX {
            map[i as usize] = out.positions.len() as u32;
            out.positions.push(mesh.positions[i as usize]);
            if let (Some(o), Some(s)) = (out.normals.as_mut(), &mesh.normals) {
                o.push(s[i as usize]);
            }
            if let (Some(o), Some(s)) = (out.uvs.as_mut(), &mesh.uvs) {
                o.push(s[i as usize]);
            }
            if let (Some(o), Some(s)) = (out.colors.as_mut(), &mesh.colors) {
                o.push(s[i as usize]);
            }
        }
        tri[k % 3] = map[i as usize];
        if k % 3 == 2 {
            out.indices.push(tri);
        }
    }
    out
}

/// Simplify to about `ratio` of the triangles. Vertices with `locked[v]` never move (the voxel
/// faces), `lock_border` also locks the mesh's open borders; attribute seams (same position,
/// different UV) are collapsed only along the seam, so one atlas serves every level.
/// `ratio >= 1` returns the mesh unchanged with error 0. `locked` may be shorter than the
/// vertex list (an empty slice locks nothing): the missing entries are unlocked (meshopt reads
/// one entry per vertex, so it always gets a full list).
pub fn simplify(mesh: &TriMesh, locked: &[bool], ratio: f64, lock_border: bool) -> Level {
    if ratio >= 1.0 || mesh.indices.is_empty() {
        return Level {
            mesh: mesh.clone(),
            error: 0.0,
        };
    }
    let flat: &[u32] = mesh.indices.as_flattened();
    let bytes: &[u8] = meshopt::typed_to_bytes(&mesh.positions);
    let adapter = VertexDataAdapter::new(bytes, 12, 0).expect("positions are 12-byte records");
    let target = ((mesh.indices.len() as f64 * ratio).round() as usize).max(1) * 3;
    let mut options = SimplifyOptions::ErrorAbsolute;
    if lock_border {
        options |= SimplifyOptions::LockBorder;
    }
    let mut lock = vec![false; mesh.positions.len()];
    for (l, &v) in lock.iter_mut().zip(locked) {
        *l = v;
    }
    let mut err = 0.0f32;
    let out = meshopt::simplify_with_locks(
        flat,
        &adapter,
        &lock,
        target,
        f32::MAX,
        options,
        Some(&mut err),
    );
    // collapses in folded regions can map two faces onto the same corners: drop the copies
    // (and any degenerate face), so a boundary edge is never hidden by a doubled face
    let (m, _) = crate::repair::repair(&compact(mesh, &out));
    let m = compact(&m, m.indices.as_flattened());
    Level {
        mesh: m,
        error: err as f64,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An `n` x `n` quad grid over the unit square with heights `z(x, y)`.
    fn height_grid(n: usize, z: impl Fn(f32, f32) -> f32) -> TriMesh {
        let mut m = TriMesh::default();
        for j in 0..=n {
            for i in 0..=n {
                let (x, y) = (i as f32 / n as f32, j as f32 / n as f32);
                m.positions.push([x, y, z(x, y)]);
            }
        }
        m.indices.extend(crate::mesh::grid_triangles(0, n, n));
        m
    }

    #[test]
    fn an_empty_lock_list_locks_nothing_and_is_safe() {
        let m = height_grid(30, |x, _| 0.01 * (7.0 * x).sin());
        let all = simplify(&m, &vec![false; m.positions.len()], 0.1, true);
        let none = simplify(&m, &[], 0.1, true);
        assert_eq!(all.mesh.indices, none.mesh.indices);
        assert!(none.mesh.indices.len() < m.indices.len() / 5);
    }

    #[test]
    fn a_bumpy_grid_simplifies_and_keeps_locked_vertices() {
        let n = 40usize;
        let mut m = height_grid(n, |x, y| 0.02 * (6.0 * x).sin() * (5.0 * y).cos());
        m.uvs = Some(m.positions.iter().map(|p| [p[0], p[1]]).collect());
        let locked: Vec<bool> = m
            .positions
            .iter()
            .map(|p| p[0] == 0.0 || p[0] == 1.0)
            .collect();
        let l = simplify(&m, &locked, 0.1, false);
        assert!(
            l.mesh.indices.len() <= m.indices.len() / 5,
            "{}",
            l.mesh.indices.len()
        );
        assert!(l.error > 0.0 && l.error < 0.05, "{}", l.error);
        // every locked vertex survives in place (the x = 0 and x = 1 columns, 82 vertices)
        let kept = l
            .mesh
            .positions
            .iter()
            .filter(|p| p[0] == 0.0 || p[0] == 1.0)
            .count();
        assert_eq!(kept, 2 * (n + 1));
        // uvs still equal (x, y) of the kept vertices: collapses keep a vertex's own attributes
        for (p, uv) in l.mesh.positions.iter().zip(l.mesh.uvs.as_ref().unwrap()) {
            assert_eq!([p[0], p[1]], *uv);
        }
        let same = simplify(&m, &locked, 1.0, false);
        assert_eq!(same.mesh, m);
    }
}
