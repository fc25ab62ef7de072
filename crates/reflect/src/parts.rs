//! The parts of a site that the solver recovers: each input mesh gets a texture atlas
//! (`igi_geometry::atlas`) whose texel caches give the world position and normal of every texel
//! centre that lies on the surface.

use crate::ReflectError;
use glam::{Vec2, Vec3};
use igi_geometry::atlas::{build_atlas, AtlasOptions};
use igi_geometry::TriMesh;
use igi_imaging::HdrImage;
use rayon::prelude::*;

/// A texel whose centre lies on the surface.
#[derive(Clone, Copy, Debug)]
pub struct Texel {
    /// Index into the atlas image: `row * resolution + column`.
    pub index: u32,
    pub position: Vec3,
    pub normal: Vec3,
}

/// The covered texels of one atlas.
#[derive(Clone, Debug)]
pub struct TexelCache {
    pub resolution: usize,
    pub texels: Vec<Texel>,
}

impl TexelCache {
    /// Texture coordinate of a texel centre (FORMATS.md: row 0 at the top, v up).
    pub fn uv(&self, index: u32) -> Vec2 {
        let r = self.resolution;
        let (x, y) = (index as usize % r, index as usize / r);
        Vec2::new((x as f32 + 0.5) / r as f32, 1.0 - (y as f32 + 0.5) / r as f32)
    }
}

/// One part of the site: a mesh with atlas UVs and its texel cache.
pub struct Part {
    pub name: String,
    /// The mesh with atlas UVs (vertices split along chart borders).
    pub mesh: TriMesh,
    pub texel_size: f64,
    pub cache: TexelCache,
    /// 1 on covered texels, 0.5 on gutter texels, 0 elsewhere.
    pub coverage: HdrImage,
}

impl Part {
    pub fn resolution(&self) -> usize {
        self.cache.resolution
    }
}

/// Builds an atlas of `resolution` texels per side for each named mesh (normals are computed
/// when a mesh has none). Names must be unique; they name the output files.
pub fn build_parts(meshes: Vec<(String, TriMesh)>, resolution: u32) -> Result<Vec<Part>, ReflectError> {
    for (i, (a, _)) in meshes.iter().enumerate() {
        if meshes[..i].iter().any(|(b, _)| b == a) {
            return Err(ReflectError::Invalid(format!("two site meshes are both named `{a}`")));
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
            let atlas = build_atlas(&mesh, AtlasOptions { resolution, ..AtlasOptions::default() })
                .map_err(|e| ReflectError::Invalid(format!("atlas of `{name}`: {e}")))?;
            let res = atlas.resolution;
            let texels = (0..res * res)
                .filter(|&i| atlas.coverage.pixels[i][0] == 1.0)
                .map(|i| Texel {
                    index: i as u32,
                    position: Vec3::from_array(atlas.position.pixels[i]),
                    normal: Vec3::from_array(atlas.normal.pixels[i]).normalize_or(Vec3::Z),
                })
                .collect();
            Ok(Part {
                name,
                mesh: atlas.mesh,
                texel_size: atlas.texel_size,
                cache: TexelCache { resolution: res, texels },
                coverage: atlas.coverage,
            })
        })
        .collect()
}
