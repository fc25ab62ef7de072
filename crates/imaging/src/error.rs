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
    /// The image library could not read a file (`source`: its error).
    #[error("{}: cannot decode image: {source}", path.display())]
    DecodeFailed {
        path: PathBuf,
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// The image library could not write a file (`source`: its error).
    #[error("{}: cannot encode image: {source}", path.display())]
    EncodeFailed {
        path: PathBuf,
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    #[error("{}: bad image data: {msg}", path.display())]
    BadPixels { path: PathBuf, msg: String },
    #[error("{}: exif: {msg}", path.display())]
    Exif { path: PathBuf, msg: String },
    /// A photograph without readable EXIF data.
    #[error("{}: exif: no EXIF data ({source}); give the exposure times explicitly", path.display())]
    NoExif {
        path: PathBuf,
        #[source]
        source: exif::Error,
    },
    #[error("invalid input: {0}")]
    InvalidInput(String),
    /// A numeric CSV table (a camera response file) that cannot be read.
    #[error(transparent)]
    Csv(#[from] crate::csv::CsvError),
    /// A camera response file whose values cannot be a response (`photo`), with its line.
    #[error("{}:{line}: {msg}", path.display())]
    ResponseFile {
        path: PathBuf,
        line: usize,
        msg: String,
    },
    /// A photograph's bit depth or format and the transfer asked for it do not go together.
    #[error("{}: {msg}", path.display())]
    PhotoTransfer { path: PathBuf, msg: String },
    /// Exposure times and brackets that cannot be merged.
    #[error(transparent)]
    Hdr(#[from] HdrError),
    /// Flat fields or a colour checker that cannot be fitted.
    /// Images that cannot be compared (`metrics`).
    #[error(transparent)]
    Compare(#[from] CompareError),
    /// A problem inside a file (the file named, the problem as its own error).
    #[error("{}: {source}", path.display())]
    InFile {
        path: PathBuf,
        #[source]
        source: Box<ImagingError>,
    },
    /// An output file or folder, a run manifest or the folder lock (`igi-files`).
    #[error(transparent)]
    Files(#[from] igi_files::FilesError),
}

impl ImagingError {
    /// [`ImagingError::DecodeFailed`] for `path`.
    pub(crate) fn decode_failed(
        path: &std::path::Path,
        source: impl std::error::Error + Send + Sync + 'static,
    ) -> Self {
        ImagingError::DecodeFailed {
            path: path.to_path_buf(),
            source: Box::new(source),
        }
    }

    /// [`ImagingError::EncodeFailed`] for `path`.
    pub(crate) fn encode_failed(
        path: &std::path::Path,
        source: impl std::error::Error + Send + Sync + 'static,
    ) -> Self {
        ImagingError::EncodeFailed {
            path: path.to_path_buf(),
            source: Box::new(source),
        }
    }

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
    #[error("{name}: the same picture as {first} (identical pixels): brackets must be different exposures of the scene")]
    SameImage { name: String, first: String },
    #[error("noise floor {noise_floor} must be below saturation {saturation}")]
    Levels { noise_floor: f32, saturation: f32 },
    #[error("slope merge range [{lo}, {hi}] is empty")]
    SlopeRange { lo: f32, hi: f32 },
    #[error("response recovery: smoothness (lambda) must be finite and >= 0 and samples at least 2, got lambda {lambda} and {samples} samples")]
    ResponseParams { lambda: f64, samples: usize },
    /// The SVD solve failed (nalgebra's reason).
    #[error("response least squares failed: {0}")]
    Solve(&'static str),
    /// A response file asked of a linear merge, which recovers none.
    #[error("--response-out needs a response: it is not recovered with --linear")]
    ResponseOutLinear,
    /// Brackets whose EXIF gives no exposure time (`source`: why).
    #[error("missing exposure times: pass --times or --times-file")]
    MissingTimes {
        #[source]
        source: Box<ImagingError>,
    },
    /// A number of exposure times other than the number of brackets.
    #[error(
        "missing exposure times: {images} image(s) but {times} time(s) (pass one time per image)"
    )]
    TimesPerImage { images: usize, times: usize },
}

/// Two image files of a comparison and the sizes their headers declare.
#[derive(Debug)]
pub struct FileSizes {
    pub a: PathBuf,
    pub a_size: (usize, usize),
    pub b: PathBuf,
    pub b_size: (usize, usize),
}

/// Images that cannot be compared (`metrics`).
#[derive(Debug, thiserror::Error)]
pub enum CompareError {
    /// An image whose size differs from the reference's.
    #[error("{what} is {} x {}, but the images are {} x {}", size.0, size.1, expected.0, expected.1)]
    ImageSize {
        what: String,
        size: (usize, usize),
        expected: (usize, usize),
    },
    /// Two image files whose headers declare different sizes (found before decoding either).
    #[error("{} is {} x {} but {} is {} x {}: compare images of one size", .0.b.display(), .0.b_size.0, .0.b_size.1, .0.a.display(), .0.a_size.0, .0.a_size.1)]
    FileSizes(Box<FileSizes>),
    #[error("no pixel is valid in both images")]
    NoCommonPixels,
    /// A reference that is black wherever both images are valid: no relative difference and
    /// no PSNR can be given against it (they were NaN% and -inf dB).
    #[error("{}: the reference image is zero wherever both images are valid; the relative difference and PSNR against it are undefined (compare against another reference)", path.display())]
    ZeroReference { path: PathBuf },
    /// An image of a comparison that cannot be read.
    #[error("reading {}", path.display())]
    Read {
        path: PathBuf,
        #[source]
        source: Box<ImagingError>,
    },
    /// The `--within` mask of a comparison is not an RGBA EXR.
    #[error("{}: --within needs an RGBA EXR (it has no alpha)", path.display())]
    NoAlpha { path: PathBuf },
    /// The `--within` mask is not the size of the compared image.
    #[error("{}: --within is {within_pixels} pixels but {} is {image_pixels}", within.display(), image.display())]
    WithinSize {
        within: PathBuf,
        within_pixels: usize,
        image: PathBuf,
        image_pixels: usize,
    },
    /// Two image files that cannot be compared (`source`: why).
    #[error("comparing {} with {}", a.display(), b.display())]
    Comparing {
        a: PathBuf,
        b: PathBuf,
        #[source]
        source: Box<ImagingError>,
    },
}

impl CompareError {
    /// [`CompareError::Read`] of `path`.
    pub(crate) fn read(path: &std::path::Path, source: ImagingError) -> Self {
        CompareError::Read {
            path: path.to_path_buf(),
            source: Box::new(source),
        }
    }
}
