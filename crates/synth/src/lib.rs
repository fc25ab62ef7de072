//! Synthetic worlds with a known truth for igi's tests, benches and the embedded default (`igi
//! demo`): what is photographed is made here, so the production crates keep none of it.
//!
//! * [`survey`]: synthetic surveys with known albedo: a site's parts given a per-texel albedo
//!   (a function of world position), photographs path-traced under given lightings, and a
//!   FORMATS.md survey folder written with `truth/scene.toml` (the embedded default `igi demo`
//!   and the solver's tests).
//! * [`board`]: a forward renderer of lighting-board photographs from a known sky and sun, with a
//!   lens-and-pixel sensor model (round trips of `igi-probe`, the demo's probe captures).
//! * [`sample_frame`]: synthetic photographs of the hand-held BRDF sample frame with known pose,
//!   light and BRDFs (the ground truth of `igi_capture::sample_frame` and `igi brdf measure`).
//!
//! The true atlases and the scene they are rendered from are `igi_reflect::truth`'s
//! ([`igi_reflect::truth::truth_atlas`], [`igi_reflect::truth::scene_with_albedo`]), and the
//! cameras `igi_camera`'s ([`igi_camera::Camera::look_at`]): the solver reads its truth with
//! them.

pub mod board;
pub mod sample_frame;
pub mod survey;

use std::path::PathBuf;

/// Errors of making a synthetic world.
#[derive(Debug, thiserror::Error)]
pub enum SynthError {
    /// A file or folder that cannot be written.
    #[error("{path}: {msg}")]
    File { path: PathBuf, msg: String },
    /// A synthetic survey whose true and recorded lightings differ in number.
    #[error("invalid input: {lightings} lightings but {recorded} recorded lightings")]
    LightingCount { lightings: usize, recorded: usize },
    /// A synthetic shot naming a lighting that does not exist.
    #[error("invalid input: shot {shot}: no lighting {lighting}")]
    NoLighting { shot: String, lighting: usize },
    #[error(transparent)]
    Reflect(#[from] igi_reflect::ReflectError),
    #[error(transparent)]
    Format(#[from] igi_formats::FormatsError),
    #[error(transparent)]
    Imaging(#[from] igi_imaging::ImagingError),
    #[error(transparent)]
    Camera(#[from] igi_camera::CameraError),
    #[error(transparent)]
    Files(#[from] igi_files::FilesError),
    #[error(transparent)]
    Geometry(#[from] igi_geometry::GeometryError),
    #[error(transparent)]
    Render(#[from] igi_render::RenderError),
}
