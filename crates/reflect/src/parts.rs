//! The parts of a site that the solver recovers: each input mesh gets a texture atlas
//! (`igi_geometry::atlas`) whose texel caches give the world position and normal of every texel
//! centre that lies on the surface. A prepared site (`igi prepare`) gives one part per voxel and
//! one for the terrain, with the atlases and caches it already holds; their meshes stay on disk
//! and the solver loads, per voxel, only the levels that voxel's solve needs.
//!
//! A part's atlas resolution is fixed ([`build_parts`]) or chosen from the photographs
//! ([`build_parts_auto`], `igi solve --atlas auto`: one texel per pixel of the finest pixel
//! footprint on the part, within a memory budget, with large meshes cut into several parts; see
//! [`crate::atlas_size`]).

use crate::atlas_size::{plan_parts, AtlasChoice};
use crate::ReflectError;
use igi_camera::Camera;
use igi_geometry::atlas::{build_atlas, Atlas, AtlasOptions};
use igi_geometry::{SiteStore, TriMesh, VoxelId};
use igi_imaging::HdrImage;
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
                .ok_or_else(|| ReflectError::NoTerrain(self.site.clone())),
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
    /// The resolving pixel footprint of the photographs on the part (metres) when `--atlas auto`
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

impl AsRef<Part> for Part {
    fn as_ref(&self) -> &Part {
        self
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
                    return Err(ReflectError::AtlasSize {
                        path: folder.join(f),
                        width: im.width,
                        height: im.height,
                        expected: res,
                    });
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

/// The parts a fresh solve starts from: the prepared site's (`store`) when there is one, else
/// the site's `meshes` (files), each named by its file stem, packed at `atlas_resolution` or, with `atlas_auto` (both from `SolveOptions`),
/// cut and sized from the photographs' `cameras` ([`build_parts_auto`]).
pub fn site_parts(
    meshes: &[std::path::PathBuf],
    store: Option<&SiteStore>,
    atlas_resolution: u32,
    atlas_auto: Option<crate::atlas_size::AutoAtlas>,
    cameras: &[Camera],
) -> Result<Vec<Part>, ReflectError> {
    if let Some(store) = store {
        return prepared_parts(store);
    }
    let meshes = meshes
        .iter()
        .map(|m| {
            let name = m
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default();
            Ok((name, igi_geometry::read_mesh(m)?))
        })
        .collect::<Result<Vec<_>, ReflectError>>()?;
    match atlas_auto {
        None => build_parts(meshes, atlas_resolution),
        Some(auto) => build_parts_auto(meshes, cameras, auto.max),
    }
}

/// Builds an atlas of `resolution` texels per side for each named mesh (normals are computed
/// when a mesh has none). Names must be unique; they name the output files.
pub fn build_parts(
    meshes: Vec<(String, TriMesh)>,
    resolution: u32,
) -> Result<Vec<Part>, ReflectError> {
    build_parts_with(meshes, |_, _| {
        Ok(AtlasChoice {
            resolution,
            footprint_m: None,
            max: resolution,
        })
    })
}

/// [`build_parts`] for `--atlas auto`: meshes cut into parts and each part's resolution chosen
/// from the photographs' `cameras` by [`plan_parts`], at most `max` texels per side.
pub fn build_parts_auto(
    meshes: Vec<(String, TriMesh)>,
    cameras: &[Camera],
    max: u32,
) -> Result<Vec<Part>, ReflectError> {
    let planned = plan_parts(meshes, cameras, max)?;
    let choices: std::collections::HashMap<String, AtlasChoice> =
        planned.iter().map(|p| (p.name.clone(), p.choice)).collect();
    let meshes = planned.into_iter().map(|p| (p.name, p.mesh)).collect();
    build_parts_with(meshes, |name, _| Ok(choices[name]))
}

/// [`build_parts`] with each part's atlas resolution chosen by `choose` from its name and mesh
/// (with normals).
pub fn build_parts_with(
    meshes: Vec<(String, TriMesh)>,
    choose: impl Fn(&str, &TriMesh) -> Result<AtlasChoice, ReflectError> + Sync,
) -> Result<Vec<Part>, ReflectError> {
    crate::atlas_size::check_names(meshes.iter().map(|(n, _)| n.as_str()), "site meshes")?;
    meshes
        .into_par_iter()
        .map(|(name, mut mesh)| {
            if mesh.normals.is_none() {
                mesh.compute_vertex_normals();
            }
            let choice = choose(&name, &mesh)?;
            let atlas = atlas_for(&name, &mesh, &choice)?;
            if let Some(f) = choice.footprint_m {
                tracing::info!(
                    "part {name}: atlas {} texels per side, texel {:.4} m for a resolving pixel footprint of {f:.4} m",
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

/// The atlas of part `name` at the chosen resolution; with a footprint, grown in steps of 16
/// texels (up to `choice.max`) until its texels are no larger than the footprint (the trial
/// atlas that chose the resolution packs a little differently).
fn atlas_for(name: &str, mesh: &TriMesh, choice: &AtlasChoice) -> Result<Atlas, ReflectError> {
    let mut atlas = part_atlas(name, mesh, choice.resolution)?;
    let Some(f) = choice.footprint_m else {
        return Ok(atlas);
    };
    for _ in 0..4 {
        let res = atlas.resolution as u32;
        if atlas.texel_size <= f || res >= choice.max {
            break;
        }
        let grown = (res as f64 * atlas.texel_size / f / 16.0).ceil() as u32 * 16;
        let r = grown.max(res + 16).min(choice.max);
        atlas = part_atlas(name, mesh, r)?;
    }
    Ok(atlas)
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
    .map_err(|e| ReflectError::Atlas {
        part: name.to_string(),
        source: Box::new(e),
    })
}

/// A 4 m square in z = 0 as one part `ground` on an atlas of `res` texels per side (the tests'
/// smallest site).
#[cfg(test)]
pub(crate) fn square_part(res: u32) -> Vec<Part> {
    let mut m = TriMesh::default();
    for [x, y] in [[-2.0, -2.0], [2.0, -2.0], [2.0, 2.0], [-2.0, 2.0]] {
        m.positions.push([x, y, 0.0]);
    }
    m.indices = vec![[0, 1, 2], [0, 2, 3]];
    m.compute_vertex_normals();
    build_parts(vec![("ground".into(), m)], res).unwrap()
}
