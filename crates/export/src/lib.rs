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
//! * [`tiles`]: a prepared site (or a result too large for one GLB) as 3D Tiles 1.1: a GLB per
//!   part and level and `tileset.json`.
//! * [`folders`]: the folders `igi export --format gltf` and `igi view` take (a result, an
//!   opacity hull, a surface light field), told apart, each as one GLB in memory.
//! * [`outdir`]: the output folder's rules for every format (never the result folder; new,
//!   empty or an earlier igi export, replaced whole; `export.json`).
//! * [`sample`]: `igi sample`: the albedo and its standard error at surface points (for
//!   colour-checker comparisons), read and written through `igi_formats::points`.

pub mod export;
pub mod folders;
pub mod gltf;
pub mod lobefit;
pub mod outdir;
pub mod sample;
pub mod tiles;

pub use export::{
    export, folder_glb, result_glb, result_tiles, ExportFormat, Exported, FolderGlb, ResultGlb,
    STDERR_PICTURE_MAX,
};
pub use folders::{folder_kind, FolderKind};
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
    /// A folder that is none of a result, an opacity hull and a surface light field.
    #[error("{}: not a result folder of `igi solve` (report.json and parts/), an opacity-hull folder of `igi hull build` (hull.json and surfels.ply) nor a surface-light-field folder of `igi slf build` (header.json and mesh.ply)", dir.display())]
    NotExportable { dir: PathBuf },
    /// A hull or light-field folder exported to a format other than glTF.
    #[error("{}: a {kind} folder exports only as glTF (--format gltf), not {format}", dir.display())]
    GltfOnly {
        dir: PathBuf,
        kind: &'static str,
        format: &'static str,
    },
    #[error(transparent)]
    Hull(#[from] Box<igi_opacity_hull::HullError>),
    #[error(transparent)]
    LightField(#[from] Box<igi_lightfield::LightFieldError>),
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
