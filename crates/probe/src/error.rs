use igi_capture::SphereError;
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
    /// A sphere not fully seen by the camera ([`igi_capture::SphereError`]).
    #[error(transparent)]
    Sphere(#[from] SphereError),
    /// A reflectance-sample row (or the whole file) the Fresnel fit cannot use.
    #[error("{}: invalid reflectance samples: {}{problem}", path.display(), line.map(|l| format!("line {l}: ")).unwrap_or_default())]
    Samples {
        path: PathBuf,
        line: Option<usize>,
        problem: crate::fresnel::ReflectanceProblem,
    },
    /// A CSV table's structure (`igi_imaging::csv`): the file, the line and the problem.
    #[error(transparent)]
    Csv(#[from] igi_imaging::csv::CsvError),
    #[error("invalid input: {0}")]
    InvalidInput(String),
    #[error("fit failed: {0}")]
    Fit(String),
    /// A lighting file could not be written.
    #[error(transparent)]
    Format(#[from] igi_formats::FormatsError),
    /// Exposure brackets without one exposure time each.
    #[error("{brackets} brackets but {times} exposure times (give one time per bracket)")]
    BracketTimes { brackets: usize, times: usize },
    /// Brackets that could not be merged (`files` names them).
    #[error("merging brackets {files}: {source}")]
    Merge {
        files: String,
        #[source]
        source: ImagingError,
    },
}
