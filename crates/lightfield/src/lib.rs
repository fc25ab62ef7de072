//! `igi-lightfield`: surface light fields (Wood et al. 2000, `docs/LIGHTFIELD.md`).
//!
//! - [`lumisphere`]: the s-times subdivided octahedron, the map h (Eq. 3), barycentric
//!   evaluation, the umbrella Laplacian, median removal and reflection about the normal
//!   (Eqs. 9-10).
//! - [`data`]: data lumispheres from photographs, cameras and the mesh (ray-cast visibility
//!   through igi-render's Embree scene, bilinear lookups that skip invalid pixels).
//! - [`fit`]: pointwise fairing (Eqs. 5-8) by conjugate gradients.
//! - [`quantize`]: function quantization (Eqs. 11-12).
//! - [`pfa`]: principal function analysis (Eqs. 13-14).
//! - [`field`]: the surface light field, rendering and editing.
//! - [`capture`]: the whole build from a multi-view capture (`rig.toml`) and a mesh
//!   (`igi slf build`).
//! - [`store`]: the `SLF_DIR/` folder.
//! - [`job`]: `igi slf build` and `igi slf render` as one call each, from a request of paths
//!   and options.
//! - [`plot`]: the error-against-size plot of the codings.
//!
//! Grid points are the covered texels of an `igi-geometry` atlas of the mesh (standing in for
//! the paper's base-mesh parameterisation). Never depends on the solver (`igi-reflect`).

#![allow(clippy::neg_cmp_op_on_partial_ord, clippy::nonminimal_bool)]

pub mod build;
pub mod capture;
pub mod data;
pub mod field;
pub mod fit;
pub mod job;
pub mod lumisphere;
pub mod pfa;
pub mod plot;
pub mod quantize;
pub mod store;

pub use build::{grid_points, BuildOptions, Method, Prepared};
pub use capture::{build_from_rig, prepare_rig, GridOptions, RigBuild, RigPrepared};
pub use data::{
    angle_gain, gather, gather_with_hits, observation_median, pixel_hits, reparameterise,
    GatherReport, GridPoint, View,
};
pub use field::{Coding, FieldRenderer, RenderSlfOptions, SurfaceLightField};
pub use fit::{fair_pointwise, DataLumisphere, FitOptions};
pub use lumisphere::{AngleGain, Octahedron};
pub use pfa::{fit_pfa, Pfa, PfaOptions};
pub use quantize::{fit_fq, Codebook, FqOptions};

use std::path::PathBuf;

/// Errors of the surface light field.
#[derive(Debug, thiserror::Error)]
pub enum LightFieldError {
    #[error("ray casting the mesh: {0}")]
    Raycast(#[source] igi_raycast::RaycastError),
    #[error(
        "the mesh has no texture coordinates (render the atlas mesh or a deformed copy of it)"
    )]
    MeshWithoutUvs,
    #[error(transparent)]
    Imaging(#[from] igi_imaging::ImagingError),
    /// The output folder (its lock and staging) or a size check (`igi-files`).
    #[error(transparent)]
    Files(#[from] igi_files::FilesError),
    /// A camera, its file, radiometry or rig, or an OpenCV call (`igi-camera`).
    #[error(transparent)]
    Camera(#[from] igi_camera::CameraError),
    /// A plot that could not be drawn or written.
    #[error(transparent)]
    Plot(#[from] igi_plot::PlotError),
    #[error(transparent)]
    Geometry(#[from] igi_geometry::GeometryError),
    #[error("the subspace dimension q must be at least 1 (got {0})")]
    BadQ(usize),
    #[error("the octahedron subdivision level must lie in 1..=6 (got {0})")]
    BadLevel(u32),
    #[error("the fraction of triangles to keep must lie in (0, 1] (got {0})")]
    BadSimplify(f64),
    #[error("lambda must be positive and finite (got {0})")]
    BadLambda(f32),
    #[error("the codebook size must be a power of two (got {0})")]
    BadCodebookSize(usize),
    #[error("{}: the image is {got_w} x {got_h} but its camera is {want_w} x {want_h}", path.display())]
    ImageSize {
        path: PathBuf,
        got_w: usize,
        got_h: usize,
        want_w: u32,
        want_h: u32,
    },
    #[error("{}: {msg}", path.display())]
    Format { path: PathBuf, msg: String },
    /// A request of a job (`job`) that cannot be run; the message names the options.
    #[error("{0}")]
    Arguments(String),
    /// A stored field that cannot be read (`source`: why).
    #[error("reading {}", path.display())]
    Reading {
        path: PathBuf,
        #[source]
        source: Box<LightFieldError>,
    },
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
}
