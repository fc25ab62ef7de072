//! `igi brdf`: fit Lafortune BRDFs to hand-held samples, evaluate them, infer lobes from a
//! diffuse colour, cluster lumitexels (Lensch et al.), and measure samples from photographs of
//! the hand-held sample frame.

use std::path::PathBuf;

use igi_brdf::job::{
    cluster_file, eval_file, fit_file, infer_file, ClusterRequest, EvalRequest, FitRequest,
    FitStep, InferRequest,
};
use igi_capture::job::{measure_files, MeasureRequest};

use crate::report::{print_json, Ctx};

#[derive(clap::Subcommand, Debug)]
pub enum BrdfCmd {
    /// Fit Lambertian + retroreflective + specular Lafortune lobes per material (LM, staged;
    /// samples weighted by their coverage of the direction pairs, lobe growth toward grazing
    /// bounded).
    Fit(FitArgs),
    /// Evaluate a fitted material at direction pairs (writes r, g, b = pi * f).
    Eval(EvalArgs),
    /// Infer a full BRDF from a diffuse colour (PCA basis of the fitted materials).
    Infer(InferArgs),
    /// Cluster lumitexels into K BRDFs and give each lumitexel basis weights.
    Cluster(ClusterArgs),
    /// BRDF samples from photographs of the hand-held sample frame (pose from the fiducials,
    /// light from the two black spheres' highlights, the white standard, an orthographic view).
    Measure(MeasureArgs),
}

#[derive(clap::Args, Debug)]
pub struct MeasureArgs {
    /// Sample-frame description JSON (docs/BRDF.md, "Measuring samples").
    pub frame: PathBuf,
    /// A linear photograph of the frame (EXR, HDR, ...); repeat for several.
    #[arg(long = "photo", required = true)]
    pub photos: Vec<PathBuf>,
    /// Camera JSON (FORMATS.md): intrinsics and distortion; its pose is ignored.
    #[arg(long)]
    pub camera: PathBuf,
    /// Pixels of the fiducials' centres, u,v,u,v,u,v,u,v in the frame file's order; one per
    /// --photo, in the same order. Without --corners the fiducials are found as ArUco markers
    /// (needs a build with --features opencv).
    #[arg(long = "corners")]
    pub corners: Vec<String>,
    /// Output samples CSV (material,light_x..view_z,r,g,b with r g b = pi f).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Also write each photo's orthographic view of the sample as DIR/STEM_ortho.exr (STEM: the photo's file stem).
    #[arg(long)]
    pub ortho_dir: Option<PathBuf>,
    /// Print the per-photo report (pose, light, gap, highlights, regions) as JSON.
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Args, Debug)]
pub struct FitArgs {
    /// Samples CSV: material,light_x,light_y,light_z,view_x,view_y,view_z,r,g,b (r g b = pi f).
    pub samples: PathBuf,
    /// Output materials JSON.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Also draw data and fitted lobes in the plane of incidence (PNG, like the paper's Fig. 4).
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Largest lobe exponent N.
    #[arg(allow_negative_numbers = true, value_parser = crate::cmd::values::positive, long, default_value_t = 2.0e4)]
    pub max_n: f64,
    /// Weight each sample by the share of all direction pairs it stands for (its Voronoi cell in
    /// the isotropic pair space), each weight at most this times the mean; 0 = unweighted
    /// (docs/BRDF.md, "Sparse hand-held samples").
    #[arg(allow_negative_numbers = true, value_parser = crate::cmd::values::non_negative, long, default_value_t = igi_brdf::fit::COVERAGE_CAP)]
    pub coverage_cap: f64,
    /// Largest grazing gain |Cxy|^N of a lobe (its peak at grazing over its peak at normal
    /// incidence); `inf` = unbounded.
    #[arg(long, default_value_t = igi_brdf::fit::MAX_GAIN)]
    pub max_gain: f64,
    /// The plain weighted least squares of before issue 16: no coverage weights, no gain bound
    /// (overrides --coverage-cap and --max-gain).
    #[arg(long)]
    pub plain: bool,
}

#[derive(clap::Args, Debug)]
pub struct EvalArgs {
    /// Materials JSON (from `igi brdf fit`).
    pub materials: PathBuf,
    /// Material name.
    #[arg(long)]
    pub material: String,
    /// CSV with light_x..view_z columns (other columns are passed through).
    #[arg(long)]
    pub pairs: PathBuf,
    /// Output CSV: the pairs plus r, g, b = pi * f.
    #[arg(short, long)]
    pub output: PathBuf,
}

#[derive(clap::Args, Debug)]
pub struct InferArgs {
    /// Materials JSON used as the basis.
    pub materials: PathBuf,
    /// Diffuse colour r,g,b.
    #[arg(allow_negative_numbers = true, value_parser = crate::cmd::values::unit_f32, long, value_delimiter = ',', required = true)]
    pub rho: Vec<f32>,
    /// Write the inferred material as a materials JSON (name "inferred") instead of printing it.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
}

#[derive(clap::Args, Debug)]
pub struct ClusterArgs {
    /// Lumitexels CSV: id,px,py,pz,nx,ny,nz,light_x,light_y,light_z,view_x,view_y,view_z,r,g,b (world frame).
    pub lumitexels: PathBuf,
    /// Number of clusters.
    #[arg(allow_negative_numbers = true, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..), short, long)]
    pub k: usize,
    /// Output JSON: cluster BRDFs and per-lumitexel cluster and weights.
    #[arg(short, long)]
    pub output: PathBuf,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

pub fn run(cmd: BrdfCmd, ctx: &Ctx) -> anyhow::Result<()> {
    match cmd {
        BrdfCmd::Fit(a) => fit(a, ctx),
        BrdfCmd::Eval(a) => eval(a),
        BrdfCmd::Infer(a) => infer(a),
        BrdfCmd::Cluster(a) => run_cluster(a),
        BrdfCmd::Measure(a) => measure(a),
    }
}

fn fit(a: FitArgs, ctx: &Ctx) -> anyhow::Result<()> {
    let req = FitRequest {
        samples: a.samples,
        output: a.output,
        plot: a.plot,
        max_n: a.max_n,
        coverage_cap: a.coverage_cap,
        max_gain: a.max_gain,
        plain: a.plain,
    };
    let pb = ctx.progress(0, "fitting");
    let step = |s: FitStep| match s {
        FitStep::Materials(n) => pb.set_length(n as u64),
        FitStep::Fitted => pb.inc(1),
    };
    fit_file(&req, &step, &|reports| {
        pb.finish_and_clear();
        print_fits(reports);
    })?;
    Ok(())
}

/// One line per material and one per lobe.
fn print_fits(reports: &[igi_brdf::FitReport]) {
    println!(
        "{:<16} {:>7} {:>9} {:>10}  rho_d / lobes (rho, cxy, cz, n)",
        "material", "samples", "rel.rms", "abs.rms"
    );
    for r in reports {
        let b = &r.brdf;
        println!(
            "{:<16} {:>7} {:>9.4} {:>10.3e}  [{:.4}, {:.4}, {:.4}]",
            r.material, r.samples, r.rms, r.rms_abs, b.rho_d.x, b.rho_d.y, b.rho_d.z
        );
        for l in &b.lobes {
            println!(
                "{:<46}  [{:.4e}, {:.4e}, {:.4e}] {:+.4} {:+.4} {:.2}",
                "", l.rho.x, l.rho.y, l.rho.z, l.cxy, l.cz, l.n
            );
        }
    }
}

fn eval(a: EvalArgs) -> anyhow::Result<()> {
    let req = EvalRequest {
        materials: a.materials,
        material: a.material,
        pairs: a.pairs,
        output: a.output,
    };
    Ok(eval_file(&req)?)
}

fn infer(a: InferArgs) -> anyhow::Result<()> {
    let req = InferRequest {
        materials: a.materials,
        rho: a.rho,
        output: a.output,
    };
    let text = infer_file(&req)?;
    if req.output.is_none() {
        print!("{text}");
    }
    Ok(())
}

fn run_cluster(a: ClusterArgs) -> anyhow::Result<()> {
    let req = ClusterRequest {
        lumitexels: a.lumitexels,
        k: a.k,
        seed: a.seed,
        output: a.output,
    };
    for (k, c) in cluster_file(&req)?.iter().enumerate() {
        println!(
            "cluster {k}: {} lumitexels, rho_d [{:.4}, {:.4}, {:.4}]",
            c.lumitexels, c.rho_d[0], c.rho_d[1], c.rho_d[2]
        );
    }
    Ok(())
}

fn measure(a: MeasureArgs) -> anyhow::Result<()> {
    let req = MeasureRequest {
        frame: a.frame,
        photos: a.photos,
        camera: a.camera,
        corners: a.corners,
        output: a.output.clone(),
        ortho_dir: a.ortho_dir,
    };
    let r = measure_files(&req)?;
    if a.json {
        return print_json(&r.photos);
    }
    for m in &r.photos {
        let c = m.camera_center;
        let l = m.light;
        println!(
            "{}: pose from {} (rms {:.2} px), camera at [{:.4}, {:.4}, {:.4}] m, light at [{:.4}, {:.4}, {:.4}] m (rays {:.1} mm apart), intensity [{:.4}, {:.4}, {:.4}]",
            m.photo.display(), m.pose_source, m.pose_rms_px, c[0], c[1], c[2], l[0], l[1], l[2], m.gap * 1e3,
            m.intensity[0], m.intensity[1], m.intensity[2]
        );
        for r in &m.regions {
            println!(
                "  {:<14} at [{:+.4}, {:+.4}]  light [{:+.3}, {:+.3}, {:+.3}]  view [{:+.3}, {:+.3}, {:+.3}]  pi f [{:.4}, {:.4}, {:.4}]  (sd {:.1}%)",
                r.material, r.center[0], r.center[1], r.light[0], r.light[1], r.light[2], r.view[0], r.view[1], r.view[2],
                r.value[0], r.value[1], r.value[2], r.rel_std * 100.0
            );
        }
    }
    println!(
        "{} samples from {} photos -> {}",
        r.samples,
        r.photos.len(),
        a.output.display()
    );
    Ok(())
}
