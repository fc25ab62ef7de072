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
    /// Exposure times and brackets that cannot be merged.
    #[error(transparent)]
    Hdr(#[from] HdrError),
    /// Flat fields or a colour checker that cannot be fitted.
    #[error(transparent)]
    RadiometryFit(#[from] RadiometryError),
    /// A problem inside a file (the file named, the problem as its own error).
    #[error("{}: {source}", path.display())]
    InFile {
        path: PathBuf,
        #[source]
        source: Box<ImagingError>,
    },
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
    #[error("{}: {msg}", path.display())]
    NotARunFolder { path: PathBuf, msg: String },
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

/// Exposure times and brackets that cannot be merged (`hdr`).
#[derive(Debug, thiserror::Error)]
pub enum HdrError {
    #[error("cannot parse exposure time {0:?} (want seconds, e.g. 0.004 or 1/250)")]
    TimeSyntax(String),
    #[error("exposure time {0:?} must be positive and finite")]
    TimeValue(String),
    #[error("no brackets given")]
    NoBrackets,
    #[error("missing exposure times: {images} image(s) but {times} time(s)")]
    TimeCount { images: usize, times: usize },
    #[error("{name}: brackets of different sizes: {}x{} but {first} is {}x{}", size.0, size.1, first_size.0, first_size.1)]
    Sizes {
        name: String,
        size: (usize, usize),
        first: String,
        first_size: (usize, usize),
    },
    #[error("{name}: exposure time {time} must be positive and finite")]
    BracketTime { name: String, time: f64 },
    #[error("{name}: exposure times must be strictly monotonic with no duplicates (sort the brackets): {time} follows {previous}")]
    Order {
        name: String,
        time: f64,
        previous: f64,
    },
    #[error("noise floor {noise_floor} must be below saturation {saturation}")]
    Levels { noise_floor: f32, saturation: f32 },
    #[error("slope merge range [{lo}, {hi}] is empty")]
    SlopeRange { lo: f32, hi: f32 },
    #[error("response recovery: smoothness (lambda) must be finite and >= 0 and samples at least 2, got lambda {lambda} and {samples} samples")]
    ResponseParams { lambda: f64, samples: usize },
    #[error("response least squares failed: {0}")]
    Solve(String),
}

/// Flat fields and colour-checker patches that cannot be fitted (`radiometry`).
#[derive(Debug, thiserror::Error)]
pub enum RadiometryError {
    #[error("falloff fit needs at least 4 samples, got {0}")]
    FewSamples(usize),
    #[error("{what} least squares failed: {msg}")]
    Solve { what: &'static str, msg: String },
    #[error("colour matrix: {patches} source patches but {targets} targets")]
    PatchCount { patches: usize, targets: usize },
    #[error("falloff fit needs at least one flat field")]
    NoFlats,
    #[error("flat field {index} is {}x{} but the first is {}x{}", size.0, size.1, first.0, first.1)]
    FlatSize {
        index: usize,
        size: (usize, usize),
        first: (usize, usize),
    },
    #[error("colour checker patch {index} ({usable} of 81 samples usable): is it inside the image and unsaturated?")]
    Patch { index: usize, usable: usize },
    #[error("colour checker: {0} patches, expected 24")]
    CheckerPatches(usize),
    #[error("colour checker white radiance {0} must be positive")]
    White(f64),
    #[error("radiometry needs flat fields, a colour checker, or both")]
    NothingToFit,
    #[error("the colour checker photograph is {}x{} but the flat fields are {}x{}", size.0, size.1, flats.0, flats.1)]
    CheckerSize {
        size: (usize, usize),
        flats: (usize, usize),
    },
    #[error("no ColorChecker Classic (6 x 4 patches) found in the image")]
    CheckerNotFound,
}
