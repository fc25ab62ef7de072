//! `igi prepare` and `igi info` as one call each, from a request of paths and options: a
//! scanned site streamed through per-voxel spill files, repaired and prepared into a site
//! folder voxel by voxel ([`prepare_file`]; [`prepare_file_in_memory`] is the same with the
//! whole mesh in memory); a site folder summarised, optionally with one voxel loaded as a
//! solve would ([`site_info`]).

use crate::atlas::AtlasOptions;
use crate::repair::{repair, RepairReport};
use crate::store::Manifest;
use crate::{
    check_prepare_output, prepare_run, prepare_streamed, read_mesh, GeometryError, PrepareOptions,
    PrepareRun, SiteSpill, SiteStore, TriMesh, VoxelGrid, VoxelId,
};
use std::path::{Path, PathBuf};

/// `igi prepare`: the site mesh and an optional terrain, the site folder, and the options as
/// given (`origin` as `x,y,z`, `levels` as comma-separated fractions; checked by
/// [`prepare_file`]).
#[derive(Clone, Debug)]
pub struct PrepareRequest {
    pub mesh: PathBuf,
    pub terrain: Option<PathBuf>,
    pub output: PathBuf,
    /// Voxel edge, metres.
    pub voxel: f64,
    pub origin: String,
    /// Atlas texels per side, per voxel.
    pub atlas: u32,
    pub levels: String,
    /// Delete an earlier run's files in the output folder first.
    pub restart: bool,
    /// Refuse runs estimated to need more than this many GiB.
    pub max_memory_gib: f64,
}

/// One step of [`prepare_file`], for a progress bar and the log.
#[derive(Clone, Copy, Debug)]
pub enum PrepareStep<'a> {
    /// The mesh (and the terrain) read: the mesh's triangles, in this many seconds.
    Read { triangles: usize, seconds: f64 },
    /// The mesh is repaired (before it is checked to keep a triangle, and before any voxel).
    Repaired(&'a RepairReport),
    /// `done` of `total` voxels prepared.
    Voxels { done: usize, total: usize },
}

/// What [`prepare_file`] prepared: the site's manifest, and the seconds from reading the mesh
/// to the last voxel.
#[derive(Clone, Debug)]
pub struct Prepared {
    pub manifest: Manifest,
    pub seconds: f64,
}

/// Checks the request and the output folder, streams the mesh into per-voxel spill files
/// ([`SiteSpill`]), reads and repairs the terrain, and prepares (or resumes) the site folder
/// voxel by voxel ([`prepare_streamed`]): memory follows the largest voxel (and the terrain),
/// not the site; the folder is the one [`prepare_file_in_memory`] writes.
pub fn prepare_file(
    req: &PrepareRequest,
    step: &(dyn Fn(PrepareStep) + Sync),
) -> Result<Prepared, GeometryError> {
    let (opts, run) = prepare_options(req)?;
    check_prepare_output(&req.output, &run, &opts, req.terrain.is_some())?;
    // read and check everything before creating the output folder: the mesh streams into
    // per-voxel spill files in a folder of their own beside the output (removed at the end)
    let t0 = std::time::Instant::now();
    let folder = spill_folder(&req.output);
    remove_dead_spills(&folder);
    let limit = crate::store::voxel_limit(&opts, req.terrain.is_some(), &req.output)?;
    let spill = SiteSpill::bin(&req.mesh, &opts.grid, &limit, &folder)?;
    let stats = spill.stats();
    step(PrepareStep::Read {
        triangles: stats.triangles_in,
        seconds: t0.elapsed().as_secs_f64(),
    });
    if stats.triangles_in == stats.degenerate_removed {
        return Err(no_triangle_left(&req.mesh));
    }
    let terrain = read_terrain(req)?;
    let report = spill.repair_report()?;
    step(PrepareStep::Repaired(&report));
    let source = req.mesh.display().to_string();
    let progress = |done, total| step(PrepareStep::Voxels { done, total });
    let manifest = prepare_streamed(
        &spill,
        terrain,
        report,
        &req.output,
        &source,
        &run,
        &opts,
        &progress,
    )?;
    Ok(Prepared {
        manifest,
        seconds: t0.elapsed().as_secs_f64(),
    })
}

/// [`prepare_file`] as it was before streaming: the mesh read whole, repaired and cut in
/// memory ([`prepare_run`]); the same site folder, byte for byte (the streaming path's test
/// and benchmark baseline).
pub fn prepare_file_in_memory(
    req: &PrepareRequest,
    step: &(dyn Fn(PrepareStep) + Sync),
) -> Result<Prepared, GeometryError> {
    let (opts, run) = prepare_options(req)?;
    check_prepare_output(&req.output, &run, &opts, req.terrain.is_some())?;
    let t0 = std::time::Instant::now();
    let (mesh, terrain, report) = read_repaired(req, step)?;
    let source = req.mesh.display().to_string();
    let progress = |done, total| step(PrepareStep::Voxels { done, total });
    let manifest = prepare_run(
        mesh,
        terrain,
        report,
        &req.output,
        &source,
        &run,
        &opts,
        &progress,
    )?;
    Ok(Prepared {
        manifest,
        seconds: t0.elapsed().as_secs_f64(),
    })
}

/// The folder of a streamed prepare's spill files: hidden, beside the output folder (on the
/// same disk) when its parent exists (else in the system's temporary folder), named after it
/// and this process.
fn spill_folder(out: &Path) -> PathBuf {
    let name = format!(
        ".{}.spill-{}",
        out.file_name()
            .map_or("site".into(), |n| n.to_string_lossy()),
        std::process::id()
    );
    let parent = match out.parent() {
        Some(p) if p.as_os_str().is_empty() => Some(Path::new(".")),
        p => p,
    };
    match parent {
        Some(p) if out.file_name().is_some() && p.is_dir() => p.join(name),
        _ => std::env::temp_dir().join(name),
    }
}

/// Removes the spill folders a killed prepare of the same output left beside `folder` (those
/// of processes no longer running; where `/proc` cannot tell, none).
fn remove_dead_spills(folder: &Path) {
    let (Some(parent), Some(name)) = (folder.parent(), folder.file_name()) else {
        return;
    };
    let name = name.to_string_lossy();
    let Some((stem, _)) = name.rsplit_once('-') else {
        return;
    };
    if !Path::new("/proc/self").exists() {
        return;
    }
    let Ok(entries) = std::fs::read_dir(parent) else {
        return;
    };
    for e in entries.flatten() {
        let n = e.file_name().to_string_lossy().into_owned();
        let Some(pid) = n.strip_prefix(stem).and_then(|r| r.strip_prefix('-')) else {
            continue;
        };
        if pid.parse::<u32>().is_ok() && !Path::new("/proc").join(pid).exists() {
            let _ = std::fs::remove_dir_all(e.path());
        }
    }
}

fn no_triangle_left(mesh: &Path) -> GeometryError {
    GeometryError::format(mesh, "no triangle left after removing degenerate ones")
}

/// Reads and repairs the terrain, if the request has one.
fn read_terrain(req: &PrepareRequest) -> Result<Option<TriMesh>, GeometryError> {
    Ok(req
        .terrain
        .as_deref()
        .map(read_mesh)
        .transpose()?
        .map(|t| repair(&t).0))
}

/// The prepare options and run of a request.
fn prepare_options(req: &PrepareRequest) -> Result<(PrepareOptions, PrepareRun), GeometryError> {
    let origin = parse_list(&req.origin, "origin")?;
    let [x, y, z] = origin[..] else {
        return Err(GeometryError::Arguments(format!(
            "--origin needs three numbers x,y,z, got `{}`",
            req.origin
        )));
    };
    let grid = VoxelGrid::new([x, y, z], req.voxel)?;
    let opts = PrepareOptions {
        grid,
        atlas: AtlasOptions {
            resolution: req.atlas,
            ..Default::default()
        },
        levels: parse_list(&req.levels, "levels")?,
        max_memory: gib_to_bytes(req.max_memory_gib)?,
    };
    let run = PrepareRun {
        mesh: Some(req.mesh.clone()),
        terrain: req.terrain.clone(),
        restart: req.restart,
    };
    Ok((opts, run))
}

fn parse_list(s: &str, option: &'static str) -> Result<Vec<f64>, GeometryError> {
    s.split(',')
        .map(|t| {
            t.trim()
                .parse::<f64>()
                .map_err(|source| GeometryError::NotANumber {
                    option,
                    text: t.to_string(),
                    source,
                })
        })
        .collect()
}

/// A memory limit in GiB as bytes.
fn gib_to_bytes(gib: f64) -> Result<u64, GeometryError> {
    if !(gib.is_finite() && gib > 0.0) {
        return Err(GeometryError::Arguments(format!(
            "--max-memory must be a positive number of GiB, got {gib}"
        )));
    }
    Ok((gib * (1u64 << 30) as f64) as u64)
}

/// Reads and repairs the mesh (which must keep a triangle) and the terrain.
fn read_repaired(
    req: &PrepareRequest,
    step: &(dyn Fn(PrepareStep) + Sync),
) -> Result<(TriMesh, Option<TriMesh>, RepairReport), GeometryError> {
    let t0 = std::time::Instant::now();
    let mesh = read_mesh(&req.mesh)?;
    let terrain = req.terrain.as_deref().map(read_mesh).transpose()?;
    step(PrepareStep::Read {
        triangles: mesh.indices.len(),
        seconds: t0.elapsed().as_secs_f64(),
    });
    let (repaired, report) = repair(&mesh);
    drop(mesh);
    step(PrepareStep::Repaired(&report));
    if repaired.indices.is_empty() {
        return Err(no_triangle_left(&req.mesh));
    }
    let terrain = terrain.map(|t| repair(&t).0);
    Ok((repaired, terrain, report))
}

/// `igi info`: a site folder, and a voxel to load as a solve would (`i,j,k` or `middle`).
#[derive(Clone, Debug)]
pub struct InfoRequest {
    pub site: PathBuf,
    pub load_voxel: Option<String>,
}

/// A site folder's manifest, and the measured load of a voxel when asked.
#[derive(Clone, Debug)]
pub struct SiteInfo {
    pub manifest: Manifest,
    pub load: Option<VoxelLoad>,
}

/// One voxel loaded as a solve would: its parts, the triangles loaded against the full site's,
/// the reduction, the seconds.
#[derive(Clone, Debug)]
pub struct VoxelLoad {
    pub voxel: VoxelId,
    pub parts: usize,
    pub triangles_loaded: usize,
    pub triangles_full: usize,
    pub reduction: f64,
    pub seconds: f64,
}

/// Opens the site folder and, when asked, loads the voxel and measures the load.
pub fn site_info(req: &InfoRequest) -> Result<SiteInfo, GeometryError> {
    let store = SiteStore::open(&req.site)?;
    let load = match &req.load_voxel {
        Some(s) => Some(measure_load(&store, s)?),
        None => None,
    };
    Ok(SiteInfo {
        manifest: store.manifest().clone(),
        load,
    })
}

/// The voxel `i,j,k`, or for `middle` the non-empty voxel nearest the centre of the occupied
/// range.
fn parse_voxel(s: &str, store: &SiteStore) -> Result<VoxelId, GeometryError> {
    let ids = store.voxel_ids();
    if s == "middle" {
        let r = store.manifest().voxel_range;
        let c = [0, 1, 2].map(|k| (r[0][k] + r[1][k]) as f64 / 2.0);
        let d = |v: &VoxelId| (0..3).map(|k| (v[k] as f64 - c[k]).powi(2)).sum::<f64>();
        return ids
            .into_iter()
            .min_by(|a, b| d(a).total_cmp(&d(b)))
            .ok_or_else(|| GeometryError::Arguments("the site has no voxel".into()));
    }
    let v: Vec<i32> = s
        .split(',')
        .map(|t| {
            t.trim()
                .parse::<i32>()
                .map_err(|source| GeometryError::NotAnInteger {
                    option: "load-voxel",
                    text: t.to_string(),
                    source,
                })
        })
        .collect::<Result<_, _>>()?;
    let [i, j, k] = v[..] else {
        return Err(GeometryError::Arguments(
            "--load-voxel needs i,j,k or `middle`".into(),
        ));
    };
    Ok([i, j, k])
}

/// Loads `voxel` as a solve would and measures it.
fn measure_load(store: &SiteStore, voxel: &str) -> Result<VoxelLoad, GeometryError> {
    let man = store.manifest();
    let v = parse_voxel(voxel, store)?;
    let t0 = std::time::Instant::now();
    let parts = store.load_for_voxel(v, 1)?;
    let seconds = t0.elapsed().as_secs_f64();
    let loaded: usize = parts.iter().map(|p| p.mesh.indices.len()).sum();
    let full: usize =
        man.triangles_per_level[0] + man.terrain.as_ref().map_or(0, |t| t.triangles[0]);
    Ok(VoxelLoad {
        voxel: v,
        parts: parts.len(),
        triangles_loaded: loaded,
        triangles_full: full,
        reduction: 1.0 - loaded as f64 / full as f64,
        seconds,
    })
}
