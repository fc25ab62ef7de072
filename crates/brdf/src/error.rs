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
    #[error("json: {0}")]
    Json(#[from] serde_json::Error),
}
