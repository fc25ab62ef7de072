//! The errors of a job: the file and the problem, or the layer below's own error.

use std::path::PathBuf;

/// Errors of a job: its inputs, its folder, or the libraries it runs.
#[derive(Debug, thiserror::Error)]
pub enum WorkflowError {
    /// A file or folder that is missing, unreadable or cannot mean what it is used for.
    #[error("{}: {msg}", path.display())]
    File { path: PathBuf, msg: String },
    /// A BRDF file (samples) that reads but cannot be fitted.
    #[error("{}: {source}", path.display())]
    BrdfFile {
        path: PathBuf,
        #[source]
        source: igi_brdf::BrdfError,
    },
    /// A probe capture of a photograph that the probe pipeline could not process.
    #[error("{}: processing the probe capture of photo `{photo}`: {source}", path.display())]
    ProbeCapture {
        path: PathBuf,
        photo: String,
        #[source]
        source: Box<igi_probe::ProbeError>,
    },
    /// A request of a job that cannot be run (the message names the option).
    #[error("{0}")]
    Arguments(String),
    /// A scene that could not be rendered (`source`: why; `path`: the scene as given).
    #[error("rendering {}", path.display())]
    Rendering {
        path: PathBuf,
        #[source]
        source: Box<igi_render::RenderError>,
    },
    /// Demo options that cannot make a demo (the message names the option).
    #[error("invalid input: {0}")]
    Options(String),
    #[error(transparent)]
    Reflect(#[from] igi_reflect::ReflectError),
    #[error(transparent)]
    Format(#[from] igi_formats::FormatsError),
    #[error(transparent)]
    Imaging(#[from] igi_imaging::ImagingError),
    /// A camera, its file, radiometry or rig, or an OpenCV call (`igi-camera`).
    #[error(transparent)]
    Camera(#[from] igi_camera::CameraError),
    /// An output file or folder, a run manifest or the folder lock.
    #[error(transparent)]
    Files(#[from] igi_files::FilesError),
    #[error(transparent)]
    Geometry(#[from] igi_geometry::GeometryError),
    #[error(transparent)]
    Render(#[from] igi_render::RenderError),
    #[error(transparent)]
    Brdf(#[from] igi_brdf::BrdfError),
    /// The sun or sky model of a photo whose light is estimated.
    #[error(transparent)]
    Sky(#[from] igi_sky::SkyError),
    #[error(transparent)]
    Probe(Box<igi_probe::ProbeError>),
    /// The demo's synthetic survey could not be made.
    #[error(transparent)]
    Synth(#[from] igi_synth::SynthError),
}

impl WorkflowError {
    pub(crate) fn file(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        WorkflowError::File {
            path: path.into(),
            msg: msg.into(),
        }
    }
}

impl From<igi_probe::ProbeError> for WorkflowError {
    fn from(e: igi_probe::ProbeError) -> Self {
        WorkflowError::Probe(Box::new(e))
    }
}
