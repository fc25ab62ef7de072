//! `igi-brdf`: isotropic Lafortune BRDFs for the igi toolkit.
//!
//! - [`Lafortune`] / [`LafortuneRef`]: the model `rho_d/pi + sum rho_l max(0, Cxy(ux vx + uy vy) + Cz uz vz)^N`
//!   in the local shading frame ([`Frame`], z = normal), with evaluation, importance sampling
//!   (cosine + cosine-power lobes, mixture pdf for MIS) and directional albedo.
//! - [`fit_material`]: the staged Lafortune fit; by default each sample weighted by its
//!   [`coverage`] of the direction pairs and each lobe's growth toward grazing bounded, so fits
//!   from sparse hand-held samples generalise.
//! - The samples come from photographs of the hand-held sample frame, measured by
//!   `igi_capture::sample_frame` (photogrammetry lives there, not here).
//! - [`job`]: `igi brdf fit`, `eval`, `infer` and `cluster` as one call each, from a request
//!   of paths and options.
//! - Directions are unit vectors pointing away from the surface; values are linear RGB, f32.

pub mod basis;
pub mod cluster;
pub mod coverage;
pub mod error;
pub mod fit;
pub mod frame;
pub mod job;
pub mod lafortune;
pub mod materials;
pub mod plot;
pub mod samples;

pub use basis::Basis;
pub use cluster::{
    basis_weights, cluster, read_lumitexels, ClusterOptions, ClusterResult, Lumitexel,
};
pub use error::BrdfError;
pub use fit::{fit_material, fit_materials, FitOptions, FitReport, LobeStderr, Stderr};
pub use frame::Frame;
pub use lafortune::{luminance, BsdfSample, Lafortune, LafortuneRef, Lobe};
pub use materials::{MaterialEntry, MaterialsFile};
pub use samples::{read_pairs, read_samples, BrdfSample, PairRow, PairTable};

#[cfg(test)]
mod lafortune_tests;
