use igi_imaging::ImagingError;
use std::path::PathBuf;

/// Errors of the probe crate. Variants about a file name it.
#[derive(Debug, thiserror::Error)]
pub enum ProbeError {
    #[error(transparent)]
    Imaging(#[from] ImagingError),
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{}: invalid board file: {msg}", path.display())]
    Board { path: PathBuf, msg: String },
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
    #[error("{}: invalid reflectance samples: {msg}", path.display())]
    Samples { path: PathBuf, msg: String },
    #[error("invalid input: {0}")]
    InvalidInput(String),
    #[error("fit failed: {0}")]
    Fit(String),
}
