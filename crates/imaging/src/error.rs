use std::path::PathBuf;

/// Errors of the imaging crate. Every variant that concerns a file names it.
#[derive(Debug, thiserror::Error)]
pub enum ImagingError {
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{}: unknown image format (extension {ext:?}); supported: .exr .hdr .png .jpg .jpeg .tif .tiff", path.display())]
    UnknownFormat { path: PathBuf, ext: String },
    #[error("{}: cannot decode image: {msg}", path.display())]
    Decode { path: PathBuf, msg: String },
    #[error("{}: cannot encode image: {msg}", path.display())]
    Encode { path: PathBuf, msg: String },
    #[error("{}: bad image data: {msg}", path.display())]
    BadPixels { path: PathBuf, msg: String },
    #[error("{}: invalid camera file: {msg}", path.display())]
    Camera { path: PathBuf, msg: String },
    #[error("{}: invalid camera radiometry file: {msg}", path.display())]
    Radiometry { path: PathBuf, msg: String },
    #[error("{}: exif: {msg}", path.display())]
    Exif { path: PathBuf, msg: String },
    #[error("{}: {msg}", path.display())]
    Rig { path: PathBuf, msg: String },
    #[error("{}: view {view:?}: {msg}", path.display())]
    RigView {
        path: PathBuf,
        view: String,
        msg: String,
    },
    #[error("{}: view {view:?}: {source}", path.display())]
    RigViewFile {
        path: PathBuf,
        view: String,
        #[source]
        source: Box<ImagingError>,
    },
    #[error("invalid input: {0}")]
    InvalidInput(String),
    #[error("{}: is a file, not a folder (cannot write into {})", path.display(), wanted.display())]
    NotAFolder { path: PathBuf, wanted: PathBuf },
    #[error("{}: output folder does not exist", path.display())]
    NoFolder { path: PathBuf },
    #[error("{}: cannot write into this folder", path.display())]
    NotWritable {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{}: holds a run with a different {what} (there: {was}; now: {now}); use --restart to start afresh, or another output folder", path.display())]
    RunMismatch {
        path: PathBuf,
        what: String,
        was: String,
        now: String,
    },
    #[error("{}: unreadable run manifest: {msg}; use --restart to start afresh", path.display())]
    BadManifest { path: PathBuf, msg: String },
    #[error("built without opencv: rebuild with --features opencv")]
    NoOpenCv,
    #[error("opencv: {0}")]
    OpenCv(String),
}

impl ImagingError {
    pub(crate) fn io(path: &std::path::Path, source: std::io::Error) -> Self {
        ImagingError::Io {
            path: path.to_path_buf(),
            source,
        }
    }
}
