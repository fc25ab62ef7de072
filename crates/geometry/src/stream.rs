//! A site mesh streamed into per-voxel spill files, for a `prepare` whose memory follows the
//! voxel, not the site ([`crate::store::prepare_streamed`]).
//!
//! The mesh file is read once (twice when it has no vertex normals: a first pass sums the face
//! normals; once more when the lattice cells of its bounds could pass the voxels allowed: a
//! pass counts the voxels and writes nothing, so that a lattice far too fine for the memory
//! allowed is refused in seconds); its vertex table stays in memory while the faces go past in chunks (binary and
//! ASCII PLY; an OBJ is read whole first), then is dropped. Each non-degenerate triangle is
//! written, with its corners' source vertex index, position, normal (and colour), to the spill
//! file of every voxel of its box of voxels ([`crate::voxel`]'s `cell_box`), in the mesh's
//! order. So a voxel's spill file holds every triangle of which `partition` can put a piece in
//! that voxel, every copy of a duplicate triangle whose smallest corner lies in the voxel, and
//! every triangle on an edge whose smallest corner lies in it: the repair
//! (`repair::repair_share`) and the cut (`voxel::partition_voxel`) of one voxel from its spill
//! file give what [`crate::repair::repair`] and [`crate::voxel::partition`] of the whole mesh
//! give for that voxel, bit for bit, and the voxels' repair counts sum to the whole mesh's.
//!
//! One difference: for a mesh without vertex normals, the normals are summed over the
//! triangles before duplicates are removed (the whole-mesh path sums them after), so a vertex
//! of a duplicated triangle can get another normal there.

use crate::error::{GeometryError, MeshInvariant};
use crate::mesh::{accumulate_face_normals, check_indices, finish_normals, tri_area, TriMesh};
use crate::repair::{duplicates, repair_share, RepairReport};
use crate::voxel::{cell_box, partition_voxel, VoxelGrid, VoxelId, VoxelLimit, CV};
use rayon::prelude::*;
use std::collections::HashMap;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Bytes one voxel's spill buffer holds before it is appended to the voxel's file.
const VOXEL_BUFFER: usize = 1 << 20;

/// Bytes the spill buffers hold together before all of them are written out.
pub const SPILL_BUFFERS: usize = 256 << 20;

/// A site mesh binned into per-voxel spill files in a folder of its own, removed when this is
/// dropped.
pub struct SiteSpill {
    dir: PathBuf,
    grid: VoxelGrid,
    has_colors: bool,
    /// The voxels with a spill file and the triangles in it, sorted by voxel.
    voxels: Vec<(VoxelId, usize)>,
    stats: SpillStats,
}

/// What binning a site found and what it held in memory.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SpillStats {
    pub vertices: usize,
    /// Triangles read (polygons fan-triangulated).
    pub triangles_in: usize,
    /// Zero-area triangles (repeated vertex or collinear corners), not spilled.
    pub degenerate_removed: usize,
    /// Surface area of the spilled triangles, m^2.
    pub area: f64,
    /// (min, max) of every vertex position.
    pub bounds: [[f32; 3]; 2],
    /// Triangles written, summed over the voxels (a triangle across voxel faces is written
    /// once per voxel of its box).
    pub spilled_triangles: usize,
    /// The most triangles in one voxel's spill file: what one voxel's work reads.
    pub largest_voxel_triangles: usize,
    /// Bytes of one spilled triangle.
    pub record_bytes: usize,
    /// The most bytes the spill buffers held at once (at most [`SPILL_BUFFERS`] plus one voxel's
    /// buffer).
    pub max_buffered_bytes: usize,
    /// Bytes of the vertex table held while the faces go past (positions and attributes, and
    /// computed normals).
    pub vertex_table_bytes: usize,
}

/// How a binning pass ended.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Pass {
    Done,
    /// The voxels must be counted first ([`count_voxels`]).
    NeedsCount,
    /// The mesh has no normals: they must be summed first ([`normals_pass`]).
    NeedsNormals,
}

impl SiteSpill {
    /// Reads the mesh at `path` (`.ply` or `.obj`) in chunks and bins its triangles into spill
    /// files in the new folder `dir` (which must not exist; it is removed again on error and
    /// when the spill is dropped). The mesh is checked as [`crate::read_mesh`] checks it
    /// (errors name the file). A lattice that gives more voxels than `limit` allows (a
    /// prepare's is its [`crate::store::voxel_limit`]) is refused before anything is written,
    /// by a pass that counts them when the lattice cells of the mesh's bounds could pass the
    /// limit (and not otherwise).
    pub fn bin(
        path: &Path,
        grid: &VoxelGrid,
        limit: &VoxelLimit,
        dir: &Path,
    ) -> Result<SiteSpill, GeometryError> {
        std::fs::create_dir(dir).map_err(|e| GeometryError::io(dir, e))?;
        let mut spill = SiteSpill {
            dir: dir.to_path_buf(),
            grid: *grid,
            has_colors: false,
            voxels: Vec::new(),
            stats: SpillStats::default(),
        };
        let (mut normals, mut counted) = (None, false);
        loop {
            match spill.bin_pass(path, normals.as_deref(), limit, counted)? {
                Pass::Done => return Ok(spill),
                Pass::NeedsCount => {
                    count_voxels(path, grid, limit)?;
                    counted = true;
                }
                Pass::NeedsNormals => {
                    let n = normals_pass(path)?;
                    spill.stats.vertex_table_bytes = 12 * n.len();
                    normals = Some(n);
                }
            }
        }
    }

    /// One pass over the mesh writing the spill files. It stops before writing anything when
    /// the lattice cells of the mesh's bounds pass the `limit` and the voxels have not been
    /// `counted` (the count's pass is needed only then), or when the mesh has no normals and
    /// none are given.
    fn bin_pass(
        &mut self,
        path: &Path,
        normals: Option<&[[f32; 3]]>,
        limit: &VoxelLimit,
        counted: bool,
    ) -> Result<Pass, GeometryError> {
        let mut b = Binner {
            dir: &self.dir,
            grid: self.grid,
            limit,
            stop: (!counted).then_some(Pass::NeedsCount),
            bins: HashMap::new(),
            buffered: 0,
            stats: std::mem::take(&mut self.stats),
            has_colors: false,
            checked: false,
        };
        let mut sink = |mesh: &TriMesh, first: usize, chunk: &[[u32; 3]]| {
            b.chunk(path, mesh, normals, first, chunk)
        };
        let table = match read_chunked(path, &mut sink) {
            Err(_) if b.stop.is_some() => return Ok(b.stop.expect("a stop")),
            r => r?,
        };
        b.flush_all()?;
        let mut stats = b.stats;
        if stats.triangles_in == 0 || table.positions.is_empty() {
            return Err(GeometryError::from(MeshInvariant::Empty {
                vertices: table.positions.len(),
                triangles: stats.triangles_in,
            })
            .in_file(path));
        }
        let (lo, hi) = table.bounds().expect("a vertex");
        stats.bounds = [lo, hi];
        stats.vertices = table.positions.len();
        stats.vertex_table_bytes += table.positions.len()
            * (12
                + 12 * usize::from(table.normals.is_some())
                + 8 * usize::from(table.uvs.is_some())
                + 12 * usize::from(table.colors.is_some()));
        self.has_colors = b.has_colors;
        let mut voxels: Vec<(VoxelId, usize)> =
            b.bins.into_iter().map(|(v, bin)| (v, bin.count)).collect();
        voxels.sort_unstable();
        stats.spilled_triangles = voxels.iter().map(|v| v.1).sum();
        stats.largest_voxel_triangles = voxels.iter().map(|v| v.1).max().unwrap_or(0);
        stats.record_bytes = record_bytes(self.has_colors);
        self.voxels = voxels;
        self.stats = stats;
        Ok(Pass::Done)
    }

    pub fn stats(&self) -> &SpillStats {
        &self.stats
    }

    /// The voxels with a spill file (some may hold no piece of surface), sorted.
    pub fn voxel_ids(&self) -> Vec<VoxelId> {
        self.voxels.iter().map(|v| v.0).collect()
    }

    /// The triangles in voxel `v`'s spill file, in the mesh's order.
    fn read_voxel(&self, v: VoxelId) -> Result<Vec<[CV; 3]>, GeometryError> {
        let path = spill_file(&self.dir, v);
        let bytes = std::fs::read(&path).map_err(|e| GeometryError::io(&path, e))?;
        let rec = record_bytes(self.has_colors);
        if bytes.len() % rec != 0 {
            return Err(GeometryError::format(&path, "truncated spill file"));
        }
        Ok(bytes
            .chunks_exact(rec)
            .map(|r| decode(r, self.has_colors))
            .collect())
    }

    /// Voxel `v`'s share of the repair: its duplicates, border and non-manifold edges.
    fn repair_voxel(&self, v: VoxelId) -> Result<[usize; 3], GeometryError> {
        let tris = self.read_voxel(v)?;
        let r = repair_share(&soup(&tris), &|p| self.grid.voxel_of(p) == v);
        Ok([r.duplicate_removed, r.border_edges, r.non_manifold_edges])
    }

    /// The repair of the whole mesh, from the voxels' shares (read in parallel): what
    /// [`crate::repair::repair`] reports for the mesh.
    pub fn repair_report(&self) -> Result<RepairReport, GeometryError> {
        let sums = self
            .voxels
            .par_iter()
            .map(|(v, _)| self.repair_voxel(*v))
            .try_reduce(
                || [0; 3],
                |a, b| Ok([a[0] + b[0], a[1] + b[1], a[2] + b[2]]),
            )?;
        let s = &self.stats;
        Ok(RepairReport {
            triangles_in: s.triangles_in,
            degenerate_removed: s.degenerate_removed,
            duplicate_removed: sums[0],
            non_manifold_edges: sums[2],
            border_edges: sums[1],
            triangles_out: s.triangles_in - s.degenerate_removed - sums[0],
        })
    }

    /// Voxel `v` of the repaired mesh's partition (`None` when no piece lies in it): the mesh
    /// `partition(&repair(mesh).0, grid)[&v]` is.
    pub fn voxel_mesh(&self, v: VoxelId) -> Result<Option<TriMesh>, GeometryError> {
        let tris = self.read_voxel(v)?;
        let dup = duplicates(&soup(&tris));
        let kept = tris
            .into_iter()
            .zip(dup)
            .filter(|(_, d)| !d)
            .map(|(t, _)| t);
        Ok(partition_voxel(v, kept, &self.grid, self.has_colors))
    }
}

impl Drop for SiteSpill {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// One voxel's buffered spill records and its triangle count.
#[derive(Default)]
struct Bin {
    buf: Vec<u8>,
    count: usize,
}

/// The state of one binning pass.
struct Binner<'a> {
    dir: &'a Path,
    grid: VoxelGrid,
    /// The most voxels allowed.
    limit: &'a VoxelLimit,
    /// Why the pass stopped at its first chunk, before writing anything: `NeedsCount` while
    /// the voxels may pass the limit uncounted (cleared when the mesh's bounds cannot hold
    /// that many), `NeedsNormals` for a mesh without normals.
    stop: Option<Pass>,
    bins: HashMap<VoxelId, Bin>,
    buffered: usize,
    stats: SpillStats,
    has_colors: bool,
    /// The vertex table has been checked.
    checked: bool,
}

impl Binner<'_> {
    /// Checks and bins one chunk of triangles (numbered from `first`).
    fn chunk(
        &mut self,
        path: &Path,
        mesh: &TriMesh,
        normals: Option<&[[f32; 3]]>,
        first: usize,
        chunk: &[[u32; 3]],
    ) -> Result<(), GeometryError> {
        let nv = mesh.positions.len();
        if !self.checked {
            check_vertex_table(path, mesh)?;
            let (lo, hi) = mesh.bounds().expect("checked: a vertex");
            let cells: f64 = (0..3)
                .map(|k| (self.grid.cell(k, hi[k]) as f64 - self.grid.cell(k, lo[k]) as f64) + 1.0)
                .product();
            if cells <= self.limit.voxels as f64 {
                self.stop = None;
            }
            if self.stop.is_none() && mesh.normals.is_none() && normals.is_none() {
                self.stop = Some(Pass::NeedsNormals);
            }
            if self.stop.is_some() {
                return Err(GeometryError::Arguments("the pass stops".into()));
            }
            self.has_colors = mesh.colors.is_some();
            self.checked = true;
        }
        check_indices(chunk, first, nv).map_err(|e| e.in_file(path))?;
        let nrm = mesh.normals.as_deref().or(normals).expect("checked");
        let mut rec = Vec::with_capacity(record_bytes(self.has_colors));
        self.stats.triangles_in += chunk.len();
        for tri in chunk {
            let Some(cells) = TriangleCells::of(&self.grid, tri, &mesh.positions) else {
                self.stats.degenerate_removed += 1;
                continue;
            };
            self.stats.area += cells.area;
            // a safety net: the voxels were counted, or the mesh's bounds cannot hold too many
            let span = cells.span;
            if span > self.limit.voxels {
                let (grid, area) = (&self.grid, self.stats.area);
                return Err(too_many_voxels(grid, area, span, span, self.limit));
            }
            rec.clear();
            for &i in tri {
                let i = i as usize;
                rec.extend_from_slice(&(i as u32).to_le_bytes());
                push_f32(&mut rec, &mesh.positions[i]);
                push_f32(&mut rec, &nrm[i]);
                if let Some(c) = &mesh.colors {
                    push_f32(&mut rec, &c[i]);
                }
            }
            for v in cells.voxels() {
                self.push(v, &rec)?;
            }
            if self.bins.len() as u64 > self.limit.voxels {
                let (grid, area, found) = (&self.grid, self.stats.area, self.bins.len() as u64);
                return Err(too_many_voxels(grid, area, found, span, self.limit));
            }
        }
        Ok(())
    }

    /// Appends a record to voxel `v`'s buffer, writing buffers out when they are full.
    fn push(&mut self, v: VoxelId, rec: &[u8]) -> Result<(), GeometryError> {
        let bin = self.bins.entry(v).or_default();
        bin.buf.extend_from_slice(rec);
        bin.count += 1;
        self.buffered += rec.len();
        self.stats.max_buffered_bytes = self.stats.max_buffered_bytes.max(self.buffered);
        if bin.buf.len() >= VOXEL_BUFFER {
            self.buffered -= bin.buf.len();
            append(self.dir, v, std::mem::take(&mut bin.buf))?;
        }
        if self.buffered >= SPILL_BUFFERS {
            self.flush_all()?;
        }
        Ok(())
    }

    /// Writes every buffer out.
    fn flush_all(&mut self) -> Result<(), GeometryError> {
        for (v, bin) in self.bins.iter_mut() {
            if !bin.buf.is_empty() {
                append(self.dir, *v, std::mem::take(&mut bin.buf))?;
            }
        }
        self.buffered = 0;
        Ok(())
    }
}

/// The refusal of a lattice too fine for the surface read so far: `area` m^2 of it gives at
/// least `found` voxels (one triangle's box spanning `span`), more than `limit` allows.
fn too_many_voxels(
    grid: &VoxelGrid,
    area: f64,
    found: u64,
    span: u64,
    limit: &VoxelLimit,
) -> GeometryError {
    let (size, limit) = (grid.size, limit.describe());
    GeometryError::TooLarge {
        what: format!(
            "a {size} m voxel over {area:.3} m^2 of surface (so far) gives at least {found} voxels (one triangle spanning {span}; {limit}): choose a larger --voxel"
        ),
    }
}

/// Counts the voxels binning will give the mesh at `path` (those of its non-degenerate
/// triangles' boxes), in a pass that writes nothing, and refuses as soon as they pass
/// `limit`: a lattice far too fine is refused in seconds, before millions of spill files.
fn count_voxels(path: &Path, grid: &VoxelGrid, limit: &VoxelLimit) -> Result<(), GeometryError> {
    let mut count = VoxelCount::new(grid, limit);
    let mut checked = false;
    let mut sink = |mesh: &TriMesh, first: usize, chunk: &[[u32; 3]]| {
        if !checked {
            check_vertex_table(path, mesh)?;
            checked = true;
        }
        check_indices(chunk, first, mesh.positions.len()).map_err(|e| e.in_file(path))?;
        chunk
            .iter()
            .try_for_each(|tri| count.add(tri, &mesh.positions))
    };
    read_chunked(path, &mut sink).map(|_| ())
}

/// [`count_voxels`] of a mesh in memory (checked): the voxels of its non-degenerate triangles'
/// boxes, at least those [`crate::voxel::partition`] gives it, refused as soon as they pass
/// `limit`.
pub(crate) fn count_mesh_voxels(
    mesh: &TriMesh,
    grid: &VoxelGrid,
    limit: &VoxelLimit,
) -> Result<u64, GeometryError> {
    let mut count = VoxelCount::new(grid, limit);
    for tri in &mesh.indices {
        count.add(tri, &mesh.positions)?;
    }
    Ok(count.seen.len() as u64)
}

/// The voxels of the triangles' boxes seen so far, and their area.
struct VoxelCount<'a> {
    grid: &'a VoxelGrid,
    limit: &'a VoxelLimit,
    seen: std::collections::HashSet<VoxelId>,
    area: f64,
}

impl<'a> VoxelCount<'a> {
    fn new(grid: &'a VoxelGrid, limit: &'a VoxelLimit) -> Self {
        let seen = Default::default();
        VoxelCount {
            grid,
            limit,
            seen,
            area: 0.0,
        }
    }

    /// Adds triangle `tri`'s box (a degenerate one adds nothing); refuses past the limit.
    fn add(&mut self, tri: &[u32; 3], positions: &[[f32; 3]]) -> Result<(), GeometryError> {
        let (grid, limit) = (self.grid, self.limit);
        let Some(cells) = TriangleCells::of(grid, tri, positions) else {
            return Ok(());
        };
        self.area += cells.area;
        if cells.span > limit.voxels {
            return Err(too_many_voxels(
                grid, self.area, cells.span, cells.span, limit,
            ));
        }
        self.seen.extend(cells.voxels());
        let found = self.seen.len() as u64;
        if found > limit.voxels {
            return Err(too_many_voxels(grid, self.area, found, cells.span, limit));
        }
        Ok(())
    }
}

/// A non-degenerate triangle's area and the box of voxels it spans, the one per-triangle step
/// of the binner and of the voxel count.
struct TriangleCells {
    area: f64,
    lo: VoxelId,
    hi: VoxelId,
    /// The voxels in the box.
    span: u64,
}

impl TriangleCells {
    /// Triangle `tri` (indices into `positions`, checked) on `grid`; `None` when it is
    /// degenerate: a repeated index, or no area (NaN included).
    fn of(grid: &VoxelGrid, tri: &[u32; 3], positions: &[[f32; 3]]) -> Option<TriangleCells> {
        let p = tri.map(|i| positions[i as usize]);
        let area = tri_area(p[0], p[1], p[2]);
        if tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2] || !(area > 0.0) {
            return None;
        }
        let (lo, hi) = cell_box(grid, p);
        let span = (0..3).map(|k| (hi[k] - lo[k]) as u64 + 1).product();
        Some(TriangleCells { area, lo, hi, span })
    }

    /// Every voxel of the box.
    fn voxels(&self) -> impl Iterator<Item = VoxelId> {
        let (lo, hi) = (self.lo, self.hi);
        (lo[0]..=hi[0]).flat_map(move |a| {
            (lo[1]..=hi[1]).flat_map(move |b| (lo[2]..=hi[2]).map(move |c| [a, b, c]))
        })
    }
}

/// The vertex table's checks of [`TriMesh::validate`] (errors name the file).
fn check_vertex_table(path: &Path, mesh: &TriMesh) -> Result<(), GeometryError> {
    if mesh.positions.is_empty() {
        return Err(GeometryError::from(MeshInvariant::Empty {
            vertices: 0,
            triangles: 0,
        })
        .in_file(path));
    }
    mesh.validate_vertices().map_err(|e| e.in_file(path))
}

/// The first pass over a mesh without normals: the area-weighted vertex normals
/// ([`TriMesh::compute_vertex_normals`]) summed chunk by chunk.
fn normals_pass(path: &Path) -> Result<Vec<[f32; 3]>, GeometryError> {
    let mut acc: Vec<[f64; 3]> = Vec::new();
    let mut sink = |mesh: &TriMesh, first: usize, chunk: &[[u32; 3]]| {
        if acc.is_empty() {
            check_vertex_table(path, mesh)?;
            acc = vec![[0.0; 3]; mesh.positions.len()];
        }
        check_indices(chunk, first, mesh.positions.len()).map_err(|e| e.in_file(path))?;
        accumulate_face_normals(&mesh.positions, chunk, &mut acc);
        Ok(())
    };
    read_chunked(path, &mut sink)?;
    Ok(finish_normals(acc))
}

/// Reads a `.ply` (streamed) or `.obj` (read whole, then handed over) mesh, giving its faces to
/// `sink` in chunks; returns the vertex table.
fn read_chunked(path: &Path, sink: crate::ply::FaceSink) -> Result<TriMesh, GeometryError> {
    match path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .as_deref()
    {
        Some("ply") => crate::ply::read_ply_chunked(path, sink),
        Some("obj") => {
            let mut mesh = crate::obj::read_obj(path)?;
            let indices = std::mem::take(&mut mesh.indices);
            for (c, chunk) in indices.chunks(crate::ply::FACE_CHUNK).enumerate() {
                sink(&mesh, c * crate::ply::FACE_CHUNK, chunk)?;
            }
            Ok(mesh)
        }
        _ => Err(GeometryError::UnknownFormat {
            path: path.to_path_buf(),
        }),
    }
}

/// Bytes of one spilled triangle: per corner the source vertex index, position, normal (and
/// colour).
fn record_bytes(has_colors: bool) -> usize {
    3 * (4 + 12 + 12 + if has_colors { 12 } else { 0 })
}

fn push_f32(rec: &mut Vec<u8>, v: &[f32; 3]) {
    for x in v {
        rec.extend_from_slice(&x.to_le_bytes());
    }
}

/// One spilled triangle.
fn decode(r: &[u8], has_colors: bool) -> [CV; 3] {
    let word = |o: usize| u32::from_le_bytes(r[o..o + 4].try_into().expect("4 bytes"));
    let vec3 = |o: usize| [0, 1, 2].map(|k| f32::from_bits(word(o + 4 * k)));
    let corner = 4 + 12 + 12 + if has_colors { 12 } else { 0 };
    [0, 1, 2].map(|k| {
        let o = k * corner;
        CV {
            src: word(o),
            p: vec3(o + 4),
            n: vec3(o + 16),
            c: if has_colors { vec3(o + 28) } else { [0.0; 3] },
        }
    })
}

/// The triangles as an unwelded mesh (three vertices each), for the repair's position keys.
fn soup(tris: &[[CV; 3]]) -> TriMesh {
    TriMesh {
        positions: tris.iter().flat_map(|t| t.map(|c| c.p)).collect(),
        indices: (0..tris.len() as u32)
            .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
            .collect(),
        ..Default::default()
    }
}

fn spill_file(dir: &Path, v: VoxelId) -> PathBuf {
    dir.join(format!("{}_{}_{}.bin", v[0], v[1], v[2]))
}

/// Appends `buf` to voxel `v`'s spill file.
fn append(dir: &Path, v: VoxelId, buf: Vec<u8>) -> Result<(), GeometryError> {
    let path = spill_file(dir, v);
    let mut f = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(&path)
        .map_err(|e| GeometryError::io(&path, e))?;
    f.write_all(&buf).map_err(|e| GeometryError::io(&path, e))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::job::{prepare_file, prepare_file_in_memory, PrepareRequest};
    use crate::procedural::{colonnade_field, colonnade_site};
    use std::collections::BTreeMap;

    /// Every file under `dir` (but the lock) with its bytes, by relative path.
    fn tree(dir: &Path) -> BTreeMap<String, Vec<u8>> {
        let mut out = BTreeMap::new();
        let mut stack = vec![dir.to_path_buf()];
        while let Some(d) = stack.pop() {
            for e in std::fs::read_dir(&d).unwrap() {
                let p = e.unwrap().path();
                if p.is_dir() {
                    stack.push(p);
                } else if !p.ends_with(".igi-lock") {
                    let rel = p.strip_prefix(dir).unwrap().display().to_string();
                    out.insert(rel, std::fs::read(&p).unwrap());
                }
            }
        }
        out
    }

    /// The colonnade's parts as one site mesh and the terrain.
    fn site(parts: Vec<(String, TriMesh)>) -> (TriMesh, TriMesh) {
        let mut site = TriMesh::default();
        let mut terrain = TriMesh::default();
        for (name, m) in parts {
            if name == "terrain" {
                terrain = m;
            } else {
                site.append(&m);
            }
        }
        (site, terrain)
    }

    fn request(mesh: &Path, terrain: &Path, out: &Path) -> PrepareRequest {
        PrepareRequest {
            mesh: mesh.to_path_buf(),
            terrain: Some(terrain.to_path_buf()),
            output: out.to_path_buf(),
            voxel: 1.3,
            origin: "0.1,-0.2,0.05".into(),
            atlas: 64,
            levels: "1.0,0.3,0.1".into(),
            restart: false,
            max_memory_gib: 8.0,
        }
    }

    #[test]
    fn a_streamed_site_is_the_in_memory_site_byte_for_byte() {
        let tmp = tempfile::tempdir().unwrap();
        let (mut mesh, terrain) = site(colonnade_site(3, 2));
        let t_path = tmp.path().join("terrain.ply");
        crate::write_ply(&t_path, &terrain).unwrap();
        // a duplicate (reversed, unwelded copy), a repeated one and two degenerate triangles,
        // so the repair has something to count in the voxels' shares
        let n = mesh.indices.len();
        let [a, b, c] = mesh.indices[n / 2];
        let base = mesh.positions.len() as u32;
        for i in [c, b, a] {
            mesh.positions.push(mesh.positions[i as usize]);
            mesh.normals.as_mut().unwrap().push([0.0, 0.0, 1.0]);
            mesh.uvs.as_mut().unwrap().push([0.0, 0.0]);
        }
        mesh.indices.extend([
            [base, base + 1, base + 2],
            mesh.indices[7],
            [a, a, b],
            [a, b, a],
        ]);
        let with_normals = tmp.path().join("site.ply");
        crate::write_ply(&with_normals, &mesh).unwrap();
        // the same without normals (and without the duplicates, whose normals differ, see the
        // module's overview): the normals are summed in a first pass
        mesh.indices.truncate(n);
        mesh.normals = None;
        let without = tmp.path().join("bare.ply");
        crate::write_ply(&without, &mesh).unwrap();
        for (i, m) in [&with_normals, &without].into_iter().enumerate() {
            let streamed = tmp.path().join(format!("streamed{i}.igi"));
            let whole = tmp.path().join(format!("whole{i}.igi"));
            let s = prepare_file(&request(m, &t_path, &streamed), &|_| {}).unwrap();
            let w = prepare_file_in_memory(&request(m, &t_path, &whole), &|_| {}).unwrap();
            assert!(s.manifest.voxels.len() > 20, "{}", s.manifest.voxels.len());
            if i == 0 {
                let r = &s.manifest.repair;
                assert_eq!((r.degenerate_removed, r.duplicate_removed), (2, 2), "{r:?}");
            }
            assert_eq!(s.manifest.repair, w.manifest.repair);
            let (ts, tw) = (tree(&streamed), tree(&whole));
            assert_eq!(ts.keys().collect::<Vec<_>>(), tw.keys().collect::<Vec<_>>());
            for (k, v) in &ts {
                assert!(v == &tw[k], "{k} differs");
            }
            // the spill folder is gone
            let left: Vec<_> = std::fs::read_dir(tmp.path())
                .unwrap()
                .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                .filter(|n| n.contains("spill"))
                .collect();
            assert!(left.is_empty(), "{left:?}");
        }
    }

    #[test]
    fn a_killed_runs_spill_folder_is_removed_and_bad_input_leaves_none() {
        let tmp = tempfile::tempdir().unwrap();
        let (mesh, terrain) = site(colonnade_site(1, 1));
        let (m, t) = (tmp.path().join("s.ply"), tmp.path().join("t.ply"));
        crate::write_ply(&m, &mesh).unwrap();
        crate::write_ply(&t, &terrain).unwrap();
        // a spill folder of a process that no longer runs (pid beyond the kernel's limit)
        let dead = tmp.path().join(".out.igi.spill-2147483647");
        std::fs::create_dir(&dead).unwrap();
        std::fs::write(dead.join("0_0_0.bin"), [0u8; 84]).unwrap();
        let out = tmp.path().join("out.igi");
        prepare_file(&request(&m, &t, &out), &|_| {}).unwrap();
        assert!(!dead.exists());
        // an index out of range: refused by name, no output and no spill folder left
        let b = tmp.path().join("bad.ply");
        let text = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 7 2\n";
        std::fs::write(&b, text).unwrap();
        let e = prepare_file(&request(&b, &t, &tmp.path().join("bad.igi")), &|_| {})
            .unwrap_err()
            .to_string();
        assert!(e.contains("bad.ply") && e.contains("triangle 1"), "{e}");
        let left: Vec<_> = std::fs::read_dir(tmp.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.contains("spill") || n.starts_with("bad.igi"))
            .collect();
        assert!(left.is_empty(), "{left:?}");
    }

    /// The voxel limit is exact: a site binned within a limit of its own voxel count (which
    /// the cells of its bounds pass, so the counting pass runs) gives the voxels it gives
    /// without a limit; one voxel fewer is refused, naming the limit, before a file is written.
    #[test]
    fn the_voxel_limit_is_counted_exactly_before_anything_is_written() {
        let tmp = tempfile::tempdir().unwrap();
        let (mesh, _) = site(colonnade_site(1, 1));
        let path = tmp.path().join("site.ply");
        crate::write_ply(&path, &mesh).unwrap();
        let grid = VoxelGrid::new([0.0; 3], 0.5).unwrap();
        let max = VoxelLimit::max();
        let free = SiteSpill::bin(&path, &grid, &max, &tmp.path().join("a")).unwrap();
        let n = free.voxel_ids().len() as u64;
        let (lo, hi) = mesh.bounds().unwrap();
        let cells: i64 = (0..3)
            .map(|k| (grid.cell(k, hi[k]) - grid.cell(k, lo[k]) + 1) as i64)
            .product();
        assert!(cells as u64 > n && n > 10, "{cells} cells, {n} voxels");
        let limit = |n| VoxelLimit::max().at_most(n, || "the test's".into());
        let exact = SiteSpill::bin(&path, &grid, &limit(n), &tmp.path().join("b")).unwrap();
        assert_eq!(exact.voxel_ids(), free.voxel_ids());
        let e = SiteSpill::bin(&path, &grid, &limit(n - 1), &tmp.path().join("c"))
            .err()
            .expect("refused")
            .to_string();
        assert!(e.contains(&format!("limit {}", n - 1)), "{e}");
        assert!(!tmp.path().join("c").exists());
    }

    #[test]
    fn the_largest_chunk_in_memory_does_not_grow_with_the_site() {
        // one colonnade against a 3 x 3 field of them 20 m apart, on 5 m voxels (20 m is four
        // voxels, so every colonnade is cut alike): 9 times the triangles, the same largest voxel
        let tmp = tempfile::tempdir().unwrap();
        let grid = VoxelGrid::new([0.0; 3], 5.0).unwrap();
        let mut stats = Vec::new();
        for g in [1, 3] {
            let (mesh, _) = site(colonnade_field(1, 6, g));
            let path = tmp.path().join(format!("field{g}.ply"));
            crate::write_ply(&path, &mesh).unwrap();
            let spill = SiteSpill::bin(
                &path,
                &grid,
                &VoxelLimit::max(),
                &tmp.path().join(format!("spill{g}")),
            )
            .unwrap();
            stats.push(spill.stats().clone());
        }
        let (one, nine) = (&stats[0], &stats[1]);
        eprintln!("{one:?}\n{nine:?}");
        assert_eq!(nine.triangles_in, 9 * one.triangles_in);
        assert!(one.triangles_in > 100_000, "{}", one.triangles_in);
        assert!(
            nine.spilled_triangles >= 9 * one.spilled_triangles - 9 * one.spilled_triangles / 100
        );
        // the most one voxel's work reads: the same voxel content at 9 times the site
        let ratio = nine.largest_voxel_triangles as f64 / one.largest_voxel_triangles as f64;
        assert!((0.98..=1.02).contains(&ratio), "{ratio}");
        assert!(one.largest_voxel_triangles * 4 < one.spilled_triangles);
        // the spill buffers stay under their cap (plus a voxel's buffer) at any site size
        for s in &stats {
            assert!(s.max_buffered_bytes <= SPILL_BUFFERS + VOXEL_BUFFER + s.record_bytes);
        }
    }
}
