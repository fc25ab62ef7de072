//! `igi hull`: opacity hulls from multi-view captures (Matusik et al. 2002).
use crate::report::{print_json, Ctx};
use igi_opacity_hull::build::{build, load_model, BuildOptions, Stage};
use igi_opacity_hull::render::{render, RenderOptions};
use std::path::PathBuf;

#[derive(clap::Subcommand, Debug)]
pub enum HullCmd {
    /// Build a hull folder from a rig.toml: mattes, visual hull (hull.ply), surfels
    /// (surfels.ply), volume against views (volume.png) and report.json (per-view IoU, timings).
    Build(BuildArgs),
    /// Render a hull folder from a camera to an RGBA EXR (colour premultiplied by alpha) with
    /// unstructured-lumigraph blending of the input photos.
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
    /// Carving cells per axis of the bounding box (at least 256).
    #[arg(long, default_value_t = 256)]
    pub resolution: usize,
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
    /// Lighting file: relighting from one-light-at-a-time captures (not implemented yet).
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
    let rig = igi_imaging::Rig::load(&a.rig)?;
    let opts = BuildOptions {
        resolution: a.resolution,
        ..Default::default()
    };
    let pb = ctx.progress(6, "hull");
    let mut progress = |s: Stage| {
        pb.set_message(format!("{s:?}").to_lowercase());
        pb.inc(1);
    };
    let r = build(&rig, &a.output, opts, &mut progress)?;
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
    }
    Ok(())
}

fn run_render(a: RenderArgs) -> anyhow::Result<()> {
    if let Some(l) = &a.lighting {
        anyhow::bail!(
            "{}: relighting from one-light-at-a-time captures is not implemented yet",
            l.display()
        );
    }
    let camera = igi_imaging::Camera::load(&a.camera)?;
    let model = load_model(&a.hull)?;
    let t = std::time::Instant::now();
    let opts = RenderOptions {
        k: a.k as usize,
        ..Default::default()
    };
    let (img, alpha) = render(&model, &camera, opts);
    let seconds = t.elapsed().as_secs_f64();
    igi_imaging::write_exr_rgba(&a.output, &img, &alpha)?;
    if a.json {
        print_json(&serde_json::json!({
            "seconds": seconds,
            "width": img.width,
            "height": img.height,
            "surfels": model.surfels.len(),
        }))?;
    } else {
        println!(
            "rendered {} x {} from {} surfels in {:.3} s -> {}",
            img.width,
            img.height,
            model.surfels.len(),
            seconds,
            a.output.display()
        );
    }
    Ok(())
}
