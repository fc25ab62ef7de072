//! `igi brdf`: fit Lafortune BRDFs to hand-held samples, evaluate them, infer lobes from a
//! diffuse colour, cluster lumitexels (Lensch et al.), and measure samples from photographs of
//! the hand-held sample frame.

use std::path::PathBuf;

use anyhow::{bail, Context};
use glam::Vec3;
use igi_brdf::{
    cluster, fit_materials, plot::plot_fits, plot::write_text_atomic, read_lumitexels, read_pairs,
    read_samples, samples::group_by_material, samples::write_pairs, samples::write_samples, Basis,
    ClusterOptions, FitOptions, MaterialsFile,
};

use crate::report::Ctx;

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
    #[arg(long, default_value_t = 2.0e4)]
    pub max_n: f64,
    /// Weight each sample by the share of all direction pairs it stands for (its Voronoi cell in
    /// the isotropic pair space), each weight at most this times the mean; 0 = unweighted
    /// (docs/BRDF.md, "Sparse hand-held samples").
    #[arg(long, default_value_t = igi_brdf::fit::COVERAGE_CAP)]
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
        BrdfCmd::Measure(a) => measure(a),
    }
}

/// The fit options of the command line (checked before any work).
fn fit_options(a: &FitArgs) -> anyhow::Result<FitOptions> {
    if !(a.coverage_cap >= 0.0 && a.coverage_cap.is_finite()) {
        bail!(
            "--coverage-cap must be a finite number >= 0 (got {})",
            a.coverage_cap
        );
    }
    if a.max_gain.is_nan() || a.max_gain < 1.0 {
        bail!("--max-gain must be at least 1 (got {})", a.max_gain);
    }
    let base = if a.plain {
        FitOptions::plain()
    } else {
        FitOptions {
            coverage_cap: a.coverage_cap,
            max_gain: a.max_gain,
            ..FitOptions::default()
        }
    };
    Ok(FitOptions {
        max_n: a.max_n,
        ..base
    })
}

fn fit(a: FitArgs, ctx: &Ctx) -> anyhow::Result<()> {
    let opts = fit_options(&a)?;
    let samples = read_samples(&a.samples)?;
    let n = group_by_material(&samples).len();
    let pb = ctx.progress(n as u64, "fitting");
    let fits = fit_materials(&samples, &opts, &|| pb.inc(1))
        .with_context(|| format!("fitting {}", a.samples.display()))?;
    pb.finish_and_clear();
    let reports: Vec<_> = fits.iter().map(|(_, r)| r.clone()).collect();
    let file = MaterialsFile::from_reports(&reports);
    write_text_atomic(&a.output, &file.to_json())?;
    println!(
        "{:<16} {:>7} {:>9} {:>10}  rho_d / lobes (rho, cxy, cz, n)",
        "material", "samples", "rel.rms", "abs.rms"
    );
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
        let m: Vec<_> = fits
            .iter()
            .map(|(s, r)| (r.material.clone(), s.clone(), r.brdf.clone()))
            .collect();
        plot_fits(p, &m)?;
    }
    Ok(())
}

fn eval(a: EvalArgs) -> anyhow::Result<()> {
    let file = MaterialsFile::read(&a.materials)?;
    let m = file
        .get(&a.material)
        .with_context(|| format!("in {}", a.materials.display()))?;
    let table = read_pairs(&a.pairs)?;
    let values: Vec<Vec3> = table
        .rows
        .iter()
        .map(|r| m.as_ref().eval(r.light, r.view) * std::f32::consts::PI)
        .collect();
    write_pairs(&a.output, &table, &values)?;
    Ok(())
}

fn infer(a: InferArgs) -> anyhow::Result<()> {
    if a.rho.len() != 3 || a.rho.iter().any(|x| !x.is_finite() || *x < 0.0) {
        bail!(
            "--rho needs three finite non-negative numbers r,g,b (got {:?})",
            a.rho
        );
    }
    let file = MaterialsFile::read(&a.materials)?;
    let basis = Basis::new(file.brdfs())?;
    let m = basis.infer(Vec3::new(a.rho[0], a.rho[1], a.rho[2]));
    let mut out = MaterialsFile::default();
    out.materials.insert(
        "inferred".into(),
        igi_brdf::MaterialEntry {
            rho_d: m.rho_d,
            lobes: m.lobes,
            rms: None,
            rms_abs: None,
            samples: None,
            stderr: None,
        },
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
    let r = cluster(
        &lts,
        &ClusterOptions {
            k: a.k,
            seed: a.seed,
            ..Default::default()
        },
    )
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
        println!(
            "cluster {k}: {n} lumitexels, rho_d [{:.4}, {:.4}, {:.4}]",
            b.rho_d.x, b.rho_d.y, b.rho_d.z
        );
    }
    Ok(())
}

fn parse_corners(s: &str) -> anyhow::Result<Vec<glam::DVec2>> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .ok()
        .filter(|v: &Vec<f64>| v.len() >= 8 && v.len().is_multiple_of(2) && v.iter().all(|x| x.is_finite()))
        .with_context(|| format!("--corners {s:?}: expected u,v pairs for the four fiducials, e.g. 101.5,88,912,90.2,905,700,98,702"))?;
    Ok(v.chunks(2).map(|c| glam::DVec2::new(c[0], c[1])).collect())
}

fn measure(a: MeasureArgs) -> anyhow::Result<()> {
    use igi_capture::sample_frame::{
        measure_photo, orthographic_view, MeasureOptions, PoseInput, SampleFrame,
    };
    let frame = SampleFrame::load(&a.frame)?;
    let camera = igi_camera::Camera::load(&a.camera)?;
    if !a.corners.is_empty() && a.corners.len() != a.photos.len() {
        bail!(
            "{} --photo but {} --corners: give one --corners per photo, or none (ArUco)",
            a.photos.len(),
            a.corners.len()
        );
    }
    let opts = MeasureOptions::default();
    let mut reports = Vec::new();
    let mut samples = Vec::new();
    for (k, photo) in a.photos.iter().enumerate() {
        let input = match a.corners.get(k) {
            Some(c) => PoseInput::Corners(parse_corners(c)?),
            None => PoseInput::Aruco,
        };
        let img = igi_imaging::read_image(photo)?;
        let m = measure_photo(&frame, &camera, &img, photo, &input, &opts)?;
        if let Some(dir) = &a.ortho_dir {
            std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
            let stem = photo
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| format!("photo{k}"));
            let cam = igi_camera::Camera {
                pose: m.pose(),
                ..camera.clone()
            };
            igi_imaging::write_exr(
                &dir.join(format!("{stem}_ortho.exr")),
                &orthographic_view(&frame, &cam, &img),
            )?;
        }
        samples.extend(m.samples());
        reports.push(m);
    }
    write_samples(&a.output, &samples)?;
    if a.json {
        crate::report::print_json(&reports)?;
        return Ok(());
    }
    for m in &reports {
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
        samples.len(),
        reports.len(),
        a.output.display()
    );
    Ok(())
}
