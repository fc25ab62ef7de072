//! # igi-probe
//!
//! Natural illumination from one photograph of the lighting-capture board (Debevec et al.
//! 2004, section 3.3): a mirrored steel sphere (the sky), a shiny black sphere (a sharp,
//! unsaturated image of the sun) and a diffuse grey sphere (the sun's intensity, indirectly).
//!
//! The board is a recipe on `igi-capture`, which owns the photogrammetry it shares with the
//! hand-held BRDF sample frame: sphere views ([`igi_capture::sphere`]), the sun's spot
//! ([`igi_capture::highlight::locate_spot`], [`igi_capture::spot`]) and the fiducial matching
//! ([`igi_capture::fiducial`]).
//!
//! * [`board`]: the FORMATS.md board file and the spheres' calibration (diffuse paint
//!   reflectance, the mirror's complex index, the black coat's index).
//! * [`fiducial`]: the board's pose from its ArUco fiducials (OpenCV, feature `opencv`), which
//!   places spheres given in the board frame into the camera frame.
//! * [`fresnel`]: conductor and dielectric Fresnel reflectance; a Levenberg-Marquardt fit of a
//!   complex index from reflectance-versus-angle samples.
//! * [`envmap`]: lat-long lookups, the 512x512 upper-hemisphere layout, hole filling, and the
//!   diffuse convolution of a map by direct integration (no spherical-harmonic truncation).
//! * [`input`]: the board photograph: one HDR or 8-bit image, or merged exposure brackets.
//! * [`job`]: `igi probe` and `igi probe calibrate-mirror` as one call each, from a request
//!   of paths and options.
//! * [`outputs`]: the lighting file and what is written beside it (maps, pictures, diagnostics).
//! * [`outline`]: sphere centres refined from their silhouettes in the photograph (sub-pixel
//!   edges along the predicted outline's normals, the tangent cone fitted across the line of
//!   sight), for spheres placed by an imprecise pose.
//! * [`pipeline`]: [`process`]: unwarp the mirror (and black) sphere into lat-long and
//!   hemisphere maps divided by the sphere's reflectance, with a validity mask (saturation,
//!   camera reflection, blind directions); decide whether the sun is visible; if so, its
//!   direction from the sub-pixel centre of the black sphere's spot, reflected, and its
//!   radiance from the per-channel least squares `D' + a D* = D` over the diffuse sphere;
//!   the 2 % check of the final lighting against the diffuse sphere.
//! * [`resample`]: area-preserving resampling of a sphere's photograph into direction maps
//!   (box reconstruction of the pixels, solid-angle weighted, sub-directions at the pixel
//!   grid's Nyquist rate).
//!
//! All radiance is linear `f32`; directions are in igi's world frame (Z up), obtained from the
//! camera pose (board centres are given in the camera frame).

pub mod board;
pub mod envmap;
mod error;
pub mod fiducial;
pub mod fresnel;
pub mod input;
pub mod job;
pub mod outline;
pub mod outputs;
pub mod pipeline;
pub mod resample;

pub use board::{Board, BoardSpec, BoardSphere, SphereKind};
pub use error::{IorFitProblem, ProbeError};
pub use pipeline::{process, Diagnostics, ProbeOptions, ProbeResult, SunEstimate};
