//! Errors of the capture crate.

use igi_imaging::ImagingError;
use std::path::PathBuf;

/// A sphere that cannot be used in a photograph (it is not fully seen by the camera).
#[derive(Debug, thiserror::Error)]
pub enum SphereError {
    #[error(
        "{kind} sphere is partly outside the {width}x{height} image: its outline reaches pixel ({x:.1}, {y:.1}); \
         move the board or fix its centre/radius"
    )]
    OutsideImage {
        kind: String,
        width: u32,
        height: u32,
        x: f64,
        y: f64,
    },
    #[error(
        "{kind} sphere is behind the camera or contains it (centre {center:?}, radius {radius})"
    )]
    BadSphere {
        kind: String,
        center: [f64; 3],
        radius: f64,
    },
}

/// Errors of a capture recipe. Variants about a file name it.
#[derive(Debug, thiserror::Error)]
pub enum CaptureError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    /// A description file or a photograph that cannot be used, and why.
    #[error("{path}: {msg}")]
    File { path: PathBuf, msg: String },
    #[error(transparent)]
    Imaging(#[from] ImagingError),
    #[error(transparent)]
    Sphere(#[from] SphereError),
}
