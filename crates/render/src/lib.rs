//! `igi-render`: the Monte-Carlo path tracer behind `igi render` and the inverse solver.
//!
//! - [`embree`]: every Embree call (triangle scene, closest hit, occlusion, ray streams).
//! - [`lighting`]: lat-long environment (importance-sampled) and the sun disk; lighting TOML loader.
//! - [`scene`]: meshes + Lafortune materials + Embree; scene TOML loader; surface points.
//! - [`integrator`]: the path tracer (NEE + MIS), image rendering and the batched solver queries.
//! - [`refine`]: camera pose refinement by matching the model's edges and silhouette to a photograph's.
//! - [`compare`]: RMSE / relative mean / PSNR / noise-explained RMSE between two images.
//! - [`sampling`]: per-pixel PCG streams, piecewise-constant 1D/2D distributions, cone sampling, MIS.
//!
//! Conventions: world Z up, metres; linear f32 RGB radiance; directions are unit vectors.
//! See `docs/RENDER.md` for the lighting model, MIS and lookup rules.

// `!(x > 0.0)` is deliberate throughout: it is true for NaN, which must take the safe branch.
#![allow(
    clippy::neg_cmp_op_on_partial_ord,
    clippy::nonminimal_bool,
    clippy::type_complexity
)]

pub mod compare;
pub mod embree;
pub mod integrator;
pub mod lighting;
pub mod refine;
pub mod sampling;
pub mod scene;
pub mod sky;

pub use compare::{compare_images, difference_image, Comparison};
pub use integrator::{
    irradiance, radiance_toward, render_image, Estimate, PathTracer, RenderOptions, RenderOutput,
};
pub use lighting::{Environment, Lighting, Sun};
pub use scene::{Albedo, LobeMap, Material, Object, Scene, SurfacePoint, Texture};

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
    #[error("photo is {}x{} but its camera is {}x{}", photo.0, photo.1, camera.0, camera.1)]
    PhotoSize {
        photo: (usize, usize),
        camera: (u32, u32),
    },
    #[error("pose refinement: only {matched} model edge points match an edge of the photo ({found} found); is the model in view and the pose within {search_px} px?")]
    TooFewEdgeMatches {
        matched: usize,
        found: usize,
        search_px: f64,
    },
}

#[cfg(test)]
mod integrator_tests;
