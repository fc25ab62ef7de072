//! Import repair: remove degenerate and duplicate triangles, report non-manifold edges.

use crate::mesh::TriMesh;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// What [`repair`] found and did.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RepairReport {
    pub triangles_in: usize,
    /// Zero-area triangles (repeated vertex or collinear corners) removed.
    pub degenerate_removed: usize,
    /// Triangles with the same three corner positions as an earlier one (any order) removed.
    pub duplicate_removed: usize,
    /// Edges (by corner positions) used by more than two triangles, after removal.
    pub non_manifold_edges: usize,
    /// Edges used by exactly one triangle (holes and open borders), after removal.
    pub border_edges: usize,
    pub triangles_out: usize,
}

fn hash_words(words: &[u32]) -> u64 {
    // FNV-1a over the words, then a final mix
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for w in words {
        h ^= *w as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01B3);
    }
    h ^= h >> 33;
    h = h.wrapping_mul(0xff51_afd7_ed55_8ccd);
    h ^ (h >> 33)
}

fn pos_key(p: [f32; 3]) -> [u32; 3] {
    // +0.0 and -0.0 are the same point
    p.map(|x| if x == 0.0 { 0 } else { x.to_bits() })
}

/// Remove degenerate and duplicate triangles (comparing corner positions, so unwelded
/// duplicates are found too) and count non-manifold and border edges. Vertices are kept.
pub fn repair(mesh: &TriMesh) -> (TriMesh, RepairReport) {
    let mut rep = RepairReport {
        triangles_in: mesh.indices.len(),
        ..Default::default()
    };
    let keep = non_degenerate(mesh);
    rep.degenerate_removed = keep.iter().filter(|k| !**k).count();
    let dup = later_duplicates(mesh, &keep);
    rep.duplicate_removed = dup.iter().filter(|d| **d).count();
    let indices: Vec<[u32; 3]> = mesh
        .indices
        .iter()
        .enumerate()
        .filter(|(t, _)| keep[*t] && !dup[*t])
        .map(|(_, t)| *t)
        .collect();
    let out = TriMesh {
        positions: mesh.positions.clone(),
        normals: mesh.normals.clone(),
        uvs: mesh.uvs.clone(),
        colors: mesh.colors.clone(),
        indices,
    };
    (rep.border_edges, rep.non_manifold_edges) = count_open_and_non_manifold_edges(&out, &|_| true);
    rep.triangles_out = out.indices.len();
    (out, rep)
}

/// What [`repair_share`] found in one voxel's share of a mesh.
pub(crate) struct ShareRepair {
    /// Duplicates whose smallest corner (by position) this share owns.
    pub duplicate_removed: usize,
    /// Border and non-manifold edges whose smallest corner this share owns.
    pub border_edges: usize,
    pub non_manifold_edges: usize,
}

/// [`repair`] of one part of a mesh streamed voxel by voxel: `mesh` holds, in the mesh's order,
/// every non-degenerate triangle whose box of voxels holds this voxel (so every copy of a
/// triangle, and every triangle on an edge, whose smallest corner lies in the voxel); `owns(p)`
/// says whether the voxel holds the point `p`. Each duplicate and each edge is counted by
/// exactly one voxel, the one holding its smallest corner, so the shares sum to [`repair`]'s
/// report.
pub(crate) fn repair_share(
    mesh: &TriMesh,
    owns: &(dyn Fn([f32; 3]) -> bool + Sync),
) -> ShareRepair {
    let duplicate = duplicates(mesh);
    let duplicate_removed = (0..mesh.indices.len())
        .filter(|&t| duplicate[t] && owns(key_point(triangle_key(mesh, t)[0])))
        .count();
    let kept = TriMesh {
        positions: mesh.positions.clone(),
        indices: mesh
            .indices
            .iter()
            .zip(&duplicate)
            .filter(|(_, d)| !**d)
            .map(|(t, _)| *t)
            .collect(),
        ..Default::default()
    };
    let (border_edges, non_manifold_edges) =
        count_open_and_non_manifold_edges(&kept, &|k| owns(key_point(k[0])));
    ShareRepair {
        duplicate_removed,
        border_edges,
        non_manifold_edges,
    }
}

/// True for each triangle of `mesh` with the same corner positions as an earlier one (the
/// duplicates [`repair`] removes, when `mesh` has no degenerate triangle).
pub(crate) fn duplicates(mesh: &TriMesh) -> Vec<bool> {
    later_duplicates(mesh, &vec![true; mesh.indices.len()])
}

/// The point of a position key (`-0.0` read as `0.0`, which lies in the same voxel).
fn key_point(k: [u32; 3]) -> [f32; 3] {
    k.map(f32::from_bits)
}

/// False for triangles with a repeated vertex or zero area.
fn non_degenerate(mesh: &TriMesh) -> Vec<bool> {
    mesh.indices
        .par_iter()
        .enumerate()
        .map(|(t, tri)| {
            tri[0] != tri[1] && tri[1] != tri[2] && tri[0] != tri[2] && mesh.triangle_area(t) > 0.0
        })
        .collect()
}

/// Triangle `t`'s corner positions, sorted.
fn triangle_key(mesh: &TriMesh, t: usize) -> [[u32; 3]; 3] {
    let mut k = mesh.indices[t].map(|i| pos_key(mesh.positions[i as usize]));
    k.sort();
    k
}

/// Edge `e` (corner `e % 3` of triangle `e / 3` to the next) as its sorted corner positions.
fn edge_key(mesh: &TriMesh, e: usize) -> [[u32; 3]; 2] {
    let tri = mesh.indices[e / 3];
    let (a, b) = (tri[e % 3], tri[(e + 1) % 3]);
    let mut k = [
        pos_key(mesh.positions[a as usize]),
        pos_key(mesh.positions[b as usize]),
    ];
    k.sort();
    k
}

/// The end of the run of equal hashes starting at `i` in a sorted `(hash, id)` list.
fn run_end(keyed: &[(u64, u32)], i: usize) -> usize {
    let mut j = i + 1;
    while j < keyed.len() && keyed[j].0 == keyed[i].0 {
        j += 1;
    }
    j
}

/// True for each kept triangle with the same corner positions as a kept triangle of smaller
/// index. Sorts (hash, index) and compares exactly inside runs of equal hash.
fn later_duplicates(mesh: &TriMesh, keep: &[bool]) -> Vec<bool> {
    let mut keyed: Vec<(u64, u32)> = (0..mesh.indices.len())
        .into_par_iter()
        .filter(|&t| keep[t])
        .map(|t| (hash_words(triangle_key(mesh, t).as_flattened()), t as u32))
        .collect();
    keyed.par_sort_unstable();
    let mut dup = vec![false; mesh.indices.len()];
    let mut i = 0;
    while i < keyed.len() {
        let j = run_end(&keyed, i);
        if j - i > 1 {
            for a in i..j {
                let ta = keyed[a].1 as usize;
                if dup[ta] {
                    continue;
                }
                let ka = triangle_key(mesh, ta);
                for b in a + 1..j {
                    let tb = keyed[b].1 as usize;
                    if !dup[tb] && triangle_key(mesh, tb) == ka {
                        dup[tb] = true; // keeps the one with the smaller index (sorted by index in a run)
                    }
                }
            }
        }
        i = j;
    }
    dup
}

/// Edges (by corner positions) used by exactly one triangle, and by more than two, among
/// the edges whose key passes `counted`.
fn count_open_and_non_manifold_edges(
    mesh: &TriMesh,
    counted: &(dyn Fn(&[[u32; 3]; 2]) -> bool + Sync),
) -> (usize, usize) {
    let (mut border, mut non_manifold) = (0, 0);
    // edges by position: (hash, edge id), exact compare in runs
    let mut edges: Vec<(u64, u32)> = (0..mesh.indices.len() * 3)
        .into_par_iter()
        .filter_map(|e| {
            let k = edge_key(mesh, e);
            counted(&k).then(|| (hash_words(k.as_flattened()), e as u32))
        })
        .collect();
    edges.par_sort_unstable();
    let mut i = 0;
    while i < edges.len() {
        let j = run_end(&edges, i);
        if j - i == 1 {
            border += 1;
        } else {
            // group the run by exact key
            let mut keys: Vec<[[u32; 3]; 2]> = edges[i..j]
                .iter()
                .map(|e| edge_key(mesh, e.1 as usize))
                .collect();
            keys.sort();
            let mut a = 0;
            while a < keys.len() {
                let mut b = a + 1;
                while b < keys.len() && keys[b] == keys[a] {
                    b += 1;
                }
                match b - a {
                    1 => border += 1,
                    2 => {}
                    _ => non_manifold += 1,
                }
                a = b;
            }
        }
        i = j;
    }
    (border, non_manifold)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn removes_degenerate_and_duplicates_and_counts_edges() {
        // a closed tetrahedron + a duplicate face (reversed, unwelded copy) + a degenerate sliver
        // + a repeated-index triangle + a fin on edge (0,1) making it non-manifold
        let mut m = TriMesh {
            positions: vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
                // unwelded copies of 0, 1, 2
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                // collinear point
                [2.0, 0.0, 0.0],
                // fin apex
                [0.5, -1.0, 0.5],
            ],
            indices: vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]],
            ..Default::default()
        };
        m.indices.push([4, 5, 6]); // duplicate of [0,2,1]
        m.indices.push([0, 1, 7]); // collinear
        m.indices.push([1, 1, 3]); // repeated index
        m.indices.push([0, 1, 8]); // fin
        let (out, rep) = repair(&m);
        assert_eq!(rep.triangles_in, 8);
        assert_eq!(rep.degenerate_removed, 2);
        assert_eq!(rep.duplicate_removed, 1);
        assert_eq!(rep.triangles_out, 5);
        assert_eq!(out.indices.len(), 5);
        assert_eq!(rep.non_manifold_edges, 1, "edge (0,1) has three faces");
        assert_eq!(rep.border_edges, 2, "the fin's two free edges");
        assert_eq!(
            out.indices[0],
            [0, 2, 1],
            "the first of the duplicates is kept"
        );
    }
}
