//! # igi-export
//!
//! Results out: what reads a solve result folder (`igi_reflect::SolveResult`) for other tools.
//!
//! * [`mod@export`]: `igi export --format ply|obj|mitsuba|gltf`: per part the mesh with atlas UVs, the
//!   albedo texture with an sRGB preview, a picture of its standard error, the per-texel lobe
//!   maps, an igi `scene.toml` that renders like the result, and for Mitsuba 3 a `scene.xml`
//!   (diffuse term only: Mitsuba has no Lafortune BSDF, and the file says so).
//! * [`gltf`]: `igi export --format gltf`: one binary glTF 2.0 file of the result (Y up at the
//!   root node, v flipped, the albedo as an embedded sRGB PNG), whose materials approximate the
//!   Lafortune lobes with `KHR_materials_specular` ([`lobefit`], the fit's error reported) and
//!   keep the exact lobes in `extras`.
//! * [`outdir`]: the output folder's rules for every format (never the result folder; new,
//!   empty or an earlier igi export, replaced whole; `export.json`).
//! * [`sample`]: `igi sample`: the albedo and its standard error at surface points (for
//!   colour-checker comparisons), read and written through `igi_formats::points`.

pub mod export;
pub mod gltf;
pub mod lobefit;
pub mod outdir;
pub mod sample;

pub use export::{export, ExportFormat, Exported, STDERR_PICTURE_MAX};
pub use lobefit::{fit_gltf, GltfFit};
pub use sample::{sample_albedo, sample_file, AlbedoSample};

use std::path::PathBuf;

/// Errors of exporting or sampling a result; each names its file or point.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// A file of the result or of the export that cannot be used or written.
    #[error("{}: {msg}", path.display())]
    File { path: PathBuf, msg: String },
    /// A query point of `igi sample` too far from every surface of the result (1-based index).
    #[error("invalid input: point {index} ({}, {}, {}) is {distance:.3e} m from the nearest surface of the result (at most {far:.2} m)", point.x, point.y, point.z)]
    FarPoint {
        index: usize,
        point: glam::Vec3,
        distance: f32,
        far: f32,
    },
    #[error(transparent)]
    Reflect(#[from] igi_reflect::ReflectError),
    #[error(transparent)]
    Format(#[from] igi_formats::FormatsError),
    #[error(transparent)]
    Imaging(#[from] igi_imaging::ImagingError),
    #[error(transparent)]
    Files(#[from] igi_files::FilesError),
    #[error(transparent)]
    Geometry(#[from] igi_geometry::GeometryError),
    #[error(transparent)]
    Render(#[from] igi_render::RenderError),
}

impl ExportError {
    pub(crate) fn file(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        ExportError::File {
            path: path.into(),
            msg: msg.into(),
        }
    }
}
