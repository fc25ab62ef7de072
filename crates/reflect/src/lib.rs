//! Iterative inverse global illumination (Debevec et al. 2004, sections 4.1-4.2).
//!
//! Given a site (meshes), photographs with their cameras, and the lighting captured with each
//! photograph, recover the diffuse albedo `rho_d` of every texel of the site's texture atlases,
//! then infer the specular lobes from `rho_d` with a BRDF basis (when hand-held samples are
//! given). The loop, per iteration:
//!
//! 1. render, for each texel `p` and photo `I`, the radiance leaving `p` toward `I`'s camera
//!    under `I`'s lighting with the current reflectance everywhere (path tracing with
//!    `igi-render`, two indirect bounces by default);
//! 2. form the ratio proposal `rho_d(p) * I(p) / L_render(p)` per channel;
//! 3. average the proposals over photos with weights (cosine of the view angle, lowered near
//!    occlusion boundaries and near shadow edges, see [`weights`]);
//! 4. repeat with more samples per estimate until the change in `rho_d` is below a tolerance,
//!    or, once the samples stop growing, below the photographs' own noise in `rho_d`.
//!
//! Texels seen by no photo are filled from their seen neighbours (see [`fill`]). Results are
//! written per part (an input mesh, or a voxel of a prepared site) atomically, with a report of
//! every iteration, and a killed run resumes after its last finished iteration.
//!
//! Modules: [`parts`] (atlases and texel caches of the site), [`atlas_size`] (`--atlas auto`:
//! atlas sizes, and cutting meshes into parts), [`solver`] (the iteration, over photographs
//! already loaded: [`Photo`]), [`weights`] and [`fill`] (the documented rules),
//! [`result`] (the result folder: atlases, `scene.toml`, `report.json`, export, sampling),
//! [`truth`] (ground truth: the true atlases and scene, and the albedo error per texel and over
//! the surface).
//!
//! The survey folder, where each photo's light comes from, the run manifest, the folder lock
//! and the demo are `igi-workflow`'s: this crate solves what it is given. The synthetic surveys
//! the tests and the demo solve are made by `igi-synth`.

pub mod atlas_size;
mod deblur;
pub mod distributed;
pub mod fill;
pub mod parts;
pub mod photo;
pub mod plot;
pub mod record;
pub mod result;
mod smooth;
pub mod solver;
pub mod truth;
pub mod weights;

use std::path::PathBuf;

pub use parts::{Part, TexelCache};
pub use photo::Photo;
pub use result::{load_result_scene, SolveResult, UNKNOWN_STDERR};
pub use solver::{
    solve, solve_in_memory, IterationRecord, Progress, Schedule, SolveOptions, SolveReport,
};

/// Errors of the inverse solver.
#[derive(Debug, thiserror::Error)]
pub enum ReflectError {
    /// A file is missing, unreadable or malformed.
    #[error("{path}: {msg}")]
    File { path: PathBuf, msg: String },
    /// Input that cannot be used (kept for callers' own checks, e.g. a checkpoint callback).
    #[error("invalid input: {0}")]
    Invalid(String),
    /// Solve options that cannot mean a solve (the message names the option).
    #[error("invalid input: {0}")]
    Options(String),
    /// No photograph to solve from.
    #[error("invalid input: no photographs to solve from")]
    NoPhotos,
    /// A part name that cannot name files (empty, or with a path separator).
    #[error("invalid input: `{0}` cannot name a part")]
    UnnamablePart(String),
    /// Two site meshes with the same name.
    #[error("invalid input: two site meshes are both named `{0}`")]
    DuplicatePart(String),
    /// `--atlas auto` cut a piece whose name another mesh has.
    #[error("invalid input: {source}: a site mesh has the name `--atlas auto` gives a piece cut from another (NAME-K); rename the mesh")]
    PieceName {
        #[source]
        source: Box<ReflectError>,
    },
    /// The atlas of a part could not be built.
    #[error("invalid input: atlas of `{part}`: {source}")]
    Atlas {
        part: String,
        #[source]
        source: Box<igi_geometry::GeometryError>,
    },
    /// The trial atlas of `--atlas auto` could not be built.
    #[error("invalid input: trial atlas: {0}")]
    TrialAtlas(#[source] Box<igi_geometry::GeometryError>),
    /// A part selection (`--parts`) names no part; `known` lists some of the parts.
    #[error("invalid input: --parts: no part named `{name}` in the site (parts: {known})")]
    UnknownPart { name: String, known: String },
    /// A voxel or part to solve that the plan does not hold; `known` lists some of them.
    #[error("invalid input: no voxel or part `{name}` to solve (there are {count}: {known})")]
    UnknownGroup {
        name: String,
        count: usize,
        known: String,
    },
    /// A prepared site's voxel that the result has no part for.
    #[error("invalid input: the prepared site holds {0}, which the result does not")]
    UnknownVoxel(String),
    /// A voxel group without the prepared site it comes from.
    #[error("invalid input: a voxel group needs its prepared site")]
    NoPreparedSite,
    /// Prepared voxels mixed with plain meshes.
    #[error("invalid input: a site is either prepared or a set of meshes, not both")]
    MixedSite,
    /// Distributed iterations under another schedule than Jacobi.
    #[error("invalid input: distributed iterations need the Jacobi schedule")]
    NotJacobi,
    /// No photograph saw any texel of the parts being solved.
    #[error("no photograph sees any solved part (0 observations in iteration {0}): check the cameras' poses and sizes against the site, and the part selection")]
    NoObservations(u32),
    /// A merge found tasks of its iteration unfinished.
    #[error("iteration {iteration}: {} task(s) have not finished: {}", groups.len(), groups.join(", "))]
    MissingTasks { iteration: u32, groups: Vec<String> },
    #[error(transparent)]
    Format(#[from] igi_formats::FormatsError),
    #[error(transparent)]
    Imaging(#[from] igi_imaging::ImagingError),
    /// A camera, its file, radiometry or rig, or an OpenCV call (`igi-camera`).
    #[error(transparent)]
    Camera(#[from] igi_camera::CameraError),
    /// A plot that could not be drawn or written.
    #[error(transparent)]
    Plot(#[from] igi_plot::PlotError),
    /// An output file or folder, a run manifest or the folder lock.
    #[error(transparent)]
    Files(#[from] igi_files::FilesError),
    #[error(transparent)]
    Geometry(#[from] igi_geometry::GeometryError),
    #[error(transparent)]
    Render(#[from] igi_render::RenderError),
    /// The ray scene of the site (`--atlas auto`'s visibility tests).
    #[error(transparent)]
    Raycast(#[from] igi_raycast::RaycastError),
    #[error(transparent)]
    Brdf(#[from] igi_brdf::BrdfError),
    /// A BRDF file (samples, materials) that reads but cannot be used.
    #[error("{path}: {source}")]
    BrdfFile {
        path: PathBuf,
        #[source]
        source: igi_brdf::BrdfError,
    },
    /// A numeric CSV table (`igi sample`'s points): the file, the line and the problem.
    #[error(transparent)]
    Csv(#[from] igi_imaging::csv::CsvError),
}

impl ReflectError {
    pub(crate) fn file(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        ReflectError::File {
            path: path.into(),
            msg: msg.into(),
        }
    }
}
