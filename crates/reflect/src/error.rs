//! The errors of the inverse solver: what went wrong, with the file it concerns and the error
//! beneath it as its source.

use std::path::PathBuf;

/// Errors of the inverse solver.
#[derive(Debug, thiserror::Error)]
pub enum ReflectError {
    /// An atlas image whose size is not its part's.
    #[error("{path}: is {width}x{height}, expected {expected}x{expected}")]
    AtlasSize {
        path: PathBuf,
        width: usize,
        height: usize,
        expected: usize,
    },
    /// A prepared site without a terrain where its terrain part was asked for.
    #[error("{0}: the prepared site has no terrain")]
    NoTerrain(PathBuf),
    /// A result folder whose last checkpoint was staged but not moved into place.
    #[error("{0}: a solve was killed while committing a checkpoint; run the same `igi solve` again to finish it")]
    UnfinishedCheckpoint(PathBuf),
    /// A folder that is not a solve result (no `scene.toml` and `report.json`).
    #[error("{0}: not a solve result folder (no scene.toml and report.json)")]
    NotAResult(PathBuf),
    /// A file a cluster task writes that its folder does not hold.
    #[error("{0}: missing (a task writes it)")]
    MissingTaskFile(PathBuf),
    /// A file or folder the solver could not read, write, create, move or remove.
    #[error("{path}: cannot {action}: {source}")]
    Io {
        path: PathBuf,
        /// What was tried ("read", "create folder", "move a staged file", ...).
        action: &'static str,
        #[source]
        source: std::io::Error,
    },
    /// A JSON file of the result that does not hold what it should.
    #[error("{path}: not a {what}: {source}")]
    Json {
        path: PathBuf,
        /// What it should hold ("solve report", "task report", "lobe list").
        what: &'static str,
        #[source]
        source: serde_json::Error,
    },
    /// A result's report whose parts cannot be read: none, or names that repeat or cannot name
    /// files.
    #[error("{}: {source}", path.display())]
    ReportParts {
        path: PathBuf,
        #[source]
        source: Box<ReflectError>,
    },
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
    /// Two site meshes, or two parts of a result, with the same name (`what` says which).
    #[error("invalid input: two {what} are both named `{name}`")]
    DuplicatePart { what: &'static str, name: String },
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
    /// [`ReflectError::Io`]: `action` on `path` failed with `source`.
    pub(crate) fn io(
        path: impl Into<PathBuf>,
        action: &'static str,
        source: std::io::Error,
    ) -> Self {
        ReflectError::Io {
            path: path.into(),
            action,
            source,
        }
    }

    /// [`ReflectError::Json`]: `path` does not parse as a `what`.
    pub(crate) fn json(
        path: impl Into<PathBuf>,
        what: &'static str,
        source: serde_json::Error,
    ) -> Self {
        ReflectError::Json {
            path: path.into(),
            what,
            source,
        }
    }
}
