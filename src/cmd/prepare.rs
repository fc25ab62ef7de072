//! `igi prepare` (voxelize a scanned site into a multiresolution store with atlases) and
//! `igi info` (summarise a prepared site).

use crate::report::Ctx;
use igi_geometry::job::{prepare_file, site_info, InfoRequest, PrepareRequest, PrepareStep};
use igi_geometry::repair::RepairReport;
use igi_geometry::store::Manifest;
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct PrepareArgs {
    /// Site mesh (.ply or .obj), world Z up, metres.
    pub mesh: PathBuf,
    /// Output site folder (created; an interrupted run with the same settings resumes).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Voxel edge in metres.
    #[arg(allow_negative_numbers = true, value_parser = crate::cmd::values::positive, long, default_value_t = 4.3)]
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
    #[arg(allow_negative_numbers = true, value_parser = crate::cmd::values::positive, long, default_value_t = 8.0)]
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

pub fn run_prepare(a: PrepareArgs, ctx: &Ctx) -> anyhow::Result<()> {
    let req = PrepareRequest {
        mesh: a.mesh,
        terrain: a.terrain,
        output: a.output,
        voxel: a.voxel,
        origin: a.origin,
        atlas: a.atlas,
        levels: a.levels,
        restart: a.restart,
        max_memory_gib: a.max_memory,
    };
    let pb = ctx.progress(0, "voxels");
    let p = prepare_file(&req, &|s| match s {
        PrepareStep::Read { triangles, seconds } => {
            tracing::info!("read {triangles} triangles in {seconds:.1} s")
        }
        PrepareStep::Repaired(r) => print_repair(r),
        PrepareStep::Voxels { done, total } => {
            pb.set_length(total as u64);
            pb.set_position(done as u64);
        }
    })?;
    pb.finish_and_clear();
    let man = &p.manifest;
    if a.json {
        return crate::report::print_json(man);
    }
    println!(
        "{}: {} voxels ({:.2} m), triangles per level {:?}, texel {:.4}..{:.4} m, atlas coverage {:.1}%{} in {:.1} s",
        req.output.display(),
        man.voxels.len(),
        man.grid.size,
        man.triangles_per_level,
        man.texel_size_min,
        man.texel_size_max,
        100.0 * man.coverage_mean,
        man.terrain.as_ref().map_or(String::new(), |t| format!(", terrain {:?}", t.triangles)),
        p.seconds
    );
    Ok(())
}

/// What the repair removed, when it removed anything or found non-manifold edges.
fn print_repair(report: &RepairReport) {
    if report.degenerate_removed + report.duplicate_removed > 0 || report.non_manifold_edges > 0 {
        eprintln!(
            "repair: removed {} degenerate and {} duplicate triangles; {} non-manifold edges, {} border edges",
            report.degenerate_removed, report.duplicate_removed, report.non_manifold_edges, report.border_edges
        );
    }
}

pub fn run_info(a: InfoArgs, _ctx: &Ctx) -> anyhow::Result<()> {
    let req = InfoRequest {
        site: a.site,
        load_voxel: a.load_voxel,
    };
    let info = site_info(&req)?;
    let load = info.load.map(|l| {
        serde_json::json!({
            "voxel": l.voxel, "parts": l.parts, "triangles_loaded": l.triangles_loaded,
            "triangles_full": l.triangles_full, "reduction": l.reduction, "seconds": l.seconds,
        })
    });
    if a.json {
        let mut v = serde_json::to_value(&info.manifest)?;
        if let Some(l) = load {
            v["load"] = l;
        }
        return crate::report::print_json(&v);
    }
    print_site(&req.site, &info.manifest);
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
