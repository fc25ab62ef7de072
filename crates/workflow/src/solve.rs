//! `igi solve` as one job: [`SolveJob::check`] checks everything a solve of a survey needs
//! before the first byte of work or output (the survey and the files it names, the options,
//! the result folder against its run manifest, the BRDF basis, the truth scene), then
//! [`SolveJob::run`] loads the photographs, resumes the folder's checkpoint or starts a fresh
//! result under its lock, and iterates, writing a checkpoint after each step.
//!
//! The demo runs the same job on the survey it makes; a cluster task reloads the same inputs
//! through [`reopen`].

use crate::session::SolveSession;
use crate::survey::Survey;
use crate::WorkflowError;
use igi_brdf::Basis;
use igi_geometry::SiteStore;
use igi_reflect::atlas_size::AutoAtlas;
use igi_reflect::coarse::{coarse_parts, solve_coarse_first, CoarseInputs};
use igi_reflect::parts::site_parts;
use igi_reflect::solver::{truth_from_scene, SolveInputs, Truth};
use igi_reflect::{Photo, Progress, SolveOptions, SolveResult};
use std::path::{Path, PathBuf};

/// How the parts' atlases are sized (a prepared site keeps its own).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AtlasRequest {
    /// Every part this many texels per side.
    Fixed(u32),
    /// Each part's from the pixel footprints of the photographs that resolve it, at most `max`.
    Auto { max: u32 },
}

/// What `igi solve` is asked for.
#[derive(Clone, Debug)]
pub struct SolveRequest {
    /// The survey folder, or its `survey.toml`.
    pub survey: PathBuf,
    /// The result folder (created; an unfinished result of the same run there is resumed).
    pub output: PathBuf,
    pub atlas: AtlasRequest,
    /// The iteration's options; the atlas fields are set from `atlas` (and a prepared site).
    pub options: SolveOptions,
    /// A scene file with the true albedo over the same geometry: the report then records the
    /// albedo error per iteration.
    pub truth: Option<PathBuf>,
    /// Remove what an earlier solve wrote into `output` and start afresh.
    pub restart: bool,
}

/// A checked solve, ready to run.
pub struct SolveJob {
    survey: Survey,
    store: Option<SiteStore>,
    options: SolveOptions,
    session: SolveSession,
    basis: Option<Basis>,
    truth_scene: Option<igi_render::Scene>,
    output: PathBuf,
}

/// Checks `request` and runs it (see the module overview).
pub fn solve(
    request: &SolveRequest,
    progress: &dyn Progress,
) -> Result<SolveResult, WorkflowError> {
    SolveJob::check(request)?.run(progress)
}

impl SolveJob {
    /// Everything that can be checked before work: nothing is written.
    pub fn check(request: &SolveRequest) -> Result<SolveJob, WorkflowError> {
        Self::check_survey(Survey::load(&request.survey)?, request)
    }

    /// [`SolveJob::check`] of `request` with its survey already loaded (`survey` is
    /// `request.survey`'s).
    pub fn check_survey(survey: Survey, request: &SolveRequest) -> Result<SolveJob, WorkflowError> {
        let store = match &survey.prepared {
            Some(p) => Some(SiteStore::open(p)?),
            None => None,
        };
        let options = atlas_options(request, store.as_ref());
        if let (AtlasRequest::Fixed(r), None) = (request.atlas, &store) {
            let texels = (r as u128).pow(2) * survey.meshes.len() as u128;
            let what = format!(
                "the atlases of {} meshes at {r} texels a side (--atlas {r})",
                survey.meshes.len()
            );
            check_atlas_memory(&what, texels)?;
            check_light_transport_memory(&survey, texels)?;
        }
        let session = SolveSession::check(
            &request.output,
            &survey,
            &options,
            request.truth.as_deref(),
            request.restart,
        )?;
        let basis = survey.basis()?;
        let truth_scene = match &request.truth {
            Some(t) => Some(igi_render::Scene::load(t)?.0),
            None => None,
        };
        Ok(SolveJob {
            survey,
            store,
            options,
            session,
            basis,
            truth_scene,
            output: request.output.clone(),
        })
    }

    /// The options the solve runs with (the atlas as requested, or the prepared site's).
    pub fn options(&self) -> &SolveOptions {
        &self.options
    }

    /// The survey, resolved and checked.
    pub fn survey(&self) -> &Survey {
        &self.survey
    }

    /// The prepared site the survey names, opened.
    pub fn store(&self) -> Option<&SiteStore> {
        self.store.as_ref()
    }

    /// Loads the photographs, resumes or starts the result, and iterates to the end.
    pub fn run(self, progress: &dyn Progress) -> Result<SolveResult, WorkflowError> {
        self.start(progress)?.iterate(progress)
    }

    /// Loads the photographs and resumes the folder's checkpoint, or starts a fresh result
    /// (its `run.json` and geometry written, under the folder's lock).
    pub fn start(self, progress: &dyn Progress) -> Result<StartedSolve, WorkflowError> {
        let photos = self.survey.load_photos(progress)?;
        let state = self.start_or_resume(&photos)?;
        let truth = self
            .truth_scene
            .as_ref()
            .map(|scene| truth_from_scene(&state.parts, scene));
        let sky = self.survey.estimated_photos();
        // estimated light is fitted on the result's own atlases: no coarse stage then
        let coarse = match sky.iter().any(Option::is_some) {
            true => None,
            false => self.coarse_stage(&state)?,
        };
        let bodies = self.survey.photos.iter().map(|p| p.body.clone()).collect();
        Ok(StartedSolve {
            sky,
            bodies,
            references: self.survey.references.clone(),
            state,
            photos,
            basis: self.basis,
            truth,
            coarse,
            options: self.options,
            output: self.output,
            _session: self.session,
        })
    }

    /// With `--atlas auto`, before the first iteration: the coarse parts the first iterations
    /// run on (`igi_reflect::coarse`), with the truth on them. Not where light is estimated.
    fn coarse_stage(&self, state: &SolveResult) -> Result<Option<CoarseStage>, WorkflowError> {
        let fresh = state.report.iterations.is_empty() && state.report.pending.is_none();
        if self.options.atlas_auto.is_none() || !fresh {
            return Ok(None);
        }
        let Some(parts) = coarse_parts(&state.parts, &self.options)? else {
            return Ok(None);
        };
        let truth = self
            .truth_scene
            .as_ref()
            .map(|scene| truth_from_scene(&parts, scene));
        Ok(Some(CoarseStage { parts, truth }))
    }

    /// The folder's checkpoint of this run, or a fresh result on the survey's parts.
    fn start_or_resume(&self, photos: &[Photo]) -> Result<SolveResult, WorkflowError> {
        if self.session.resumes() {
            let mut r = self.session.load()?;
            // a resume may raise --iterations: the report records the maximum now asked for
            r.report.options.max_iterations = self.options.max_iterations;
            tracing::info!("resuming after iteration {}", r.report.iterations.len());
            return Ok(r);
        }
        let cameras: Vec<_> = photos.iter().map(|p| p.camera.clone()).collect();
        let parts = site_parts(
            &self.survey.meshes,
            self.store.as_ref(),
            self.options.atlas_resolution,
            self.options.atlas_auto,
            &cameras,
        )?;
        if let Some(auto) = self.options.atlas_auto.filter(|_| self.store.is_none()) {
            let texels = parts.iter().map(|p| (p.resolution() as u128).pow(2)).sum();
            let what = format!(
                "the atlases --atlas auto chose for {} parts (at most {} texels a side, --atlas-max)",
                parts.len(),
                auto.max
            );
            check_atlas_memory(&what, texels)?;
        }
        let ids = photos.iter().map(|p| p.id.clone()).collect();
        self.session.start(parts, ids, &self.options)
    }
}

/// A solve whose result folder is started (or resumed) and locked, with everything it reads.
pub struct StartedSolve {
    /// Per photo (survey order): the sun and site of a photo whose light is estimated.
    pub sky: Vec<Option<crate::lightfit::SkyPhoto>>,
    /// Per photo (survey order): the camera body that took it (`body = ...`).
    pub bodies: Vec<Option<String>>,
    /// The survey's `[[reference]]` targets (they fix the scale of estimated light).
    pub references: Vec<igi_formats::survey::ReferenceTarget>,
    /// The result as it stands: fresh, or the checkpoint resumed.
    pub state: SolveResult,
    pub photos: Vec<Photo>,
    pub basis: Option<Basis>,
    pub truth: Option<Truth>,
    /// The coarse stage the iterations start with (`--atlas auto`, a fresh result).
    pub coarse: Option<CoarseStage>,
    pub options: SolveOptions,
    output: PathBuf,
    /// Holds the folder's lock until the solve is done.
    _session: SolveSession,
}

impl StartedSolve {
    /// What the solver reads besides its state.
    pub fn inputs(&self) -> SolveInputs<'_> {
        SolveInputs {
            photos: &self.photos,
            basis: self.basis.as_ref(),
            truth: self.truth.as_ref(),
        }
    }

    /// Iterates to the end (the coarse stage first, when there is one), writing a checkpoint
    /// into the result folder after each step on the result's own atlases.
    pub fn iterate(mut self, progress: &dyn Progress) -> Result<SolveResult, WorkflowError> {
        if let Some(c) = self.coarse.take() {
            let inputs = CoarseInputs {
                photos: &self.photos,
                basis: self.basis.as_ref(),
                truth: c.truth.as_ref(),
            };
            self.state = solve_coarse_first(self.state, c.parts, &inputs, &self.options, progress)?;
        }
        let out = &self.output;
        if self.sky.iter().any(Option::is_some) {
            let e = crate::lightfit::Estimation {
                sky: &self.sky,
                bodies: &self.bodies,
                references: &self.references,
                basis: self.basis.as_ref(),
                truth: self.truth.as_ref(),
                options: &self.options,
                output: out,
            };
            return crate::lightfit::iterate(self.state, &mut self.photos, &e, progress);
        }
        let result = igi_reflect::solve(
            self.state,
            &self.photos,
            self.basis.as_ref(),
            self.truth.as_ref(),
            &self.options,
            progress,
            &mut |r| r.write_state(out),
        )?;
        Ok(result)
    }
}

/// The coarse parts of a coarse-to-fine solve and the truth on them.
pub struct CoarseStage {
    pub parts: Vec<igi_reflect::Part>,
    pub truth: Option<Truth>,
}

/// Refuses, before any work, the light transport of a survey with estimated light
/// ([`crate::lightbasis::memory`]) when it could pass the limit on atlases of at most
/// `texels` texels.
fn check_light_transport_memory(survey: &Survey, texels: u128) -> Result<(), WorkflowError> {
    let pixels = survey
        .photos
        .iter()
        .zip(survey.estimated_photos())
        .filter(|(_, s)| s.is_some())
        .map(|(p, _)| {
            let c = igi_camera::Camera::load(&p.camera)?;
            Ok(c.width as u128 * c.height as u128)
        })
        .collect::<Result<Vec<u128>, WorkflowError>>()?;
    if pixels.is_empty() {
        return Ok(());
    }
    let what = format!(
        "the lighting estimation's light transport of up to {texels} texels and {} photographs",
        pixels.len()
    );
    igi_files::check_alloc_default(&what, crate::lightbasis::memory(texels, &pixels))?;
    Ok(())
}

/// Refuses atlases of `texels` texels whose memory estimate
/// ([`igi_reflect::solver::atlas_memory`], before the observations) is above the limit
/// (`IGI_MAX_MEMORY`, 8 GiB by default); a prepared site's atlases were sized by `igi prepare`
/// under its own `--max-memory` and are not checked again.
fn check_atlas_memory(what: &str, texels: u128) -> Result<(), WorkflowError> {
    let what = format!(
        "{what}: {texels} texels at {} bytes each before the observations",
        igi_reflect::solver::BYTES_PER_TEXEL
    );
    igi_files::check_alloc_default(&what, igi_reflect::solver::atlas_memory(texels))?;
    Ok(())
}

/// The request's options with its atlas: a prepared site's own resolution, else `atlas`.
fn atlas_options(request: &SolveRequest, store: Option<&SiteStore>) -> SolveOptions {
    let (fixed, auto) = match request.atlas {
        AtlasRequest::Fixed(n) => (n, None),
        AtlasRequest::Auto { max } => (512, Some(AutoAtlas { max })),
    };
    let (atlas_resolution, atlas_auto) = match store {
        Some(s) => (s.manifest().atlas_resolution, None),
        None => (fixed, auto),
    };
    SolveOptions {
        atlas_resolution,
        atlas_auto,
        ..request.options.clone()
    }
}

/// The photographs and BRDF basis of a run that was checked and started earlier (a cluster
/// task or merge), after checking that its inputs have not changed since (the run manifest
/// names the difference).
pub fn reopen(
    survey: &Path,
    result: &Path,
    options: &SolveOptions,
) -> Result<(Vec<Photo>, Option<Basis>), WorkflowError> {
    let survey = Survey::load(survey)?;
    SolveSession::check(result, &survey, options, None, false)?;
    let photos = survey.load_photos(&igi_reflect::solver::NoProgress)?;
    Ok((photos, survey.basis()?))
}
