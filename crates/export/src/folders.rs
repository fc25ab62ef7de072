//! The folders `igi export --format gltf` and `igi view` take: a solve result, an opacity
//! hull or a surface light field, told apart by their manifests and read through their own
//! crates' readers (`igi_reflect::SolveResult`, `igi_opacity_hull::build::load_model`,
//! `igi_lightfield::store::load`), each made into one GLB (docs/EXPORT.md, "Hulls and light
//! fields").
//!
//! * A hull: its surfels as points (`mode` 0) coloured by the mean of the photographs that see
//!   each, weighted by its opacity in each (the opacity its mean over those views), unlit; its surface `hull.ply` as a grey
//!   mesh when present.
//! * A light field: its atlas mesh with the median radiance as an unlit texture (8-bit sRGB,
//!   scaled so that the 99th percentile of the median's luminance is white; the scale in
//!   `extras`). The view-dependent part (the lumispheres) stays in the folder.

use crate::ExportError;
use glam::{Vec2, Vec3};
use igi_imaging::HdrImage;
use serde_json::json;
use std::path::{Path, PathBuf};

/// What a folder holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FolderKind {
    /// A result folder of `igi solve` (`report.json` and `parts/`).
    Result,
    /// An opacity-hull folder of `igi hull build` (`hull.json` and `surfels.ply`).
    Hull,
    /// A surface-light-field folder of `igi slf build` (`header.json` and `mesh.ply`).
    LightField,
}

impl FolderKind {
    /// The word for it (`result`, `hull`, `light field`).
    pub fn name(self) -> &'static str {
        match self {
            FolderKind::Result => "result",
            FolderKind::Hull => "hull",
            FolderKind::LightField => "light field",
        }
    }
}

/// What `dir` is, by the files that mark each kind; anything else is refused
/// ([`ExportError::NotExportable`]).
pub fn folder_kind(dir: &Path) -> Result<FolderKind, ExportError> {
    let has = |f: &str| dir.join(f).is_file();
    if has("report.json") && dir.join("parts").is_dir() {
        Ok(FolderKind::Result)
    } else if has("hull.json") && has("surfels.ply") {
        Ok(FolderKind::Hull)
    } else if has("header.json") && has("mesh.ply") {
        Ok(FolderKind::LightField)
    } else {
        Err(ExportError::NotExportable {
            dir: dir.to_path_buf(),
        })
    }
}

/// Each surfel's colour (the mean of the views that see it, weighted by its opacity in each,
/// so a view whose matte says the surfel is not there adds nothing) and opacity (the mean
/// over those views); a surfel no view sees, or none sees opaque, is black and transparent.
pub fn surfel_colors(model: &igi_opacity_hull::render::HullModel) -> Vec<[f32; 4]> {
    let s = &model.surfels;
    let nv = s.views;
    (0..s.len())
        .map(|i| {
            let (mut c, mut a, mut n) = (Vec3::ZERO, 0.0f32, 0usize);
            for v in 0..nv {
                if s.visible[i * nv + v] {
                    let o = s.opacity[i * nv + v].max(0.0);
                    c += o * Vec3::from(model.colors[i * nv + v]);
                    a += o;
                    n += 1;
                }
            }
            if n == 0 || a <= 0.0 {
                [0.0; 4]
            } else {
                let c = c / a;
                [c.x, c.y, c.z, a / n as f32]
            }
        })
        .collect()
}

pub(crate) fn hull_glb(dir: &Path) -> Result<(Vec<u8>, Vec<String>), ExportError> {
    let model = igi_opacity_hull::build::load_model(dir).map_err(Box::new)?;
    let colors = surfel_colors(&model);
    let surface_path = dir.join("hull.ply");
    let surface = if surface_path.is_file() {
        Some(igi_geometry::read_mesh(&surface_path)?)
    } else {
        None
    };
    let s = &model.surfels;
    let mut items = vec![crate::gltf::GlbItem::Points {
        name: "surfels",
        positions: &s.positions,
        normals: &s.normals,
        colors: &colors,
        extras: json!({
            "surfels": s.len(),
            "views": s.views,
            "radius_mean": s.radius.iter().sum::<f32>() / s.len().max(1) as f32,
            "color": "mean of the photographs of the views that see the surfel, weighted by its opacity in each (linear, clipped to [0, 1]); alpha: the mean opacity over those views",
        }),
    }];
    if let Some(m) = &surface {
        items.push(crate::gltf::GlbItem::Plain {
            name: "hull",
            mesh: m,
            extras: json!({"mesh": "hull.ply", "what": "the visual hull's surface"}),
        });
    }
    let asset = json!({
        "hull": dir.display().to_string(),
        "axes": "igi world Z up (metres); the root node rotates it to glTF's Y up",
    });
    let bytes =
        crate::gltf::glb_of_items(&glb_name(dir), &items, "igi hull (Z up to Y up)", asset)?;
    let mut summary = vec![format!("{} surfels seen by {} views", s.len(), s.views)];
    if let Some(m) = &surface {
        summary.push(format!("hull surface of {} triangles", m.indices.len()));
    }
    Ok((bytes, summary))
}

/// The name errors give the GLB of `dir`.
fn glb_name(dir: &Path) -> PathBuf {
    dir.join("scene.glb")
}

/// The light field's median radiance as an atlas image (every texel that maps to a grid
/// point, gutters included), and the scale that makes it the texture (the 99th percentile of
/// the median's luminance maps to 1).
pub fn median_texture(field: &igi_lightfield::SurfaceLightField) -> (HdrImage, f32) {
    let r = field.resolution;
    let mut lum: Vec<f32> = field
        .median
        .iter()
        .map(|m| igi_imaging::color::luminance(m.to_array()))
        .filter(|l| l.is_finite())
        .collect();
    lum.sort_by(f32::total_cmp);
    let p99 = lum
        .get((lum.len() as f64 * 0.99) as usize)
        .or(lum.last())
        .copied()
        .unwrap_or(1.0);
    let scale = if p99 > 0.0 { 1.0 / p99 } else { 1.0 };
    let mut img = HdrImage::new(r, r);
    for y in 0..r {
        for x in 0..r {
            let uv = Vec2::new(
                (x as f32 + 0.5) / r as f32,
                1.0 - (y as f32 + 0.5) / r as f32,
            );
            if let Some(p) = field.point_at(uv) {
                img.pixels[y * r + x] = (field.median[p] * scale).to_array();
            }
        }
    }
    (img, scale)
}

/// The light field of `dir` as GLB bytes, its summary, and the field with its median
/// texture's scale.
pub(crate) type LightFieldGlb = (
    Vec<u8>,
    Vec<String>,
    (igi_lightfield::SurfaceLightField, f32),
);

pub(crate) fn light_field_glb(dir: &Path) -> Result<LightFieldGlb, ExportError> {
    let (field, mesh) = igi_lightfield::store::load(dir).map_err(Box::new)?;
    let (texture, scale) = median_texture(&field);
    let items = [crate::gltf::GlbItem::Unlit {
        name: "light field",
        mesh: &mesh,
        image: &texture,
        extras: json!({
            "median": "the median of each grid point's lumisphere (radiance) times median_scale, as 8-bit sRGB",
            "median_scale": scale,
            "coding": field.coding.name(),
            "view_dependent": "the lumispheres (header.json, the coding's files) stay in the folder: igi slf render and igi view draw them",
        }),
    }];
    let asset = json!({
        "light_field": dir.display().to_string(),
        "axes": "igi world Z up (metres); the root node rotates it to glTF's Y up",
        "texcoord": "v_gltf = 1 - v_igi (igi's atlas origin is the bottom-left)",
    });
    let bytes = crate::gltf::glb_of_items(
        &glb_name(dir),
        &items,
        "igi light field (Z up to Y up)",
        asset,
    )?;
    let summary = vec![format!(
        "{} grid points on a mesh of {} triangles, coding {}",
        field.median.len(),
        mesh.indices.len(),
        field.coding.name()
    )];
    Ok((bytes, summary, (field, scale)))
}
