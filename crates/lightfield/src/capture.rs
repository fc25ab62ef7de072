//! A surface light field from a multi-view capture (`rig.toml`, FORMATS.md "Multi-view
//! capture") and a mesh of the object in the same world frame: what `igi slf build` runs.
//!
//! Each view's photo is read as linear RGB; pixels outside the view's optional mask, and the
//! clipped pixels of 8-bit photos (PNG, JPEG: a channel at 254/255 or more), are invalid and
//! never contribute (`data::gather` skips bilinear lookups that touch them). The grid points
//! are the covered texels of a fresh atlas of the mesh (`--atlas` texels a side, 1-texel
//! gutters); the mesh's own texture coordinates, if any, are not used. Every pixel centre's
//! ray is cast once ([`crate::data::pixel_hits`]) and serves both the silhouette check of the
//! masks and the gathering's silhouette rule.

use crate::build::{BuildOptions, Method, Prepared};
use crate::data::{mask_clipped, pixel_hits, GatherReport, View};
use crate::field::SurfaceLightField;
use crate::LightFieldError;
use igi_camera::rig::RigView;
use igi_camera::{Camera, Rig};
use igi_geometry::atlas::{build_atlas_with, Atlas, AtlasOptions, Unwrapper};
use igi_geometry::TriMesh;
use igi_imaging::{read_image, HdrImage, Mask};
use igi_raycast::RtScene;
use rayon::prelude::*;
use std::path::Path;

/// The value at or above which an 8-bit photo's channel counts as clipped (254 of 255).
pub const CLIP_8BIT: f32 = 254.0 / 255.0;

/// What [`build_from_rig`] made.
pub struct RigBuild {
    pub field: SurfaceLightField,
    /// The atlas whose covered texels are the grid points (its mesh is what `store::save` keeps).
    pub atlas: Atlas,
    pub report: GatherReport,
    /// Views read, and their pixels marked invalid (masked or clipped).
    pub views: usize,
    pub invalid_pixels: usize,
    /// One line per view whose mask has more than [`MAX_SILHOUETTE_MISS`] of its pixels off the
    /// mesh (the mesh and the photographs disagree there), naming the view.
    pub warnings: Vec<String>,
}

/// The fraction of a view's silhouette (mask) pixels whose centre ray may miss the mesh before
/// the build warns about that view.
pub const MAX_SILHOUETTE_MISS: f64 = 0.01;

/// A loaded view: camera, photo with invalid pixels marked, and its silhouette when the rig
/// gives a mask.
pub struct LoadedView {
    pub id: String,
    pub camera: Camera,
    pub photo: HdrImage,
    pub mask: Option<Mask>,
}

/// Reads every view of `rig`: its camera and its photo with invalid pixels marked.
pub fn load_views(rig: &Rig) -> Result<Vec<LoadedView>, LightFieldError> {
    rig.views.iter().map(|v| load_view(rig, v)).collect()
}

fn load_view(rig: &Rig, v: &RigView) -> Result<LoadedView, LightFieldError> {
    let camera = rig.load_camera(v)?;
    let read = |p: &Path| -> Result<HdrImage, LightFieldError> {
        let img = read_image(p).map_err(|e| rig.view_error(v, e))?;
        if (img.width, img.height) != (camera.width as usize, camera.height as usize) {
            return Err(LightFieldError::ImageSize {
                path: p.to_path_buf(),
                got_w: img.width,
                got_h: img.height,
                want_w: camera.width,
                want_h: camera.height,
            });
        }
        Ok(img)
    };
    let mut photo = read(&v.photo)?;
    if is_8bit(&v.photo) {
        mask_clipped(&mut photo, CLIP_8BIT);
    }
    let mask = match &v.mask {
        Some(m) => Some(Mask::threshold(&read(m)?, 0.0)),
        None => None,
    };
    if let Some(mask) = &mask {
        for (ok, inside) in photo.valid.iter_mut().zip(&mask.data) {
            *ok &= *inside;
        }
    }
    Ok(LoadedView {
        id: v.id.clone(),
        camera,
        photo,
        mask,
    })
}

/// The fraction of `mask`'s pixels whose centre ray misses the scene, from the view's
/// [`pixel_hits`] (`hits`, the mask's size).
pub fn silhouette_miss(hits: &[bool], mask: &Mask) -> f64 {
    let inside = mask.data.iter().filter(|m| **m).count();
    let missed = mask
        .data
        .iter()
        .zip(hits)
        .filter(|(m, h)| **m && !**h)
        .count();
    missed as f64 / inside.max(1) as f64
}

/// A warning for each view whose silhouette misses the mesh by more than
/// [`MAX_SILHOUETTE_MISS`] (`hits`: each view's [`pixel_hits`]).
fn silhouette_warnings(views: &[LoadedView], hits: &[Vec<bool>]) -> Vec<String> {
    views
        .iter()
        .zip(hits)
        .filter_map(|(v, hit)| {
            let miss = silhouette_miss(hit, v.mask.as_ref()?);
            (miss > MAX_SILHOUETTE_MISS).then(|| {
                format!(
                    "view {:?}: {:.1} % of its mask's pixels miss the mesh (more than {} %): the mesh and the photographs disagree there",
                    v.id,
                    100.0 * miss,
                    100.0 * MAX_SILHOUETTE_MISS
                )
            })
        })
        .collect()
}

/// PNG and JPEG photos are 8-bit (their top code value is clipped light).
fn is_8bit(p: &Path) -> bool {
    let ext = p
        .extension()
        .map(|e| e.to_string_lossy().to_lowercase())
        .unwrap_or_default();
    matches!(ext.as_str(), "png" | "jpg" | "jpeg")
}

/// The stages of [`build_from_rig`], reported to its `stage` callback as they begin.
pub const STAGES: [&str; 4] = ["reading the views", "atlas", "gathering samples", "fitting"];

/// The grid of a build: the atlas resolution and how far to simplify the mesh first.
#[derive(Clone, Copy, Debug)]
pub struct GridOptions {
    /// Atlas texels a side.
    pub atlas: u32,
    /// Keep about this fraction of the mesh's triangles (meshopt, borders locked) before the
    /// atlas: dense scans and hull meshes have more charts than an atlas can hold. 1: as is,
    /// up to one triangle per 4 atlas texels (a denser mesh is simplified to that many).
    pub simplify: f64,
}

impl GridOptions {
    /// Checks the options before any work.
    pub fn validate(&self) -> Result<(), LightFieldError> {
        if !(self.simplify > 0.0 && self.simplify <= 1.0) {
            return Err(LightFieldError::BadSimplify(self.simplify));
        }
        Ok(())
    }
}

impl Default for GridOptions {
    fn default() -> Self {
        GridOptions {
            atlas: 256,
            simplify: 1.0,
        }
    }
}

/// Builds the surface light field of `mesh` from the views of `rig` with `method`; `stage(k)`
/// is called as stage `k` of [`STAGES`] begins.
pub fn build_from_rig(
    rig: &Rig,
    mesh: &TriMesh,
    grid: GridOptions,
    method: Method,
    opts: &BuildOptions,
    stage: &dyn Fn(usize),
) -> Result<RigBuild, LightFieldError> {
    opts.validate(method)?;
    let prepared = prepare_rig(rig, mesh, grid, opts.level, stage)?;
    stage(3);
    let field = prepared.prepared.fit(method, opts)?;
    Ok(RigBuild {
        field,
        atlas: prepared.atlas,
        report: prepared.prepared.report.clone(),
        views: prepared.views,
        invalid_pixels: prepared.invalid_pixels,
        warnings: prepared.warnings,
    })
}

/// The first three stages of [`build_from_rig`] (reading, atlas, gathering): the data
/// lumispheres ready for any number of fits.
pub struct RigPrepared {
    pub prepared: Prepared,
    /// The atlas whose covered texels are the grid points.
    pub atlas: Atlas,
    /// Views read, and their pixels marked invalid (masked or clipped).
    pub views: usize,
    pub invalid_pixels: usize,
    /// As [`RigBuild::warnings`].
    pub warnings: Vec<String>,
}

/// Reads the views of `rig`, builds the atlas of `mesh` and gathers the data lumispheres of its
/// grid points on an octahedron of `level` (stages 0-2 of [`STAGES`], reported to `stage`).
pub fn prepare_rig(
    rig: &Rig,
    mesh: &TriMesh,
    grid: GridOptions,
    level: u32,
    stage: &dyn Fn(usize),
) -> Result<RigPrepared, LightFieldError> {
    grid.validate()?;
    stage(0);
    let views = load_views(rig)?;
    stage(1);
    let mut mesh = mesh.clone();
    mesh.uvs = None;
    // at most one triangle per 4 atlas texels: finer triangles add charts, not grid points (a
    // marching-cubes hull of 800,000 triangles gives 11,528 charts, more than 256 x 256 holds;
    // at one triangle per texel its charts leave 8 mm texels, at one per 4 texels 0.85 mm)
    let budget = grid.atlas as f64 * grid.atlas as f64 / 4.0 / mesh.indices.len().max(1) as f64;
    let mut mesh = igi_geometry::levels::simplify(&mesh, &[], grid.simplify.min(budget), true).mesh;
    mesh.normals = None;
    mesh.compute_vertex_normals();
    // uvunwrap charts: a scan or hull mesh gives tens of thousands of six-axis projected charts
    let atlas = build_atlas_with(
        &mesh,
        AtlasOptions {
            resolution: grid.atlas,
            gutter: 1,
        },
        Unwrapper::Uvunwrap,
    )?;
    let rt = RtScene::new(&[(
        atlas.mesh.positions.as_slice(),
        atlas.mesh.indices.as_slice(),
    )])
    .map_err(LightFieldError::Raycast)?;
    stage(2);
    let refs: Vec<View> = views
        .iter()
        .map(|v| View {
            camera: &v.camera,
            image: &v.photo,
        })
        .collect();
    // every pixel's ray is cast once: for the silhouette check and for the gathering
    let hits: Vec<Vec<bool>> = refs.par_iter().map(|v| pixel_hits(&rt, v)).collect();
    let warnings = silhouette_warnings(&views, &hits);
    let prepared = Prepared::with_hits(&atlas, &rt, &refs, &hits, level);
    let invalid_pixels = views
        .iter()
        .map(|v| v.photo.valid.iter().filter(|ok| !**ok).count())
        .sum();
    Ok(RigPrepared {
        prepared,
        atlas,
        views: views.len(),
        invalid_pixels,
        warnings,
    })
}
