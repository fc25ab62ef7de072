//! Iterative inverse global illumination (Debevec et al. 2004, sections 4.1-4.2).
//!
//! Given a site (meshes), photographs with their cameras, and the lighting captured with each
//! photograph, recover the diffuse albedo `rho_d` of every texel of the site's texture atlases,
//! then infer the specular lobes from `rho_d` with a BRDF basis (when hand-held samples are
//! given). The loop, per iteration:
//!
//! 1. render, for each texel `p` and photo `I`, the radiance leaving `p` toward `I`'s camera
//!    under `I`'s lighting with the current reflectance everywhere (path tracing with
//!    `igi-render`, two indirect bounces by default);
//! 2. form the ratio proposal `rho_d(p) * I(p) / L_render(p)` per channel;
//! 3. average the proposals over photos with weights (cosine of the view angle, lowered near
//!    occlusion boundaries and near shadow edges, see [`weights`]);
//! 4. repeat with more samples per estimate until the change in `rho_d` is below a tolerance,
//!    or, once the samples stop growing, below the photographs' own noise in `rho_d`.
//!
//! Texels seen by no photo are filled from their seen neighbours (see [`fill`]). Results are
//! written per part (an input mesh, or a voxel of a prepared site) atomically, with a report of
//! every iteration, and a killed run resumes after its last finished iteration.
//!
//! Modules: [`parts`] (atlases and texel caches of the site), [`atlas_size`] (`--atlas auto`:
//! atlas sizes, and cutting meshes into parts), [`coarse`] (the first iterations on coarser
//! atlases, then one on the fine ones), [`solver`] (the iteration, over photographs
//! already loaded: [`Photo`]), [`weights`] and [`fill`] (the documented rules),
//! [`result`] (the result folder: atlases, `scene.toml`, `report.json`, export, sampling),
//! [`truth`] (ground truth: the true atlases and scene, and the albedo error per texel and over
//! the surface), and the errors ([`ReflectError`], in `error.rs`).
//!
//! The survey folder, where each photo's light comes from, the run manifest, the folder lock
//! and the demo are `igi-workflow`'s: this crate solves what it is given. The synthetic surveys
//! the tests and the demo solve are made by `igi-synth`.

pub mod atlas_size;
pub mod coarse;
mod deblur;
pub mod distributed;
mod error;
pub mod fill;
mod lattice;
pub mod parts;
pub mod photo;
pub mod plot;
pub mod record;
pub mod result;
mod smooth;
pub mod solver;
pub mod truth;
pub mod weights;

pub use error::ReflectError;
pub use parts::{Part, TexelCache};
pub use photo::Photo;
pub use result::{load_result_scene, PartResult, SolveResult, UNKNOWN_STDERR};
pub use solver::{
    solve, solve_in_memory, IterationRecord, Progress, Schedule, SolveOptions, SolveReport,
};
