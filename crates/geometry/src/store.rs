//! The prepared-site store: voxel levels, atlases and caches on disk, and the loader.
//!
//! Layout of a site folder:
//! ```text
//! site.igi/manifest.json            bounds, grid, counts per level, texel sizes, coverage
//! site.igi/run.json                 run manifest: input fingerprints and options (for resuming)
//! site.igi/voxels/I_J_K/level0.ply  binary PLY per level (0 = full resolution), with atlas UVs
//! site.igi/voxels/I_J_K/position.exr, normal.exr, coverage.exr   texel caches
//! site.igi/voxels/I_J_K/done.json   written last: the voxel's statistics
//! site.igi/terrain/...              the same for the optional terrain mesh (not voxelized)
//! ```
//! Every file is written atomically; a voxel whose `done.json` and level files exist is skipped
//! when `prepare` runs again on the same folder with the same run manifest (the same source
//! files, by content hash, and the same options; see `igi_files::run`). A different one is
//! refused with the differing option named, unless the run asks to restart. Temporary files of
//! killed runs are removed on resume. A running prepare holds the folder's lock
//! (`site.igi/.igi-lock`, `igi_files::FolderLock`): a second prepare on the same folder
//! meanwhile is refused.

use crate::atlas::{build_atlas, AtlasOptions};
use crate::error::GeometryError;
use crate::levels::simplify;
use crate::mesh::TriMesh;
use crate::repair::RepairReport;
use crate::stream::{SiteSpill, SpillStats};
use crate::voxel::{partition, VoxelGrid, VoxelId, VoxelLimit};
use igi_files::run::RUN_FILE;
use igi_files::RunManifest;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Options of [`prepare`].
#[derive(Clone, Debug)]
pub struct PrepareOptions {
    pub grid: VoxelGrid,
    pub atlas: AtlasOptions,
    /// Triangle fractions per level, first = 1.0 (full resolution), decreasing.
    pub levels: Vec<f64>,
    /// Refuse runs estimated to need more memory than this, in bytes.
    pub max_memory: u64,
}

impl Default for PrepareOptions {
    fn default() -> Self {
        PrepareOptions {
            grid: VoxelGrid {
                origin: [0.0; 3],
                size: 4.3,
            },
            atlas: AtlasOptions::default(),
            levels: vec![1.0, 0.2, 0.05],
            max_memory: DEFAULT_MAX_MEMORY,
        }
    }
}

impl PrepareOptions {
    fn check(&self) -> Result<(), GeometryError> {
        VoxelGrid::new(self.grid.origin, self.grid.size)?;
        if self.atlas.resolution < 8 || self.atlas.resolution > MAX_ATLAS {
            return Err(GeometryError::InvalidArgument(format!(
                "atlas resolution {} is outside 8..={MAX_ATLAS}",
                self.atlas.resolution
            )));
        }
        let l = &self.levels;
        if l.is_empty()
            || l[0] != 1.0
            || l.iter().any(|x| !(*x > 0.0 && *x <= 1.0))
            || l.windows(2).any(|w| w[1] >= w[0])
        {
            return Err(GeometryError::InvalidArgument(format!(
                "levels must start at 1.0 and decrease inside (0, 1], got {l:?}"
            )));
        }
        Ok(())
    }
}

/// Statistics of one stored part (a voxel or the terrain).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PartEntry {
    /// `None` for the terrain.
    pub voxel: Option<VoxelId>,
    /// Folder relative to the site folder.
    pub dir: String,
    pub triangles: Vec<usize>,
    /// Geometric error per level in metres (0 for level 0).
    pub errors: Vec<f64>,
    /// Atlas texel edge in metres.
    pub texel_size: f64,
    /// Fraction of atlas texels on the surface.
    pub coverage: f64,
    pub charts: usize,
    pub overlap_texels: usize,
    pub area: f64,
}

/// The site's `manifest.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Manifest {
    pub format: String,
    pub source: String,
    pub grid: VoxelGrid,
    pub levels: Vec<f64>,
    pub atlas_resolution: u32,
    /// (min, max) of all stored geometry.
    pub bounds: [[f32; 3]; 2],
    /// Smallest and largest voxel index per axis.
    pub voxel_range: [VoxelId; 2],
    pub repair: RepairReport,
    /// Sum over voxels per level (terrain excluded).
    pub triangles_per_level: Vec<usize>,
    pub texel_size_min: f64,
    pub texel_size_max: f64,
    pub coverage_mean: f64,
    pub voxels: Vec<PartEntry>,
    pub terrain: Option<PartEntry>,
}

/// The input files and the restart choice of a [`prepare_run`]; the files are fingerprinted
/// into the run manifest (`run.json`).
#[derive(Clone, Debug, Default)]
pub struct PrepareRun {
    /// The site mesh file (named in the manifest and fingerprinted), if it came from a file.
    pub mesh: Option<PathBuf>,
    pub terrain: Option<PathBuf>,
    /// Delete an earlier run's files in the output folder instead of resuming it.
    pub restart: bool,
}

impl PrepareRun {
    fn manifest(
        &self,
        opts: &PrepareOptions,
        has_terrain: bool,
    ) -> Result<RunManifest, GeometryError> {
        let mut m = RunManifest::new("prepare");
        let g = &opts.grid;
        m.option("--voxel", format!("{:?}", g.size))
            .option(
                "--origin",
                format!("{:?},{:?},{:?}", g.origin[0], g.origin[1], g.origin[2]),
            )
            .option("--levels", format!("{:?}", opts.levels))
            .option("--atlas", opts.atlas.resolution)
            .option("atlas gutter", opts.atlas.gutter)
            .option("--terrain", has_terrain);
        if let Some(p) = &self.mesh {
            m.input("mesh", p)?;
        }
        if let Some(p) = &self.terrain {
            m.input("terrain", p)?;
        }
        Ok(m)
    }
}

/// The files a prepare run writes into its output folder, as `igi_files::remove_own`
/// patterns: what `restart` removes (nothing else, so a user's file in `voxels/` stays).
const SITE_FILES: [&str; 13] = [
    "voxels/*_*_*/done.json",
    "voxels/*_*_*/position.exr",
    "voxels/*_*_*/normal.exr",
    "voxels/*_*_*/coverage.exr",
    "voxels/*_*_*/level*.ply",
    "terrain/done.json",
    "terrain/position.exr",
    "terrain/normal.exr",
    "terrain/coverage.exr",
    "terrain/level*.ply",
    "manifest.json",
    "settings.json",
    RUN_FILE,
];

/// Checks, before any work or output, that `out` can take this prepare run: the options are
/// valid, `out` is (or can become) a writable folder, and it is empty, or holds a run with an
/// identical manifest (resumed), or `run.restart` is set. Returns the run manifest.
pub fn check_prepare_output(
    out: &Path,
    run: &PrepareRun,
    opts: &PrepareOptions,
    has_terrain: bool,
) -> Result<RunManifest, GeometryError> {
    opts.check()?;
    igi_files::check_output_folder(out)?;
    let manifest = run.manifest(opts, has_terrain)?;
    manifest.check_folder(out, run.restart, "settings.json", "site")?;
    Ok(manifest)
}

/// Removes what an earlier prepare wrote into `out` (only the names a prepare writes).
fn remove_site_entries(out: &Path) -> Result<(), GeometryError> {
    igi_files::remove_own(out, &SITE_FILES)?;
    Ok(())
}

const FORMAT: &str = "igi-site-1";

/// The largest atlas side (texels) a prepare accepts: 16384^2 texels are 3 GiB per cache.
pub const MAX_ATLAS: u32 = 16384;

/// Bytes a prepare may use by default (see [`PrepareOptions::max_memory`]).
pub const DEFAULT_MAX_MEMORY: u64 = 8 << 30;

/// The bytes of the atlases a prepare works on at once: one atlas with its three caches per
/// worker thread (and one for the terrain).
fn atlas_bytes(opts: &PrepareOptions, has_terrain: bool) -> f64 {
    let res = opts.atlas.resolution as f64;
    let threads = rayon::current_num_threads() as f64 + f64::from(u8::from(has_terrain));
    threads * res * res * 3.0 * 16.0
}

/// The most voxels a prepare with `opts` may make: [`MAX_VOXELS`], or fewer when their
/// [`BYTES_PER_VOXEL`] beside the atlases would pass `opts.max_memory`. Binning a streamed
/// site refuses as soon as it passes this, before the rest of the mesh is read.
pub fn voxel_budget(opts: &PrepareOptions, has_terrain: bool) -> u64 {
    let room = (opts.max_memory as f64 - atlas_bytes(opts, has_terrain)).max(0.0);
    ((room / BYTES_PER_VOXEL) as u64).min(MAX_VOXELS)
}

/// The most voxels a prepare with `opts` into `out` may make: [`MAX_VOXELS`], fewer when their
/// memory would pass `opts.max_memory` ([`voxel_budget`]), and fewer when the file system of
/// `out` cannot hold their files: each voxel's spill file and its part folder (itself, the
/// atlas images, a mesh per level and `done.json`), every entry at least one block
/// ([`igi_files::disk`]), with what an interrupted run already wrote there counted as free.
/// Binning a streamed site refuses as soon as it passes this, before the spill files fill the
/// disk.
pub fn voxel_limit(
    opts: &PrepareOptions,
    has_terrain: bool,
    out: &Path,
) -> Result<VoxelLimit, GeometryError> {
    let free = igi_files::disk::free_space(out)?;
    Ok(voxel_limit_within(opts, has_terrain, out, free))
}

/// [`voxel_limit`] on a file system with `free` space.
fn voxel_limit_within(
    opts: &PrepareOptions,
    has_terrain: bool,
    out: &Path,
    free: igi_files::disk::FreeSpace,
) -> VoxelLimit {
    let limit = memory_limit(opts, has_terrain);
    let (part, per) = (part_entries(opts), part_entries(opts) + 1);
    let written = match std::fs::read_dir(out.join("voxels")) {
        Ok(dir) => dir.count() as u64 * part,
        Err(_) => 0,
    };
    let terrain = part * u64::from(has_terrain);
    let entries = free.files.saturating_add(written).saturating_sub(terrain);
    let bytes = (free.bytes / free.block)
        .saturating_add(written)
        .saturating_sub(terrain);
    let disk = entries.min(bytes) / per;
    limit.at_most(disk, || {
        format!(
            "fewer on the file system of {}: {per} files a voxel (its spill file and its part folder) of at least one {}-byte block each, beside {} free and {} free file entries",
            out.display(),
            free.block,
            igi_files::memory::show_bytes(free.bytes as u128),
            free.files,
        )
    })
}

/// [`MAX_VOXELS`], or fewer within `opts.max_memory` ([`voxel_budget`]).
fn memory_limit(opts: &PrepareOptions, has_terrain: bool) -> VoxelLimit {
    VoxelLimit::max().at_most(voxel_budget(opts, has_terrain), || {
        format!("fewer within --max-memory at {BYTES_PER_VOXEL} bytes each beside the atlases")
    })
}

/// Files and folders a part's folder holds: itself, the three atlas images, a mesh per level
/// and `done.json`.
fn part_entries(opts: &PrepareOptions) -> u64 {
    5 + opts.levels.len() as u64
}

/// Refuses, before any allocation, a prepare of a mesh in memory whose voxel count or memory
/// would explode (a voxel edge far below the mesh's scale): the voxels of the triangles' boxes
/// are counted (at least those the partition gives; refused as soon as they pass
/// [`memory_limit`]), memory estimated as the voxel pieces, [`BYTES_PER_VOXEL`] per voxel, and
/// one atlas with its three caches per worker thread.
fn check_resources(
    site: &TriMesh,
    terrain: Option<&TriMesh>,
    opts: &PrepareOptions,
) -> Result<(), GeometryError> {
    let limit = memory_limit(opts, terrain.is_some());
    let voxels = crate::stream::count_mesh_voxels(site, &opts.grid, &limit)? as f64;
    // a clipped piece: 3 indices, ~2 new vertices with position, normal and uv, per voxel crossed
    let pieces = (site.indices.len() as f64 + 4.0 * voxels) * 96.0;
    let bytes = pieces + voxels * BYTES_PER_VOXEL + atlas_bytes(opts, terrain.is_some());
    if bytes > opts.max_memory as f64 {
        return Err(GeometryError::TooLarge {
            what: format!(
                "a {} m voxel over {:.3} m^2 of surface gives {voxels} voxels and needs about {:.1} GiB (limit {:.1} GiB, see --max-memory)",
                opts.grid.size,
                site.total_area(),
                bytes / (1u64 << 30) as f64,
                opts.max_memory as f64 / (1u64 << 30) as f64
            ),
        });
    }
    Ok(())
}

pub use crate::voxel::{BYTES_PER_VOXEL, MAX_VOXELS};

fn voxel_dir(v: VoxelId) -> String {
    format!("voxels/{}_{}_{}", v[0], v[1], v[2])
}

fn level_file(l: usize) -> String {
    format!("level{l}.ply")
}

fn write_json<T: Serialize>(path: &Path, v: &T) -> Result<(), GeometryError> {
    let text = serde_json::to_string_pretty(v).expect("serialisable");
    crate::atomic::write_atomic_with(path, |w| std::io::Write::write_all(w, text.as_bytes()))
}

fn read_json<T: for<'de> Deserialize<'de>>(path: &Path) -> Result<T, GeometryError> {
    let text = std::fs::read_to_string(path).map_err(|e| GeometryError::io(path, e))?;
    serde_json::from_str(&text).map_err(|source| GeometryError::Json {
        path: path.to_path_buf(),
        source,
    })
}

fn mkdir(p: &Path) -> Result<(), GeometryError> {
    std::fs::create_dir_all(p).map_err(|e| GeometryError::io(p, e))
}

/// The entry of a part an earlier run finished (its `done.json`, levels and caches present).
fn finished_part(
    site: &Path,
    dir: &str,
    voxel: Option<VoxelId>,
    opts: &PrepareOptions,
) -> Option<PartEntry> {
    let folder = site.join(dir);
    let entry = read_json::<PartEntry>(&folder.join("done.json")).ok()?;
    let complete = (0..opts.levels.len()).all(|l| folder.join(level_file(l)).exists())
        && ["position.exr", "normal.exr", "coverage.exr"]
            .iter()
            .all(|f| folder.join(f).exists());
    (complete && entry.voxel == voxel).then_some(entry)
}

/// Atlas, caches and levels of one part, written into `site/dir`; reuses a finished part.
fn process_part(
    site: &Path,
    dir: &str,
    voxel: Option<VoxelId>,
    mesh: TriMesh,
    opts: &PrepareOptions,
) -> Result<PartEntry, GeometryError> {
    if let Some(entry) = finished_part(site, dir, voxel, opts) {
        return Ok(entry);
    }
    let folder = site.join(dir);
    let done = folder.join("done.json");
    mkdir(&folder)?;
    let area = mesh.total_area();
    let atlas = build_atlas(&mesh, opts.atlas).map_err(|e| match e {
        GeometryError::InvalidArgument(m) => GeometryError::InvalidArgument(format!("{dir}: {m}")),
        e => e,
    })?;
    drop(mesh);
    igi_imaging::write_exr(&folder.join("position.exr"), &atlas.position)?;
    igi_imaging::write_exr(&folder.join("normal.exr"), &atlas.normal)?;
    igi_imaging::write_exr(&folder.join("coverage.exr"), &atlas.coverage)?;
    let locked: Vec<bool> = match voxel {
        Some(v) => atlas
            .mesh
            .positions
            .iter()
            .map(|p| opts.grid.on_voxel_face(v, *p))
            .collect(),
        None => vec![false; atlas.mesh.positions.len()],
    };
    let mut triangles = Vec::new();
    let mut errors = Vec::new();
    for (l, &ratio) in opts.levels.iter().enumerate() {
        // open borders locked too: a border vertex next to a voxel face could otherwise collapse
        // onto it and take a boundary edge with it
        let level = simplify(&atlas.mesh, &locked, ratio, true);
        crate::ply::write_ply(&folder.join(level_file(l)), &level.mesh)?;
        triangles.push(level.mesh.indices.len());
        errors.push(level.error);
    }
    let entry = PartEntry {
        voxel,
        dir: dir.to_string(),
        triangles,
        errors,
        texel_size: atlas.texel_size,
        coverage: atlas.coverage_fraction(),
        charts: atlas.charts,
        overlap_texels: atlas.overlap_texels,
        area,
    };
    write_json(&done, &entry)?;
    Ok(entry)
}

/// Voxelize a (repaired) site mesh and write the store into `out`. `progress(done, total)` is
/// called after each part. Resumes an interrupted run with the same settings (meshes given in
/// memory are not fingerprinted; see [`prepare_run`]).
pub fn prepare(
    site: TriMesh,
    terrain: Option<TriMesh>,
    repair: RepairReport,
    out: &Path,
    source: &str,
    opts: &PrepareOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<Manifest, GeometryError> {
    let run = PrepareRun::default();
    prepare_run(site, terrain, repair, out, source, &run, opts, progress)
}

/// [`prepare`] with the source files fingerprinted into the run manifest, so that a resume on
/// another mesh or with other options is refused (or, with `run.restart`, starts afresh).
#[allow(clippy::too_many_arguments)]
pub fn prepare_run(
    site: TriMesh,
    terrain: Option<TriMesh>,
    repair: RepairReport,
    out: &Path,
    source: &str,
    run: &PrepareRun,
    opts: &PrepareOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<Manifest, GeometryError> {
    site.validate()?;
    if let Some(t) = &terrain {
        t.validate()?;
    }
    check_prepare_output(out, run, opts, terrain.is_some())?;
    check_resources(&site, terrain.as_ref(), opts)?;
    let (lo, hi) = site.bounds().expect("validated mesh has vertices");
    let bounds = combined_bounds([lo, hi], terrain.as_ref());
    let parts: Vec<(VoxelId, TriMesh)> = partition(&site, &opts.grid).into_iter().collect();
    drop(site);
    let ids: Vec<VoxelId> = parts.iter().map(|(v, _)| *v).collect();
    check_site_disk(out, &ids, terrain.is_some(), opts)?;
    let fresh = !out.exists();
    let _lock = open_site(out, run, opts, terrain.is_some())?;
    removed_on_error(out, fresh, || {
        let part = |(v, m): (VoxelId, TriMesh)| {
            process_part(out, &voxel_dir(v), Some(v), m, opts).map(Some)
        };
        let (voxels, terrain) = process_parts(out, parts, &part, terrain, opts, progress)?;
        finish_site(out, source, opts, bounds, repair, voxels, terrain)
    })
}

/// The work of a prepare on its site folder `out`: when this run created the folder
/// (`fresh`) and the work fails (charts that do not fit the atlas, a voxel that cannot be
/// written), the folder is removed, so that a refused prepare leaves nothing to block the
/// corrected retry (issue 36); a folder that held an earlier run keeps what that run and this
/// one finished, for a resume.
fn removed_on_error<T>(
    out: &Path,
    fresh: bool,
    work: impl FnOnce() -> Result<T, GeometryError>,
) -> Result<T, GeometryError> {
    let result = work();
    if result.is_err() && fresh {
        let _ = std::fs::remove_dir_all(out);
    }
    result
}

/// [`prepare_run`] of a site streamed from its mesh file through per-voxel spill files
/// ([`SiteSpill`]): each voxel is repaired, cut and prepared from its own spill file, two at a
/// time (one per worker thread), so memory follows the largest voxel, not the site. `repair`
/// is the spill's [`SiteSpill::repair_report`]. The store is the one [`prepare_run`] writes
/// for the read and repaired mesh, byte for byte (for a mesh with duplicate triangles and no
/// vertex normals, see [`crate::stream`]).
#[allow(clippy::too_many_arguments)]
pub fn prepare_streamed(
    site: &SiteSpill,
    terrain: Option<TriMesh>,
    repair: RepairReport,
    out: &Path,
    source: &str,
    run: &PrepareRun,
    opts: &PrepareOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<Manifest, GeometryError> {
    if let Some(t) = &terrain {
        t.validate()?;
    }
    check_prepare_output(out, run, opts, terrain.is_some())?;
    check_streamed_resources(
        site.stats(),
        site.voxel_ids().len(),
        terrain.is_some(),
        opts,
    )?;
    check_site_disk(out, &site.voxel_ids(), terrain.is_some(), opts)?;
    let fresh = !out.exists();
    let _lock = open_site(out, run, opts, terrain.is_some())?;
    removed_on_error(out, fresh, || {
        streamed_parts(site, terrain, repair, out, source, opts, progress)
    })
}

/// [`prepare_streamed`]'s work in its opened site folder.
fn streamed_parts(
    site: &SiteSpill,
    terrain: Option<TriMesh>,
    repair: RepairReport,
    out: &Path,
    source: &str,
    opts: &PrepareOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<Manifest, GeometryError> {
    let bounds = combined_bounds(site.stats().bounds, terrain.as_ref());
    let part = |v: VoxelId| -> Result<Option<PartEntry>, GeometryError> {
        let dir = voxel_dir(v);
        if let Some(entry) = finished_part(out, &dir, Some(v), opts) {
            return Ok(Some(entry));
        }
        match site.voxel_mesh(v)? {
            Some(m) => process_part(out, &dir, Some(v), m, opts).map(Some),
            None => Ok(None),
        }
    };
    let (voxels, terrain) = process_parts(out, site.voxel_ids(), &part, terrain, opts, progress)?;
    finish_site(out, source, opts, bounds, repair, voxels, terrain)
}

/// Creates (or resumes) the site folder `out` for a run whose settings are checked: takes
/// its lock (held until the returned guard is dropped; the folder is checked again under the
/// lock), removes an earlier run's files on restart and dead temporary files, and writes the
/// run manifest.
fn open_site(
    out: &Path,
    run: &PrepareRun,
    opts: &PrepareOptions,
    has_terrain: bool,
) -> Result<igi_files::FolderLock, GeometryError> {
    let manifest = run.manifest(opts, has_terrain)?;
    mkdir(out)?;
    // one writer at a time; the folder is checked again under the lock
    let lock = igi_files::FolderLock::acquire(out)?;
    manifest.check_folder(out, run.restart, "settings.json", "site")?;
    if run.restart {
        remove_site_entries(out)?;
    }
    mkdir(&out.join("voxels"))?;
    igi_files::remove_dead_temps(out, true)?;
    manifest.write(out)?;
    Ok(lock)
}

/// Writes the site's `manifest.json` from the parts' entries (sorted by voxel here).
#[allow(clippy::too_many_arguments)]
fn finish_site(
    out: &Path,
    source: &str,
    opts: &PrepareOptions,
    bounds: [[f32; 3]; 2],
    repair: RepairReport,
    mut voxels: Vec<PartEntry>,
    terrain: Option<PartEntry>,
) -> Result<Manifest, GeometryError> {
    voxels.sort_by_key(|e| e.voxel);
    let manifest = site_manifest(source, opts, bounds, repair, voxels, terrain);
    write_json(&out.join("manifest.json"), &manifest)?;
    Ok(manifest)
}

/// [`check_resources`] for a streamed site: the voxels its binning found, memory as the
/// largest voxel's spill (read, and cut into pieces) plus an atlas with its caches, per worker
/// thread, and [`BYTES_PER_VOXEL`] per voxel. (The vertex table held while binning is already
/// behind.)
fn check_streamed_resources(
    stats: &SpillStats,
    voxels: usize,
    has_terrain: bool,
    opts: &PrepareOptions,
) -> Result<(), GeometryError> {
    let size = opts.grid.size;
    let voxels = voxels as f64;
    let threads = rayon::current_num_threads() as f64 + f64::from(u8::from(has_terrain));
    let largest = stats.largest_voxel_triangles as f64;
    let pieces = threads * largest * (stats.record_bytes as f64 + 120.0 + 96.0);
    let bytes = pieces + voxels * BYTES_PER_VOXEL + atlas_bytes(opts, has_terrain);
    if voxels > MAX_VOXELS as f64 || bytes > opts.max_memory as f64 {
        return Err(GeometryError::TooLarge {
            what: format!(
                "a {size} m voxel over {:.3} m^2 of surface gives about {voxels:.3e} voxels (limit {MAX_VOXELS}) and needs about {:.1} GiB (limit {:.1} GiB, see --max-memory)",
                stats.area,
                bytes / (1u64 << 30) as f64,
                opts.max_memory as f64 / (1u64 << 30) as f64
            ),
        });
    }
    Ok(())
}

/// Refuses a prepare whose part folders not yet written cannot fit on the file system of
/// `out`: each is a folder of the three atlas images, a mesh per level and `done.json`, every
/// entry at least one block ([`igi_files::disk`]; on ext4 the block at `--voxel 0.05 --atlas 32`
/// takes 32,791 bytes a voxel for these 8 blocks of 4 KiB, and more at larger atlases:
/// docs/RELIABILITY.md). Folders an interrupted run finished are not counted again.
fn check_site_disk(
    out: &Path,
    voxels: &[VoxelId],
    has_terrain: bool,
    opts: &PrepareOptions,
) -> Result<(), GeometryError> {
    let (need, what) = site_disk_need(out, voxels, has_terrain, opts);
    Ok(igi_files::check_disk(out, &what, need)?)
}

/// What [`check_site_disk`] asks of the file system, and its words for it.
fn site_disk_need(
    out: &Path,
    voxels: &[VoxelId],
    has_terrain: bool,
    opts: &PrepareOptions,
) -> (igi_files::DiskNeed, String) {
    let parts = voxels.len() + usize::from(has_terrain);
    let written = match out.exists() {
        true => voxels
            .iter()
            .filter(|&&v| out.join(voxel_dir(v)).exists())
            .count(),
        false => 0,
    };
    let todo = (parts - written) as u64;
    let per = part_entries(opts);
    let need = igi_files::DiskNeed {
        entries: todo * per,
        bytes: 0,
    };
    (need, format!("{todo} part folders of {per} files each"))
}

/// Bounds of the site (`site`) and the terrain together.
fn combined_bounds(site: [[f32; 3]; 2], terrain: Option<&TriMesh>) -> [[f32; 3]; 2] {
    let [mut lo, mut hi] = site;
    if let Some((tl, th)) = terrain.and_then(|t| t.bounds()) {
        for k in 0..3 {
            lo[k] = lo[k].min(tl[k]);
            hi[k] = hi[k].max(th[k]);
        }
    }
    [lo, hi]
}

/// Process every voxel part in parallel, with the terrain (one large part) beside them;
/// `progress(done, total)` after each part.
fn process_parts<T: Send>(
    out: &Path,
    parts: Vec<T>,
    part: &(dyn Fn(T) -> Result<Option<PartEntry>, GeometryError> + Sync),
    terrain: Option<TriMesh>,
    opts: &PrepareOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<(Vec<PartEntry>, Option<PartEntry>), GeometryError> {
    let total = parts.len() + usize::from(terrain.is_some());
    let count = std::sync::atomic::AtomicUsize::new(0);
    let tick = || {
        progress(
            count.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1,
            total,
        )
    };
    let (voxels, terrain) = rayon::join(
        || {
            parts
                .into_par_iter()
                .map(|p| {
                    let r = part(p);
                    tick();
                    r
                })
                .filter_map(Result::transpose)
                .collect::<Result<Vec<PartEntry>, _>>()
        },
        || -> Result<Option<PartEntry>, GeometryError> {
            match terrain {
                Some(t) => {
                    mkdir(&out.join("terrain"))?;
                    let e = process_part(out, "terrain", None, t, opts)?;
                    tick();
                    Ok(Some(e))
                }
                None => Ok(None),
            }
        },
    );
    let voxels = voxels?;
    let terrain = terrain?;
    Ok((voxels, terrain))
}

/// The site manifest: settings, bounds, the voxel range and the parts' totals.
fn site_manifest(
    source: &str,
    opts: &PrepareOptions,
    bounds: [[f32; 3]; 2],
    repair: RepairReport,
    voxels: Vec<PartEntry>,
    terrain: Option<PartEntry>,
) -> Manifest {
    let mut vr = [[i32::MAX; 3], [i32::MIN; 3]];
    for e in &voxels {
        let v = e.voxel.unwrap();
        for k in 0..3 {
            vr[0][k] = vr[0][k].min(v[k]);
            vr[1][k] = vr[1][k].max(v[k]);
        }
    }
    let triangles_per_level = (0..opts.levels.len())
        .map(|l| voxels.iter().map(|e| e.triangles[l]).sum())
        .collect();
    let all = voxels.iter().chain(terrain.iter());
    let texel_size_min = all
        .clone()
        .map(|e| e.texel_size)
        .fold(f64::INFINITY, f64::min);
    let texel_size_max = all.clone().map(|e| e.texel_size).fold(0.0, f64::max);
    let n = all.clone().count().max(1) as f64;
    let coverage_mean = all.map(|e| e.coverage).sum::<f64>() / n;
    Manifest {
        format: FORMAT.to_string(),
        source: source.to_string(),
        grid: opts.grid,
        levels: opts.levels.clone(),
        atlas_resolution: opts.atlas.resolution,
        bounds,
        voxel_range: vr,
        repair,
        triangles_per_level,
        texel_size_min,
        texel_size_max,
        coverage_mean,
        voxels,
        terrain,
    }
}

/// One mesh loaded from the store.
pub struct LoadedPart {
    /// `None` for the terrain.
    pub voxel: Option<VoxelId>,
    pub level: usize,
    pub mesh: TriMesh,
}

/// What a site's manifest must hold for its parts to be read: at least one level, and every
/// part's folder inside the site (a relative path without `..`).
fn check_manifest(m: &Manifest) -> Result<(), String> {
    if m.levels.is_empty() {
        return Err("lists no levels".into());
    }
    let inside = |dir: &str| {
        let p = Path::new(dir);
        !dir.is_empty()
            && p.components()
                .all(|c| matches!(c, std::path::Component::Normal(_)))
    };
    match m.voxels.iter().chain(&m.terrain).find(|e| !inside(&e.dir)) {
        Some(e) => Err(format!(
            "part folder {:?} is not a folder inside the site",
            e.dir
        )),
        None => Ok(()),
    }
}

/// A prepared site on disk.
pub struct SiteStore {
    dir: PathBuf,
    manifest: Manifest,
}

impl SiteStore {
    /// Open a site folder (reads `manifest.json` only).
    pub fn open(dir: &Path) -> Result<SiteStore, GeometryError> {
        let path = dir.join("manifest.json");
        if !path.exists() {
            return Err(GeometryError::format(
                dir,
                "not a prepared site (no manifest.json; run `igi prepare`)",
            ));
        }
        let manifest: Manifest = read_json(&path)?;
        if manifest.format != FORMAT {
            return Err(GeometryError::format(
                &path,
                format!("unknown site format `{}`", manifest.format),
            ));
        }
        check_manifest(&manifest).map_err(|msg| GeometryError::format(&path, msg))?;
        Ok(SiteStore {
            dir: dir.to_path_buf(),
            manifest,
        })
    }

    pub fn manifest(&self) -> &Manifest {
        &self.manifest
    }

    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The non-empty voxels, sorted.
    pub fn voxel_ids(&self) -> Vec<VoxelId> {
        self.manifest
            .voxels
            .iter()
            .filter_map(|e| e.voxel)
            .collect()
    }

    fn entry(&self, v: VoxelId) -> Result<&PartEntry, GeometryError> {
        self.manifest
            .voxels
            .iter()
            .find(|e| e.voxel == Some(v))
            .ok_or_else(|| {
                GeometryError::InvalidArgument(format!("voxel {v:?} is empty or outside the site"))
            })
    }

    /// Folder of a voxel (its level PLYs and `position.exr`, `normal.exr`, `coverage.exr`).
    pub fn voxel_folder(&self, v: VoxelId) -> Result<PathBuf, GeometryError> {
        Ok(self.dir.join(&self.entry(v)?.dir))
    }

    /// Folder of the terrain, if the site has one.
    pub fn terrain_folder(&self) -> Option<PathBuf> {
        self.manifest
            .terrain
            .as_ref()
            .map(|e| self.dir.join(&e.dir))
    }

    /// Read one voxel at one level (0 = full resolution).
    pub fn load_voxel(&self, v: VoxelId, level: usize) -> Result<TriMesh, GeometryError> {
        let level = level.min(self.manifest.levels.len() - 1);
        crate::ply::read_ply(&self.voxel_folder(v)?.join(level_file(level)))
    }

    /// What the solver of voxel `v` needs: `v` at level 0, its 26 neighbours at
    /// `neighbour_level` (1 in the paper's load; 0 for a distributed Jacobi iteration), every
    /// other voxel and the terrain at the lowest level. Reads only those files.
    pub fn load_for_voxel(
        &self,
        v: VoxelId,
        neighbour_level: usize,
    ) -> Result<Vec<LoadedPart>, GeometryError> {
        self.entry(v)?;
        let low = self.manifest.levels.len() - 1;
        self.load_with(&|u| match u {
            Some(u) => match (0..3).map(|k| (u[k] - v[k]).abs()).max().unwrap() {
                0 => 0,
                1 => neighbour_level.min(low),
                _ => low,
            },
            None => low,
        })
    }

    /// What the solver of the terrain needs: the terrain at level 0 and every voxel at level 1
    /// (the buildings that shadow it).
    pub fn load_for_terrain(&self) -> Result<Vec<LoadedPart>, GeometryError> {
        if self.manifest.terrain.is_none() {
            return Err(GeometryError::InvalidArgument(
                "the site has no terrain".into(),
            ));
        }
        let medium = 1.min(self.manifest.levels.len() - 1);
        self.load_with(&|u| if u.is_some() { medium } else { 0 })
    }

    /// Every stored part (the voxels in [`voxel_ids`](Self::voxel_ids) order, then the
    /// terrain) at the level `level_of` gives it (clamped to the stored levels).
    pub fn load_with(
        &self,
        level_of: &(dyn Fn(Option<VoxelId>) -> usize + Sync),
    ) -> Result<Vec<LoadedPart>, GeometryError> {
        let last = self.manifest.levels.len() - 1;
        let ids = self.voxel_ids();
        let mut out: Vec<LoadedPart> = ids
            .par_iter()
            .map(|&u| {
                let level = level_of(Some(u)).min(last);
                Ok(LoadedPart {
                    voxel: Some(u),
                    level,
                    mesh: self.load_voxel(u, level)?,
                })
            })
            .collect::<Result<_, GeometryError>>()?;
        if let Some(t) = self.terrain_folder() {
            let level = level_of(None).min(last);
            out.push(LoadedPart {
                voxel: None,
                level,
                mesh: crate::ply::read_ply(&t.join(level_file(level)))?,
            });
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    /// Files and folders under `dir`, recursively.
    fn entries_under(dir: &Path) -> u64 {
        std::fs::read_dir(dir)
            .unwrap()
            .map(|e| {
                let e = e.unwrap();
                1 + if e.file_type().unwrap().is_dir() {
                    entries_under(&e.path())
                } else {
                    0
                }
            })
            .sum()
    }

    /// The in-memory prepare counts its voxels as the streamed one does: at least the voxels
    /// the partition gives (the area-over-face estimate it replaced was no bound), exactly
    /// refused one below its count, and a prepare whose memory limit is below it is refused
    /// before anything is written.
    #[test]
    fn the_in_memory_voxel_count_bounds_the_partition_and_is_refused_exactly() {
        let site = bunny();
        let grid = VoxelGrid::new([0.0; 3], 0.5).unwrap();
        let n = crate::stream::count_mesh_voxels(&site, &grid, &VoxelLimit::max()).unwrap();
        let parts = partition(&site, &grid).len() as u64;
        let estimate = site.total_area() / 0.25;
        eprintln!("boxes {n}, partition {parts}, area over face {estimate:.1}");
        assert!(n >= parts && parts > 100, "{n} {parts}");
        let below = VoxelLimit::max().at_most(n - 1, || "the test's".into());
        let e = crate::stream::count_mesh_voxels(&site, &grid, &below).unwrap_err();
        assert!(e.to_string().contains(&format!("limit {}", n - 1)), "{e}");
        let opts = PrepareOptions {
            grid,
            max_memory: (atlas_bytes(&PrepareOptions::default(), false) + 100.0 * BYTES_PER_VOXEL)
                as u64,
            ..Default::default()
        };
        let d = tempfile::tempdir().unwrap();
        let out = d.path().join("site.igi");
        let (site, rep) = crate::repair::repair(&site);
        let e = prepare(site, None, rep, &out, "bunny", &opts, &|_, _| {}).unwrap_err();
        assert!(e.to_string().contains("--max-memory"), "{e}");
        assert!(!out.exists());
    }

    /// The voxel limit on a small file system (20 MiB and 1999 file entries free, as a tmpfs
    /// mounted with `size=20m,nr_inodes=2000`): 9 entries a voxel at three levels, so 222 voxels
    /// (1999 / 9) where the blocks would allow 568 (5120 / 9); 2 TiB of blocks and unlimited
    /// entries leave the memory budget in charge; an interrupted run's part folders count as
    /// free; the terrain's folder is taken first.
    #[test]
    fn the_voxel_limit_follows_the_file_entries_and_blocks_the_output_has() {
        let opts = PrepareOptions::default();
        let small = igi_files::disk::FreeSpace {
            bytes: 20 << 20,
            files: 1999,
            block: 4096,
        };
        let d = tempfile::tempdir().unwrap();
        let out = d.path().join("site.igi");
        let l = voxel_limit_within(&opts, false, &out, small);
        assert_eq!(l.voxels, 1999 / 9);
        assert!(
            l.describe()
                .contains("limit 222: 10000000 at most, and fewer on the file system of")
                && l.why.contains("9 files a voxel")
                && l.why.contains("1999 free file entries"),
            "{}",
            l.describe()
        );
        let blocks = igi_files::disk::FreeSpace {
            files: u64::MAX,
            ..small
        };
        assert_eq!(
            voxel_limit_within(&opts, false, &out, blocks).voxels,
            5120 / 9
        );
        assert_eq!(
            voxel_limit_within(&opts, true, &out, blocks).voxels,
            (5120 - 8) / 9
        );
        let roomy = igi_files::disk::FreeSpace {
            bytes: 2 << 40,
            files: u64::MAX,
            block: 4096,
        };
        assert_eq!(
            voxel_limit_within(&opts, false, &out, roomy).voxels,
            voxel_budget(&opts, false)
        );
        for v in 0..10 {
            std::fs::create_dir_all(out.join("voxels").join(format!("{v}_0_0"))).unwrap();
        }
        let resumed = voxel_limit_within(&opts, false, &out, small);
        assert_eq!(resumed.voxels, (1999 + 10 * 8) / 9);
    }

    /// The disk check asks for the part folders a prepare writes, entry for entry (the bunny
    /// over several voxels of 4.3 m), and for none of those an interrupted run finished.
    #[test]
    fn the_disk_check_counts_every_file_and_folder_a_prepare_writes() {
        let site = bunny();
        let opts = PrepareOptions {
            atlas: AtlasOptions {
                resolution: 128,
                gutter: 2,
            },
            ..Default::default()
        };
        let ids: Vec<VoxelId> = partition(&site, &opts.grid).into_keys().collect();
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("site.igi");
        let (need, what) = site_disk_need(&out, &ids, false, &opts);
        let (site, rep) = crate::repair::repair(&site);
        prepare(site, None, rep, &out, "bunny", &opts, &|_, _| {}).unwrap();
        let written = entries_under(&out.join("voxels"));
        assert_eq!((need.entries, need.bytes), (written, 0), "{what}");
        assert!(ids.len() > 1 && what.starts_with(&format!("{} part folders", ids.len())));
        let (again, _) = site_disk_need(&out, &ids, false, &opts);
        assert_eq!(
            again.entries, 0,
            "a resume asks nothing for finished folders"
        );
    }

    fn bunny() -> TriMesh {
        let p = Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../../shared/data/meshes/stanford_bunny/reconstruction/bun_zipper_res2.ply"
        ));
        let mut m = crate::read_mesh(p).unwrap();
        // about 0.155 m across: scale by 60 so it spans 2-3 voxels of 4.3 m per axis
        for q in &mut m.positions {
            *q = q.map(|x| x * 60.0);
        }
        m
    }

    type Edge = [[u32; 3]; 2];

    /// Border edges (used by one triangle, by position) of a mesh that lie in the plane.
    fn border_edges_on_plane(m: &TriMesh, axis: usize, plane: f32) -> Vec<Edge> {
        let mut count: HashMap<Edge, usize> = HashMap::new();
        for t in &m.indices {
            for k in 0..3 {
                let a = m.positions[t[k] as usize].map(f32::to_bits);
                let b = m.positions[t[(k + 1) % 3] as usize].map(f32::to_bits);
                let e = if a < b { [a, b] } else { [b, a] };
                *count.entry(e).or_default() += 1;
            }
        }
        let mut out: Vec<Edge> = count
            .into_iter()
            .filter(|(e, c)| {
                *c == 1
                    && f32::from_bits(e[0][axis]) == plane
                    && f32::from_bits(e[1][axis]) == plane
            })
            .map(|(e, _)| e)
            .collect();
        out.sort();
        out
    }

    #[test]
    fn bunny_site_partition_levels_atlases_and_loader() {
        let (m, rep) = crate::repair::repair(&bunny());
        let area = m.total_area();
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("bunny.igi");
        let opts = PrepareOptions {
            grid: VoxelGrid::new([-1.0, 0.3, -0.7], 4.3).unwrap(),
            atlas: AtlasOptions {
                resolution: 256,
                gutter: 2,
            },
            levels: vec![1.0, 0.2, 0.05],
            ..Default::default()
        };
        let prepare_bunny = |opts: &PrepareOptions| {
            prepare(
                m.clone(),
                None,
                rep.clone(),
                &out,
                "bunny",
                opts,
                &|_, _| {},
            )
        };
        let man = prepare_bunny(&opts).unwrap();
        assert!(man.voxels.len() >= 8, "{} voxels", man.voxels.len());
        let store = SiteStore::open(&out).unwrap();
        let ids = store.voxel_ids();
        let levels = bunny_voxels_cover_the_area_once(&store, &opts, &ids, area);
        bunny_neighbours_share_their_border_edges(&opts, &ids, &levels);
        bunny_levels_shrink_with_growing_error(&man);
        let v = ids[ids.len() / 2];
        bunny_texel_cache_lies_on_the_mesh(&man, &store, &levels[&(v, 0)], v);
        bunny_loader_picks_levels_by_distance(&man, &store, &ids, v);
        // 6. resume: a finished voxel is not rewritten; a broken one is redone
        let f0 = store.voxel_folder(ids[0]).unwrap().join("level0.ply");
        let t0 = std::fs::metadata(&f0).unwrap().modified().unwrap();
        let f1 = store.voxel_folder(ids[1]).unwrap();
        std::fs::remove_file(f1.join("level2.ply")).unwrap();
        std::thread::sleep(std::time::Duration::from_millis(20));
        let man2 = prepare_bunny(&opts).unwrap();
        assert_eq!(std::fs::metadata(&f0).unwrap().modified().unwrap(), t0);
        assert!(f1.join("level2.ply").exists());
        assert_eq!(man2.voxels.len(), man.voxels.len());
        for (a, b) in man2.voxels.iter().zip(&man.voxels) {
            assert_eq!(
                (a.voxel, &a.triangles, a.charts),
                (b.voxel, &b.triangles, b.charts)
            );
            assert!((a.texel_size - b.texel_size).abs() < 1e-12 && (a.area - b.area).abs() < 1e-9);
        }
        // different settings on the same folder are refused
        let mut other = opts.clone();
        other.grid.size = 3.0;
        let e = prepare_bunny(&other).unwrap_err().to_string();
        assert!(
            e.contains("option --voxel") && e.contains("--restart"),
            "{e}"
        );
    }

    /// Step 1 of the bunny test: every piece of surface in exactly one voxel, inside its
    /// bounds; returns every voxel's mesh at every level.
    fn bunny_voxels_cover_the_area_once(
        store: &SiteStore,
        opts: &PrepareOptions,
        ids: &[VoxelId],
        area: f64,
    ) -> HashMap<(VoxelId, usize), TriMesh> {
        let mut sum = 0.0;
        let mut levels: HashMap<(VoxelId, usize), TriMesh> = HashMap::new();
        for &v in ids {
            let (lo, hi) = opts.grid.bounds(v);
            for l in 0..3 {
                let mesh = store.load_voxel(v, l).unwrap();
                for p in &mesh.positions {
                    for k in 0..3 {
                        assert!(
                            p[k] >= lo[k] && p[k] <= hi[k],
                            "{v:?} level {l}: {p:?} outside"
                        );
                    }
                }
                assert!(mesh.uvs.is_some() && mesh.normals.is_some());
                levels.insert((v, l), mesh);
            }
            sum += levels[&(v, 0)].total_area();
        }
        assert!(
            (sum - area).abs() < 1e-5 * area,
            "voxel area {sum} vs mesh {area}"
        );
        levels
    }

    /// Step 2: boundary edges of face neighbours match exactly, at every pair of levels.
    fn bunny_neighbours_share_their_border_edges(
        opts: &PrepareOptions,
        ids: &[VoxelId],
        levels: &HashMap<(VoxelId, usize), TriMesh>,
    ) {
        let mut checked = 0;
        for &a in ids {
            for axis in 0..3 {
                let mut b = a;
                b[axis] += 1;
                if !ids.contains(&b) {
                    continue;
                }
                let plane = opts.grid.plane(axis, b[axis]);
                let ea0 = border_edges_on_plane(&levels[&(a, 0)], axis, plane);
                if ea0.is_empty() {
                    continue;
                }
                for la in 0..3 {
                    for lb in 0..3 {
                        let ea = border_edges_on_plane(&levels[&(a, la)], axis, plane);
                        let eb = border_edges_on_plane(&levels[&(b, lb)], axis, plane);
                        let only_a: Vec<_> = ea
                            .iter()
                            .filter(|e| !eb.contains(e))
                            .map(|e| e.map(|p| p.map(f32::from_bits)))
                            .collect();
                        let only_b: Vec<_> = eb
                            .iter()
                            .filter(|e| !ea.contains(e))
                            .map(|e| e.map(|p| p.map(f32::from_bits)))
                            .collect();
                        assert!(
                            only_a.is_empty() && only_b.is_empty(),
                            "{a:?} level {la} vs {b:?} level {lb} on axis {axis}: only in a {only_a:?}, only in b {only_b:?}"
                        );
                        assert_eq!(ea, ea0);
                    }
                }
                checked += 1;
            }
        }
        assert!(checked >= 3, "only {checked} shared faces checked");
    }

    /// Step 3: levels really are smaller and report their error.
    fn bunny_levels_shrink_with_growing_error(man: &Manifest) {
        let t: Vec<usize> = man.triangles_per_level.clone();
        assert_eq!(
            t[0],
            man.voxels.iter().map(|e| e.triangles[0]).sum::<usize>()
        );
        assert!(t[1] < t[0] / 2 && t[2] < t[1], "{t:?}");
        assert!(man
            .voxels
            .iter()
            .all(|e| e.errors[0] == 0.0 && e.errors.iter().all(|x| x.is_finite() && *x >= 0.0)));
        let err_sum = |l: usize| man.voxels.iter().map(|e| e.errors[l]).sum::<f64>();
        assert!(
            err_sum(2) > err_sum(1) && err_sum(1) > 0.0,
            "{} {}",
            err_sum(1),
            err_sum(2)
        );
        // the errors are small against the 9 m bunny
        assert!(
            man.voxels.iter().all(|e| e.errors[2] < 0.5),
            "{:?}",
            man.voxels.iter().map(|e| e.errors[2]).collect::<Vec<_>>()
        );
    }

    /// Step 4: coverage and texel caches: the cached positions of voxel `v` (level-0 mesh
    /// `m0`) lie on the mesh.
    fn bunny_texel_cache_lies_on_the_mesh(
        man: &Manifest,
        store: &SiteStore,
        m0: &TriMesh,
        v: VoxelId,
    ) {
        assert!(
            man.coverage_mean > 0.05 && man.coverage_mean <= 1.0,
            "{}",
            man.coverage_mean
        );
        let e = man.voxels.iter().find(|e| e.voxel == Some(v)).unwrap();
        let pos =
            igi_imaging::read_image(&store.voxel_folder(v).unwrap().join("position.exr")).unwrap();
        let uv = m0.uvs.as_ref().unwrap();
        // "Texel caches reproduce positions on the mesh within half a texel": for points on
        // the mesh (three per triangle), the cache looked up bilinearly at the point's UV is
        // within half a texel of the point, and the nearest texel's cached position is within
        // half that texel's diagonal, measured on the surface through the triangle's own
        // UV-to-world Jacobian.
        let ts = e.texel_size;
        let res = pos.width;
        let (mut worst_bilinear, mut worst_nearest_ratio, mut n) = (0.0f64, 0.0f64, 0usize);
        for tri in &m0.indices {
            let p = tri.map(|i| m0.positions[i as usize].map(f64::from));
            let t = tri.map(|i| uv[i as usize].map(f64::from));
            let Some(half_diag) = half_texel_diagonal(p, t, res) else {
                continue;
            };
            for (a, b) in [
                (1.0 / 6.0, 1.0 / 6.0),
                (2.0 / 3.0, 1.0 / 6.0),
                (1.0 / 6.0, 2.0 / 3.0),
            ] {
                let c = 1.0 - a - b;
                let q = [0, 1, 2].map(|k| c * p[0][k] + a * p[1][k] + b * p[2][k]);
                let u = [0, 1].map(|k| (c * t[0][k] + a * t[1][k] + b * t[2][k]) as f32);
                let [x, y] = crate::atlas::uv_to_pixel(u, res);
                let dist = |r: [f32; 3]| norm([0, 1, 2].map(|k| r[k] as f64 - q[k]));
                let bl = pos
                    .bilinear(x, y)
                    .expect("bilinear lookup reaches an empty texel");
                worst_bilinear = worst_bilinear.max(dist(bl));
                let (j, i) = (x.round() as usize, y.round() as usize);
                assert!(pos.is_valid(j, i), "texel under a surface point is empty");
                worst_nearest_ratio = worst_nearest_ratio.max(dist(pos.get(j, i)) / half_diag);
                n += 1;
            }
        }
        assert!(n > 1000, "{n}");
        assert!(
            worst_bilinear <= 0.5 * ts,
            "bilinear cache lookup off by {worst_bilinear} m (half a texel is {} m)",
            0.5 * ts
        );
        assert!(
            worst_nearest_ratio <= 1.0 + 1e-3,
            "nearest cached position off by {worst_nearest_ratio} half-texel diagonals"
        );
        eprintln!(
            "bunny texel cache: {n} points, bilinear worst {:.3} texel, nearest worst {:.3} half-diagonals",
            worst_bilinear / ts,
            worst_nearest_ratio
        );
    }

    fn norm(a: [f64; 3]) -> f64 {
        (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
    }

    /// Half a texel diagonal of a `res` atlas on the triangle with corners `p` and UVs `t`
    /// (the longer of the two diagonals, through the triangle's Jacobian d(world)/d(uv));
    /// `None` when its UVs are degenerate.
    fn half_texel_diagonal(p: [[f64; 3]; 3], t: [[f64; 2]; 3], res: usize) -> Option<f64> {
        let (du1, dv1) = (t[1][0] - t[0][0], t[1][1] - t[0][1]);
        let (du2, dv2) = (t[2][0] - t[0][0], t[2][1] - t[0][1]);
        let det = du1 * dv2 - du2 * dv1;
        if det.abs() < 1e-14 {
            return None;
        }
        let e1 = [0, 1, 2].map(|k| p[1][k] - p[0][k]);
        let e2 = [0, 1, 2].map(|k| p[2][k] - p[0][k]);
        let ju = [0, 1, 2].map(|k| (e1[k] * dv2 - e2[k] * dv1) / det);
        let jv = [0, 1, 2].map(|k| (e2[k] * du1 - e1[k] * du2) / det);
        let h = 0.5 / res as f64;
        Some(
            [1.0, -1.0]
                .map(|s| norm([0, 1, 2].map(|k| h * (ju[k] + s * jv[k]))))
                .into_iter()
                .fold(0.0, f64::max),
        )
    }

    /// Step 5: the loader gives `v` high, its neighbours medium (or high, as a Jacobi task
    /// loads them), the rest low.
    fn bunny_loader_picks_levels_by_distance(
        man: &Manifest,
        store: &SiteStore,
        ids: &[VoxelId],
        v: VoxelId,
    ) {
        let t = &man.triangles_per_level;
        let jacobi = store.load_for_voxel(v, 0).unwrap();
        for p in &jacobi {
            let u = p.voxel.unwrap();
            let d = (0..3).map(|k| (u[k] - v[k]).abs()).max().unwrap();
            assert_eq!(p.level, [0, 0, 2][d.min(2) as usize]);
        }
        let parts = store.load_for_voxel(v, 1).unwrap();
        assert_eq!(parts.len(), ids.len());
        let mut loaded = 0;
        for p in &parts {
            let u = p.voxel.unwrap();
            let d = (0..3).map(|k| (u[k] - v[k]).abs()).max().unwrap();
            assert_eq!(p.level, [0, 1, 2][d.min(2) as usize]);
            assert_eq!(
                p.mesh.indices.len(),
                man.voxels
                    .iter()
                    .find(|e| e.voxel == Some(u))
                    .unwrap()
                    .triangles[p.level]
            );
            loaded += p.mesh.indices.len();
        }
        assert!(loaded < t[0]);
        assert!(store.load_for_voxel([99, 99, 99], 1).is_err());
    }

    #[test]
    fn procedural_site_with_terrain_kept_apart() {
        let mut site = TriMesh::default();
        let mut terrain = None;
        for (name, m) in crate::procedural::colonnade_site(2, 2) {
            if name == "terrain" {
                terrain = Some(m);
            } else {
                site.append(&m);
            }
        }
        let terrain = terrain.unwrap();
        let (t_tris, t_area) = (terrain.indices.len(), terrain.total_area());
        let site_area = site.total_area();
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("site.igi");
        let opts = PrepareOptions {
            atlas: AtlasOptions {
                resolution: 128,
                gutter: 2,
            },
            ..Default::default()
        };
        let (site, rep) = crate::repair::repair(&site);
        let man = prepare(
            site,
            Some(terrain),
            rep,
            &out,
            "procedural",
            &opts,
            &|_, _| {},
        )
        .unwrap();
        let t = man.terrain.as_ref().unwrap();
        assert_eq!(t.triangles[0], t_tris);
        assert!(t.triangles[2] < t_tris / 10, "{:?}", t.triangles);
        assert!((t.area - t_area).abs() < 1e-6 * t_area);
        let voxel_area: f64 = man.voxels.iter().map(|e| e.area).sum();
        assert!(
            (voxel_area - site_area).abs() < 1e-5 * site_area,
            "{voxel_area} vs {site_area}"
        );
        // 40 x 40 m terrain in one 128-texel atlas: texels of at least 40/128 m
        assert!(t.texel_size >= 40.0 / 128.0, "{}", t.texel_size);
        let store = SiteStore::open(&out).unwrap();
        let parts = store.load_for_voxel(store.voxel_ids()[0], 1).unwrap();
        let terr: Vec<_> = parts.iter().filter(|p| p.voxel.is_none()).collect();
        assert_eq!(terr.len(), 1);
        assert_eq!(
            (terr[0].level, terr[0].mesh.indices.len()),
            (2, t.triangles[2])
        );
        // the stylobate sits on the voxel plane z = 0: its faces lie in or above it, never below
        assert!(man.voxel_range[0][2] >= 0, "{:?}", man.voxel_range);
        // a manifest that lists no levels (loading took `levels.len() - 1`: a panic or a wrapped
        // level), or a part folder outside the site, is refused naming manifest.json
        let mp = out.join("manifest.json");
        let good: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&mp).unwrap()).unwrap();
        type Edit = fn(&mut serde_json::Value);
        let edits: [(Edit, &str); 4] = [
            (|m| m["levels"] = serde_json::json!([]), "lists no levels"),
            (
                |m| m["voxels"][0]["dir"] = "../elsewhere".into(),
                "\"../elsewhere\" is not",
            ),
            (
                |m| m["terrain"]["dir"] = "/tmp".into(),
                "\"/tmp\" is not a folder inside",
            ),
            (
                |m| m["voxels"][1]["dir"] = "".into(),
                "\"\" is not a folder inside",
            ),
        ];
        for (edit, says) in edits {
            let mut m = good.clone();
            edit(&mut m);
            std::fs::write(&mp, m.to_string()).unwrap();
            let err = SiteStore::open(&out).err().unwrap().to_string();
            assert!(err.contains("manifest.json") && err.contains(says), "{err}");
        }
    }

    #[test]
    fn bad_levels_are_refused() {
        let mut o = PrepareOptions {
            levels: vec![0.5, 0.2],
            ..Default::default()
        };
        assert!(o.check().is_err());
        o.levels = vec![1.0, 0.2, 0.3];
        assert!(o.check().is_err());
        o.levels = vec![1.0, 0.0];
        assert!(o.check().is_err());
        o.levels = vec![1.0, 0.25, 0.05];
        o.check().unwrap();
    }
}
