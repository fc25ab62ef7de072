//! igi's jobs: what turns a survey into a checked solve and runs it, the same way for the
//! binary (`igi solve`, `igi demo`) and the cluster tasks (`igi-cluster`).
//!
//! A job is checked before the first byte of work or output (the survey and every file it
//! names, the options, the output folder and its run manifest), then run: photographs loaded
//! once, the checkpoint resumed or a fresh result started under the folder lock, the solver's
//! iterations with a checkpoint after each, progress reported through
//! [`igi_reflect::Progress`].
//!
//! Modules:
//! - [`survey`]: the survey folder of FORMATS.md resolved and checked, and where each photo's
//!   light comes from ([`LightingSource`]: a lighting file, or a probe capture processed as
//!   `igi probe` does), decided once, here; photographs loaded into the solver's
//!   [`igi_reflect::Photo`]; the BRDF basis fitted from the survey's samples.
//! - [`lightfit`]: lighting without probes (issue 34): a photo with a time and no lighting
//!   lit by the SPA sun and a Hosek-Wilkie / CIE overcast sky whose scales and turbidity are
//!   fitted to the photographs, alternating with the albedo solve; the global scale from
//!   `[[reference]]` targets.
//! - [`lightbasis`]: the fit's light transport, traced once per solve: each texel's
//!   hemisphere rays (the sky bin each leaves through, or the texel it lands on), each
//!   photo's sun visibility and what its pixels see, so that a round of the fit traces no ray.
//! - [`lightfit_picture`]: the picture of a photo whose light was estimated (photograph,
//!   re-rendering, fitted sky).
//! - [`session`]: the resume rule of a result folder: the run manifest (`run.json`), the
//!   folder lock, `--restart`.
//! - [`mod@solve`]: `igi solve` as one job ([`SolveRequest`] -> [`SolveJob`] -> result), and the
//!   inputs a cluster task reloads ([`reopen`]).
//! - [`mod@render`]: `igi render` as one job: a scene file, or a solve result re-lit, rendered
//!   through a camera and written ([`render::render`]).
//! - [`demo`]: the embedded default (`igi demo`): a synthetic survey made (by `igi-synth`,
//!   the one crate of synthetic worlds), then solved by the same job, then re-lit from a
//!   held-out view.

pub mod demo;
mod error;
pub mod lightbasis;
pub mod lightfit;
pub mod lightfit_picture;
pub mod render;
pub mod session;
pub mod solve;
pub mod survey;

pub use error::WorkflowError;
pub use session::SolveSession;
pub use solve::{reopen, solve, AtlasRequest, SolveJob, SolveRequest, StartedSolve};
pub use survey::{lighting_from_probe, LightingSource, PhotoSpec, Survey};
