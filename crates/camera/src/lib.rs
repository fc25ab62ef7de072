//! # igi-camera
//!
//! Cameras, as every pipeline shares them: the model, its poses, its calibration and its
//! radiometry, and the multi-view capture file that lists them.
//!
//! * [`camera`]: OpenCV pinhole camera with (k1, k2, p1, p2, k3) distortion, typed poses
//!   ([`WorldToCamera`], [`CameraToWorld`]), JSON load/save, projection, pixel rays and
//!   image undistortion.
//! * [`radiometry`]: lens falloff (vignetting) polynomial fit, 3x3 colour matrices, the colour
//!   checker, and the camera radiometry file.
//! * [`planar`]: pure-Rust homography (normalised DLT) and the pose of a plane from four or
//!   more points (no OpenCV needed).
//! * [`rig`]: the multi-view capture file `rig.toml` (FORMATS.md) with paths resolved
//!   against its folder.
//! * [`cv`]: every OpenCV call of igi: calibration, PnP, homography, ArUco detection and
//!   drawing, ColorChecker detection (cargo feature `opencv`; without it the same functions
//!   return [`CameraError::NoOpenCv`]).
//! * [`job`]: `igi camera`'s jobs, each one call from a request of paths and options
//!   (undistort, pose, calibrate, radiometry).
//!
//! Conventions: pixel centres at integer coordinates (the centre of the top-left pixel is
//! (0, 0)), camera x right, y down, z forward, `x_cam = R x_world + t`.

// `!(x > 0.0)` is used on purpose: it is also true for NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod camera;
pub mod cv;
mod error;
pub mod job;
pub mod planar;
pub mod radiometry;
pub mod rig;

pub use camera::{
    Camera, CameraFile, CameraToWorld, Distortion, Intrinsics, PixelRays, WorldToCamera,
};
pub use error::{
    CameraError, CameraFileError, PlanarError, PnpError, RadiometryError, RotationError,
};
pub use rig::Rig;
