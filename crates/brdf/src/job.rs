//! `igi brdf`'s jobs, each one call from a request of paths and options: fit materials to a
//! samples file, evaluate a fitted material at direction pairs, infer a material from a diffuse
//! colour, cluster lumitexels. (Measuring samples from photographs is `igi_capture::job`'s.)

use crate::plot::{plot_fits, write_text_atomic};
use crate::samples::{group_by_material, read_pairs, read_samples, write_pairs};
use crate::{
    cluster, fit_materials, read_lumitexels, Basis, BrdfError, ClusterOptions, FitOptions,
    FitReport, Lafortune, MaterialEntry, MaterialsFile,
};
use glam::Vec3;
use std::path::PathBuf;

/// `igi brdf fit`: the samples CSV, the materials JSON to write, an optional plot (PNG), and
/// the fit's options as given (checked by [`fit_file`]).
#[derive(Clone, Debug)]
pub struct FitRequest {
    pub samples: PathBuf,
    pub output: PathBuf,
    pub plot: Option<PathBuf>,
    /// Largest lobe exponent N.
    pub max_n: f64,
    /// Largest coverage weight over the mean (0: unweighted).
    pub coverage_cap: f64,
    /// Largest grazing gain of a lobe (infinite: unbounded).
    pub max_gain: f64,
    /// The plain weighted least squares (overrides `coverage_cap` and `max_gain`).
    pub plain: bool,
}

/// One step of [`fit_file`], for a progress bar.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FitStep {
    /// The samples are read: this many materials will be fitted.
    Materials(usize),
    /// One material fitted.
    Fitted,
}

/// Fits every material of the samples file, writes the materials file, tells `written` the
/// fits (in the order the materials first appear), then draws the plot when asked.
pub fn fit_file(
    req: &FitRequest,
    step: &(dyn Fn(FitStep) + Sync),
    written: &dyn Fn(&[FitReport]),
) -> Result<Vec<FitReport>, BrdfError> {
    let opts = fit_options(req)?;
    igi_files::check_input_file(&req.samples, "the samples file")?;
    let samples = read_samples(&req.samples)?;
    step(FitStep::Materials(group_by_material(&samples).len()));
    let fits = fit_materials(&samples, &opts, &|| step(FitStep::Fitted)).map_err(|e| {
        BrdfError::Fitting {
            path: req.samples.clone(),
            source: Box::new(e),
        }
    })?;
    let reports: Vec<FitReport> = fits.iter().map(|(_, r)| r.clone()).collect();
    MaterialsFile::from_reports(&reports).write(&req.output)?;
    written(&reports);
    if let Some(p) = &req.plot {
        let m: Vec<_> = fits
            .iter()
            .map(|(s, r)| (r.material.clone(), s.clone(), r.brdf.clone()))
            .collect();
        plot_fits(p, &m)?;
    }
    Ok(reports)
}

/// The fit options of a request, checked before any work.
fn fit_options(req: &FitRequest) -> Result<FitOptions, BrdfError> {
    if !(req.coverage_cap >= 0.0 && req.coverage_cap.is_finite()) {
        return Err(BrdfError::Arguments(format!(
            "--coverage-cap must be a finite number >= 0 (got {})",
            req.coverage_cap
        )));
    }
    if req.max_gain.is_nan() || req.max_gain < 1.0 {
        return Err(BrdfError::Arguments(format!(
            "--max-gain must be at least 1 (got {})",
            req.max_gain
        )));
    }
    let base = if req.plain {
        FitOptions::plain()
    } else {
        FitOptions {
            coverage_cap: req.coverage_cap,
            max_gain: req.max_gain,
            ..FitOptions::default()
        }
    };
    Ok(FitOptions {
        max_n: req.max_n,
        ..base
    })
}

/// `igi brdf eval`: a materials file, the material's name, a direction-pair table, and the
/// table to write with `r, g, b = pi f` added.
#[derive(Clone, Debug)]
pub struct EvalRequest {
    pub materials: PathBuf,
    pub material: String,
    pub pairs: PathBuf,
    pub output: PathBuf,
}

/// Evaluates the material at every pair of the table and writes the table with the values.
pub fn eval_file(req: &EvalRequest) -> Result<(), BrdfError> {
    let file = MaterialsFile::read(&req.materials)?;
    let m = file.get(&req.material).map_err(|e| BrdfError::InFile {
        path: req.materials.clone(),
        source: Box::new(e),
    })?;
    let table = read_pairs(&req.pairs)?;
    let values: Vec<Vec3> = table
        .rows
        .iter()
        .map(|r| m.as_ref().eval(r.light, r.view) * std::f32::consts::PI)
        .collect();
    Ok(write_pairs(&req.output, &table, &values)?)
}

/// `igi brdf infer`: the materials file of the basis, the diffuse colour `r,g,b`, and where
/// to write the inferred material (`None`: nowhere; the text is returned either way).
#[derive(Clone, Debug)]
pub struct InferRequest {
    pub materials: PathBuf,
    pub rho: Vec<f32>,
    pub output: Option<PathBuf>,
}

/// Infers a full BRDF from the diffuse colour through the basis of the materials file; returns
/// it as a materials JSON text (one material, `inferred`), written to the output when given.
pub fn infer_file(req: &InferRequest) -> Result<String, BrdfError> {
    if req.rho.len() != 3 || req.rho.iter().any(|x| !x.is_finite() || *x < 0.0) {
        return Err(BrdfError::Arguments(format!(
            "--rho needs three finite non-negative numbers r,g,b (got {:?})",
            req.rho
        )));
    }
    let file = MaterialsFile::read(&req.materials)?;
    let basis = Basis::new(file.brdfs())?;
    let m = basis.infer(Vec3::new(req.rho[0], req.rho[1], req.rho[2]));
    let mut out = MaterialsFile::default();
    out.materials.insert(
        "inferred".into(),
        MaterialEntry {
            rho_d: m.rho_d,
            lobes: m.lobes,
            rms: None,
            rms_abs: None,
            samples: None,
            stderr: None,
        },
    );
    let text = out.to_json();
    if let Some(p) = &req.output {
        out.write(p)?;
    }
    Ok(text)
}

/// `igi brdf cluster`: the lumitexels CSV, the number of clusters, the seed, the JSON to write
/// (cluster BRDFs and per-lumitexel cluster and weights).
#[derive(Clone, Debug)]
pub struct ClusterRequest {
    pub lumitexels: PathBuf,
    pub k: usize,
    pub seed: u64,
    pub output: PathBuf,
}

/// One cluster as [`cluster_file`] reports it.
#[derive(Clone, Debug)]
pub struct ClusterSummary {
    pub lumitexels: usize,
    pub rho_d: [f32; 3],
}

#[derive(serde::Serialize)]
struct ClusterOut {
    brdfs: Vec<Lafortune>,
    lumitexels: Vec<LumitexelOut>,
}

#[derive(serde::Serialize)]
struct LumitexelOut {
    id: String,
    cluster: Option<usize>,
    weights: Vec<f32>,
    rms: f64,
}

/// Clusters the lumitexels into `k` BRDFs (Lensch et al.), writes the clusters and each
/// lumitexel's weights, and returns each cluster's size and diffuse colour.
pub fn cluster_file(req: &ClusterRequest) -> Result<Vec<ClusterSummary>, BrdfError> {
    let (ids, lts) = read_lumitexels(&req.lumitexels)?;
    let opts = ClusterOptions {
        k: req.k,
        seed: req.seed,
        ..Default::default()
    };
    let r = cluster(&lts, &opts).map_err(|e| BrdfError::Clustering {
        path: req.lumitexels.clone(),
        source: Box::new(e),
    })?;
    let lumitexels = ids.into_iter().enumerate().map(|(t, id)| LumitexelOut {
        id,
        cluster: (r.assignment[t] != usize::MAX).then_some(r.assignment[t]),
        weights: r.weights[t].clone(),
        rms: r.errors[t],
    });
    let out = ClusterOut {
        brdfs: r.brdfs.clone(),
        lumitexels: lumitexels.collect(),
    };
    write_text_atomic(&req.output, &(serde_json::to_string_pretty(&out)? + "\n"))?;
    let size = |k: usize| r.assignment.iter().filter(|&&x| x == k).count();
    Ok((r.brdfs.iter().enumerate())
        .map(|(k, b)| ClusterSummary {
            lumitexels: size(k),
            rho_d: b.rho_d.to_array(),
        })
        .collect())
}
