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
    /// A request of a job (`job`) that cannot be run; the message names the option.
    #[error("{0}")]
    Arguments(String),
    /// A failure inside a file (`source`), the file named.
    #[error("in {}", path.display())]
    InFile {
        path: PathBuf,
        #[source]
        source: Box<BrdfError>,
    },
    /// The samples of a file that could not be fitted (`source`: why).
    #[error("fitting {}", path.display())]
    Fitting {
        path: PathBuf,
        #[source]
        source: Box<BrdfError>,
    },
    /// The lumitexels of a file that could not be clustered (`source`: why).
    #[error("clustering {}", path.display())]
    Clustering {
        path: PathBuf,
        #[source]
        source: Box<BrdfError>,
    },
    #[error("fit of material `{material}` failed: {msg}")]
    Fit { material: String, msg: String },
    /// A lumitexel table's structure (read through `igi_imaging::csv`).
    #[error(transparent)]
    Csv(#[from] igi_imaging::csv::CsvError),
    /// A BRDF basis of no material.
    #[error("invalid input: a BRDF basis needs at least one material")]
    EmptyBasis,
    /// Clustering into no cluster.
    #[error("invalid input: the number of clusters k must be at least 1")]
    NoClusters,
    /// Too few usable lumitexels (or samples above the surface) for `k` clusters.
    #[error("invalid input: {lumitexels} usable lumitexels with {samples} samples above the surface cannot make {k} clusters")]
    TooFewLumitexels {
        lumitexels: usize,
        samples: usize,
        k: usize,
    },
    /// A cluster whose members all agree, so it cannot be split.
    #[error("invalid input: cluster {cluster} cannot be split further ({members} members agree)")]
    Unsplittable { cluster: usize, members: usize },
    /// A cluster that no lumitexel fits better than the others, even after reseeding.
    #[error("cluster {cluster} of {k} stays empty: the lumitexels hold fewer than {k} distinguishable materials; lower -k")]
    EmptyCluster { cluster: usize, k: usize },
    /// A material name not in the materials file; `have` lists its names.
    #[error("invalid input: no material `{name}` (have: {have})")]
    NoMaterial { name: String, have: String },
    /// A samples or direction-pair file (`igi-formats`).
    #[error(transparent)]
    Formats(#[from] igi_formats::FormatsError),
    #[error("json: {0}")]
    Json(#[from] serde_json::Error),
    /// An input or output file checked by `igi-files` (a device given as the samples file).
    #[error(transparent)]
    Files(Box<igi_files::FilesError>),
}

impl From<igi_files::FilesError> for BrdfError {
    fn from(e: igi_files::FilesError) -> Self {
        BrdfError::Files(Box::new(e))
    }
}
