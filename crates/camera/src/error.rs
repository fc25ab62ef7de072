//! The errors of the camera crate: camera files, radiometry, rigs, poses and OpenCV.

use std::path::PathBuf;

/// Errors of the camera crate. Every variant that concerns a file names it.
#[derive(Debug, thiserror::Error)]
pub enum CameraError {
    #[error("{}: invalid camera file: {problem}", path.display())]
    Camera {
        path: PathBuf,
        #[source]
        problem: CameraFileError,
    },
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
        source: Box<CameraError>,
    },
    #[error("invalid input: {0}")]
    InvalidInput(String),
    /// A request of a job (`job`) that cannot be run; the message names the option or file.
    #[error("{0}")]
    Arguments(String),
    /// A failure about a file (`source`), the file named.
    #[error("{}", path.display())]
    At {
        path: PathBuf,
        #[source]
        source: Box<CameraError>,
    },
    /// An image of a radiometry calibration whose size is not the first image's.
    #[error("{}: image is {}x{} but the first is {}x{}; all must come from the same camera setting", path.display(), size.0, size.1, first.0, first.1)]
    ImageSize {
        path: PathBuf,
        size: (usize, usize),
        first: (usize, usize),
    },
    /// The colour checker could not be found in its photograph.
    #[error("{}: automatic colour-checker detection (OpenCV mcc) failed; give the patch grid's corners with --corners", path.display())]
    CheckerDetection {
        path: PathBuf,
        #[source]
        source: Box<CameraError>,
    },
    /// Flat fields and a checker that could not be fitted.
    #[error("fitting the camera radiometry")]
    RadiometryFitting {
        #[source]
        source: Box<CameraError>,
    },
    /// A numeric CSV table (e.g. the correspondences of a pose) that cannot be read.
    #[error(transparent)]
    Csv(#[from] igi_imaging::csv::CsvError),
    #[error(transparent)]
    RadiometryFit(#[from] RadiometryError),
    /// An image that could not be read or written (`igi-imaging`).
    #[error(transparent)]
    Imaging(#[from] igi_imaging::ImagingError),
    /// A file igi-formats could not write.
    #[error(transparent)]
    Formats(#[from] igi_formats::FormatsError),
    /// An output file or folder (`igi-files`).
    #[error(transparent)]
    Files(#[from] igi_files::FilesError),
    #[error("built without opencv: rebuild with --features opencv")]
    NoOpenCv,
    /// OpenCV gave a result that cannot be used (`cv`, feature `opencv`).
    #[error("opencv: {0}")]
    OpenCv(String),
    /// An OpenCV call failed (`cv`, feature `opencv`; `opencv::Error` as the source).
    #[error("opencv: {0}")]
    OpenCvCall(#[source] Box<dyn std::error::Error + Send + Sync>),
    /// Correspondences from which no camera pose can be solved (`cv`).
    #[error("invalid input: {0}")]
    Pnp(#[from] PnpError),
    /// Points from which no homography or plane pose can be solved (`planar`, `cv`).
    #[error("invalid input: {0}")]
    Planar(#[from] PlanarError),
}

impl CameraError {
    /// [`CameraError::Camera`] for `path`.
    pub(crate) fn camera(path: &std::path::Path, problem: CameraFileError) -> Self {
        CameraError::Camera {
            path: path.to_path_buf(),
            problem,
        }
    }

    /// [`CameraError::At`]: `source`, about the file `path`.
    pub(crate) fn at(path: &std::path::Path, source: CameraError) -> Self {
        CameraError::At {
            path: path.to_path_buf(),
            source: Box::new(source),
        }
    }

    pub(crate) fn io(path: &std::path::Path, source: std::io::Error) -> Self {
        CameraError::Imaging(igi_imaging::ImagingError::Io {
            path: path.to_path_buf(),
            source,
        })
    }
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

/// Correspondences from which no camera pose can be solved (`cv::solve_pnp*`).
#[derive(Debug, thiserror::Error)]
pub enum PnpError {
    #[error("PnP: {world} world points but {pixels} pixels")]
    Unpaired { world: usize, pixels: usize },
    #[error("PnP needs at least {need} correspondences, got {got}")]
    TooFew { need: usize, got: usize },
    #[error("PnP RANSAC found no consistent pose")]
    RansacFailed,
    #[error("PnP (SQPnP) found no pose")]
    SqpnpFailed,
    #[error("PnP: only {inliers} of {points} points reproject within {threshold_px} px")]
    FewInliers {
        inliers: usize,
        points: usize,
        threshold_px: f64,
    },
}

/// Points from which no homography or plane pose can be solved (`planar`, `cv`).
#[derive(Debug, thiserror::Error)]
pub enum PlanarError {
    #[error("homography: the points coincide or are not finite")]
    Coincident,
    #[error("homography needs at least 4 matching points ({src} and {dst})")]
    HomographyPoints { src: usize, dst: usize },
    #[error("homography: a point is not finite")]
    NonFinitePoint,
    #[error("homography: three of the four points are (nearly) collinear (normalised triangle area {area:.2e})")]
    Collinear { area: f64 },
    #[error("homography: SVD failed")]
    Svd,
    #[error("homography: degenerate point configuration (rank-deficient system)")]
    RankDeficient,
    #[error("homography: non-finite result")]
    NonFiniteHomography,
    #[error(
        "planar pose needs at least 4 matching points ({plane} plane points, {pixels} pixels)"
    )]
    PosePoints { plane: usize, pixels: usize },
    #[error("planar pose: a point lies behind the camera")]
    Behind,
    #[error("planar pose: no finite solution")]
    NonFinitePose,
    #[error("pixel ({x:.2}, {y:.2}) cannot be undistorted (outside the lens model)")]
    Undistort { x: f64, y: f64 },
}

/// Why a camera file (FORMATS.md JSON) cannot be used; the message is the problem alone, the
/// file is named by [`CameraError::Camera`].
#[derive(Debug, thiserror::Error)]
pub enum CameraFileError {
    /// The text is not the JSON of a camera file.
    #[error("{0}")]
    Json(#[source] serde_json::Error),
    #[error("{what} must be a positive integer, found {found}")]
    Dimension {
        what: &'static str,
        found: serde_json::Value,
    },
    #[error("{width}x{height} is {} Mpixel, beyond the limit of {} Mpixel (an image that size needs more than {} GiB)", *width as u64 * *height as u64 / 1_000_000, limit / 1_000_000, (limit * 13) >> 30)]
    TooLarge { width: u32, height: u32, limit: u64 },
    #[error("{what} must be an array of numbers")]
    NotNumbers { what: &'static str },
    #[error("{what} contains a non-number: {value}")]
    NonNumber {
        what: &'static str,
        value: serde_json::Value,
    },
    #[error("{what} must be a 3x3 array of rows")]
    NotMatrix { what: &'static str },
    #[error("{what} must have 3 rows, found {rows}")]
    Rows { what: &'static str, rows: usize },
    #[error("{what} row {row} must have 3 entries, found {entries}")]
    RowLength {
        what: &'static str,
        row: usize,
        entries: usize,
    },
    #[error("{what} has a non-finite entry")]
    NonFinite { what: &'static str },
    #[error("K must be [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] (no skew), found {0:?}")]
    Skew([[f64; 3]; 3]),
    #[error("focal lengths must be positive, found fx={fx}, fy={fy}")]
    Focal { fx: f64, fy: f64 },
    #[error("dist must have 5 entries [k1, k2, p1, p2, k3] (or 4), found {0}")]
    DistLength(usize),
    #[error("dist {dist:?} cannot be a lens: pixel ({:.1}, {:.1}) {why}", pixel[0], pixel[1])]
    Lens {
        dist: [f64; 5],
        pixel: [f64; 2],
        why: String,
    },
    #[error("t must have 3 entries, found {0}")]
    TranslationLength(usize),
    #[error(transparent)]
    Rotation(#[from] RotationError),
}

/// Why a matrix is not a rotation ([`crate::camera::check_rotation`]).
#[derive(Debug, thiserror::Error)]
pub enum RotationError {
    #[error("R has a NaN or infinite entry")]
    NonFinite,
    #[error("R is not orthonormal: max |R^T R - I| = {max:.3e} > 1e-6")]
    NotOrthonormal { max: f64 },
    #[error("R is not a rotation: det(R) = {det:.6} (must be +1)")]
    NotRotation { det: f64 },
}
