//! `igi-render`: the Monte-Carlo path tracer behind `igi render` and the inverse solver.
//!
//! - Ray queries (the Embree scene, closest hit, occlusion, ray streams) are `igi-raycast`'s.
//! - [`lighting`]: lat-long environment (importance-sampled) and the sun disk, built from a
//!   parsed lighting file (`igi_formats::lighting`).
//! - [`scene`]: meshes + Lafortune materials + Embree, built from a parsed scene file
//!   (`igi_formats::scene`); surface points.
//! - [`integrator`]: the path tracer (NEE + MIS), image rendering and the batched solver queries.
//! - [`adaptive`]: adaptive sampling, the per-pixel sample counts of a render from a pilot.
//! - [`compare_images`], [`difference_image`]: re-exported from `igi_imaging::metrics`.
//! - [`fastmath`]: inlined sine/cosine, arctangent and lat-long mapping for the hot loop.
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

pub mod adaptive;
pub mod fastmath;
pub mod integrator;
pub mod lighting;
pub mod sampling;
pub mod scene;
pub mod sky;

/// Image comparison lives in `igi_imaging::metrics`; re-exported for the renderer's users.
pub use igi_imaging::metrics::{compare_images, difference_image, Comparison};
pub use integrator::{
    irradiance, radiance_toward, render_image, render_images, Estimate, PathTracer, RenderJob,
    RenderOptions, RenderOutput,
};
pub use lighting::{Environment, Lighting, Sun};
pub use scene::{Albedo, LobeMap, LobeMapError, Material, Object, Scene, SurfacePoint, Texture};

use std::path::PathBuf;

/// Errors of the renderer. Every file error names the file.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// The scene's ray queries could not be built.
    #[error(transparent)]
    Raycast(#[from] igi_raycast::RaycastError),
    /// A scene or lighting file that parses but describes nothing usable.
    #[error("{path}: {msg}")]
    File { path: PathBuf, msg: String },
    /// A scene or lighting file could not be read or parsed (`igi-formats`).
    #[error(transparent)]
    Format(#[from] igi_formats::FormatsError),
    /// A lighting file's light that cannot be read or used (`igi_formats::lighting`).
    #[error(transparent)]
    Lighting(#[from] igi_formats::lighting::LightingLoadError),
    /// A lighting value that cannot light anything (a map pixel, the sun's values).
    #[error(transparent)]
    LightingValue(#[from] igi_formats::lighting::LightingValueError),
    /// Something a scene or lighting file names or holds cannot be used: `context` says which
    /// part (`environment map sky.exr`, `object 2: mesh wall.ply`, `[sun]`), `source` why.
    #[error("{path}: {context}: {source}")]
    InFile {
        path: PathBuf,
        context: String,
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// The objects a scene file lists do not make a scene.
    #[error("{path}: {source}")]
    Scene {
        path: PathBuf,
        #[source]
        source: Box<RenderError>,
    },
    /// Lighting that can only render black.
    #[error("no lighting: the scene names no lighting file and none was given (--lighting)")]
    NoLighting,
    /// A render or query asked for no samples.
    #[error("spp must be at least 1")]
    ZeroSpp,
    /// An adaptive render with too few samples per pixel for its pilot (`spp`, the least).
    #[error("adaptive sampling needs at least {1} samples per pixel, got {0}")]
    AdaptiveSpp(u32, u32),
    /// A camera without pixels.
    #[error("camera image size {0} x {1} is empty")]
    EmptyImage(usize, usize),
    /// Two lists that must pair up do not (`what`: e.g. "points" and "targets").
    #[error("{len} {what} but {other_len} {other}")]
    Unpaired {
        what: &'static str,
        len: usize,
        other: &'static str,
        other_len: usize,
    },
    /// An object whose mesh cannot be rendered (`object`: its name).
    #[error("{object}: {problem}")]
    Mesh {
        object: String,
        problem: MeshProblem,
    },
}

impl RenderError {
    /// [`RenderError::InFile`] for `path`.
    pub(crate) fn in_file(
        path: &std::path::Path,
        context: impl Into<String>,
        source: Box<dyn std::error::Error + Send + Sync>,
    ) -> Self {
        RenderError::InFile {
            path: path.to_path_buf(),
            context: context.into(),
            source,
        }
    }
}

#[cfg(test)]
mod integrator_tests;

/// Why an object's mesh cannot be rendered.
#[derive(Debug, thiserror::Error)]
pub enum MeshProblem {
    #[error("{normals} normals for {vertices} vertices")]
    Normals { normals: usize, vertices: usize },
    #[error("{uvs} UVs for {vertices} vertices")]
    Uvs { uvs: usize, vertices: usize },
    #[error("an albedo texture needs UVs, and the mesh has none")]
    TextureWithoutUvs,
    #[error("triangle {triangle} has vertex index {indices:?} out of range ({vertices} vertices)")]
    IndexOutOfRange {
        triangle: usize,
        indices: [u32; 3],
        vertices: usize,
    },
}
