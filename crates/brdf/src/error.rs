//! Errors of the BRDF crate.

use std::path::PathBuf;

/// Everything that can go wrong while reading, fitting, inferring or clustering BRDFs.
#[derive(Debug, thiserror::Error)]
pub enum BrdfError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}:{line}: {msg}")]
    Parse {
        path: PathBuf,
        line: usize,
        msg: String,
    },
    #[error("{path}: {msg}")]
    File { path: PathBuf, msg: String },
    #[error("fit of material `{material}` failed: {msg}")]
    Fit { material: String, msg: String },
    #[error("invalid input: {0}")]
    Invalid(String),
    /// A BRDF-sample or pair file (read by `igi-formats`): the file and the problem.
    #[error(transparent)]
    Format(#[from] igi_formats::FormatsError),
    /// A lumitexel table's structure (read through `igi_imaging::csv`).
    #[error(transparent)]
    Csv(#[from] igi_imaging::csv::CsvError),
    #[error("json: {0}")]
    Json(#[from] serde_json::Error),
}
