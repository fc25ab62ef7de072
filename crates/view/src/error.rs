use std::path::PathBuf;

/// Why a viewer could not start.
#[derive(Debug, thiserror::Error)]
pub enum ViewError {
    /// The folder is not one igi view shows.
    #[error("{}: not a result folder of `igi solve` (report.json and parts/), an opacity-hull folder of `igi hull build` (hull.json and surfels.ply), a surface-light-field folder of `igi slf build` (header.json and mesh.ply) nor a 3D Tiles export of `igi export --format gltf` (tileset.json); igi view shows these", dir.display())]
    NotViewable { dir: PathBuf },
    /// The folder cannot be read.
    #[error("{}: {source}", dir.display())]
    Folder {
        dir: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The result could not be made into a scene.
    #[error(transparent)]
    Export(#[from] igi_export::ExportError),
    /// A lighting file given with `--lighting` cannot light the page.
    #[error(transparent)]
    Lighting(#[from] igi_formats::lighting::LightingLoadError),
    /// The survey given with `--survey` (its photographs, their cameras) cannot be read.
    #[error(transparent)]
    Survey(Box<igi_workflow::WorkflowError>),
    /// A camera file given with `--camera` cannot be read (the error names the file).
    #[error(transparent)]
    Camera(#[from] igi_camera::CameraError),
    /// The port could not be bound (in use, or not permitted).
    #[error("cannot listen on 127.0.0.1:{port}: {reason}")]
    Bind { port: u16, reason: String },
}
