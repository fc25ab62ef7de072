use igi_capture::SphereError;
use igi_imaging::ImagingError;
use std::path::PathBuf;

/// Errors of the probe crate. Variants about a file name it.
#[derive(Debug, thiserror::Error)]
pub enum ProbeError {
    #[error(transparent)]
    Imaging(#[from] ImagingError),
    /// A camera, its file, radiometry or rig, or an OpenCV call (`igi-camera`).
    #[error(transparent)]
    Camera(#[from] igi_camera::CameraError),
    /// An output file or folder, a run manifest or the folder lock.
    #[error(transparent)]
    Files(#[from] igi_files::FilesError),
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    /// A request of a job (`job`) that cannot be run; the message names the option.
    #[error("{0}")]
    Arguments(String),
    /// A lighting file to write whose name does not end in `.toml`.
    #[error("{}: -o names the lighting file written (.toml); its maps are written beside it", path.display())]
    LightingName { path: PathBuf },
    /// A board that could not be placed in the camera frame (`source`: why).
    #[error("placing the board {} in the camera frame", board.display())]
    Placing {
        board: PathBuf,
        #[source]
        source: Box<ProbeError>,
    },
    /// A board photograph that could not be processed (`source`: why).
    #[error("processing the board photograph {photo}")]
    Processing {
        photo: String,
        #[source]
        source: Box<ProbeError>,
    },
    /// Reflectance samples the complex index could not be fitted to (`source`: why).
    #[error("fitting the complex index to {}", path.display())]
    FittingIor {
        path: PathBuf,
        #[source]
        source: Box<ProbeError>,
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
        problem: ReflectanceProblem,
    },
    /// A CSV table's structure (`igi_imaging::csv`): the file, the line and the problem.
    #[error(transparent)]
    Csv(#[from] igi_imaging::csv::CsvError),
    /// Too few of the board's fiducials found for a pose.
    #[error("invalid input: found {found} of the board's {markers} fiducials ({dictionary} dictionary; {seen} markers of that dictionary in the image): the pose needs at least 2")]
    TooFewFiducials {
        found: usize,
        markers: usize,
        dictionary: String,
        seen: usize,
    },
    /// A photograph whose size is not its camera's.
    #[error(
        "invalid input: the image is {image_w}x{image_h} but the camera is {camera_w}x{camera_h}"
    )]
    ImageSize {
        image_w: usize,
        image_h: usize,
        camera_w: u32,
        camera_h: u32,
    },
    /// Map and convolution widths that do not fit together.
    #[error("invalid input: map width {map} must be even and a multiple of the convolution width {conv}")]
    MapWidth { map: usize, conv: usize },
    /// The sun sphere (black, else mirror) has no pixel to look for the sun in.
    #[error("invalid input: the sun sphere has no usable pixels")]
    NoSunPixels,
    /// A non-finite value in an unwarped map.
    #[error("invalid input: non-finite value in the unwarped map")]
    NonFiniteMap,
    /// Too few usable diffuse sphere pixels for its solve.
    #[error(
        "invalid input: only {used} usable diffuse sphere pixels ({masked} saturated or invalid)"
    )]
    TooFewDiffusePixels { used: usize, masked: usize },
    /// The complex index of refraction could not be fitted (the reason says why).
    #[error("fit failed: {0}")]
    Fit(IorFitProblem),
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
        source: Box<ImagingError>,
    },
}

/// Why a complex index of refraction could not be fitted.
#[derive(Debug, thiserror::Error)]
pub enum IorFitProblem {
    #[error("need at least 3 reflectance samples, got {0}")]
    TooFewSamples(usize),
    #[error("bad sample (angle {angle} rad, reflectance {reflectance}): want angle in [0, pi/2) and reflectance in [0, 1]")]
    BadSample { angle: f64, reflectance: f64 },
    #[error("Levenberg-Marquardt stopped: {0}")]
    Stopped(String),
}

/// What a reflectance-sample row or file means that the fit cannot use.
#[derive(Clone, Debug, PartialEq)]
pub enum ReflectanceProblem {
    /// An incidence angle outside [0, 90) degrees.
    Angle(f64),
    /// A reflectance outside [0, 1].
    Reflectance([f64; 3]),
    /// Fewer than the 3 samples the fit needs.
    TooFew(usize),
}

impl std::fmt::Display for ReflectanceProblem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ReflectanceProblem::Angle(a) => write!(f, "angle {a} degrees is not in [0, 90)"),
            ReflectanceProblem::Reflectance([r, g, b]) => {
                write!(f, "reflectance ({r}, {g}, {b}) is not in [0, 1]")
            }
            ReflectanceProblem::TooFew(n) => write!(f, "{n} samples; the fit needs at least 3"),
        }
    }
}
