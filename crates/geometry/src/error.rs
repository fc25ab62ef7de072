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
    /// A file name whose extension names no format this crate reads or writes.
    #[error("{}: unknown mesh format (expected .ply or .obj)", path.display())]
    UnknownFormat { path: PathBuf },
    /// A mesh that breaks an invariant (empty, NaN coordinates, index out of range, attribute length).
    #[error("invalid mesh: {0}")]
    InvalidMesh(String),
    /// A bad argument (voxel size, level list, voxel id...).
    #[error("invalid argument: {0}")]
    InvalidArgument(String),
    /// A run whose estimated size is beyond the limits (checked before allocating).
    #[error("too large: {what}")]
    TooLarge { what: String },
    /// An error from the imaging layer (EXR caches, atomic writes).
    #[error(transparent)]
    Imaging(#[from] igi_imaging::ImagingError),
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
            GeometryError::InvalidMesh(m) => GeometryError::format(path, m),
            e => e,
        }
    }
}
