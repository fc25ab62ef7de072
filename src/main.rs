//! `igi`: the command-line front end of the igi toolkit.
//!
//! This binary only parses arguments, calls the libraries in `crates/` and reports.
//! Every algorithm lives in a library crate; see `docs/ARCHITECTURE.md`.

mod cmd;
mod report;

use clap::{Parser, Subcommand};

/// Outdoor inverse global illumination: recover per-texel reflectance of a scanned site
/// from photographs and captured natural light, and re-render it under any light.
#[derive(Parser, Debug)]
#[command(name = "igi", version, about, long_about = None, propagate_version = true)]
struct Cli {
    /// More logging (-v info, -vv debug, -vvv trace). Logs go to stderr.
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    verbose: u8,

    /// Hide progress bars.
    #[arg(short, long, global = true)]
    quiet: bool,

    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// High-dynamic-range images: merge exposure brackets.
    #[command(subcommand)]
    Hdr(cmd::hdr::HdrCmd),
    /// Cameras: undistort images, estimate a pose (PnP), calibrate intrinsics.
    #[command(subcommand)]
    Camera(cmd::camera::CameraCmd),
    /// Render a scene file (or a recovered site) with the path tracer.
    Render(cmd::render::RenderArgs),
    /// Compare two images: RMSE, relative mean difference, PSNR and a difference picture.
    Compare(cmd::compare::CompareArgs),
    /// Lighting from a capture of the three-sphere board: sky map, sun, diagnostics.
    Probe(cmd::probe::ProbeArgs),
    /// BRDFs from hand-held samples: fit, eval, infer, cluster.
    #[command(subcommand)]
    Brdf(cmd::brdf::BrdfCmd),
    /// Voxelize a scanned site into a multiresolution store with atlases.
    Prepare(cmd::prepare::PrepareArgs),
    /// Summarise a prepared site.
    Info(cmd::prepare::InfoArgs),
    /// Recover per-texel reflectance from a survey folder (iterative inverse global illumination).
    Solve(cmd::solve::SolveArgs),
    /// Recovered diffuse albedo at given surface points (compare with colour-checker readings).
    Sample(cmd::solve::SampleArgs),
    /// Export a recovered site as PLY, OBJ, a Mitsuba 3 scene or glTF 2.0.
    Export(cmd::solve::ExportArgs),
    /// Solve a prepared site across a Slurm cluster: submit, status, resume, cancel.
    #[command(subcommand)]
    Cluster(cmd::cluster::ClusterCmd),
    /// Surface light fields (Wood et al. 2000): render a stored field, edit it.
    #[command(subcommand)]
    Slf(cmd::slf::SlfCmd),
    /// Opacity hulls (Matusik et al. 2002): backdrops, Middlebury import, build, render.
    #[command(subcommand)]
    Hull(cmd::hull::HullCmd),
    /// Photogrammetry models as survey folders (COLMAP), aligned to the scan by control points.
    #[command(subcommand)]
    Import(cmd::import::ImportCmd),
    /// The embedded default: a procedural site photographed under three skies, solved, re-lit.
    Demo(cmd::demo::DemoArgs),
    /// A local web viewer of a result folder (three.js, on 127.0.0.1): orbit, relight with a
    /// sun, albedo alone; the first line of output is its URL.
    View(cmd::view::ViewArgs),
    /// The lighting file of a place and time: sun position (NREL SPA) and Hosek-Wilkie clear
    /// sky, or the CIE overcast sky, as a lat-long map and `[sun]`.
    Sky(cmd::sky::SkyArgs),
}

fn main() {
    let cli = Cli::parse();
    report::init_logging(cli.verbose);
    let ctx = report::Ctx { quiet: cli.quiet };
    let result = match cli.command {
        Command::Hdr(c) => cmd::hdr::run(c, &ctx),
        Command::Camera(c) => cmd::camera::run(c, &ctx),
        Command::Render(a) => cmd::render::run(a, &ctx),
        Command::Compare(a) => cmd::compare::run(a, &ctx),
        Command::Probe(a) => cmd::probe::run(a, &ctx),
        Command::Brdf(c) => cmd::brdf::run(c, &ctx),
        Command::Prepare(a) => cmd::prepare::run_prepare(a, &ctx),
        Command::Info(a) => cmd::prepare::run_info(a, &ctx),
        Command::Solve(a) => cmd::solve::run_solve(a, &ctx),
        Command::Sample(a) => cmd::solve::run_sample(a, &ctx),
        Command::Export(a) => cmd::solve::run_export(a, &ctx),
        Command::Demo(a) => cmd::demo::run(a, &ctx),
        Command::Slf(c) => cmd::slf::run(c, &ctx),
        Command::Hull(c) => cmd::hull::run(c, &ctx),
        Command::Cluster(c) => cmd::cluster::run(c, &ctx),
        Command::Import(c) => cmd::import::run(c, &ctx),
        Command::View(a) => cmd::view::run(a, &ctx),
        Command::Sky(a) => cmd::sky::run(a, &ctx),
    };
    if let Err(e) = result {
        eprintln!("error: {}", error_chain(&e));
        std::process::exit(1);
    }
}

/// The error and its causes joined by ": ", leaving out a cause its parent already shows
/// (error types that print their source would otherwise repeat it).
fn error_chain(e: &anyhow::Error) -> String {
    let mut msg = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        if msg.contains(&text) {
            continue;
        }
        if !msg.is_empty() {
            msg.push_str(": ");
        }
        msg.push_str(&text);
    }
    msg
}
