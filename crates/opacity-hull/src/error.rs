//! The one error type of `igi-opacity-hull`.

use std::path::PathBuf;

/// Everything that can go wrong importing, matting, carving, building or rendering a hull.
#[derive(Debug, thiserror::Error)]
pub enum HullError {
    /// Camera, image, rig or mask trouble (these name their file, and the view where known).
    #[error(transparent)]
    Imaging(#[from] igi_imaging::ImagingError),
    /// A camera, its file, radiometry or rig, or an OpenCV call (`igi-camera`).
    #[error(transparent)]
    Camera(#[from] igi_camera::CameraError),
    /// A plot that could not be drawn or written.
    #[error(transparent)]
    Plot(#[from] igi_plot::PlotError),
    /// An output file or folder, a run manifest or the folder lock.
    #[error(transparent)]
    Files(#[from] igi_files::FilesError),
    /// Mesh or point-cloud trouble.
    #[error(transparent)]
    Geometry(#[from] igi_geometry::GeometryError),
    /// An operating-system error on a named file.
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A line of a Middlebury `_par.txt` file that does not parse.
    #[error("{}: line {line}: {msg}", path.display())]
    ParLine {
        path: PathBuf,
        line: usize,
        msg: String,
    },
    /// A Middlebury rotation too far from a rotation to be a measurement error.
    #[error("{}: line {line} ({image}): R is {distance:.3e} from the nearest rotation (more than {limit:.0e})", path.display())]
    NotRotation {
        path: PathBuf,
        line: usize,
        image: String,
        distance: f64,
        limit: f64,
    },
    /// A silhouette with nothing (or everything) in it.
    #[error("{}: view {view:?}: the silhouette is {what}", rig.display())]
    Silhouette {
        rig: PathBuf,
        view: String,
        what: &'static str,
    },
    /// Carving left nothing: `view` removed the last cells.
    #[error("{}: the hull is empty after carving with view {view:?} (its silhouette disagrees with the views before it, or with the bounding box)", rig.display())]
    CarvedEmpty { rig: PathBuf, view: String },
    /// A hull folder that is missing a file or has a bad manifest.
    #[error("{}: {msg}", path.display())]
    HullFolder { path: PathBuf, msg: String },
    /// A lighting file that cannot be read or used (names the file, and the map).
    #[error(transparent)]
    Lighting(#[from] igi_formats::lighting::LightingLoadError),
    /// `--lighting` on a hull folder built without light images.
    #[error("{}: this hull has no surface reflectance field (its rig's views list no `lights` images), so it cannot be relit; rebuild it from a rig with one-light-at-a-time images", dir.display())]
    NoReflectance { dir: PathBuf },
    /// The SVD of a block of light images did not converge.
    #[error("view {view:?}: the SVD of the light images' block ({bx}, {by}) did not converge")]
    Svd { view: String, bx: u32, by: u32 },
    /// A carving resolution outside 2..=2048 cells per axis.
    #[error("invalid argument: carving resolution {0} must be 2..=2048 cells per axis")]
    CarvingResolution(usize),
    /// Relighting with no light direction.
    #[error("invalid argument: relighting needs at least one light direction")]
    NoLights,
    /// A build resolution coarser than the bounding box over 256.
    #[error("invalid argument: resolution {0}: a hull is carved from at least 256 cells per axis of the bounding box")]
    CoarseResolution(usize),
    /// A rig with more views than a hull is carved from.
    #[error("{}: {views} views; a hull is carved from at most {max} (Matusik et al.'s rig had 216)", rig.display())]
    TooManyViews {
        rig: PathBuf,
        views: usize,
        max: usize,
    },
    /// A backdrop pattern size outside 1..32768 on a side.
    #[error("invalid argument: backdrop size {width}x{height} must be 1..32768 on each side")]
    BackdropSize { width: usize, height: usize },
}

impl HullError {
    pub(crate) fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        HullError::Io {
            path: path.into(),
            source,
        }
    }
}
