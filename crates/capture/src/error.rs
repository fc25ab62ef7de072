//! Errors of the capture crate.

use igi_imaging::ImagingError;
use std::path::PathBuf;

/// A sphere that cannot be used in a photograph (it is not fully seen by the camera).
#[derive(Debug, thiserror::Error)]
pub enum SphereError {
    #[error(
        "{kind} sphere is partly outside the {width}x{height} image: its outline reaches pixel ({x:.1}, {y:.1}); \
         move the board or fix its centre/radius"
    )]
    OutsideImage {
        kind: String,
        width: u32,
        height: u32,
        x: f64,
        y: f64,
    },
    #[error(
        "{kind} sphere is behind the camera or contains it (centre {center:?}, radius {radius})"
    )]
    BadSphere {
        kind: String,
        center: [f64; 3],
        radius: f64,
    },
}

/// Errors of a capture recipe. Variants about a file name it.
#[derive(Debug, thiserror::Error)]
pub enum CaptureError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    /// A folder that cannot be created.
    #[error("creating {}", path.display())]
    CreateDir {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A request of a job (`job`) that cannot be run; the message names the option or file.
    #[error("{0}")]
    Arguments(String),
    /// A photograph whose size is not the one its camera file gives.
    #[error("{}: image is {}x{} but its camera {} says {}x{}", photo.display(), size.0, size.1, camera.display(), camera_size.0, camera_size.1)]
    PhotoCameraSize {
        photo: PathBuf,
        size: (usize, usize),
        camera: PathBuf,
        camera_size: (u32, u32),
    },
    /// A pose that could not be refined against a photograph (`source`: why).
    #[error("refining the pose of {}", photo.display())]
    Refining {
        photo: PathBuf,
        #[source]
        source: Box<CaptureError>,
    },
    /// A model mesh that cannot be read (`igi-geometry`).
    #[error(transparent)]
    Geometry(#[from] igi_geometry::GeometryError),
    /// A file igi-formats could not write (the samples CSV).
    #[error(transparent)]
    Formats(#[from] igi_formats::FormatsError),
    /// An output file's name or folder (`igi-files`).
    #[error(transparent)]
    Files(#[from] igi_files::FilesError),
    /// A description file or a photograph that cannot be used, and why.
    #[error("{path}: {msg}")]
    File { path: PathBuf, msg: String },
    #[error(transparent)]
    Imaging(#[from] ImagingError),
    /// A camera, its file, radiometry or rig, or an OpenCV call (`igi-camera`).
    #[error(transparent)]
    Camera(#[from] igi_camera::CameraError),
    #[error(transparent)]
    Sphere(#[from] SphereError),
    /// The model's ray queries could not be built (pose refinement).
    #[error(transparent)]
    Raycast(#[from] igi_raycast::RaycastError),
    /// A photograph whose size is not its camera's (pose refinement).
    #[error("photo is {}x{} but its camera is {}x{}", photo.0, photo.1, camera.0, camera.1)]
    PhotoSize {
        photo: (usize, usize),
        camera: (u32, u32),
    },
    /// Too few of the model's edge points found an edge in the photograph.
    #[error("pose refinement: only {matched} model edge points match an edge of the photo ({found} found); is the model in view and the pose within {search_px} px?")]
    TooFewEdgeMatches {
        matched: usize,
        found: usize,
        search_px: f64,
    },
}
