//! `igi slf`: surface light fields (Wood et al. 2000; docs/LIGHTFIELD.md).
use crate::report::{print_json, Ctx};
use anyhow::Context;
use igi_lightfield::field::RenderSlfOptions;
use std::path::PathBuf;

#[derive(clap::Subcommand, Debug)]
pub enum SlfCmd {
    /// Render a stored surface light field (SLF_DIR) through a camera; with --mesh, a rotated
    /// or deformed copy of the stored mesh (same triangles and UVs) looks up its new normals.
    Render(RenderArgs),
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
    #[arg(long, default_value_t = 1.0)]
    pub white: f32,
    /// Output EXR: RGB plus the coverage as its `valid` channel.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Print the timing as JSON.
    #[arg(long)]
    pub json: bool,
}

pub fn run(c: SlfCmd, ctx: &Ctx) -> anyhow::Result<()> {
    match c {
        SlfCmd::Render(a) => render(a, ctx),
    }
}

fn render(a: RenderArgs, _ctx: &Ctx) -> anyhow::Result<()> {
    if !(a.bias > 0.0 && a.bias < 1.0) || !(a.white > 0.0 && a.white.is_finite()) {
        anyhow::bail!(
            "--bias must lie in (0, 1) and --white be positive (got {} and {})",
            a.bias,
            a.white
        );
    }
    let camera = igi_imaging::Camera::load(&a.camera)?;
    let (field, stored) = igi_lightfield::store::load(&a.slf_dir)
        .with_context(|| format!("reading {}", a.slf_dir.display()))?;
    let mesh = match &a.mesh {
        Some(p) => {
            let mut m = igi_geometry::read_mesh(p)?;
            if m.positions.len() != stored.positions.len() || m.indices != stored.indices {
                anyhow::bail!(
                    "{}: not a deformed copy of {} (vertex count or triangles differ)",
                    p.display(),
                    a.slf_dir.join("mesh.ply").display()
                );
            }
            if m.uvs.is_none() {
                m.uvs = stored.uvs.clone();
            }
            m.normals = None;
            m
        }
        None => stored,
    };
    let t = std::time::Instant::now();
    let (mut img, alpha) = field.render(
        &mesh,
        &camera,
        &RenderSlfOptions {
            bias: a.bias,
            white: a.white,
        },
    )?;
    let seconds = t.elapsed().as_secs_f64();
    img.valid = alpha.iter().map(|a| *a > 0.5).collect();
    igi_imaging::write_exr(&a.output, &img)?;
    if a.json {
        print_json(
            &serde_json::json!({ "seconds": seconds, "width": img.width, "height": img.height }),
        )?;
    } else {
        println!(
            "rendered {} x {} in {:.3} s -> {}",
            img.width,
            img.height,
            seconds,
            a.output.display()
        );
    }
    Ok(())
}
