//! The resume rule of `igi solve`: a result folder belongs to one run.
//!
//! [`SolveSession::check`] runs before any work or output: it validates the options, checks
//! that the output folder is (or can become) a writable folder, and builds the run manifest
//! (`run.json`, see `igi_files::run`): fingerprints of the survey file, meshes or prepared
//! site, photographs, cameras, lighting and BRDF samples, and every result-changing option
//! (`--atlas`, `--spp`, `--indirect`, `--seed`, `--initial`, the weighting rules, `--schedule`
//! and `--deblur` when not their defaults, `--shading-smoothing` when on) with the part
//! selection as the shard's `owns`.
//! `--tolerance` (when not the default) and the `--truth` scene (an input) are recorded too:
//! they change what the report says. `--iterations` is recorded as a raisable option: a
//! resume with more iterations continues the same run (run.json and the report then record
//! the new maximum), one with fewer is refused.
//!
//! A folder with a `run.json` is resumed only when the manifests are equal; otherwise the
//! error names the first differing option or input and suggests `--restart`. Two shards
//! (different `--parts`) therefore never share a folder. `--restart` removes what an earlier
//! solve wrote (only the file names a solve writes, and only in a folder whose `run.json` names
//! `solve`, or an older igi's result) before starting afresh; a folder igi did not write is
//! refused, `--restart` or not. Temporary files of
//! killed runs are removed on resume.
//!
//! From [`SolveSession::start`] or [`SolveSession::load`] on, the session holds the folder's
//! [`FolderLock`]: a second solve on the same folder while this one runs is refused, naming
//! this process. `start` checks the folder again under the lock, so two fresh runs racing
//! past [`SolveSession::check`] cannot both write.

use crate::survey::{LightingSource, Survey};
use crate::WorkflowError;
use igi_files::run::FolderState;
use igi_files::{FolderLock, RunManifest};
use igi_reflect::result::{SolveResult, STAGED};
use igi_reflect::{Part, Schedule, SolveOptions};
use std::cell::OnceCell;
use std::path::{Path, PathBuf};

/// The files a solve writes into its result folder, as `igi_files::remove_own` patterns: what
/// `--restart` removes (a user's `parts/notes.txt` stays).
const RESULT_FILES: [&str; 29] = [
    "parts/*.ply",
    "parts/*_position.exr",
    "parts/*_normal.exr",
    "parts/*_coverage.exr",
    "parts/*_rho_d.exr",
    "parts/*_weight.exr",
    "parts/*_observations.exr",
    "parts/*_stderr.exr",
    "parts/*_lobes.json",
    "parts/*_lobe*_rho.exr",
    "parts/*_lobe*_shape.exr",
    "staged/parts/*.ply",
    "staged/parts/*_position.exr",
    "staged/parts/*_normal.exr",
    "staged/parts/*_coverage.exr",
    "staged/parts/*_rho_d.exr",
    "staged/parts/*_weight.exr",
    "staged/parts/*_observations.exr",
    "staged/parts/*_stderr.exr",
    "staged/parts/*_lobes.json",
    "staged/parts/*_lobe*_rho.exr",
    "staged/parts/*_lobe*_shape.exr",
    "staged/report.json",
    "staged/scene.toml",
    "staged/convergence.png",
    "report.json",
    "scene.toml",
    "convergence.png",
    "run.json",
];

/// A checked result folder and the run manifest of this solve.
pub struct SolveSession {
    dir: PathBuf,
    manifest: RunManifest,
    resume: bool,
    restart: bool,
    lock: OnceCell<FolderLock>,
}

impl SolveSession {
    /// Checks everything that can be checked before work (see the module overview).
    pub fn check(
        dir: &Path,
        survey: &Survey,
        opts: &SolveOptions,
        truth: Option<&Path>,
        restart: bool,
    ) -> Result<SolveSession, WorkflowError> {
        opts.validate()?;
        igi_files::check_output_folder(dir)?;
        let mut manifest = run_manifest(survey, opts)?;
        if let Some(t) = truth {
            manifest.input("truth scene (--truth)", t)?;
        }
        let state = manifest.check_folder(dir, restart, "report.json", "result")?;
        let resume = state == FolderState::Resume && has_checkpoint(dir);
        Ok(SolveSession {
            dir: dir.to_path_buf(),
            manifest,
            resume,
            restart,
            lock: OnceCell::new(),
        })
    }

    /// Whether the folder holds a finished checkpoint of this same run, to continue from.
    pub fn resumes(&self) -> bool {
        self.resume
    }

    /// Loads the checkpoint to continue from (after removing dead runs' temporary files).
    pub fn load(&self) -> Result<SolveResult, WorkflowError> {
        self.claim()?;
        igi_files::remove_dead_temps(&self.dir, true)?;
        // the same run, perhaps with more iterations: run.json records them
        self.manifest.write(&self.dir)?;
        SolveResult::recover(&self.dir)?;
        Ok(SolveResult::load(&self.dir)?)
    }

    /// Starts a fresh result: checks the part selection against `parts`, removes an earlier
    /// run's files (with restart) and dead temporary files, then writes `run.json` and the
    /// parts' geometry.
    pub fn start(
        &self,
        parts: Vec<Part>,
        photo_ids: Vec<String>,
        opts: &SolveOptions,
    ) -> Result<SolveResult, WorkflowError> {
        igi_reflect::solver::check_selection(&parts, opts)?;
        std::fs::create_dir_all(&self.dir)
            .map_err(|e| WorkflowError::file(&self.dir, format!("cannot create folder: {e}")))?;
        self.claim()?;
        // another run may have written here since `check`
        let state = self
            .manifest
            .check_folder(&self.dir, self.restart, "report.json", "result")?;
        if state == FolderState::Resume && has_checkpoint(&self.dir) {
            return Err(WorkflowError::file(
                &self.dir,
                "another solve wrote this folder while this one was starting; run again to resume it",
            ));
        }
        if self.restart {
            igi_files::remove_own(&self.dir, &RESULT_FILES)?;
        }
        igi_files::remove_dead_temps(&self.dir, true)?;
        self.manifest.write(&self.dir)?;
        let r = SolveResult::fresh(parts, photo_ids, opts);
        r.write_geometry(&self.dir)?;
        Ok(r)
    }
}

/// Whether `dir` holds a checkpoint: committed, or staged past its commit point (rolled
/// forward on load).
fn has_checkpoint(dir: &Path) -> bool {
    dir.join("report.json").is_file() || dir.join(STAGED).join("report.json").is_file()
}

impl SolveSession {
    /// Takes the folder's lock (once; held until the session is dropped).
    fn claim(&self) -> Result<(), WorkflowError> {
        if self.lock.get().is_none() {
            let lock = FolderLock::acquire(&self.dir)?;
            let _ = self.lock.set(lock);
        }
        Ok(())
    }
}

/// The run manifest of a solve of `survey` with `opts`.
fn run_manifest(survey: &Survey, opts: &SolveOptions) -> Result<RunManifest, WorkflowError> {
    let mut m = RunManifest::new("solve");
    let a = opts.initial_albedo;
    match opts.atlas_auto {
        // numeric as before, so folders of earlier igi versions still resume
        None => m.option("--atlas", opts.atlas_resolution),
        Some(a) => m.option("--atlas", "auto").option("--atlas-max", a.max),
    };
    // how far to go: more iterations continue the same run, fewer are refused
    m.raisable("--iterations", opts.max_iterations as u64);
    let defaults = SolveOptions::default();
    // recorded only when not the default, so folders of earlier igi versions still resume
    if opts.tolerance.to_bits() != defaults.tolerance.to_bits() {
        m.option("--tolerance", format!("{:?}", opts.tolerance));
    }
    if opts.min_iterations != defaults.min_iterations {
        m.option("minimum iterations", opts.min_iterations);
    }
    m.option("--spp", join(&opts.spp))
        .option("--indirect", opts.indirect)
        .option("--seed", opts.seed)
        .option("--initial", format!("{:?},{:?},{:?}", a[0], a[1], a[2]))
        .option(
            "minimum evaluation albedo",
            format!("{:?}", opts.min_eval_albedo),
        )
        .option(
            "weighting rules",
            serde_json::to_string(&opts.rules).expect("rules serialise"),
        );
    // recorded only when not the default, so folders of earlier igi versions still resume
    if opts.schedule != Schedule::GaussSeidel {
        m.option("--schedule", opts.schedule.name());
    }
    if opts.deblur != 0 {
        m.option("--deblur", opts.deblur);
    }
    // recorded when on (igi solve's default without --spp): a folder of an igi without it
    // resumes only with a --spp given
    if opts.adaptive_spp {
        m.option("adaptive samples", true);
    }
    // recorded when on (the default): a folder of an igi without it resumes only with it off
    if opts.smooth_shading {
        m.option("--shading-smoothing", true);
    }
    // recorded when off: the folders of an igi without the option traced on the lattice
    if !opts.lattice_shading {
        m.option("--shading-lattice", false);
    }
    m.owns = opts.parts.as_ref().map(|p| {
        let mut v = p.clone();
        v.sort();
        v.dedup();
        v
    });
    m.input("survey", &survey.file)?;
    for (i, p) in survey.meshes.iter().enumerate() {
        m.input(&format!("mesh {i}"), p)?;
    }
    if let Some(p) = &survey.prepared {
        m.input("prepared site", &p.join("manifest.json"))?;
    }
    for p in &survey.photos {
        m.input(&format!("photo {} image", p.id), &p.image)?;
        m.input(&format!("photo {} camera", p.id), &p.camera)?;
        match &p.lighting {
            LightingSource::File(l) => {
                m.input(&format!("photo {} lighting", p.id), l)?;
            }
            LightingSource::Probe {
                image,
                camera,
                board,
            } => {
                m.input(&format!("photo {} probe image", p.id), image)?;
                m.input(&format!("photo {} probe camera", p.id), camera)?;
                m.input(&format!("photo {} probe board", p.id), board)?;
            }
            // its time and the site are in the survey file
            LightingSource::Estimated(_) => {}
        }
    }
    if let Some(p) = &survey.brdf_samples {
        m.input("BRDF samples", p)?;
    }
    Ok(m)
}

fn join(v: &[u32]) -> String {
    v.iter()
        .map(|x| x.to_string())
        .collect::<Vec<_>>()
        .join(",")
}
