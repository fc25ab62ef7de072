//! The errors of an import: each names the file it is about (and the line of a text file, the
//! byte offset of a binary file, the row of a control-point file).

use std::path::PathBuf;

/// Why an import cannot go on.
#[derive(Debug, thiserror::Error)]
pub enum ImportError {
    /// A file that cannot be read.
    #[error("{}: cannot read {what}: {source}", path.display())]
    Read {
        path: PathBuf,
        what: &'static str,
        #[source]
        source: std::io::Error,
    },
    /// A file that cannot be written.
    #[error("{}: cannot write: {source}", path.display())]
    Write {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A COLMAP folder without the files of a model.
    #[error("{}: no COLMAP {what} (neither {what}.bin nor {what}.txt)", dir.display())]
    MissingModelFile { dir: PathBuf, what: &'static str },
    /// A line of a COLMAP text file that does not mean what it must.
    #[error("{}:{line}: {problem}", path.display())]
    Text {
        path: PathBuf,
        line: usize,
        problem: String,
    },
    /// Bytes of a COLMAP binary file that do not mean what they must.
    #[error("{}: at byte {offset}: {problem}", path.display())]
    Binary {
        path: PathBuf,
        offset: u64,
        problem: String,
    },
    /// A model that is well formed but cannot become contract cameras.
    #[error("{}: {problem}", path.display())]
    Model { path: PathBuf, problem: String },
    /// Control points that cannot align the model.
    #[error("{}: {problem}", path.display())]
    Control { path: PathBuf, problem: String },
    /// An input the survey would name that is missing or unusable.
    #[error("{}: {problem}", path.display())]
    Input { path: PathBuf, problem: String },
    /// The output folder cannot take the survey.
    #[error("{}: {problem}", path.display())]
    Output { path: PathBuf, problem: String },
    #[error(transparent)]
    Files(#[from] igi_files::FilesError),
    #[error(transparent)]
    Formats(#[from] igi_formats::FormatsError),
    #[error(transparent)]
    Camera(#[from] igi_camera::CameraError),
    /// The site mesh (`--mesh`) cannot be read.
    #[error(transparent)]
    Geometry(#[from] igi_geometry::GeometryError),
    /// The ICP refinement against the mesh (`--icp`) cannot be made.
    #[error("{}: ICP of the model's sparse points: {source}", meshes.iter().map(|m| m.display().to_string()).collect::<Vec<_>>().join(", "))]
    Icp {
        /// The meshes matched against (`--mesh`, all of them).
        meshes: Vec<PathBuf>,
        #[source]
        source: IcpError,
    },
}

impl ImportError {
    pub(crate) fn text(path: &std::path::Path, line: usize, problem: impl Into<String>) -> Self {
        ImportError::Text {
            path: path.to_path_buf(),
            line,
            problem: problem.into(),
        }
    }

    pub(crate) fn control(path: &std::path::Path, problem: impl Into<String>) -> Self {
        ImportError::Control {
            path: path.to_path_buf(),
            problem: problem.into(),
        }
    }
}

/// The fewest sparse points ICP runs on (`crate::icp::MIN_POINTS`).
pub const ICP_MIN_POINTS: usize = 10;

/// Why the ICP refinement (`crate::icp`) cannot be made.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum IcpError {
    #[error("the mesh has no triangle of nonzero area")]
    EmptyMesh,
    #[error("{0} sparse points: ICP needs at least {ICP_MIN_POINTS}")]
    TooFewPoints(usize),
    #[error("keep fraction {0} is not in (0, 1]")]
    BadKeep(f64),
    #[error("a point is not finite")]
    NotFinite,
    #[error("the kept points are degenerate (all on a point or line): no similarity fits them")]
    Degenerate,
    #[error("the refinement would {0}: the control-point alignment and the mesh disagree, so nearest points are not correspondences")]
    TooFar(String),
    #[error("the refinement does not lower the kept points' RMS distance to the mesh ({before:.4} m -> {after:.4} m)")]
    NoGain { before: f64, after: f64 },
}
