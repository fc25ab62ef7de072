//! `igi solve`, `igi sample` and `igi export`: the inverse solver and what reads its result.
use crate::report::{Bar, Ctx};
use anyhow::bail;
use igi_export::ExportFormat;
use igi_reflect::{Schedule, SolveOptions};
use igi_workflow::{AtlasRequest, SolveRequest};
use std::path::PathBuf;

/// The options of the iteration, shared by `igi solve` and `igi cluster submit`.
#[derive(clap::Args, Debug)]
pub struct IterationArgs {
    /// Most iterations.
    #[arg(long, default_value_t = 4)]
    pub iterations: u32,
    /// Stop when the mean change of rho_d over seen texels is below this, or below the
    /// photographs' own noise in rho_d (after 2 iterations).
    #[arg(allow_negative_numbers = true, value_parser = crate::cmd::values::non_negative_f32, long, default_value_t = 0.002)]
    pub tolerance: f32,
    /// Samples per radiance estimate, per iteration (the last repeats). Without it: 16, 64,
    /// 256 as levels, the solve moving to the next level only after an iteration that changed
    /// rho_d by no more than its Monte-Carlo noise (while the albedo still settles, more
    /// samples would not make it settle faster; docs/SOLVER.md).
    #[arg(allow_negative_numbers = true, value_parser = clap::builder::RangedU64ValueParser::<u32>::new().range(1..), long, value_delimiter = ',')]
    pub spp: Option<Vec<u32>>,
    /// Indirect bounces after direct lighting.
    #[arg(allow_negative_numbers = true, value_parser = clap::builder::RangedU64ValueParser::<u32>::new().range(0..=64), long, default_value_t = 2)]
    pub indirect: u32,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Initial albedo of every texel (r,g,b).
    #[arg(allow_negative_numbers = true, value_parser = crate::cmd::values::unit_f32, long, value_delimiter = ',', default_value = "0.5,0.5,0.5")]
    pub initial: Vec<f32>,
    /// Rounds of footprint deblurring per iteration: each texel's reading of a photograph is
    /// corrected by the blur of the pixel footprint that the current albedo predicts. For
    /// albedo detail near the pixel size (the demo: MAE -20 % at 4 rounds); on smooth albedo
    /// each round adds noise (docs/SOLVER.md). 0: one bilinear read per texel and photograph.
    #[arg(allow_negative_numbers = true, value_parser = clap::builder::RangedU64ValueParser::<u32>::new().range(0..=100), long, default_value_t = 0)]
    pub deblur: u32,
    /// Average each texel's rendered shading with its neighbours' of the same surface and
    /// light (3 x 3 texels, never across a shadow edge or a crease) before dividing the
    /// photograph by it: the shading is smooth where the albedo is not, so this takes most of
    /// the solve's Monte-Carlo noise out of rho_d (docs/SOLVER.md). `false`: each texel's own.
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    pub shading_smoothing: bool,
    /// In the fine iteration after the coarse stage of `--atlas auto`, path-trace the shading
    /// at every fifth texel per atlas row and column and read the texels between bilinearly
    /// (never across a shadow edge, a crease, an occlusion boundary or a chart border;
    /// docs/SOLVER.md). `false`: trace every texel, the same error at several times the time.
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    pub shading_lattice: bool,
}

impl IterationArgs {
    /// These options over the defaults of [`SolveOptions`].
    pub fn options(&self) -> anyhow::Result<SolveOptions> {
        let [r, g, b] = self.initial[..] else {
            bail!("--initial takes three values r,g,b");
        };
        Ok(SolveOptions {
            max_iterations: self.iterations,
            tolerance: self.tolerance,
            spp: self
                .spp
                .clone()
                .unwrap_or_else(|| SolveOptions::default().spp),
            adaptive_spp: self.spp.is_none(),
            indirect: self.indirect,
            seed: self.seed,
            initial_albedo: [r, g, b],
            deblur: self.deblur,
            smooth_shading: self.shading_smoothing,
            lattice_shading: self.shading_lattice,
            ..SolveOptions::default()
        })
    }
}

#[derive(clap::Args, Debug)]
pub struct SolveArgs {
    /// Survey folder holding survey.toml (FORMATS.md), or the survey.toml itself.
    pub survey: PathBuf,
    /// Result folder (created; an unfinished result there is resumed).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Atlas resolution per part: `auto` (the default) chooses each part's from the pixel
    /// footprints of the photographs that resolve it (as many texels as the pixels of the
    /// finest photograph that sees each point unhidden, at most --atlas-max; a mesh that would
    /// exceed it, or whose far and near ends differ much, is cut into parts NAME-K;
    /// docs/SOLVER.md "Atlas resolution"), or a number gives every part that many texels per
    /// side (8 to 16384). With `auto`, the first iterations run on atlases three times coarser
    /// until their albedo settles, and one more on the chosen atlases ends the solve
    /// (docs/SOLVER.md "Coarse to fine").
    /// A prepared site keeps its own atlases. The atlases' memory is estimated before any work
    /// (192 bytes a texel, before the observations) and refused above 8 GiB, or the
    /// environment's IGI_MAX_MEMORY (e.g. 32G) (docs/RELIABILITY.md).
    #[arg(long, default_value = "auto", value_parser = parse_atlas)]
    pub atlas: AtlasArg,
    /// With `--atlas auto`: the most texels per side of any part (the memory budget; at least
    /// 64).
    #[arg(long, default_value_t = 2048)]
    pub atlas_max: u32,
    #[command(flatten)]
    pub iteration: IterationArgs,
    /// Solve only these parts, comma-separated, to share a site between machines: site meshes
    /// by file stem (a mesh that --atlas auto cut into pieces NAME-K selects all of them, and
    /// NAME-K one), or for a prepared site voxels as I_J_K (and `terrain`).
    #[arg(
        long,
        visible_alias = "voxels",
        value_delimiter = ',',
        allow_hyphen_values = true
    )]
    pub parts: Option<Vec<String>>,
    /// A scene file with the true albedo over the same geometry: the report then records the
    /// rho_d error per iteration, over the texels seen twice and over the surface (as rendered,
    /// at area-uniform points whose texel was seen twice: comparable between atlas resolutions).
    #[arg(long)]
    pub truth: Option<PathBuf>,
    /// Start afresh: remove what an earlier solve wrote into the output folder. Without it, a
    /// folder holding a run with other inputs, options or parts is refused (run.json).
    #[arg(long)]
    pub restart: bool,
    /// Order of updates in a prepared site's iteration: gauss-seidel (each voxel sees the new
    /// albedo of the voxels solved before it) or jacobi (iteration k sees only iteration k-1:
    /// the voxels are independent, as on a cluster; checkpoints once per iteration).
    #[arg(long, default_value = "gauss-seidel", value_parser = ["gauss-seidel", "jacobi"])]
    pub schedule: String,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
}

/// The value of `--atlas`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AtlasArg {
    Fixed(u32),
    Auto,
}

fn parse_atlas(s: &str) -> Result<AtlasArg, String> {
    if s == "auto" {
        return Ok(AtlasArg::Auto);
    }
    s.parse::<u32>().map(AtlasArg::Fixed).map_err(|_| {
        format!("`{s}` is neither `auto` nor a resolution in texels per side (e.g. 512)")
    })
}

impl SolveArgs {
    /// The job `igi solve` asks for.
    fn request(&self) -> anyhow::Result<SolveRequest> {
        let options = SolveOptions {
            parts: self.parts.clone(),
            schedule: if self.schedule == "jacobi" {
                Schedule::Jacobi
            } else {
                Schedule::GaussSeidel
            },
            ..self.iteration.options()?
        };
        Ok(SolveRequest {
            survey: self.survey.clone(),
            output: self.output.clone(),
            atlas: match self.atlas {
                AtlasArg::Fixed(n) => AtlasRequest::Fixed(n),
                AtlasArg::Auto => AtlasRequest::Auto {
                    max: self.atlas_max,
                },
            },
            options,
            truth: self.truth.clone(),
            restart: self.restart,
        })
    }
}

pub fn run_solve(a: SolveArgs, ctx: &Ctx) -> anyhow::Result<()> {
    let request = a.request()?;
    let bar = Bar(ctx.progress(1, "solve"));
    let result = igi_workflow::solve(&request, &bar)?;
    bar.0.finish_and_clear();
    print_report(&result.report, &a.output, a.json)
}

/// Per iteration and per part, one line each (or the report as JSON).
fn print_report(
    report: &igi_reflect::SolveReport,
    output: &std::path::Path,
    json: bool,
) -> anyhow::Result<()> {
    if json {
        return crate::report::print_json(report);
    }
    for r in &report.iterations {
        let truth = r
            .truth_mae
            .map(|m| format!(", rho_d MAE {:.4} {:.4} {:.4}", m[0], m[1], m[2]))
            .unwrap_or_default();
        let surface = r
            .truth_surface_mae
            .map(|m| format!(" (over the surface {:.4} {:.4} {:.4})", m[0], m[1], m[2]))
            .unwrap_or_default();
        println!(
            "iteration {}{}: {} spp, {:.1} s, {} observations, residual {:.2}% (relative RMS), change {:.4}{}{}",
            r.iteration,
            if r.coarse { " (coarse atlases)" } else { "" },
            r.spp,
            r.wall_s,
            r.observations,
            100.0 * r.residual_rel_rms,
            r.delta_rho,
            truth,
            surface
        );
    }
    for p in &report.parts {
        let footprint = p
            .footprint_m
            .map(|f| format!(" (resolving pixel footprint {f:.4} m)"))
            .unwrap_or_default();
        println!(
            "part {}: {}x{} atlas, {} texels of {:.4} m{footprint}, {} seen ({} by 2+ photos), {} filled",
            p.name,
            p.resolution,
            p.resolution,
            p.covered_texels,
            p.texel_size_m,
            p.seen_texels,
            p.seen_twice_texels,
            p.filled_texels
        );
    }
    println!("result in {}", output.display());
    Ok(())
}

#[derive(clap::Args, Debug)]
pub struct SampleArgs {
    /// Result folder of `igi solve`.
    pub result: PathBuf,
    /// CSV with x,y,z,nx,ny,nz per row (a header row is allowed).
    #[arg(long)]
    pub points: PathBuf,
    /// Output CSV: the input columns plus r,g,b (diffuse albedo) and sr,sg,sb (its standard
    /// error per channel at the nearest texel; empty where unknown: a texel not seen in the
    /// last iteration, or a result written before standard errors were stored).
    #[arg(short, long)]
    pub output: PathBuf,
}

pub fn run_sample(a: SampleArgs, _ctx: &Ctx) -> anyhow::Result<()> {
    let n = igi_export::sample_file(&a.result, &a.points, &a.output)?;
    println!("{n} points -> {}", a.output.display());
    Ok(())
}

#[derive(clap::Args, Debug)]
pub struct ExportArgs {
    /// Result folder of `igi solve`.
    pub result: PathBuf,
    /// ply, obj, mitsuba or gltf. Every format writes per part the albedo (NAME_albedo.exr)
    /// and the lobe maps when the result has lobes (NAME_lobeK_rho.exr, NAME_lobeK_shape.exr);
    /// ply, obj and mitsuba the mesh with atlas UVs and an igi scene.toml of them; mitsuba adds
    /// scene.xml, which keeps the diffuse term only (Mitsuba 3 has no Lafortune BSDF). gltf
    /// writes one binary glTF 2.0 file, scene.glb: a mesh and a material per part, Y up at its
    /// root node, base colour the albedo as an embedded 8-bit sRGB PNG, the lobes approximated
    /// by roughness and KHR_materials_specular fitted by least squares (the fit's relative RMS
    /// error printed; retroreflective lobes folded in), the exact lobes in the material's
    /// extras (docs/EXPORT.md). A prepared site's result, or one whose single GLB would pass
    /// 2 GiB, is written as 3D Tiles 1.1 instead: NAME_levelL.glb per part and level and a
    /// tileset.json.
    #[arg(long)]
    pub format: ExportFormat,
    /// Output folder: new, empty, or an earlier `igi export` (its export.json lists its files),
    /// which is replaced whole; never the result folder or a folder inside it.
    #[arg(short, long)]
    pub output: PathBuf,
}

pub fn run_export(a: ExportArgs, _ctx: &Ctx) -> anyhow::Result<()> {
    let done = igi_export::export(&a.result, a.format, &a.output)?;
    for (part, lobes, f) in &done.materials {
        if *lobes == 0 {
            println!("part {part}: no lobes: pure diffuse (roughness 1, specular 0, exact)");
        } else {
            let retro = if f.retroreflective_lobes > 0 {
                format!(
                    ", {} retroreflective lobe(s) folded in",
                    f.retroreflective_lobes
                )
            } else {
                String::new()
            };
            println!(
                "part {part}: {lobes} lobe(s) as roughness {:.3}, specular {:.3}, specular colour {:.3} {:.3} {:.3}: fit error {:.1}% (relative RMS){retro}",
                f.roughness,
                f.specular,
                f.specular_color[0],
                f.specular_color[1],
                f.specular_color[2],
                100.0 * f.rel_rms
            );
        }
    }
    println!(
        "{} files written to {}",
        done.files.len(),
        a.output.display()
    );
    Ok(())
}
