//! What a solve is asked and what it did: [`SolveOptions`] (with the update [`Schedule`]),
//! the per-iteration [`IterationRecord`], the per-part [`PartSummary`], the [`SolveReport`]
//! written to `report.json`, the running sums of an iteration in progress ([`Pending`]), and
//! one texel's observation in one photograph (`Obs`, crate-private), which the solver makes,
//! the shading smoothing (`crate::smooth`) denoises and the footprint deblurring
//! (`crate::deblur`) corrects. Below the solver, the smoothing, the deblurring, the result
//! folder and the plots, which all read these types.

use crate::parts::{Part, StoredPart};
use crate::weights::WeightRules;
use crate::ReflectError;
use glam::{Vec2, Vec3};
use serde::{Deserialize, Serialize};

/// One texel's observation in one photograph: its ratio proposal and what the combination,
/// the statistics, the shading smoothing and the footprint deblurring (`crate::deblur`) need.
#[derive(Clone)]
pub(crate) struct Obs {
    pub part: u32,
    pub texel: u32,
    /// Atlas index of the texel.
    pub atlas: u32,
    pub photo: u32,
    /// Where the texel projects in the photograph (pixel coordinates).
    pub px: Vec2,
    /// Radiance toward the camera per unit albedo, per channel (`L / rho_eval`; 0 where the
    /// channel is unlit and the proposal keeps the current albedo).
    pub shading: Vec3,
    /// How much of the deblurring correction the proposal takes: (texel / pixel footprint)^2,
    /// at most 1. Where a pixel covers several texels, the footprint operator cannot be
    /// inverted and the correction would mostly amplify noise.
    pub deblur_gain: f32,
    pub proposal: Vec3,
    pub weight: f32,
    /// Variance of `proposal` from the Monte-Carlo noise of the rendered radiance.
    pub mc_var: Vec3,
    /// Neither near an occlusion boundary nor on a shadow edge.
    pub clean: bool,
    pub residual: Vec3,
    pub pixel: Vec3,
}

/// Options of a solve.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SolveOptions {
    /// Atlas resolution per part (texels per side).
    pub atlas_resolution: u32,
    /// `--atlas auto`: each part's resolution chosen from the photographs' pixel footprint on
    /// it, within this budget (`atlas_resolution` is then unused for survey meshes).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub atlas_auto: Option<crate::atlas_size::AutoAtlas>,
    /// Iterations at most; the solve stops earlier (after `min_iterations`) when the mean
    /// change of `rho_d` over seen texels drops below `tolerance`, or, once the samples per
    /// estimate stop growing, when its change beyond the Monte-Carlo noise drops below the
    /// photographs' noise in `rho_d` (`IterationRecord::systematic_change_rho`, `noise_rho`):
    /// another iteration at the same samples would only redraw the Monte-Carlo noise.
    pub max_iterations: u32,
    pub min_iterations: u32,
    pub tolerance: f32,
    /// Samples per radiance estimate in iteration k (the last entry repeats): later iterations
    /// use more samples, as in the paper. With `adaptive_spp` the entries are levels instead.
    pub spp: Vec<u32>,
    /// The solve stays at a level of `spp` while an iteration changed the albedo by more than
    /// its Monte-Carlo noise (`IterationRecord::systematic_change_rho` above `mc_noise_rho`):
    /// the albedo is still settling, and more samples would not make it settle faster (the
    /// default of `igi solve`). Off: level k in iteration k (results written before the option
    /// existed read off).
    #[serde(default)]
    pub adaptive_spp: bool,
    /// Indirect bounces after direct lighting (2 as at the site).
    pub indirect: u32,
    pub seed: u64,
    /// Initial diffuse albedo of every texel.
    pub initial_albedo: [f32; 3],
    /// The evaluation albedo is at least this per channel, so a texel that is currently black
    /// can still become brighter (the ratio update is multiplicative).
    pub min_eval_albedo: f32,
    pub rules: WeightRules,
    /// Parts to solve (all when `None`); the others keep their current albedo.
    pub parts: Option<Vec<String>>,
    /// In which order a prepared site's voxels see each other's new albedo.
    #[serde(default)]
    pub schedule: Schedule,
    /// Rounds of footprint deblurring of the proposals per iteration (`crate::deblur`; 0, the
    /// default: each texel reads its photographs with one bilinear sample). It helps where the
    /// albedo has detail near the pixel size and adds noise on smooth albedo (docs/SOLVER.md).
    /// Options files written before the field existed read 0, their meaning.
    #[serde(default)]
    pub deblur: u32,
    /// Average each observation's rendered shading over its 3 x 3 texel neighbourhood of the
    /// same surface and light before dividing (`crate::smooth`; on by default: it takes most
    /// of the solve's Monte-Carlo noise out of the albedo). Options files written before the
    /// field existed read `false`, their meaning.
    #[serde(default)]
    pub smooth_shading: bool,
    /// In the fine iteration after a coarse stage, trace the shading at every fifth texel per
    /// atlas row and column only and read the rest bilinearly from them (`crate::lattice`; on
    /// by default). `false` traces every texel: the same error at several times the time
    /// (docs/SOLVER.md, "Coarse to fine"). Options files written before the field existed read
    /// `true`, their meaning.
    #[serde(default = "yes")]
    pub lattice_shading: bool,
    /// This solve is the coarse stage of a coarse-to-fine solve (set by `crate::coarse`, never
    /// stored): with `adaptive_spp` it also ends once the next iteration's change is predicted
    /// within the Monte-Carlo noise (`solver::coarse_settled`), since the fine iteration
    /// traces the shading again anyway.
    #[serde(skip)]
    pub coarse_stage: bool,
}

fn yes() -> bool {
    true
}

/// The order of updates within an iteration of a voxel-by-voxel solve.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Schedule {
    /// Each voxel is solved against the albedo its predecessors in this iteration just
    /// produced (converges in fewer iterations; inherently sequential). Checkpoints after
    /// every voxel.
    #[default]
    GaussSeidel,
    /// Iteration k reads only iteration k-1's albedo, so the voxels of an iteration are
    /// independent and can be solved on different machines (`igi cluster`); the local run is
    /// the reference a distributed run must equal. Checkpoints after every iteration (a killed
    /// run redoes the iteration in progress). A voxel's 26 neighbours are loaded at full
    /// resolution (Gauss-Seidel loads them at level 1).
    Jacobi,
}

impl Schedule {
    /// The name on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Schedule::GaussSeidel => "gauss-seidel",
            Schedule::Jacobi => "jacobi",
        }
    }

    /// The stored level a voxel group loads its 26 neighbours at.
    pub fn neighbour_level(self) -> usize {
        match self {
            Schedule::GaussSeidel => 1,
            Schedule::Jacobi => 0,
        }
    }
}

impl Default for SolveOptions {
    fn default() -> Self {
        SolveOptions {
            atlas_resolution: 512,
            atlas_auto: None,
            max_iterations: 4,
            min_iterations: 2,
            tolerance: 0.002,
            spp: vec![16, 64, 256],
            adaptive_spp: false,
            indirect: 2,
            seed: 1,
            initial_albedo: [0.5; 3],
            min_eval_albedo: 0.02,
            rules: WeightRules::default(),
            parts: None,
            schedule: Schedule::GaussSeidel,
            deblur: 0,
            smooth_shading: true,
            lattice_shading: true,
            coarse_stage: false,
        }
    }
}

impl SolveOptions {
    /// Refuses options that cannot mean a solve (checked before any work or output).
    pub fn validate(&self) -> Result<(), ReflectError> {
        let bad = |m: String| Err(ReflectError::Options(m));
        if self.max_iterations == 0 {
            return bad("--iterations 0 would solve nothing; give at least 1".into());
        }
        if self.spp.is_empty() || self.spp.contains(&0) {
            return bad(format!(
                "--spp: the schedule must be non-empty and positive, got {:?}",
                self.spp
            ));
        }
        if !(8..=16384).contains(&self.atlas_resolution) {
            return bad(format!(
                "--atlas {} is outside 8..=16384",
                self.atlas_resolution
            ));
        }
        if let Some(a) = self.atlas_auto {
            if !(crate::atlas_size::AUTO_ATLAS_MIN..=16384).contains(&a.max) {
                return bad(format!(
                    "--atlas-max {} is outside {}..=16384",
                    a.max,
                    crate::atlas_size::AUTO_ATLAS_MIN
                ));
            }
        }
        if !(self.tolerance.is_finite() && self.tolerance >= 0.0) {
            return bad(format!(
                "--tolerance must be finite and non-negative, got {}",
                self.tolerance
            ));
        }
        if !self
            .initial_albedo
            .iter()
            .all(|a| a.is_finite() && *a >= 0.0 && *a <= 1.0)
        {
            return bad(format!(
                "--initial: an albedo lies in [0, 1], got {:?}",
                self.initial_albedo
            ));
        }
        if self.indirect > 64 {
            return bad(format!(
                "--indirect {} is more bounces than can matter (at most 64)",
                self.indirect
            ));
        }
        Ok(())
    }
}

/// One iteration in the report.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct IterationRecord {
    pub iteration: u32,
    pub spp: u32,
    /// Wall time of this iteration and since the start of the solve, in seconds.
    pub wall_s: f64,
    pub cumulative_s: f64,
    /// Observations (texel, photo) that entered the update.
    pub observations: u64,
    /// RMS of rendered minus photographed radiance over the observations, with the reflectance
    /// of the start of the iteration; and that RMS divided by the RMS of the photographed values.
    pub residual_rms: f32,
    pub residual_rel_rms: f32,
    /// Mean over seen texels of the largest per-channel change of `rho_d`.
    pub delta_rho: f32,
    /// RMS over seen texels and channels of the standard error of `rho_d` beyond the
    /// Monte-Carlo noise (`weights::Combined::photo_noise`): what the photographs leave
    /// uncertain, which no number of samples reduces.
    #[serde(default)]
    pub noise_rho: f32,
    /// RMS over seen texels and channels of this iteration's change of `rho_d` beyond what the
    /// Monte-Carlo noise of this and the previous estimate explains: sqrt(max(0, mean(d^2 -
    /// mc_k^2 - mc_(k-1)^2))). Once the samples per estimate stop growing, the solve stops
    /// when it is below `noise_rho`: the iteration moved the albedo by less than the
    /// photographs can tell apart, and another at the same samples would only redraw the
    /// Monte-Carlo noise.
    #[serde(default)]
    pub systematic_change_rho: f32,
    /// RMS over seen texels and channels of the Monte-Carlo part of the standard error of
    /// `rho_d` (what more samples reduce); `None` in reports written before it existed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mc_noise_rho: Option<f32>,
    /// With ground truth: mean absolute error of `rho_d` per channel over texels seen in at
    /// least two photos, and its RMS.
    pub truth_mae: Option<[f32; 3]>,
    pub truth_rms: Option<f32>,
    /// With ground truth: mean absolute error of `rho_d` per channel as rendered (the atlases'
    /// bilinear lookup) at area-uniform points of the true surface whose texel was seen in at
    /// least two photos (`crate::truth`: the same whatever the atlas resolution). Reports
    /// written before the field existed read `None`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub truth_surface_mae: Option<[f32; 3]>,
    pub seen_texels: u64,
    /// Groups (voxels) of a distributed iteration that kept their previous albedo because their
    /// task never finished (`igi cluster resume --skip-voxels`); an iteration with any is never
    /// counted as converged.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub stale: Vec<String>,
    /// The iteration ran on the coarse atlases of a coarse-to-fine solve (`crate::coarse`):
    /// its albedo is the coarse one (its errors against the truth are the coarse atlases'),
    /// and the one iteration on the solve's own atlases follows the last such. Reports
    /// written before the field existed read `false`.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub coarse: bool,
}

/// How many times larger the texels of a coarse-to-fine solve's coarse stage are, per side
/// (`crate::coarse`); the fine iteration after it traces its shading at the same spacing
/// (`crate::lattice`).
pub const COARSE_FACTOR: u32 = 3;

/// Per-part summary in the report.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PartSummary {
    pub name: String,
    pub resolution: usize,
    pub texel_size_m: f64,
    pub covered_texels: usize,
    pub seen_texels: usize,
    pub seen_twice_texels: usize,
    pub filled_texels: usize,
    /// Where the part lives in a prepared site (none for a part built from a survey mesh).
    #[serde(default)]
    pub stored: Option<StoredPart>,
    /// Triangles in the scene its last solve traced against (with a prepared site: the
    /// multiresolution load of its voxel).
    #[serde(default)]
    pub scene_triangles: u64,
    /// The resolving pixel footprint of the photographs on the part (metres) when `--atlas auto`
    /// chose its resolution (`atlas_size::auto_resolution`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub footprint_m: Option<f64>,
}

impl PartSummary {
    /// The summary of part `p` before any solve has seen it.
    pub(crate) fn unsolved(p: &Part) -> PartSummary {
        PartSummary {
            name: p.name.clone(),
            resolution: p.resolution(),
            texel_size_m: p.texel_size,
            covered_texels: p.cache.texels.len(),
            seen_texels: 0,
            seen_twice_texels: 0,
            filled_texels: 0,
            stored: p.stored.clone(),
            scene_triangles: 0,
            footprint_m: p.footprint_m,
        }
    }
}

/// The report of a solve (`report.json`).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SolveReport {
    pub options: SolveOptions,
    pub photos: Vec<String>,
    pub iterations: Vec<IterationRecord>,
    pub parts: Vec<PartSummary>,
    pub converged: bool,
    /// The prepared site the parts come from (solved voxel by voxel), if any.
    #[serde(default)]
    pub site: Option<std::path::PathBuf>,
    /// The iteration in progress when a voxel-by-voxel solve was checkpointed after a voxel.
    #[serde(default)]
    pub pending: Option<Pending>,
    /// The lighting estimated with the albedo for photos without lighting files (written by
    /// `igi-workflow`'s `lightfit`: fitted sky parameters with uncertainties, the global
    /// scale); absent otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lighting: Option<serde_json::Value>,
}

/// A voxel-by-voxel iteration in progress: the groups already solved and the running sums of
/// the iteration's statistics, so a killed run resumes with the next voxel.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct Pending {
    pub iteration: u32,
    pub done: Vec<String>,
    pub wall_s: f64,
    pub observations: u64,
    /// Sum of squared residuals (photograph minus prediction, per channel).
    #[serde(alias = "res2")]
    pub residual_sq: f64,
    /// Sum of squared photograph values over the same channels (for the relative RMS).
    #[serde(alias = "rel2")]
    pub pixel_sq: f64,
    /// Channels summed into `residual_sq`.
    #[serde(alias = "nres")]
    pub residual_channels: u64,
    pub delta: f64,
    /// Texels with at least one observation.
    #[serde(alias = "nseen")]
    pub seen_texels: u64,
    /// Sums over seen texels of the mean per-channel squared photograph noise of `rho_d`, and
    /// of its squared change less the change the Monte-Carlo noise of this and the previous
    /// estimate explains (may be negative; see [`IterationRecord::systematic_change_rho`]).
    #[serde(default)]
    pub noise2: f64,
    #[serde(default)]
    pub systematic2: f64,
    /// Sum over seen texels of the mean per-channel squared Monte-Carlo noise of `rho_d`.
    #[serde(default)]
    pub mc2: f64,
}

impl Pending {
    /// Adds a group's statistics (groups are added in their order, so sums do not depend on
    /// where a run stopped or which machine solved a group).
    pub fn add(&mut self, g: &Pending) {
        self.observations += g.observations;
        self.residual_sq += g.residual_sq;
        self.pixel_sq += g.pixel_sq;
        self.residual_channels += g.residual_channels;
        self.delta += g.delta;
        self.seen_texels += g.seen_texels;
        self.noise2 += g.noise2;
        self.systematic2 += g.systematic2;
        self.mc2 += g.mc2;
    }
}
