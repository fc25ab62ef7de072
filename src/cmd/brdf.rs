//! `igi brdf`: fit Lafortune BRDFs to hand-held samples, evaluate them, infer lobes from a
//! diffuse colour, and cluster lumitexels (Lensch et al.).

use std::path::PathBuf;

use anyhow::{bail, Context};
use glam::Vec3;
use igi_brdf::{
    cluster, fit_material, plot::plot_fits, plot::write_text_atomic, read_lumitexels, read_pairs, read_samples,
    samples::group_by_material, samples::pairs_to_csv, Basis, ClusterOptions, FitOptions, MaterialsFile,
};
use rayon::prelude::*;

use crate::report::Ctx;

#[derive(clap::Subcommand, Debug)]
pub enum BrdfCmd {
    /// Fit Lambertian + retroreflective + specular Lafortune lobes per material (LM, staged).
    Fit(FitArgs),
    /// Evaluate a fitted material at direction pairs (writes r, g, b = pi * f).
    Eval(EvalArgs),
    /// Infer a full BRDF from a diffuse colour (PCA basis of the fitted materials).
    Infer(InferArgs),
    /// Cluster lumitexels into K BRDFs and give each lumitexel basis weights.
    Cluster(ClusterArgs),
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
    #[arg(long, default_value_t = 2.0e4)]
    pub max_n: f64,
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
    #[arg(long, value_delimiter = ',', required = true)]
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
    #[arg(short, long)]
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
    }
}

fn fit(a: FitArgs, ctx: &Ctx) -> anyhow::Result<()> {
    let samples = read_samples(&a.samples)?;
    let groups = group_by_material(&samples);
    let opts = FitOptions { max_n: a.max_n, ..Default::default() };
    let pb = ctx.progress(groups.len() as u64, "fitting");
    let reports: Vec<_> = groups
        .par_iter()
        .map(|(name, s)| {
            let r = fit_material(name, s, &opts).with_context(|| format!("fitting {}", a.samples.display()));
            pb.inc(1);
            r
        })
        .collect::<Result<_, _>>()?;
    pb.finish_and_clear();
    let file = MaterialsFile::from_reports(&reports);
    write_text_atomic(&a.output, &file.to_json())?;
    println!("{:<16} {:>7} {:>9} {:>10}  rho_d / lobes (rho, cxy, cz, n)", "material", "samples", "rel.rms", "abs.rms");
    for r in &reports {
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
    if let Some(p) = &a.plot {
        let m: Vec<_> = reports
            .iter()
            .zip(&groups)
            .map(|(r, (name, s))| (name.clone(), s.clone(), r.brdf.clone()))
            .collect();
        plot_fits(p, &m)?;
    }
    Ok(())
}

fn eval(a: EvalArgs) -> anyhow::Result<()> {
    let file = MaterialsFile::read(&a.materials)?;
    let m = file.get(&a.material).with_context(|| format!("in {}", a.materials.display()))?;
    let table = read_pairs(&a.pairs)?;
    let values: Vec<Vec3> = table.rows.iter().map(|r| m.as_ref().eval(r.light, r.view) * std::f32::consts::PI).collect();
    write_text_atomic(&a.output, &pairs_to_csv(&table, &values))?;
    Ok(())
}

fn infer(a: InferArgs) -> anyhow::Result<()> {
    if a.rho.len() != 3 || a.rho.iter().any(|x| !x.is_finite() || *x < 0.0) {
        bail!("--rho needs three finite non-negative numbers r,g,b (got {:?})", a.rho);
    }
    let file = MaterialsFile::read(&a.materials)?;
    let basis = Basis::new(file.brdfs())?;
    let m = basis.infer(Vec3::new(a.rho[0], a.rho[1], a.rho[2]));
    let mut out = MaterialsFile::default();
    out.materials.insert(
        "inferred".into(),
        igi_brdf::MaterialEntry { rho_d: m.rho_d, lobes: m.lobes, rms: None, rms_abs: None, samples: None, stderr: None },
    );
    match &a.output {
        Some(p) => write_text_atomic(p, &out.to_json())?,
        None => print!("{}", out.to_json()),
    }
    Ok(())
}

#[derive(serde::Serialize)]
struct ClusterOut {
    brdfs: Vec<igi_brdf::Lafortune>,
    lumitexels: Vec<LumitexelOut>,
}

#[derive(serde::Serialize)]
struct LumitexelOut {
    id: String,
    cluster: Option<usize>,
    weights: Vec<f32>,
    rms: f64,
}

fn run_cluster(a: ClusterArgs) -> anyhow::Result<()> {
    let (ids, lts) = read_lumitexels(&a.lumitexels)?;
    let r = cluster(&lts, &ClusterOptions { k: a.k, seed: a.seed, ..Default::default() })
        .with_context(|| format!("clustering {}", a.lumitexels.display()))?;
    let out = ClusterOut {
        brdfs: r.brdfs.clone(),
        lumitexels: ids
            .into_iter()
            .enumerate()
            .map(|(t, id)| LumitexelOut {
                id,
                cluster: (r.assignment[t] != usize::MAX).then_some(r.assignment[t]),
                weights: r.weights[t].clone(),
                rms: r.errors[t],
            })
            .collect(),
    };
    write_text_atomic(&a.output, &(serde_json::to_string_pretty(&out)? + "\n"))?;
    for (k, b) in r.brdfs.iter().enumerate() {
        let n = r.assignment.iter().filter(|&&x| x == k).count();
        println!("cluster {k}: {n} lumitexels, rho_d [{:.4}, {:.4}, {:.4}]", b.rho_d.x, b.rho_d.y, b.rho_d.z);
    }
    Ok(())
}
