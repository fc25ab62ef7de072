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
    /// Voxelize a scanned site into a multiresolution store with atlases. (planned: issue 6)
    Prepare(cmd::prepare::PrepareArgs),
    /// Summarise a prepared site. (planned: issue 6)
    Info(cmd::prepare::InfoArgs),
    /// Recover per-texel reflectance from a survey folder. (planned: issue 7)
    Solve(cmd::planned::PlannedArgs),
    /// Recovered albedo at given surface points. (planned: issue 7)
    Sample(cmd::planned::PlannedArgs),
    /// Export a recovered site as PLY, OBJ or a Mitsuba 3 scene. (planned: issue 7)
    Export(cmd::planned::PlannedArgs),
    /// The embedded default: build a procedural site, light it, render it, report.
    Demo(cmd::demo::DemoArgs),
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
        Command::Solve(a) => cmd::planned::run("solve", 7, a),
        Command::Sample(a) => cmd::planned::run("sample", 7, a),
        Command::Export(a) => cmd::planned::run("export", 7, a),
        Command::Demo(a) => cmd::demo::run(a, &ctx),
    };
    if let Err(e) = result {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
