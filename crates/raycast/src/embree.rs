//! Every call into Embree lives in this module: device, triangle scene, closest-hit and
//! occlusion queries (single rays and the `rtcIntersect1M` / `rtcOccluded1M` streams).
//!
//! The rest of the crate sees only [`RtScene`], [`Hit`] and [`RaySegment`], all in f32 with glam
//! vectors, so the ray-tracing back end can be swapped without touching the integrator.

use crate::RaycastError;
use embree3::{
    BufferUsage, Device, Format, GeometryKind, Hit8, IntersectContext, Ray, Ray8, RayHit, RayHit8,
    Scene, SceneFlags, ValidMask, ValidMaskN,
};
use glam::{Vec2, Vec3};

/// A mesh as the scene reads it: vertex positions and triangles (indices into them).
pub type MeshRef<'a> = (&'a [[f32; 3]], &'a [[u32; 3]]);

/// Closest hit of a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Distance along the ray, in units of the ray direction's length.
    pub t: f32,
    /// Index of the mesh, in the order the meshes were given to [`RtScene::new`].
    pub geom: u32,
    /// Index of the triangle inside its mesh (in the index list given for that mesh).
    pub prim: u32,
    /// Barycentric coordinates (b1, b2) of the hit: p = (1 - b1 - b2) v0 + b1 v1 + b2 v2.
    pub bary: Vec2,
    /// Geometric normal (v1 - v0) x (v2 - v0), not normalised, as Embree reports it.
    pub ng: Vec3,
}

/// A ray for the batched queries: origin, direction, and the segment [tnear, tfar].
#[derive(Clone, Copy, Debug)]
pub struct RaySegment {
    pub origin: Vec3,
    pub dir: Vec3,
    pub tnear: f32,
    pub tfar: f32,
}

/// A committed Embree triangle scene, safe to query from many threads at once.
pub struct RtScene {
    // `scene` holds its own clone of the device; the field order drops the scene first.
    scene: Scene<'static>,
    _device: Device,
    n_meshes: u32,
}

/// An Embree error code as an error (`embree3::Error` only implements `Display`).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct EmbreeCode(pub embree3::Error);

fn embree_err(what: &'static str, e: embree3::Error) -> RaycastError {
    RaycastError::Embree {
        what,
        source: EmbreeCode(e),
    }
}

impl RtScene {
    /// Builds a scene of triangle meshes. `meshes[k] = (positions, triangles)`; hits report
    /// `geom = k`. Meshes with no triangles are allowed (they are simply never hit).
    /// The caller removes degenerate triangles beforehand (see `scene.rs`); Embree itself
    /// ignores them too, so they never produce hits.
    pub fn new(meshes: &[MeshRef]) -> Result<Self, RaycastError> {
        let device = Device::new().map_err(|e| embree_err("creating the Embree device", e))?;
        let mut scene = device
            .create_scene()
            .map_err(|e| embree_err("creating the Embree scene", e))?;
        // ROBUST: watertight-ish traversal so rays do not slip between neighbouring triangles
        // (a leak would let sky light into closed rooms and break the furnace tests).
        scene.set_flags(SceneFlags::ROBUST);
        for (k, (positions, tris)) in meshes.iter().enumerate() {
            let mut g = device
                .create_geometry(GeometryKind::TRIANGLE)
                .map_err(|e| embree_err("creating a triangle geometry", e))?;
            // Embree needs count >= 1: an empty mesh gets one degenerate triangle at the origin,
            // which Embree never reports as hit.
            let (pos, idx): (Vec<[f32; 3]>, Vec<[u32; 3]>) =
                if tris.is_empty() || positions.is_empty() {
                    (vec![[0.0; 3]; 3], vec![[0, 0, 0]])
                } else {
                    (positions.to_vec(), tris.to_vec())
                };
            // Vertex buffers need 16 bytes of padding after the last element: allocate one spare
            // vertex (stride 12, count n + 1) and leave it at zero.
            {
                let mut vb = g
                    .set_new_buffer::<[f32; 3]>(
                        BufferUsage::VERTEX,
                        0,
                        Format::FLOAT3,
                        12,
                        pos.len() + 1,
                    )
                    .map_err(|e| embree_err("allocating a vertex buffer", e))?;
                vb[..pos.len()].copy_from_slice(&pos);
                vb[pos.len()] = [0.0; 3];
            }
            {
                let mut ib = g
                    .set_new_buffer::<[u32; 3]>(BufferUsage::INDEX, 0, Format::UINT3, 12, idx.len())
                    .map_err(|e| embree_err("allocating an index buffer", e))?;
                ib.copy_from_slice(&idx);
            }
            let g = g.commit();
            let id = scene.attach_geometry(&g);
            if id != k as u32 {
                return Err(RaycastError::EmbreeGeometryId { id, mesh: k });
            }
        }
        scene.commit();
        let err = device.get_error();
        if err != embree3::Error::NONE {
            return Err(embree_err("committing the Embree scene", err));
        }
        Ok(RtScene {
            scene,
            _device: device,
            n_meshes: meshes.len() as u32,
        })
    }

    /// Number of meshes the scene was built from.
    pub fn mesh_count(&self) -> u32 {
        self.n_meshes
    }

    /// Closest hit along `origin + t dir` for t in [tnear, tfar].
    #[inline]
    pub fn intersect(&self, origin: Vec3, dir: Vec3, tnear: f32, tfar: f32) -> Option<Hit> {
        let mut ctx = IntersectContext::incoherent();
        let mut rh = RayHit::from(Ray::segment(origin.to_array(), dir.to_array(), tnear, tfar));
        self.scene.intersect(&mut ctx, &mut rh);
        to_hit(&rh)
    }

    /// Whether anything blocks `origin + t dir` for t in [tnear, tfar].
    #[inline]
    pub fn occluded(&self, origin: Vec3, dir: Vec3, tnear: f32, tfar: f32) -> bool {
        let mut ctx = IntersectContext::incoherent();
        let mut ray = Ray::segment(origin.to_array(), dir.to_array(), tnear, tfar);
        self.scene.occluded(&mut ctx, &mut ray)
    }

    /// Closest hits of a batch of rays through Embree's stream API (`rtcIntersect1M`).
    pub fn intersect_batch(&self, rays: &[RaySegment], coherent: bool) -> Vec<Option<Hit>> {
        let mut ctx = stream_context(coherent);
        let mut rh: Vec<RayHit> = embree_rays(rays).map(RayHit::from).collect();
        self.scene.intersect_stream_aos(&mut ctx, &mut rh);
        rh.iter().map(to_hit).collect()
    }

    /// Occlusion of a batch of rays through Embree's stream API (`rtcOccluded1M`).
    pub fn occluded_batch(&self, rays: &[RaySegment], coherent: bool) -> Vec<bool> {
        let mut ctx = stream_context(coherent);
        let mut rs: Vec<Ray> = embree_rays(rays).collect();
        self.scene.occluded_stream_aos(&mut ctx, &mut rs);
        rs.iter().map(|r| r.tfar == f32::NEG_INFINITY).collect()
    }

    /// Closest hits of up to [`PACKET`] rays through Embree's 8-wide packet
    /// (`rtcIntersect8`): `out[i]` for `rays[i]`. A single ray goes through `rtcIntersect1`.
    /// `coherent` marks rays that start close together in similar directions (a pixel's camera
    /// rays, a tile's sun rays), for which packet traversal pays.
    pub fn intersect_packet(&self, rays: &[RaySegment], coherent: bool, out: &mut [Option<Hit>]) {
        assert!(rays.len() <= PACKET && out.len() >= rays.len());
        if rays.len() <= 1 {
            if let Some(r) = rays.first() {
                out[0] = self.intersect(r.origin, r.dir, r.tnear, r.tfar);
            }
            return;
        }
        let mut ctx = stream_context(coherent);
        let (ray, valid) = packet8(rays);
        let mut rh = RayHit8 {
            ray,
            hit: Hit8::new(),
        };
        self.scene.intersect8(&mut ctx, &mut rh, &valid.0);
        for (i, o) in out.iter_mut().enumerate().take(rays.len()) {
            *o = (rh.hit.geomID[i] != u32::MAX).then(|| Hit {
                t: rh.ray.tfar[i],
                geom: rh.hit.geomID[i],
                prim: rh.hit.primID[i],
                bary: Vec2::new(rh.hit.u[i], rh.hit.v[i]),
                ng: Vec3::new(rh.hit.Ng_x[i], rh.hit.Ng_y[i], rh.hit.Ng_z[i]),
            });
        }
    }

    /// Occlusion of up to [`PACKET`] rays through Embree's 8-wide packet (`rtcOccluded8`):
    /// `out[i]` for `rays[i]`. A single ray goes through `rtcOccluded1`.
    pub fn occluded_packet(&self, rays: &[RaySegment], coherent: bool, out: &mut [bool]) {
        assert!(rays.len() <= PACKET && out.len() >= rays.len());
        if rays.len() <= 1 {
            if let Some(r) = rays.first() {
                out[0] = self.occluded(r.origin, r.dir, r.tnear, r.tfar);
            }
            return;
        }
        let mut ctx = stream_context(coherent);
        let (mut ray, valid) = packet8(rays);
        self.scene.occluded8(&mut ctx, &mut ray, &valid.0);
        for (i, o) in out.iter_mut().enumerate().take(rays.len()) {
            *o = ray.tfar[i] == f32::NEG_INFINITY;
        }
    }

    /// Axis-aligned bounds of the committed scene (lower, upper).
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let b = self.scene.get_bounds();
        (
            Vec3::new(b.lower_x, b.lower_y, b.lower_z),
            Vec3::new(b.upper_x, b.upper_y, b.upper_z),
        )
    }
}

/// The context of a ray stream: coherent for camera-like bundles, else incoherent.
fn stream_context(coherent: bool) -> IntersectContext {
    if coherent {
        IntersectContext::coherent()
    } else {
        IntersectContext::incoherent()
    }
}

/// The width of [`RtScene::intersect_packet`] and [`RtScene::occluded_packet`].
pub const PACKET: usize = 8;

/// Embree reads a packet's valid mask with aligned vector loads: 32 bytes for 8 lanes, which
/// `ValidMaskN<8>` (an array of `i32`) does not promise on its own.
#[repr(C, align(32))]
struct Aligned<T>(T);

/// An 8-wide Embree packet of `rays` (at most 8), the lanes past them inactive.
#[inline]
fn packet8(rays: &[RaySegment]) -> (Ray8, Aligned<ValidMaskN<8>>) {
    let mut ray = Ray8::empty();
    let mut valid = [ValidMask::Invalid; 8];
    for (i, r) in rays.iter().enumerate() {
        ray.org_x[i] = r.origin.x;
        ray.org_y[i] = r.origin.y;
        ray.org_z[i] = r.origin.z;
        ray.dir_x[i] = r.dir.x;
        ray.dir_y[i] = r.dir.y;
        ray.dir_z[i] = r.dir.z;
        ray.tnear[i] = r.tnear;
        ray.tfar[i] = r.tfar;
        ray.id[i] = i as u32;
        valid[i] = ValidMask::Valid;
    }
    (ray, Aligned(ValidMaskN::new(valid)))
}

/// Embree rays for a batch, each carrying its index as its id.
fn embree_rays(rays: &[RaySegment]) -> impl Iterator<Item = Ray> + '_ {
    rays.iter().enumerate().map(|(i, r)| {
        Ray::segment_with_id(
            r.origin.to_array(),
            r.dir.to_array(),
            r.tnear,
            r.tfar,
            i as u32,
        )
    })
}

#[inline]
fn to_hit(rh: &RayHit) -> Option<Hit> {
    if !rh.hit.is_valid() {
        return None;
    }
    Some(Hit {
        t: rh.ray.tfar,
        geom: rh.hit.geomID,
        prim: rh.hit.primID,
        bary: Vec2::new(rh.hit.u, rh.hit.v),
        ng: Vec3::new(rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad() -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
        (
            vec![
                [-1.0, -1.0, 0.0],
                [1.0, -1.0, 0.0],
                [1.0, 1.0, 0.0],
                [-1.0, 1.0, 0.0],
            ],
            vec![[0, 1, 2], [0, 2, 3]],
        )
    }

    #[test]
    fn hits_a_quad_with_correct_t_barycentrics_and_normal() {
        let (p, t) = quad();
        let s = RtScene::new(&[(&p, &t)]).unwrap();
        let h = s
            .intersect(
                Vec3::new(0.5, -0.25, 2.0),
                Vec3::new(0.0, 0.0, -1.0),
                0.0,
                f32::INFINITY,
            )
            .unwrap();
        assert!((h.t - 2.0).abs() < 1e-6);
        assert_eq!(h.geom, 0);
        assert_eq!(h.prim, 0);
        // p = v0 + b1 (v1 - v0) + b2 (v2 - v0): x = -1 + 2 b1 + 2 b2, y = -1 + 2 b2
        let b2 = (-0.25 + 1.0) / 2.0;
        let b1 = (0.5 + 1.0) / 2.0 - b2;
        assert!((h.bary - Vec2::new(b1, b2)).length() < 1e-5, "{:?}", h.bary);
        assert!(h.ng.normalize().abs_diff_eq(Vec3::Z, 1e-6));
        // Misses outside, respects tfar and tnear.
        assert!(s
            .intersect(Vec3::new(1.5, 0.0, 2.0), -Vec3::Z, 0.0, f32::INFINITY)
            .is_none());
        assert!(s
            .intersect(Vec3::new(0.0, 0.0, 2.0), -Vec3::Z, 0.0, 1.9)
            .is_none());
        assert!(s.occluded(Vec3::new(0.0, 0.2, 2.0), -Vec3::Z, 0.0, 2.1));
        assert!(!s.occluded(Vec3::new(0.0, 0.2, 2.0), -Vec3::Z, 0.0, 1.9));
        assert!(!s.occluded(Vec3::new(0.0, 0.2, 2.0), -Vec3::Z, 2.1, 10.0));
    }

    #[test]
    fn batches_match_single_rays_and_empty_meshes_are_fine() {
        let (p, t) = quad();
        let empty_p: Vec<[f32; 3]> = vec![];
        let empty_t: Vec<[u32; 3]> = vec![];
        let s = RtScene::new(&[(&empty_p, &empty_t), (&p, &t)]).unwrap();
        let rays: Vec<RaySegment> = (0..64)
            .map(|i| {
                let x = (i % 8) as f32 * 0.4 - 1.5;
                let y = (i / 8) as f32 * 0.4 - 1.513; // off the quad diagonal x = y
                RaySegment {
                    origin: Vec3::new(x, y, 1.0),
                    dir: -Vec3::Z,
                    tnear: 0.0,
                    tfar: f32::INFINITY,
                }
            })
            .collect();
        let hits = s.intersect_batch(&rays, true);
        let occ = s.occluded_batch(&rays, false);
        let mut n_hit = 0;
        for (i, r) in rays.iter().enumerate() {
            let single = s.intersect(r.origin, r.dir, r.tnear, r.tfar);
            assert_eq!(hits[i], single);
            assert_eq!(occ[i], single.is_some());
            if let Some(h) = single {
                assert_eq!(h.geom, 1);
                n_hit += 1;
            }
        }
        // x, y in {-1.5, -1.1, ..., 1.3}: 5 of the 8 values lie inside [-1, 1] on each axis.
        assert_eq!(n_hit, 25);
        // Packets of every length from 0 to 8 agree with single rays.
        for chunk in rays
            .chunks(3)
            .chain(rays.chunks(8))
            .chain([&rays[..0], &rays[..1]])
        {
            let mut hits = [None; PACKET];
            let mut occ = [false; PACKET];
            for coherent in [false, true] {
                s.intersect_packet(chunk, coherent, &mut hits);
                s.occluded_packet(chunk, coherent, &mut occ);
                for (i, r) in chunk.iter().enumerate() {
                    let single = s.intersect(r.origin, r.dir, r.tnear, r.tfar);
                    assert_eq!(hits[i], single);
                    assert_eq!(occ[i], single.is_some());
                }
            }
        }
    }
}
