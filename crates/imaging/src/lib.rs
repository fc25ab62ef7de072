//! # igi-imaging
//!
//! Shared camera and HDR code at the bottom of the igi dependency graph:
//!
//! * [`HdrImage`]: linear `f32` RGB image with a validity mask (row 0 at the top).
//! * [`io`]: atomic file writing, [`read_image`] (EXR, Radiance HDR, PNG/JPEG/TIFF),
//!   [`write_exr`], [`write_hdr`], [`write_png_tonemapped`].
//! * [`latlong`]: the lat-long (equirectangular) mapping of FORMATS.md (world Z up).
//! * [`camera`]: OpenCV pinhole camera with (k1, k2, p1, p2, k3) distortion, typed poses
//!   ([`WorldToCamera`], [`CameraToWorld`]), a camera at a point looking at another
//!   ([`Camera::look_at`]), JSON load/save, projection, pixel rays and image undistortion.
//! * [`hdr`]: merging exposure brackets (linear sensors, the least-squares slope of Matusik
//!   et al. 2002, or LDR via Debevec & Malik 1997 response recovery), EXIF exposure times.
//! * [`radiometry`]: lens falloff (vignetting) polynomial fit and 3x3 colour matrices.
//! * [`planar`]: pure-Rust homography (normalised DLT) and the pose of a plane from four or
//!   more points (no OpenCV needed).
//! * [`rig`]: the multi-view capture file `rig.toml` (FORMATS.md) with paths resolved
//!   against its folder.
//! * [`metrics`]: image comparison (RMSE, relative mean difference, PSNR, noise-explained
//!   RMSE) and false-colour difference pictures.
//! * [`mask`]: binary masks (threshold, disk dilation and erosion, hole filling up to an area,
//!   frame contact, IoU).
//! * [`run`]: run manifests (`run.json`): input fingerprints and result-changing options, so
//!   a resumed command never mixes two runs' work.
//! * [`csv`]: the one reader of igi's numeric CSV tables (header by name, comments, errors
//!   naming file and line).
//! * [`plot`]: font registration for plotters (diagnostic plots).
//! * [`cv`]: OpenCV-backed calibration, PnP, homography and ArUco detection (cargo feature
//!   `opencv`; without it the same functions return [`ImagingError::NoOpenCv`]).
//!
//! Conventions: linear radiance, pixel centres at integer coordinates (the centre of the
//! top-left pixel is (0, 0)), camera x right, y down, z forward, `x_cam = R x_world + t`.

// `!(x > 0.0)` is used on purpose: it is also true for NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod camera;
pub mod color;
pub mod csv;
pub mod cv;
mod error;
pub mod hdr;
mod image;
pub mod io;
pub mod latlong;
pub mod mask;
pub mod metrics;
pub mod planar;
pub mod plot;
pub mod radiometry;
pub mod rig;
pub mod run;

pub use camera::{Camera, CameraFile, CameraToWorld, Distortion, Intrinsics, WorldToCamera};
pub use error::{CompareError, HdrError, ImagingError, PlanarError, PnpError, RadiometryError};
pub use image::HdrImage;
pub use io::{
    read_exr_alpha, read_image, write_exr, write_exr_rgba, write_hdr, write_png_tonemapped,
};
pub use mask::Mask;
pub use rig::Rig;
pub use run::{Fingerprint, FolderLock, RunManifest};
