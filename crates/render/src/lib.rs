//! `igi-render`: the Monte-Carlo path tracer behind `igi render` and the inverse solver.
//!
//! - [`embree`]: every Embree call (triangle scene, closest hit, occlusion, ray streams).
//! - [`lighting`]: lat-long environment (importance-sampled) and the sun disk; lighting TOML loader.
//! - [`scene`]: meshes + Lafortune materials + Embree; scene TOML loader; surface points.
//! - [`sampling`]: per-pixel PCG streams, piecewise-constant 1D/2D distributions, cone sampling, MIS.
//!
//! Conventions: world Z up, metres; linear f32 RGB radiance; directions are unit vectors.
//! See `docs/RENDER.md` for the lighting model, MIS and lookup rules.

pub mod embree;
pub mod lighting;
pub mod sampling;
pub mod scene;

pub use lighting::{Environment, Lighting, Sun};
pub use scene::{Albedo, Material, Object, Scene, SurfacePoint, Texture};

use std::path::PathBuf;

/// Errors of the renderer. Every file error names the file.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error("Embree: {0}")]
    Embree(String),
    #[error("{path}: {msg}")]
    File { path: PathBuf, msg: String },
    #[error("{0}")]
    Invalid(String),
}
