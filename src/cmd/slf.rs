//! `igi slf`: surface light fields (Wood et al. 2000; docs/LIGHTFIELD.md).
use crate::report::{print_json, Ctx};
use igi_lightfield::capture::{GridOptions, STAGES};
use igi_lightfield::job::{build_file, render_file, BuildRequest, BuildStep, RenderRequest};
use igi_lightfield::{BuildOptions, Method};
use std::path::PathBuf;

#[derive(clap::Subcommand, Debug)]
pub enum SlfCmd {
    /// Build a surface light field from a multi-view capture (rig.toml, FORMATS.md) and a mesh
    /// of the object in the same world frame: data lumispheres at the covered texels of an
    /// atlas of the mesh, fitted by pointwise fairing, function quantization or principal
    /// function analysis, stored in SLF_DIR (docs/LIGHTFIELD.md).
    Build(BuildArgs),
    /// Render a stored surface light field (SLF_DIR) through a camera; with --mesh, a rotated
    /// or deformed copy of the stored mesh (same triangles and UVs) looks up its new normals.
    Render(RenderArgs),
}

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum MethodArg {
    /// Pointwise fairing (each lumisphere on its own).
    Fair,
    /// Function quantization (a codebook of --codewords lumispheres).
    Fq,
    /// Principal function analysis (--q prototypes per point).
    Pfa,
    /// The median texture alone (the diffuse baseline).
    Median,
}

#[derive(clap::Args, Debug)]
pub struct BuildArgs {
    /// The multi-view capture (rig.toml): views with a camera and a photo each, an optional
    /// mask (pixels outside it are ignored); clipped pixels of 8-bit photos are ignored.
    pub rig: PathBuf,
    /// The object's mesh (PLY or OBJ) in the rig's world frame.
    #[arg(long)]
    pub mesh: PathBuf,
    #[arg(long, value_enum, default_value = "pfa")]
    pub method: MethodArg,
    /// Prototypes per point for --method pfa.
    #[arg(long, default_value_t = 2)]
    pub q: usize,
    /// Codebook size for --method fq (a power of two).
    #[arg(long, default_value_t = 256)]
    pub codewords: usize,
    /// Atlas texels a side (its covered texels are the grid points).
    #[arg(long, default_value_t = 256)]
    pub atlas: u32,
    /// Keep about this fraction of the mesh's triangles before the atlas (dense scans and hull
    /// meshes have more charts than an atlas holds); 1 keeps the mesh as it is.
    #[arg(allow_negative_numbers = true, value_parser = crate::cmd::values::share, long, default_value_t = 1.0)]
    pub simplify: f64,
    /// Octahedron subdivisions of a lumisphere (3: 258 directions).
    #[arg(long, default_value_t = 3)]
    pub level: u32,
    /// Weight of the thin-plate smoothness term of the fits.
    #[arg(allow_negative_numbers = true, value_parser = crate::cmd::values::non_negative_f32, long, default_value_t = 0.02)]
    pub lambda: f32,
    /// Seed of the training subsets (same seed, same bytes).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Output folder (new, empty, or an earlier SLF_DIR, which is replaced).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Args, Debug)]
pub struct RenderArgs {
    /// The folder `igi slf build` wrote.
    pub slf_dir: PathBuf,
    /// The camera (FORMATS.md JSON).
    #[arg(long)]
    pub camera: PathBuf,
    /// A rotated or deformed copy of SLF_DIR/mesh.ply (same vertex count, triangles and UVs).
    #[arg(long)]
    pub mesh: Option<PathBuf>,
    /// Perlin bias on the output values (0.5: unchanged; lower sharpens highlights).
    #[arg(long, default_value_t = 0.5)]
    pub bias: f32,
    /// The value mapped to 1 before the bias.
    #[arg(allow_negative_numbers = true, value_parser = crate::cmd::values::positive_f32, long, default_value_t = 1.0)]
    pub white: f32,
    /// Output EXR, RGBA (FORMATS.md): radiance where the surface is seen, alpha 1 there and 0
    /// elsewhere (colour premultiplied, so 0 where alpha is 0).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Print the timing as JSON.
    #[arg(long)]
    pub json: bool,
}

pub fn run(c: SlfCmd, ctx: &Ctx) -> anyhow::Result<()> {
    match c {
        SlfCmd::Build(a) => build(a, ctx),
        SlfCmd::Render(a) => render(a, ctx),
    }
}

fn build(a: BuildArgs, ctx: &Ctx) -> anyhow::Result<()> {
    let method = match a.method {
        MethodArg::Fair => Method::Fair,
        MethodArg::Fq => Method::Fq {
            codewords: a.codewords,
        },
        MethodArg::Pfa => Method::Pfa { q: a.q },
        MethodArg::Median => Method::MedianOnly,
    };
    let req = BuildRequest {
        rig: a.rig,
        mesh: a.mesh,
        method,
        options: BuildOptions {
            level: a.level,
            lambda: a.lambda,
            seed: a.seed,
            ..BuildOptions::default()
        },
        grid: GridOptions {
            atlas: a.atlas,
            simplify: a.simplify,
        },
        output: a.output,
    };
    let bar = ctx.progress(STAGES.len() as u64, "slf build");
    let r = build_file(&req, &|s| match s {
        BuildStep::Stage(k) => {
            bar.set_position(k as u64);
            bar.set_message(STAGES[k]);
        }
        BuildStep::Warning(w) => {
            bar.finish_and_clear();
            eprintln!("warning: {w}");
        }
    })?;
    bar.finish_and_clear();
    if a.json {
        return print_json(&r.report);
    }
    println!(
        "{} views, {} grid points ({} unseen), {} samples; atlas texel {:.4} m, median pixel footprint {:.4} m; colour {} bytes ({:.1}:1 against faired RGB8) in {:.1} s -> {}",
        r.views,
        r.points,
        r.unseen_points,
        r.samples,
        r.texel_size,
        r.median_pixel_footprint,
        r.report.colour_bytes,
        r.report.compression_ratio,
        r.seconds,
        req.output.display()
    );
    if let (Some(grazing), Some(head_on)) = (r.angle_gain.first(), r.angle_gain.last()) {
        println!(
            "view-angle gain: the view-dependent colour is {:.2} times as large at grazing views as head-on (n . w = 0 against 1)",
            grazing / head_on
        );
    }
    Ok(())
}

fn render(a: RenderArgs, _ctx: &Ctx) -> anyhow::Result<()> {
    let req = RenderRequest {
        slf_dir: a.slf_dir,
        camera: a.camera,
        mesh: a.mesh,
        bias: a.bias,
        white: a.white,
        output: a.output,
    };
    let r = render_file(&req)?;
    if a.json {
        print_json(
            &serde_json::json!({ "seconds": r.seconds, "width": r.width, "height": r.height }),
        )?;
    } else {
        println!(
            "rendered {} x {} in {:.3} s -> {}",
            r.width,
            r.height,
            r.seconds,
            req.output.display()
        );
    }
    Ok(())
}
