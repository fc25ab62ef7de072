//! `igi-render`: the Monte-Carlo path tracer behind `igi render` and the inverse solver.
//!
//! - [`embree`]: every Embree call (triangle scene, closest hit, occlusion, ray streams).
//! - [`sampling`]: per-pixel PCG streams, piecewise-constant 1D/2D distributions, cone sampling, MIS.
//!
//! Conventions: world Z up, metres; linear f32 RGB radiance; directions are unit vectors.
//! See `docs/RENDER.md` for the lighting model, MIS and lookup rules.

pub mod embree;
pub mod sampling;

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
