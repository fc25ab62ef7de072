//! The one error type of `igi-geometry`.

use std::path::PathBuf;

/// Everything that can go wrong reading, checking, partitioning or storing meshes.
#[derive(Debug, thiserror::Error)]
pub enum GeometryError {
    /// An operating-system error on a named file.
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A file whose content is not what its format promises (truncated, bad header, counts that do not match...).
    #[error("{}: {msg}", path.display())]
    Format { path: PathBuf, msg: String },
    /// A JSON file of the site store that does not parse.
    #[error("{}: bad JSON: {source}", path.display())]
    Json {
        path: PathBuf,
        #[source]
        source: serde_json::Error,
    },
    /// A value of an ASCII PLY file that is not a number.
    #[error("{}: {element} element {index}: `{token}` is not a number", path.display())]
    PlyNumber {
        path: PathBuf,
        element: String,
        index: usize,
        token: String,
        #[source]
        source: std::num::ParseFloatError,
    },
    /// A file name whose extension names no format this crate reads or writes.
    #[error("{}: unknown mesh format (expected .ply or .obj)", path.display())]
    UnknownFormat { path: PathBuf },
    /// A mesh or point cloud that breaks an invariant (empty, NaN coordinates, index out of
    /// range, attribute length).
    #[error("invalid mesh: {0}")]
    InvalidMesh(#[from] MeshInvariant),
    /// A mesh file whose mesh breaks an invariant.
    #[error("{}: {problem}", path.display())]
    MeshInFile {
        path: PathBuf,
        #[source]
        problem: MeshInvariant,
    },
    /// A bad argument (voxel size, level list, voxel id...).
    #[error("invalid argument: {0}")]
    InvalidArgument(String),
    /// A request of a job (`job`) that cannot be run; the message names the option.
    #[error("{0}")]
    Arguments(String),
    /// A value of a list option that is not a number.
    #[error("--{option}: `{text}` is not a number")]
    NotANumber {
        option: &'static str,
        text: String,
        #[source]
        source: std::num::ParseFloatError,
    },
    /// A value of a list option that is not an integer.
    #[error("--{option}: `{text}` is not an integer")]
    NotAnInteger {
        option: &'static str,
        text: String,
        #[source]
        source: std::num::ParseIntError,
    },
    /// A run whose estimated size is beyond the limits (checked before allocating).
    #[error("too large: {what}")]
    TooLarge { what: String },
    /// An error from the imaging layer (EXR caches, atomic writes).
    #[error(transparent)]
    Imaging(#[from] igi_imaging::ImagingError),
    /// An output file or folder, a run manifest or the folder lock.
    #[error(transparent)]
    Files(#[from] igi_files::FilesError),
}

impl GeometryError {
    pub(crate) fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        GeometryError::Io {
            path: path.into(),
            source,
        }
    }
    pub(crate) fn format(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        GeometryError::Format {
            path: path.into(),
            msg: msg.into(),
        }
    }
    /// Attach a file name to an `InvalidMesh` error (other variants already name their file).
    pub(crate) fn in_file(self, path: &std::path::Path) -> Self {
        match self {
            GeometryError::InvalidMesh(problem) => GeometryError::MeshInFile {
                path: path.to_path_buf(),
                problem,
            },
            e => e,
        }
    }
}

/// The invariant a mesh or point cloud breaks (`TriMesh::validate`, `PointCloud::validate`).
#[derive(Debug, thiserror::Error)]
pub enum MeshInvariant {
    #[error("empty mesh ({vertices} vertices, {triangles} triangles)")]
    Empty { vertices: usize, triangles: usize },
    #[error("empty point cloud")]
    EmptyCloud,
    #[error("vertex {vertex} has a non-finite coordinate {position:?}")]
    NonFiniteVertex { vertex: usize, position: [f32; 3] },
    /// A per-vertex (`element` "vertices") or per-point ("points") attribute of the wrong length.
    #[error("{name} has {entries} entries for {count} {element}")]
    AttributeLength {
        name: String,
        entries: usize,
        count: usize,
        element: &'static str,
    },
    /// A non-finite attribute value of vertex or point (`element`) `index`.
    #[error("{name} of {element} {index} is not finite")]
    NonFiniteAttribute {
        name: String,
        element: &'static str,
        index: usize,
    },
    #[error(
        "triangle {triangle} uses vertex index {index} but there are only {vertices} vertices"
    )]
    IndexOutOfRange {
        triangle: usize,
        index: u32,
        vertices: usize,
    },
    #[error("property name {0:?} is not a new PLY identifier")]
    PropertyName(String),
}
