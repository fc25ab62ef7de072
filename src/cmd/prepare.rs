//! `igi prepare` (voxelize a scanned site into a multiresolution store with atlases) and
//! `igi info` (summarise a prepared site).

use crate::report::Ctx;
use anyhow::{bail, Context};
use igi_geometry::atlas::AtlasOptions;
use igi_geometry::repair::{repair, RepairReport};
use igi_geometry::store::Manifest;
use igi_geometry::{
    check_prepare_output, read_mesh, PrepareOptions, PrepareRun, SiteStore, TriMesh, VoxelGrid,
    VoxelId,
};
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct PrepareArgs {
    /// Site mesh (.ply or .obj), world Z up, metres.
    pub mesh: PathBuf,
    /// Output site folder (created; an interrupted run with the same settings resumes).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Voxel edge in metres.
    #[arg(long, default_value_t = 4.3)]
    pub voxel: f64,
    /// Lattice origin "x,y,z" in metres.
    #[arg(long, default_value = "0,0,0")]
    pub origin: String,
    /// Atlas resolution per voxel (texels per side).
    #[arg(long, default_value_t = 512)]
    pub atlas: u32,
    /// Triangle fractions of the levels, first 1.0, decreasing.
    #[arg(long, default_value = "1.0,0.2,0.05")]
    pub levels: String,
    /// Optional terrain mesh, kept apart (not voxelized).
    #[arg(long)]
    pub terrain: Option<PathBuf>,
    /// Delete an earlier run's files in the output folder and prepare afresh (without it, a
    /// folder holding a run with other inputs or options is refused).
    #[arg(long)]
    pub restart: bool,
    /// Refuse runs estimated to need more memory than this many GiB.
    #[arg(long, default_value_t = 8.0)]
    pub max_memory: f64,
    /// Print the manifest as JSON on stdout.
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Args, Debug)]
pub struct InfoArgs {
    /// A site folder written by `igi prepare`.
    pub site: PathBuf,
    /// Print the manifest as JSON.
    #[arg(long)]
    pub json: bool,
    /// Load the data the solver needs for one voxel ("i,j,k" or "middle") and report the reduction.
    #[arg(long)]
    pub load_voxel: Option<String>,
}

/// `--max-memory` in GiB as bytes.
pub fn gib_to_bytes(gib: f64) -> anyhow::Result<u64> {
    if !(gib.is_finite() && gib > 0.0) {
        bail!("--max-memory must be a positive number of GiB, got {gib}");
    }
    Ok((gib * (1u64 << 30) as f64) as u64)
}

fn parse_list(s: &str, what: &str) -> anyhow::Result<Vec<f64>> {
    s.split(',')
        .map(|t| {
            t.trim()
                .parse::<f64>()
                .with_context(|| format!("--{what}: `{t}` is not a number"))
        })
        .collect()
}

/// The prepare options and run of the command line.
fn prepare_options(a: &PrepareArgs) -> anyhow::Result<(PrepareOptions, PrepareRun)> {
    let origin = parse_list(&a.origin, "origin")?;
    let [x, y, z] = origin[..] else {
        bail!("--origin needs three numbers x,y,z, got `{}`", a.origin)
    };
    let grid = VoxelGrid::new([x, y, z], a.voxel)?;
    let opts = PrepareOptions {
        grid,
        atlas: AtlasOptions {
            resolution: a.atlas,
            ..Default::default()
        },
        levels: parse_list(&a.levels, "levels")?,
        max_memory: gib_to_bytes(a.max_memory)?,
    };
    let run = PrepareRun {
        mesh: Some(a.mesh.clone()),
        terrain: a.terrain.clone(),
        restart: a.restart,
    };
    Ok((opts, run))
}

/// Reads and repairs the mesh (which must keep a triangle) and the terrain, reporting what the
/// repair removed.
fn read_repaired(a: &PrepareArgs) -> anyhow::Result<(TriMesh, Option<TriMesh>, RepairReport)> {
    let t0 = std::time::Instant::now();
    let mesh = read_mesh(&a.mesh)?;
    let terrain = a.terrain.as_deref().map(read_mesh).transpose()?;
    tracing::info!(
        "read {} triangles in {:.1} s",
        mesh.indices.len(),
        t0.elapsed().as_secs_f64()
    );
    let (repaired, report) = repair(&mesh);
    drop(mesh);
    let mesh = repaired;
    if report.degenerate_removed + report.duplicate_removed > 0 || report.non_manifold_edges > 0 {
        eprintln!(
            "repair: removed {} degenerate and {} duplicate triangles; {} non-manifold edges, {} border edges",
            report.degenerate_removed, report.duplicate_removed, report.non_manifold_edges, report.border_edges
        );
    }
    if mesh.indices.is_empty() {
        bail!(
            "{}: no triangle left after removing degenerate ones",
            a.mesh.display()
        );
    }
    let terrain = terrain.map(|t| repair(&t).0);
    Ok((mesh, terrain, report))
}

pub fn run_prepare(a: PrepareArgs, ctx: &Ctx) -> anyhow::Result<()> {
    let (opts, run) = prepare_options(&a)?;
    check_prepare_output(&a.output, &run, &opts, a.terrain.is_some())?;
    // read and check everything before creating the output folder
    let t0 = std::time::Instant::now();
    let (mesh, terrain, report) = read_repaired(&a)?;
    let pb = ctx.progress(0, "voxels");
    let progress = |done: usize, total: usize| {
        pb.set_length(total as u64);
        pb.set_position(done as u64);
    };
    let man = igi_geometry::prepare_run(
        mesh,
        terrain,
        report,
        &a.output,
        &a.mesh.display().to_string(),
        &run,
        &opts,
        &progress,
    )?;
    pb.finish_and_clear();
    if a.json {
        return crate::report::print_json(&man);
    }
    println!(
        "{}: {} voxels ({:.2} m), triangles per level {:?}, texel {:.4}..{:.4} m, atlas coverage {:.1}%{} in {:.1} s",
        a.output.display(),
        man.voxels.len(),
        man.grid.size,
        man.triangles_per_level,
        man.texel_size_min,
        man.texel_size_max,
        100.0 * man.coverage_mean,
        man.terrain.as_ref().map_or(String::new(), |t| format!(", terrain {:?}", t.triangles)),
        t0.elapsed().as_secs_f64()
    );
    Ok(())
}

fn parse_voxel(s: &str, store: &SiteStore) -> anyhow::Result<VoxelId> {
    let ids = store.voxel_ids();
    if s == "middle" {
        // the non-empty voxel nearest the centre of the occupied range
        let r = store.manifest().voxel_range;
        let c = [0, 1, 2].map(|k| (r[0][k] + r[1][k]) as f64 / 2.0);
        let d = |v: &VoxelId| (0..3).map(|k| (v[k] as f64 - c[k]).powi(2)).sum::<f64>();
        return ids
            .into_iter()
            .min_by(|a, b| d(a).total_cmp(&d(b)))
            .context("the site has no voxel");
    }
    let v: Vec<i32> = s
        .split(',')
        .map(|t| {
            t.trim()
                .parse::<i32>()
                .with_context(|| format!("--load-voxel: `{t}` is not an integer"))
        })
        .collect::<anyhow::Result<_>>()?;
    let [i, j, k] = v[..] else {
        bail!("--load-voxel needs i,j,k or `middle`")
    };
    Ok([i, j, k])
}

/// Loads `voxel` as a solve would and measures it (parts, triangles against the full site,
/// seconds).
fn measure_load(store: &SiteStore, voxel: &str) -> anyhow::Result<serde_json::Value> {
    let man = store.manifest();
    let v = parse_voxel(voxel, store)?;
    let t0 = std::time::Instant::now();
    let parts = store.load_for_voxel(v, 1)?;
    let secs = t0.elapsed().as_secs_f64();
    let loaded: usize = parts.iter().map(|p| p.mesh.indices.len()).sum();
    let full: usize =
        man.triangles_per_level[0] + man.terrain.as_ref().map_or(0, |t| t.triangles[0]);
    Ok(serde_json::json!({
        "voxel": v, "parts": parts.len(), "triangles_loaded": loaded, "triangles_full": full,
        "reduction": 1.0 - loaded as f64 / full as f64, "seconds": secs,
    }))
}

pub fn run_info(a: InfoArgs, _ctx: &Ctx) -> anyhow::Result<()> {
    let store = SiteStore::open(&a.site)?;
    let man = store.manifest();
    let load = match &a.load_voxel {
        Some(s) => Some(measure_load(&store, s)?),
        None => None,
    };
    if a.json {
        let mut v = serde_json::to_value(man)?;
        if let Some(l) = load {
            v["load"] = l;
        }
        return crate::report::print_json(&v);
    }
    print_site(&a.site, man);
    if let Some(l) = load {
        println!(
            "load      voxel {} with {} parts: {} of {} triangles ({:.1}% less) in {:.2} s",
            l["voxel"],
            l["parts"],
            l["triangles_loaded"],
            l["triangles_full"],
            100.0 * l["reduction"].as_f64().unwrap_or(0.0),
            l["seconds"].as_f64().unwrap_or(0.0)
        );
    }
    Ok(())
}

/// The text report of a site's manifest: bounds, voxels, levels, terrain, atlas, repair.
fn print_site(site: &Path, man: &Manifest) {
    let r = &man.voxel_range;
    println!("site      {} (from {})", site.display(), man.source);
    println!("bounds    {:?} .. {:?} m", man.bounds[0], man.bounds[1]);
    println!(
        "voxels    {} non-empty of a {}x{}x{} lattice, {:.2} m, origin {:?}",
        man.voxels.len(),
        r[1][0] - r[0][0] + 1,
        r[1][1] - r[0][1] + 1,
        r[1][2] - r[0][2] + 1,
        man.grid.size,
        man.grid.origin
    );
    for (l, f) in man.levels.iter().enumerate() {
        let err = man.voxels.iter().map(|e| e.errors[l]).fold(0.0, f64::max);
        println!(
            "level {l}   {:>5.1}%  {:>10} triangles  max error {:.4} m",
            100.0 * f,
            man.triangles_per_level[l],
            err
        );
    }
    if let Some(t) = &man.terrain {
        println!(
            "terrain   triangles per level {:?}, texel {:.4} m",
            t.triangles, t.texel_size
        );
    }
    println!(
        "atlas     {}x{} per voxel, texel {:.4}..{:.4} m, coverage {:.1}% of texels",
        man.atlas_resolution,
        man.atlas_resolution,
        man.texel_size_min,
        man.texel_size_max,
        100.0 * man.coverage_mean
    );
    let rp = &man.repair;
    println!(
        "repair    {} -> {} triangles ({} degenerate, {} duplicate removed), {} non-manifold edges, {} border edges",
        rp.triangles_in, rp.triangles_out, rp.degenerate_removed, rp.duplicate_removed, rp.non_manifold_edges, rp.border_edges
    );
}
