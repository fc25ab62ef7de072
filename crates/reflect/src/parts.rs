//! The parts of a site that the solver recovers: each input mesh gets a texture atlas
//! (`igi_geometry::atlas`) whose texel caches give the world position and normal of every texel
//! centre that lies on the surface. A prepared site (`igi prepare`) gives one part per voxel and
//! one for the terrain, with the atlases and caches it already holds; their meshes stay on disk
//! and the solver loads, per voxel, only the levels that voxel's solve needs.
//!
//! A part's atlas resolution is fixed ([`build_parts`]) or chosen from the photographs
//! ([`auto_resolution`]: one texel per pixel of the finest pixel footprint on the part, within a
//! memory budget; `igi solve --atlas auto`).

use crate::ReflectError;
use glam::DVec3;
use igi_geometry::atlas::{build_atlas, Atlas, AtlasOptions};
use igi_geometry::{SiteStore, TriMesh, VoxelId};
use igi_imaging::{Camera, HdrImage};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

pub use igi_geometry::texels::{Texel, TexelCache};

/// Where a part of a prepared site lives.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StoredPart {
    /// The prepared site folder.
    pub site: PathBuf,
    /// The voxel (`None` for the terrain).
    pub voxel: Option<VoxelId>,
}

impl StoredPart {
    /// The part's folder in the site (its level PLYs and caches).
    pub fn folder(&self, store: &SiteStore) -> Result<PathBuf, ReflectError> {
        match self.voxel {
            Some(v) => Ok(store.voxel_folder(v)?),
            None => store
                .terrain_folder()
                .ok_or_else(|| ReflectError::file(&self.site, "the prepared site has no terrain")),
        }
    }
}

/// One part of the site: a mesh with atlas UVs and its texel cache.
#[derive(Clone)]
pub struct Part {
    pub name: String,
    /// The mesh with atlas UVs (vertices split along chart borders); empty for a part of a
    /// prepared site, whose levels are read from `stored` when needed.
    pub mesh: TriMesh,
    pub stored: Option<StoredPart>,
    pub texel_size: f64,
    /// The finest pixel footprint of the photographs on the part (metres) when `--atlas auto`
    /// chose its resolution.
    pub footprint_m: Option<f64>,
    pub cache: TexelCache,
    /// 1 on covered texels, 0.5 on gutter texels, 0 elsewhere.
    pub coverage: HdrImage,
}

impl Part {
    pub fn resolution(&self) -> usize {
        self.cache.resolution
    }

    /// The full-resolution mesh (read from the prepared site for a stored part).
    pub fn full_mesh(&self) -> Result<std::borrow::Cow<'_, TriMesh>, ReflectError> {
        match &self.stored {
            None => Ok(std::borrow::Cow::Borrowed(&self.mesh)),
            Some(s) => {
                let store = SiteStore::open(&s.site)?;
                Ok(std::borrow::Cow::Owned(igi_geometry::read_ply(
                    &s.folder(&store)?.join("level0.ply"),
                )?))
            }
        }
    }
}

/// The name of a stored part: `I_J_K` for a voxel, `terrain` for the terrain.
pub fn stored_part_name(voxel: Option<VoxelId>) -> String {
    match voxel {
        Some(v) => format!("{}_{}_{}", v[0], v[1], v[2]),
        None => "terrain".to_string(),
    }
}

/// The parts of a prepared site: every voxel, then the terrain, with the atlases and texel
/// caches `igi prepare` wrote (no mesh is read).
pub fn prepared_parts(store: &SiteStore) -> Result<Vec<Part>, ReflectError> {
    let man = store.manifest();
    let entries: Vec<_> = man
        .voxels
        .iter()
        .chain(man.terrain.iter())
        .cloned()
        .collect();
    entries
        .into_par_iter()
        .map(|e| {
            let folder = store.dir().join(&e.dir);
            let read = |f: &str| igi_imaging::read_image(&folder.join(f));
            let (pos, nrm, coverage) = (
                read("position.exr")?,
                read("normal.exr")?,
                read("coverage.exr")?,
            );
            let res = coverage.width;
            for (im, f) in [
                (&pos, "position.exr"),
                (&nrm, "normal.exr"),
                (&coverage, "coverage.exr"),
            ] {
                if im.width != res || im.height != res {
                    return Err(ReflectError::file(
                        folder.join(f),
                        format!("is {}x{}, expected {res}x{res}", im.width, im.height),
                    ));
                }
            }
            let texels = TexelCache::covered_texels(&pos, &nrm, &coverage);
            Ok(Part {
                name: stored_part_name(e.voxel),
                mesh: TriMesh::default(),
                stored: Some(StoredPart {
                    site: store.dir().to_path_buf(),
                    voxel: e.voxel,
                }),
                texel_size: e.texel_size,
                footprint_m: None,
                cache: TexelCache {
                    resolution: res,
                    texels,
                },
                coverage,
            })
        })
        .collect()
}

/// Builds an atlas of `resolution` texels per side for each named mesh (normals are computed
/// when a mesh has none). Names must be unique; they name the output files.
pub fn build_parts(
    meshes: Vec<(String, TriMesh)>,
    resolution: u32,
) -> Result<Vec<Part>, ReflectError> {
    build_parts_with(meshes, |_| {
        Ok(AtlasChoice {
            resolution,
            footprint_m: None,
        })
    })
}

/// [`build_parts`] with each part's resolution chosen by [`auto_resolution`] from the
/// photographs' `cameras` (`igi solve --atlas auto`), at most `max` texels per side.
pub fn build_parts_auto(
    meshes: Vec<(String, TriMesh)>,
    cameras: &[Camera],
    max: u32,
) -> Result<Vec<Part>, ReflectError> {
    build_parts_with(meshes, |mesh| auto_resolution(mesh, cameras, max))
}

/// [`build_parts`] with each part's atlas resolution chosen by `choose` from its mesh (with
/// normals).
pub fn build_parts_with(
    meshes: Vec<(String, TriMesh)>,
    choose: impl Fn(&TriMesh) -> Result<AtlasChoice, ReflectError> + Sync,
) -> Result<Vec<Part>, ReflectError> {
    for (i, (a, _)) in meshes.iter().enumerate() {
        if meshes[..i].iter().any(|(b, _)| b == a) {
            return Err(ReflectError::Invalid(format!(
                "two site meshes are both named `{a}`"
            )));
        }
        if a.is_empty() || a.contains(['/', '\\']) {
            return Err(ReflectError::Invalid(format!("`{a}` cannot name a part")));
        }
    }
    meshes
        .into_par_iter()
        .map(|(name, mut mesh)| {
            if mesh.normals.is_none() {
                mesh.compute_vertex_normals();
            }
            let choice = choose(&mesh)?;
            let atlas = part_atlas(&name, &mesh, choice.resolution)?;
            if let Some(f) = choice.footprint_m {
                tracing::info!(
                    "part {name}: atlas {} texels per side, texel {:.4} m for a finest pixel footprint of {f:.4} m",
                    atlas.resolution,
                    atlas.texel_size
                );
            }
            let res = atlas.resolution;
            let texels =
                TexelCache::covered_texels(&atlas.position, &atlas.normal, &atlas.coverage);
            Ok(Part {
                name,
                mesh: atlas.mesh,
                stored: None,
                texel_size: atlas.texel_size,
                footprint_m: choice.footprint_m,
                cache: TexelCache {
                    resolution: res,
                    texels,
                },
                coverage: atlas.coverage,
            })
        })
        .collect()
}

/// The atlas of part `name` at `resolution` texels per side.
fn part_atlas(name: &str, mesh: &TriMesh, resolution: u32) -> Result<Atlas, ReflectError> {
    build_atlas(
        mesh,
        AtlasOptions {
            resolution,
            ..AtlasOptions::default()
        },
    )
    .map_err(|e| ReflectError::Invalid(format!("atlas of `{name}`: {e}")))
}

/// `igi solve --atlas auto`: each part's atlas resolution follows from the photographs (see
/// [`auto_resolution`]), at most `max` texels per side (the memory budget).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct AutoAtlas {
    pub max: u32,
}

/// The smallest resolution `--atlas auto` gives a part (also a part no photograph sees).
pub const AUTO_ATLAS_MIN: u32 = 64;
/// Resolution of the trial atlas whose covered fraction measures the packing efficiency.
const TRIAL_RESOLUTION: u32 = 128;
/// The footprint that decides is this quantile (by area) of the per-point finest footprints.
const FOOTPRINT_QUANTILE: f64 = 0.05;
/// At most this many triangles are sampled per part (a deterministic stride).
const MAX_FOOTPRINT_SAMPLES: usize = 20_000;
/// Chosen resolutions are multiples of this.
const RESOLUTION_STEP: u32 = 16;

/// The atlas resolution chosen for a part.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AtlasChoice {
    /// Texels per side.
    pub resolution: u32,
    /// The finest pixel footprint on the part that decided it (metres per pixel); `None` for a
    /// fixed resolution or a part no photograph sees.
    pub footprint_m: Option<f64>,
}

/// The finest pixel footprint of `cameras` on `mesh` in metres per pixel, `None` when no
/// camera sees any of it.
///
/// Sample points are triangle centroids (every k-th triangle for a large mesh, at most
/// 20 000). A camera sees a point when the point lies in front of it and projects into its
/// frame; occlusion is ignored (a point hidden behind another surface still counts, so the
/// footprint can only come out finer than the truth, never coarser). In a camera that sees it,
/// a point's footprint is its depth along the optical axis over the focal length in pixels
/// (the geometric mean of fx and fy); obliquity is ignored, as is lens distortion's change of
/// scale. The per-point footprint is the finest over the cameras, and the part's is the 5th
/// percentile of those weighted by triangle area, so a few points that one camera sees from
/// very close do not decide the whole part.
pub fn pixel_footprint(mesh: &TriMesh, cameras: &[Camera]) -> Option<f64> {
    let n = mesh.triangle_count();
    let stride = n.div_ceil(MAX_FOOTPRINT_SAMPLES).max(1);
    let mut samples: Vec<(f64, f64)> = (0..n)
        .step_by(stride)
        .filter_map(|t| {
            let area = mesh.triangle_area(t);
            let [a, b, c] = mesh.triangle(t);
            let centroid = (DVec3::from(a.map(f64::from))
                + DVec3::from(b.map(f64::from))
                + DVec3::from(c.map(f64::from)))
                / 3.0;
            let finest = cameras
                .iter()
                .filter_map(|cam| point_footprint(cam, centroid))
                .min_by(f64::total_cmp)?;
            (area.is_finite() && area > 0.0).then_some((finest, area))
        })
        .collect();
    samples.sort_by(|x, y| x.0.total_cmp(&y.0));
    let total: f64 = samples.iter().map(|s| s.1).sum();
    let mut acc = 0.0;
    samples
        .iter()
        .find(|(_, w)| {
            acc += w;
            acc >= FOOTPRINT_QUANTILE * total
        })
        .map(|s| s.0)
}

/// The footprint of one pixel of `cam` at world point `p` (depth / focal length), `None`
/// when `cam` does not see `p` (behind it or outside its frame).
pub fn point_footprint(cam: &Camera, p: DVec3) -> Option<f64> {
    let depth = cam.pose.apply(p).z;
    let q = cam.project(p)?;
    let f = (cam.intrinsics.fx * cam.intrinsics.fy).sqrt();
    let fp = depth / f;
    (cam.in_frame(q) && fp.is_finite() && fp > 0.0).then_some(fp)
}

/// The smallest multiple of 16 texels per side (within [`AUTO_ATLAS_MIN`] to `max`) whose
/// atlas holds `area` square metres at texels of `texel_m` when charts cover `efficiency` of
/// the atlas: sqrt(area / texel^2 / efficiency).
pub fn resolution_for(area: f64, texel_m: f64, efficiency: f64, max: u32) -> u32 {
    let max = max.max(AUTO_ATLAS_MIN);
    let side = (area / (texel_m * texel_m) / efficiency).sqrt();
    if !side.is_finite() {
        return if side.is_nan() { AUTO_ATLAS_MIN } else { max };
    }
    let step = RESOLUTION_STEP as f64;
    let rounded = ((side / step).ceil() * step).min(max as f64);
    (rounded as u32).clamp(AUTO_ATLAS_MIN, max)
}

/// The atlas resolution of one part for `--atlas auto`: one texel per pixel of the finest
/// footprint ([`pixel_footprint`]; one texel per pixel, since a finer atlas would hold detail
/// no photograph resolves and a coarser one averages detail they do), in an atlas large enough
/// for the part's surface area at the packing efficiency measured on a trial atlas of 128
/// texels per side (its covered fraction). A part no camera sees gets [`AUTO_ATLAS_MIN`].
/// `mesh` needs normals (for the trial atlas).
pub fn auto_resolution(
    mesh: &TriMesh,
    cameras: &[Camera],
    max: u32,
) -> Result<AtlasChoice, ReflectError> {
    let Some(footprint) = pixel_footprint(mesh, cameras) else {
        return Ok(AtlasChoice {
            resolution: AUTO_ATLAS_MIN,
            footprint_m: None,
        });
    };
    let trial = part_atlas("trial", mesh, TRIAL_RESOLUTION)?;
    let efficiency = trial.coverage_fraction();
    Ok(AtlasChoice {
        resolution: resolution_for(mesh.total_area(), footprint, efficiency, max),
        footprint_m: Some(footprint),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use igi_imaging::WorldToCamera;

    /// A `side` x `side` metre square in the plane z = 0, centred at (cx, 0), as an n x n grid.
    fn square(side: f32, cx: f32, n: u32) -> TriMesh {
        let mut m = TriMesh::default();
        for j in 0..=n {
            for i in 0..=n {
                let (u, v) = (i as f32 / n as f32 - 0.5, j as f32 / n as f32 - 0.5);
                m.positions.push([cx + side * u, side * v, 0.0]);
            }
        }
        for j in 0..n {
            for i in 0..n {
                let a = j * (n + 1) + i;
                m.indices.push([a, a + 1, a + n + 2]);
                m.indices.push([a, a + n + 2, a + n + 1]);
            }
        }
        m.compute_vertex_normals();
        m
    }

    /// A 640 x 480 pinhole camera of focal length `f` pixels at height `d` above (x, 0, 0),
    /// looking straight down.
    fn camera_above(x: f64, d: f64, f: f64) -> Camera {
        let mut cam = Camera::pinhole(640, 480, f, f, 319.5, 239.5);
        cam.pose = WorldToCamera::look_at(DVec3::new(x, 0.0, d), DVec3::new(x, 0.0, 0.0), DVec3::Y)
            .unwrap();
        cam
    }

    #[test]
    fn a_plane_seen_head_on_has_footprint_depth_over_focal_length() {
        let plane = square(4.0, 0.0, 8);
        for (d, f) in [(10.0, 500.0), (3.0, 1200.0), (250.0, 800.0)] {
            let fp = pixel_footprint(&plane, &[camera_above(0.0, d, f)]).unwrap();
            assert!((fp / (d / f) - 1.0).abs() < 1e-6, "{fp} vs {}", d / f);
        }
        // the finest camera decides; one that does not see the plane is ignored
        let cams = [
            camera_above(0.0, 20.0, 500.0),
            camera_above(0.0, 10.0, 500.0),
            // from below, coarser (back faces count: occlusion and facing are ignored)
            camera_above(0.0, -5.0, 100.0),
            camera_above(500.0, 10.0, 5000.0),
        ];
        let fp = pixel_footprint(&plane, &cams).unwrap();
        assert!((fp - 10.0 / 500.0).abs() < 1e-9, "{fp}");
    }

    #[test]
    fn a_point_behind_or_outside_the_frame_has_no_footprint() {
        let cam = camera_above(0.0, 10.0, 500.0);
        assert!(point_footprint(&cam, DVec3::new(0.0, 0.0, 0.0)).is_some());
        assert!(point_footprint(&cam, DVec3::new(0.0, 0.0, 20.0)).is_none());
        // 500 * 7 / 10 = 350 px from the centre, beyond the 320 px half width
        assert!(point_footprint(&cam, DVec3::new(7.0, 0.0, 0.0)).is_none());
        assert!(pixel_footprint(&square(4.0, 100.0, 4), &[cam]).is_none());
        assert!(pixel_footprint(&square(4.0, 0.0, 4), &[]).is_none());
    }

    #[test]
    fn a_part_seen_twice_as_close_gets_twice_the_resolution() {
        let plane = square(4.0, 0.0, 8);
        let far = auto_resolution(&plane, &[camera_above(0.0, 20.0, 500.0)], 4096).unwrap();
        let near = auto_resolution(&plane, &[camera_above(0.0, 10.0, 500.0)], 4096).unwrap();
        assert_eq!(far.footprint_m, Some(0.04));
        // 4 m at 0.04 m per texel is 100 texels per side before the packing efficiency
        assert!((100..=160).contains(&far.resolution), "{far:?}");
        let ratio = near.resolution as f64 / far.resolution as f64;
        assert!((ratio - 2.0).abs() < 0.15, "{near:?} vs {far:?}");
        assert_eq!(near.resolution % 16, 0);
        // the budget caps it; an unseen part gets the minimum
        let capped = auto_resolution(&plane, &[camera_above(0.0, 2.0, 1000.0)], 256).unwrap();
        assert_eq!(capped.footprint_m, Some(0.002));
        assert_eq!(capped.resolution, 256);
        let unseen = auto_resolution(&plane, &[camera_above(100.0, 10.0, 500.0)], 4096).unwrap();
        assert_eq!(unseen.resolution, AUTO_ATLAS_MIN);
        assert_eq!(unseen.footprint_m, None);
    }

    #[test]
    fn resolution_rule_extremes() {
        // 16 m^2 at 0.1 m and full packing: 40 texels, below the minimum
        assert_eq!(resolution_for(16.0, 0.1, 1.0, 2048), AUTO_ATLAS_MIN);
        // 16 m^2 at 0.01 m, half packed: sqrt(320000) = 565.7, up to 576
        assert_eq!(resolution_for(16.0, 0.01, 0.5, 2048), 576);
        assert_eq!(resolution_for(16.0, 0.001, 0.5, 2048), 2048);
        assert_eq!(resolution_for(16.0, 0.01, 0.0, 2048), 2048);
        assert_eq!(resolution_for(0.0, 0.0, 0.0, 2048), AUTO_ATLAS_MIN);
        assert_eq!(resolution_for(1e30, 1e-30, 1e-30, 16384), 16384);
    }
}
