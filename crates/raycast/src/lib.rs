//! Ray queries against triangle meshes, usable without the path tracer: every Embree call of
//! igi lives in [`embree`] (device, triangle scene, closest hit, occlusion, the
//! `rtcIntersect1M` / `rtcOccluded1M` streams). The path tracer (`igi-render`), the surface
//! light field (`igi-lightfield`), pose refinement (`igi-capture`) and the solver use it.
//!
//! Everything is f32 with glam vectors: [`RtScene`] (built from meshes, queried from many
//! threads at once), [`Hit`], [`RaySegment`], and [`offset_origin`], the one rule for moving a
//! secondary ray's origin off the surface it leaves.

pub mod embree;

pub use embree::{Hit, MeshRef, RaySegment, RtScene, PACKET};

use glam::Vec3;

/// Errors of the ray-query layer.
#[derive(Debug, thiserror::Error)]
pub enum RaycastError {
    /// An Embree call failed (`what`: the call, e.g. "creating the Embree scene").
    #[error("Embree: {what}: {source}")]
    Embree {
        what: &'static str,
        #[source]
        source: embree::EmbreeCode,
    },
    /// Embree numbered the meshes of a scene out of order.
    #[error("Embree: Embree gave geometry id {id} to mesh {mesh}; expected sequential ids")]
    EmbreeGeometryId { id: u32, mesh: usize },
}

/// Offsets a ray origin off a surface along `n`, by an amount that scales with the coordinates.
#[inline]
pub fn offset_origin(p: Vec3, n: Vec3) -> Vec3 {
    let scale = 1.0 + p.abs().max_element();
    p + n * (3e-5 * scale)
}

/// The scene of `meshes` (mesh `k` reports `geom = k`).
pub fn rt_scene_of(meshes: &[igi_geometry::TriMesh]) -> Result<RtScene, RaycastError> {
    let parts: Vec<MeshRef> = meshes
        .iter()
        .map(|m| (&m.positions[..], &m.indices[..]))
        .collect();
    RtScene::new(&parts)
}
