//! The voxel lattice and the exact partition of a mesh into voxels.
//!
//! Triangles that cross voxel faces are clipped (Sutherland-Hodgman against the axis planes,
//! x planes first, then y, then z) and the convex pieces fan-triangulated. A cut point on an
//! edge is computed from the edge's endpoints taken in a canonical (lexicographic) order, and
//! its coordinate along the cut axis is set to the plane's exact `f32` value; so the two
//! triangles that share an edge produce bit-identical cut points, and the boundary edges of
//! neighbouring voxels match exactly. A vertex lying on a plane belongs to both sides; a
//! piece lying in a plane goes to the upper voxel, so every piece of surface is in exactly
//! one voxel.

use crate::error::GeometryError;
use crate::mesh::TriMesh;
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, HashMap};

/// Integer coordinates of a voxel in the lattice.
pub type VoxelId = [i32; 3];

/// The most non-empty voxels a prepare accepts.
pub const MAX_VOXELS: u64 = 10_000_000;

/// The most non-empty voxels a run may make, and why: the words its refusal gives after
/// `limit N: ` ([`MAX_VOXELS`], or fewer within the memory or the disk the run has).
#[derive(Clone, Debug, PartialEq)]
pub struct VoxelLimit {
    pub voxels: u64,
    pub why: String,
}

impl VoxelLimit {
    /// [`MAX_VOXELS`] and nothing less.
    pub fn max() -> VoxelLimit {
        VoxelLimit {
            voxels: MAX_VOXELS,
            why: String::new(),
        }
    }

    /// The lower of this limit and `voxels` (for the reason `why`).
    pub fn at_most(self, voxels: u64, why: impl FnOnce() -> String) -> VoxelLimit {
        match voxels < self.voxels {
            true => VoxelLimit { voxels, why: why() },
            false => self,
        }
    }

    /// `limit N` with its reason, for messages.
    pub fn describe(&self) -> String {
        match self.voxels < MAX_VOXELS {
            true => format!(
                "limit {}: {MAX_VOXELS} at most, and {}",
                self.voxels, self.why
            ),
            false => format!("limit {MAX_VOXELS}"),
        }
    }
}

/// Bytes a prepare holds per voxel of the site, beside the pieces and atlases being worked on
/// (its bin, its manifest entry): the slope of the peak resident memory of `igi prepare` on
/// the fixture's block at `--atlas 32` between 23 002 voxels (`--voxel 0.04`, 44.6 MB) and
/// 92 126 voxels (`--voxel 0.02`, 114.0 MB) is 1 004 bytes per voxel (docs/RELIABILITY.md).
pub const BYTES_PER_VOXEL: f64 = 1024.0;

/// A lattice of cubic voxels: voxel `[i, j, k]` spans `origin + [i, j, k] * size` to
/// `origin + [i + 1, j + 1, k + 1] * size`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct VoxelGrid {
    pub origin: [f64; 3],
    pub size: f64,
}

impl VoxelGrid {
    /// A lattice; the size must be positive and finite, the origin finite.
    pub fn new(origin: [f64; 3], size: f64) -> Result<Self, GeometryError> {
        if !(size.is_finite() && size > 0.0) {
            return Err(GeometryError::InvalidArgument(format!(
                "voxel size must be positive, got {size}"
            )));
        }
        if !origin.iter().all(|x| x.is_finite()) {
            return Err(GeometryError::InvalidArgument(format!(
                "voxel origin must be finite, got {origin:?}"
            )));
        }
        Ok(VoxelGrid { origin, size })
    }

    /// The plane between voxel `i - 1` and `i` along `axis`, as the exact `f32` used for cuts.
    pub fn plane(&self, axis: usize, i: i32) -> f32 {
        (self.origin[axis] + i as f64 * self.size) as f32
    }

    /// The voxel index along `axis` that contains coordinate `x` (planes belong to the upper voxel).
    pub fn cell(&self, axis: usize, x: f32) -> i32 {
        let mut i = ((x as f64 - self.origin[axis]) / self.size).floor() as i32;
        while self.plane(axis, i + 1) <= x {
            i += 1;
        }
        while self.plane(axis, i) > x {
            i -= 1;
        }
        i
    }

    /// The voxel containing a point.
    pub fn voxel_of(&self, p: [f32; 3]) -> VoxelId {
        [self.cell(0, p[0]), self.cell(1, p[1]), self.cell(2, p[2])]
    }

    /// Bounds (min, max) of a voxel, with the exact `f32` planes.
    pub fn bounds(&self, v: VoxelId) -> ([f32; 3], [f32; 3]) {
        (
            [
                self.plane(0, v[0]),
                self.plane(1, v[1]),
                self.plane(2, v[2]),
            ],
            [
                self.plane(0, v[0] + 1),
                self.plane(1, v[1] + 1),
                self.plane(2, v[2] + 1),
            ],
        )
    }

    /// True if `p` lies exactly on one of the six face planes of voxel `v`.
    pub fn on_voxel_face(&self, v: VoxelId, p: [f32; 3]) -> bool {
        let (lo, hi) = self.bounds(v);
        (0..3).any(|k| p[k] == lo[k] || p[k] == hi[k])
    }
}

/// A clip vertex: position and interpolated attributes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct CV {
    pub(crate) p: [f32; 3],
    pub(crate) n: [f32; 3],
    pub(crate) c: [f32; 3],
    /// index of the source vertex, or u32::MAX for a cut point
    pub(crate) src: u32,
}

fn key_lt(a: &CV, b: &CV) -> bool {
    for k in 0..3 {
        match a.p[k].total_cmp(&b.p[k]) {
            std::cmp::Ordering::Less => return true,
            std::cmp::Ordering::Greater => return false,
            _ => {}
        }
    }
    false
}

/// The point where edge (a, b) meets the plane `coordinate[axis] == plane`, from the endpoints
/// in canonical order so the result does not depend on the edge's direction.
fn cut(a: &CV, b: &CV, axis: usize, plane: f32) -> CV {
    let (a, b) = if key_lt(b, a) { (b, a) } else { (a, b) };
    let t = (plane as f64 - a.p[axis] as f64) / (b.p[axis] as f64 - a.p[axis] as f64);
    let lerp = |x: [f32; 3], y: [f32; 3]| {
        [0, 1, 2].map(|k| (x[k] as f64 + t * (y[k] as f64 - x[k] as f64)) as f32)
    };
    let mut p = lerp(a.p, b.p);
    p[axis] = plane;
    let n = lerp(a.n, b.n);
    let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    let n = if l > 0.0 { n.map(|x| x / l) } else { a.n };
    CV {
        p,
        n,
        c: lerp(a.c, b.c),
        src: u32::MAX,
    }
}

/// Split a convex polygon by the plane: (part with coordinate <= plane, part >= plane).
/// A polygon with no vertex strictly below goes entirely above, and vice versa.
fn split(poly: &[CV], axis: usize, plane: f32) -> (Vec<CV>, Vec<CV>) {
    let d: Vec<f32> = poly.iter().map(|v| v.p[axis] - plane).collect();
    let any_below = d.iter().any(|&x| x < 0.0);
    let any_above = d.iter().any(|&x| x > 0.0);
    if !any_below {
        return (Vec::new(), poly.to_vec());
    }
    if !any_above {
        return (poly.to_vec(), Vec::new());
    }
    let mut below = Vec::with_capacity(poly.len() + 2);
    let mut above = Vec::with_capacity(poly.len() + 2);
    for i in 0..poly.len() {
        let j = (i + 1) % poly.len();
        let (cur, nxt) = (&poly[i], &poly[j]);
        if d[i] <= 0.0 {
            below.push(*cur);
        }
        if d[i] >= 0.0 {
            above.push(*cur);
        }
        if (d[i] < 0.0 && d[j] > 0.0) || (d[i] > 0.0 && d[j] < 0.0) {
            let x = cut(cur, nxt, axis, plane);
            below.push(x);
            above.push(x);
        }
    }
    (below, above)
}

/// Builds one voxel's mesh, welding source vertices by index and cut points by value.
#[derive(Default)]
struct VoxelBuilder {
    mesh: TriMesh,
    normals: Vec<[f32; 3]>,
    colors: Vec<[f32; 3]>,
    by_src: HashMap<u32, u32>,
    by_value: HashMap<[u32; 9], u32>,
}

impl VoxelBuilder {
    fn vertex(&mut self, v: &CV) -> u32 {
        let next = self.mesh.positions.len() as u32;
        let id = if v.src != u32::MAX {
            *self.by_src.entry(v.src).or_insert(next)
        } else {
            let key = [
                v.p[0].to_bits(),
                v.p[1].to_bits(),
                v.p[2].to_bits(),
                v.n[0].to_bits(),
                v.n[1].to_bits(),
                v.n[2].to_bits(),
                v.c[0].to_bits(),
                v.c[1].to_bits(),
                v.c[2].to_bits(),
            ];
            *self.by_value.entry(key).or_insert(next)
        };
        if id == next {
            self.mesh.positions.push(v.p);
            self.normals.push(v.n);
            self.colors.push(v.c);
        }
        id
    }

    /// The voxel's mesh (normals always, colours when the source has them), or `None` when
    /// it has no triangle.
    fn finish(self, has_colors: bool) -> Option<TriMesh> {
        if self.mesh.indices.is_empty() {
            return None;
        }
        let mut m = self.mesh;
        m.normals = Some(self.normals);
        m.colors = has_colors.then_some(self.colors);
        Some(m)
    }

    fn polygon(&mut self, poly: &[CV]) {
        let ids: Vec<u32> = poly.iter().map(|v| self.vertex(v)).collect();
        for j in 1..ids.len() - 1 {
            let t = [ids[0], ids[j], ids[j + 1]];
            if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
                continue;
            }
            let [a, b, c] = t.map(|i| self.mesh.positions[i as usize]);
            if crate::mesh::tri_area(a, b, c) == 0.0 {
                continue; // collinear sliver from an on-plane vertex: no area, no boundary
            }
            self.mesh.indices.push(t);
        }
    }
}

/// Partition a mesh into voxels. Normals are carried (computed first if the mesh has none) and
/// interpolated at cut points, colours likewise; input UVs are dropped (each voxel gets its own
/// atlas). Returns the non-empty voxels in lexicographic order of their ids.
pub fn partition(mesh: &TriMesh, grid: &VoxelGrid) -> BTreeMap<VoxelId, TriMesh> {
    let normals = vertex_normals(mesh);
    let has_colors = mesh.colors.is_some();
    let cv = |i: u32| CV {
        p: mesh.positions[i as usize],
        n: normals[i as usize],
        c: mesh.colors.as_ref().map_or([0.0; 3], |c| c[i as usize]),
        src: i,
    };
    let mut out: BTreeMap<VoxelId, VoxelBuilder> = BTreeMap::new();
    let mut pieces = Pieces::default();
    for tri in &mesh.indices {
        pieces.place(grid, &tri.map(cv), &mut |id, poly| {
            out.entry(id).or_default().polygon(poly)
        });
    }
    out.into_iter()
        .filter_map(|(id, b)| Some((id, b.finish(has_colors)?)))
        .collect()
}

/// Voxel `v` of [`partition`] alone, from the triangles (in the mesh's order, their normals
/// given or computed as `partition` does) of which pieces may lie in `v`: the same mesh, bit for
/// bit, as `partition(mesh, grid)[&v]`, or `None` when nothing of them lies in `v`. This is how
/// a site streamed through per-voxel spill files (`crate::stream`) is cut.
pub(crate) fn partition_voxel(
    v: VoxelId,
    triangles: impl Iterator<Item = [CV; 3]>,
    grid: &VoxelGrid,
    has_colors: bool,
) -> Option<TriMesh> {
    let mut b = VoxelBuilder::default();
    let mut pieces = Pieces::default();
    for vs in triangles {
        pieces.place(grid, &vs, &mut |id, poly| {
            if id == v {
                b.polygon(poly)
            }
        });
    }
    b.finish(has_colors)
}

/// The box of voxels (lowest and highest per axis) that a triangle with corners `p` spans:
/// every piece [`partition`] cuts from it lies in one of them.
pub(crate) fn cell_box(grid: &VoxelGrid, p: [[f32; 3]; 3]) -> (VoxelId, VoxelId) {
    let mut lo = [i32::MAX; 3];
    let mut hi = [i32::MIN; 3];
    for q in p {
        for k in 0..3 {
            let c = grid.cell(k, q[k]);
            lo[k] = lo[k].min(c);
            hi[k] = hi[k].max(c);
        }
    }
    (lo, hi)
}

/// The mesh's vertex normals, computed from its triangles when it has none.
pub(crate) fn vertex_normals(mesh: &TriMesh) -> std::borrow::Cow<'_, [[f32; 3]]> {
    match &mesh.normals {
        Some(n) => std::borrow::Cow::Borrowed(n),
        None => {
            let mut m = TriMesh {
                positions: mesh.positions.clone(),
                indices: mesh.indices.clone(),
                ..Default::default()
            };
            m.compute_vertex_normals();
            std::borrow::Cow::Owned(m.normals.unwrap())
        }
    }
}

/// The polygons a triangle is clipped into, with the voxel each lies in (and scratch space
/// reused from triangle to triangle).
#[derive(Default)]
struct Pieces {
    cur: Vec<(Vec<CV>, VoxelId)>,
    next: Vec<(Vec<CV>, VoxelId)>,
}

impl Pieces {
    /// Hands each piece of triangle `vs` to `f` with its voxel (the whole triangle when it
    /// lies in one voxel), in the order `partition` uses.
    fn place(&mut self, grid: &VoxelGrid, vs: &[CV; 3], f: &mut dyn FnMut(VoxelId, &[CV])) {
        let (lo, hi) = cell_box(grid, vs.map(|v| v.p));
        if lo == hi {
            f(lo, vs);
            return;
        }
        self.clip_to_cells(grid, vs, lo, hi);
        for (poly, id) in &self.cur {
            f(*id, poly);
        }
    }

    /// Clips triangle `vs`, whose corners span cells `lo..=hi`, at the lattice planes between
    /// them, axis by axis: `cur` becomes the polygons (3 or more corners) with their voxels.
    fn clip_to_cells(&mut self, grid: &VoxelGrid, vs: &[CV; 3], lo: VoxelId, hi: VoxelId) {
        self.cur.clear();
        self.cur.push((vs.to_vec(), lo));
        for axis in 0..3 {
            self.next.clear();
            for (poly, id) in self.cur.drain(..) {
                let mut rest = poly;
                let mut id = id;
                for i in lo[axis]..hi[axis] {
                    let (below, above) = split(&rest, axis, grid.plane(axis, i + 1));
                    if below.len() >= 3 {
                        id[axis] = i;
                        self.next.push((below, id));
                    }
                    rest = above;
                    if rest.len() < 3 {
                        break;
                    }
                }
                if rest.len() >= 3 {
                    id[axis] = hi[axis];
                    self.next.push((rest, id));
                }
            }
            std::mem::swap(&mut self.cur, &mut self.next);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid() -> VoxelGrid {
        VoxelGrid::new([0.0, 0.0, 0.0], 1.0).unwrap()
    }

    #[test]
    fn cells_respect_exact_planes() {
        let g = VoxelGrid::new([0.1, -0.3, 0.0], 0.7).unwrap();
        for x in [-3.3f32, -0.3, 0.1, 0.8, 0.79999, 5.0] {
            for axis in 0..3 {
                let c = g.cell(axis, x);
                assert!(
                    g.plane(axis, c) <= x && x < g.plane(axis, c + 1),
                    "{axis} {x} -> {c}"
                );
            }
        }
        assert!(VoxelGrid::new([0.0; 3], 0.0).is_err());
        assert!(VoxelGrid::new([f64::NAN, 0.0, 0.0], 1.0).is_err());
    }

    #[test]
    fn a_big_triangle_is_cut_into_voxels_with_area_preserved() {
        let m = TriMesh {
            positions: vec![[-0.5, -0.3, 0.2], [3.7, 0.4, 1.9], [0.9, 2.6, 2.7]],
            indices: vec![[0, 1, 2]],
            ..Default::default()
        };
        let parts = partition(&m, &grid());
        assert!(parts.len() > 6, "{}", parts.len());
        let total: f64 = parts.values().map(|p| p.total_area()).sum();
        assert!(
            (total - m.total_area()).abs() < 1e-5 * m.total_area(),
            "{total} vs {}",
            m.total_area()
        );
        for (id, p) in &parts {
            let (lo, hi) = grid().bounds(*id);
            for q in &p.positions {
                for k in 0..3 {
                    assert!(q[k] >= lo[k] && q[k] <= hi[k], "{id:?} {q:?}");
                }
            }
            p.validate().unwrap();
        }
    }

    #[test]
    fn a_grid_lying_on_the_lattice_planes_is_neither_lost_nor_doubled() {
        // a tilted-free worst case: a 2 x 2 m grid in the plane z = 1 (a voxel face) whose
        // vertices and edges all lie on voxel planes x = k/2, y = k/2, plus a vertical wall in x = 1
        let g = VoxelGrid::new([0.0; 3], 0.5).unwrap();
        let mut m = TriMesh::default();
        for j in 0..=4 {
            for i in 0..=4 {
                m.positions.push([i as f32 * 0.5, j as f32 * 0.5, 1.0]);
            }
        }
        for j in 0..4u32 {
            for i in 0..4u32 {
                let a = j * 5 + i;
                m.indices.push([a, a + 1, a + 6]);
                m.indices.push([a, a + 6, a + 5]);
            }
        }
        let b = m.positions.len() as u32;
        m.positions.extend([
            [1.0, 0.0, 0.0],
            [1.0, 2.0, 0.0],
            [1.0, 2.0, 1.0],
            [1.0, 0.0, 1.0],
        ]);
        m.indices.push([b, b + 1, b + 2]);
        m.indices.push([b, b + 2, b + 3]);
        let parts = partition(&m, &g);
        let total: f64 = parts.values().map(|p| p.total_area()).sum();
        assert!((total - 6.0).abs() < 1e-6, "area {total} (expected 4 + 2)");
        // the flat grid goes to the voxels above z = 1 (k = 2), 16 of them, 2 triangles each
        let flat: Vec<_> = parts.iter().filter(|(id, _)| id[2] == 2).collect();
        assert_eq!(flat.len(), 16);
        assert!(flat.iter().all(|(_, p)| p.indices.len() == 2));
        // the wall in x = 1 goes to the voxels with x index 2, cut into 4 x 2 squares
        let wall: f64 = parts
            .iter()
            .filter(|(id, _)| id[2] < 2)
            .map(|(id, p)| {
                assert_eq!(id[0], 2);
                p.total_area()
            })
            .sum();
        assert!((wall - 2.0).abs() < 1e-6);
    }

    #[test]
    fn shared_edges_get_bit_identical_cut_points_and_coplanar_faces_go_up() {
        // two triangles sharing the edge (1, 2) in opposite directions, crossing x = 1 and y = 1
        let m = TriMesh {
            positions: vec![
                [0.3, 0.2, 0.5],
                [1.7, 0.1, 0.5],
                [0.2, 1.9, 0.6],
                [1.8, 1.7, 0.4],
            ],
            indices: vec![[0, 1, 2], [1, 3, 2]],
            ..Default::default()
        };
        let parts = partition(&m, &grid());
        // every vertex on the plane x = 1 must appear in both the x = 0 and x = 1 voxels
        let on_plane = |id: VoxelId| -> Vec<[u32; 3]> {
            parts.get(&id).map_or(vec![], |p| {
                p.positions
                    .iter()
                    .filter(|q| q[0] == 1.0)
                    .map(|q| q.map(f32::to_bits))
                    .collect()
            })
        };
        let mut a = on_plane([0, 0, 0]);
        a.extend(on_plane([0, 1, 0]));
        let mut b = on_plane([1, 0, 0]);
        b.extend(on_plane([1, 1, 0]));
        a.sort();
        a.dedup();
        b.sort();
        b.dedup();
        assert!(!a.is_empty());
        assert_eq!(a, b);
        // a triangle lying in the plane z = 1 belongs to voxel z = 1 only
        let flat = TriMesh {
            positions: vec![[0.1, 0.1, 1.0], [0.9, 0.1, 1.0], [0.1, 0.9, 1.0]],
            indices: vec![[0, 1, 2]],
            ..Default::default()
        };
        let parts = partition(&flat, &grid());
        assert_eq!(parts.keys().copied().collect::<Vec<_>>(), vec![[0, 0, 1]]);
    }
}
