//! `igi hull`: opacity hulls from multi-view captures (Matusik et al. 2002).
use crate::report::{print_json, Ctx};
use igi_opacity_hull::job::{
    build_file, render_file, BuildRequest, BuildStep, RenderRequest as HullRenderRequest,
};
use std::path::PathBuf;

#[derive(clap::Subcommand, Debug)]
pub enum HullCmd {
    /// Build a hull folder from a rig.toml: mattes, visual hull (hull.ply), surfels
    /// (surfels.ply), volume against views (volume.png) and report.json (per-view IoU; the
    /// timings are printed with --json, not stored);
    /// with light images in the rig, the surface reflectance field (reflectance/: PCA per 8x8
    /// block to 1% RMS).
    Build(BuildArgs),
    /// Render a hull folder from a camera to an RGBA EXR (colour premultiplied by alpha) with
    /// unstructured-lumigraph blending of the input photos, or with --lighting of the input
    /// views relit from their reflectance fields (Eq. 3).
    Render(RenderArgs),
    /// Write the six multi-background matting patterns (Eq. 1: lambda 27, 40, 53; n = +1, -1).
    Backdrops(BackdropArgs),
    /// Import a Middlebury multi-view set (e.g. dinoSparseRing) as a rig folder.
    ImportMiddlebury(ImportArgs),
}

#[derive(clap::Args, Debug)]
pub struct BuildArgs {
    /// The capture file (FORMATS.md, "Multi-view capture").
    pub rig: PathBuf,
    /// Output folder (must not exist, or be empty).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Carving cells per axis of the bounding box (at least 256; 8 bytes a cell of memory,
    /// refused before any work above IGI_MAX_MEMORY, 8 GiB by default: at most 1024).
    #[arg(long, default_value_t = 256, value_parser = crate::cmd::values::hull_resolution)]
    pub resolution: usize,
    /// Depth in pixels of the band along the frame's edge, wherever a view's silhouette runs
    /// into the edge, whose background is weak evidence: the object goes on outside the frame,
    /// and its shadowed parts there read like the backdrop. A cell only band pixels call
    /// background is carved when two views' bands agree or when no more views see it as
    /// object (docs/OPACITY_HULL.md). 0: every known background pixel carves.
    #[arg(long, default_value_t = 30)]
    pub frame_band: usize,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Args, Debug)]
pub struct RenderArgs {
    /// A folder written by `igi hull build`.
    pub hull: PathBuf,
    /// Camera file (FORMATS.md JSON).
    #[arg(long)]
    pub camera: PathBuf,
    /// Lighting file (FORMATS.md: lat-long map times scale, sun): relight the object. Each
    /// input view is rebuilt from its reflectance field (the one-light-at-a-time images),
    /// each light weighted by the environment integrated over its Voronoi cell of directions
    /// (the sun to its nearest light), then blended as without it. Needs a hull built from a
    /// rig with light images.
    #[arg(long)]
    pub lighting: Option<PathBuf>,
    /// Output RGBA EXR.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Views blended per surfel (Eq. 4), 1 to 16.
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u16).range(1..=16))]
    pub k: u16,
    /// Print the timing as JSON.
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Args, Debug)]
pub struct BackdropArgs {
    /// Pattern width in display pixels.
    #[arg(long)]
    pub width: usize,
    /// Pattern height in display pixels.
    #[arg(long)]
    pub height: usize,
    /// Output folder (created if missing; the six files in it are replaced).
    #[arg(short, long)]
    pub output: PathBuf,
}

#[derive(clap::Args, Debug)]
pub struct ImportArgs {
    /// The set's folder (with *_par.txt, *_good_silhouette_images.txt, README.txt, the PNGs).
    pub dir: PathBuf,
    /// Output rig folder (must not exist, or be empty).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Print the import report as JSON.
    #[arg(long)]
    pub json: bool,
}

pub fn run(c: HullCmd, ctx: &Ctx) -> anyhow::Result<()> {
    match c {
        HullCmd::Build(a) => run_build(a, ctx),
        HullCmd::Render(a) => run_render(a),
        HullCmd::Backdrops(a) => {
            for p in igi_opacity_hull::backdrop::write_patterns(&a.output, a.width, a.height)? {
                println!("{}", p.display());
            }
            Ok(())
        }
        HullCmd::ImportMiddlebury(a) => {
            let r = igi_opacity_hull::middlebury::import(&a.dir, &a.output)?;
            if a.json {
                print_json(&r)?;
            } else {
                println!(
                    "views imported        {} (skipped: {:?})",
                    r.views, r.skipped
                );
                println!(
                    "rotation corrections  up to {:.2e}",
                    r.max_rotation_correction
                );
                println!("world up (+Z) was     {}", r.up_axis);
                println!("masks touching frame  {:?}", r.masks_touching_frame);
                println!(
                    "rig                   {}",
                    a.output.join("rig.toml").display()
                );
            }
            Ok(())
        }
    }
}

fn run_build(a: BuildArgs, ctx: &Ctx) -> anyhow::Result<()> {
    let req = BuildRequest {
        rig: a.rig,
        output: a.output,
        resolution: a.resolution,
        frame_band: a.frame_band,
    };
    let pb = ctx.progress(0, "hull");
    let r = build_file(&req, &mut |s| match s {
        BuildStep::Stages(n) => pb.set_length(n),
        BuildStep::Stage(s) => {
            pb.set_message(format!("{s:?}").to_lowercase());
            pb.inc(1);
        }
    })?;
    pb.finish_and_clear();
    if a.json {
        print_json(&r)?;
    } else {
        for v in &r.views {
            println!(
                "{:>16}  IoU {:.4}  uncovered {:.4}",
                v.view, v.iou, v.uncovered
            );
        }
        println!(
            "IoU min {:.4} mean {:.4}; {} surfels, {} triangles, volume {:.3e} m^3",
            r.iou_min, r.iou_mean, r.surfels, r.triangles, r.volume_m3
        );
        if let Some(f) = &r.reflectance {
            println!(
                "reflectance field: {} light images, {} of {} blocks kept, {:.2} components a block (max {}); {} numbers stored, {:.1}x fewer than the light images ({:.1}x fewer than their kept blocks); RMS {:.3} % of the mean radiance",
                f.light_images,
                f.blocks_kept,
                f.blocks_total,
                f.mean_components,
                f.max_components,
                f.floats_stored,
                f.ratio,
                f.ratio_kept,
                100.0 * f.relative_rms
            );
        }
    }
    Ok(())
}

fn run_render(a: RenderArgs) -> anyhow::Result<()> {
    let req = HullRenderRequest {
        hull: a.hull,
        camera: a.camera,
        lighting: a.lighting,
        output: a.output,
        k: a.k as usize,
    };
    let r = render_file(&req)?;
    if a.json {
        print_json(&serde_json::json!({
            "seconds": r.seconds,
            "width": r.width,
            "height": r.height,
            "surfels": r.surfels,
        }))?;
    } else {
        println!(
            "rendered {} x {} from {} surfels in {:.3} s -> {}",
            r.width,
            r.height,
            r.surfels,
            r.seconds,
            req.output.display()
        );
    }
    Ok(())
}
