//! `igi solve --atlas auto`: how large each part's atlas is, and where a site mesh is cut into
//! several parts.
//!
//! A part's atlas holds as many texels as there are pixels that resolve it, no more: a finer
//! atlas holds detail no photograph resolves (and costs time in every iteration, since the
//! solve's work follows its texels), a coarser one averages detail they do. Each surface point
//! is resolved by the finest photograph that sees it ([`Views`]: in front of the camera, in its
//! frame, not hidden by the site, at no more than the solver's grazing limit), at that
//! photograph's pixel footprint on the surface (depth over focal length, divided by
//! sqrt(cos) for the obliquity: the geometric mean of the footprint's two sides). The part's
//! texel is the footprint that matches texels to those pixels ([`pixel_footprint`]):
//! sqrt(seen area / sum of area / footprint^2). Its resolution follows from its surface area at
//! that texel size ([`resolution_for`]), within `--atlas-max` texels per side (the memory
//! budget of one part).
//!
//! One texel size per mesh is a poor fit for a large mesh: the terrain under a building is seen
//! from a few metres, its far edge from fifty, and one atlas at one texel size puts texels
//! where no photograph resolves them and too few where one does. [`plan_parts`] therefore cuts
//! a mesh into pieces (an exact partition along axis planes, `igi_geometry::voxel::partition`,
//! halving its longest extent) when the mesh would exceed the budget, or when more than
//! [`MISPLACED_LIMIT`] of its texels are misplaced (the texels where the atlas is finer than
//! the photographs, equal to the pixels where it is coarser) and its pieces, each at its own
//! texel, misplace less than [`SPLIT_GAIN`] of them; pieces are cut again by the same rule. A
//! piece of mesh `NAME` is named `NAME-K` (and `NAME-K-L` for a piece of that), `K` counting
//! the pieces in the partition's order.
//!
//! Before issue 37 the texel was the 5th percentile of the finest footprints, without
//! occlusion, facing or obliquity: on a 44 m survey it chose 2 cm texels (5.3 M texels for
//! 1.6 M photographed pixels) and a first iteration 50 times slower than `--atlas 512`'s
//! (docs/BENCHMARKS.md).

use crate::ReflectError;
use glam::DVec3;
use igi_camera::Camera;
use igi_geometry::atlas::{build_atlas, AtlasOptions};
use igi_geometry::voxel::{partition, VoxelGrid};
use igi_geometry::TriMesh;
use igi_raycast::{offset_origin, MeshRef, RtScene};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// `igi solve --atlas auto`: each part's atlas resolution follows from the photographs (see
/// [`auto_resolution`]), at most `max` texels per side (the memory budget); larger meshes are
/// cut into parts ([`plan_parts`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct AutoAtlas {
    pub max: u32,
}

/// The smallest resolution `--atlas auto` gives a part (also a part no photograph sees).
pub const AUTO_ATLAS_MIN: u32 = 64;
/// Resolution of the trial atlas whose covered fraction measures the packing efficiency.
const TRIAL_RESOLUTION: u32 = 128;
/// At most about this many surface points are sampled per part.
const MAX_FOOTPRINT_SAMPLES: usize = 20_000;
/// Chosen resolutions are multiples of this.
const RESOLUTION_STEP: u32 = 16;
/// A mesh is cut when its pieces misplace less than this fraction of its misplaced texels (a
/// halving takes out only part of a smooth change of footprint; the next halvings the rest).
pub const SPLIT_GAIN: f64 = 0.95;
/// A mesh is considered for a cut (within the budget) when more than this fraction of its
/// texels are misplaced.
pub const MISPLACED_LIMIT: f64 = 0.25;
/// A mesh that needs fewer texels than this is not cut for the gain alone (its pieces would
/// be mostly gutter and minimum-size atlases).
const MIN_SPLIT_TEXELS: f64 = (4 * AUTO_ATLAS_MIN * AUTO_ATLAS_MIN) as f64;
/// Cuts nest at most this deep (up to 8^6 pieces of one mesh in principle; in practice a
/// handful).
const MAX_SPLIT_DEPTH: u32 = 6;
/// Packing efficiency assumed when deciding whether a mesh fits the budget (the trial atlas
/// measures the real one afterwards).
const PLANNING_EFFICIENCY: f64 = 0.5;

/// The atlas resolution chosen for a part.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AtlasChoice {
    /// Texels per side.
    pub resolution: u32,
    /// The pixel footprint on the part that decided it (metres per pixel, [`pixel_footprint`]);
    /// `None` for a fixed resolution or a part no photograph sees.
    pub footprint_m: Option<f64>,
    /// The most texels per side the part may grow to when its packed atlas comes out coarser
    /// than the footprint (the trial atlas's packing differs a little from the final one's).
    pub max: u32,
}

/// A part as [`plan_parts`] cut it: its name, mesh (with normals) and atlas resolution.
#[derive(Clone, Debug)]
pub struct PlannedPart {
    pub name: String,
    pub mesh: TriMesh,
    pub choice: AtlasChoice,
}

/// A point on a mesh with the surface area it stands for and its face's unit normal.
#[derive(Clone, Copy, Debug)]
struct Sample {
    p: DVec3,
    area: f64,
    n: DVec3,
}

/// Points on `mesh` with the surface area each stands for: for a mesh of at most
/// [`MAX_FOOTPRINT_SAMPLES`] triangles, about that many points spread by area (at least one per
/// triangle, a deterministic low-discrepancy pattern inside each); for a larger one, the
/// centroid of every k-th triangle.
fn surface_samples(mesh: &TriMesh) -> Vec<Sample> {
    let n = mesh.triangle_count();
    let corners = |t: usize| mesh.triangle(t).map(|c| DVec3::from(c.map(f64::from)));
    let normal = |[a, b, c]: [DVec3; 3]| (b - a).cross(c - a).normalize_or_zero();
    if n > MAX_FOOTPRINT_SAMPLES {
        let stride = n.div_ceil(MAX_FOOTPRINT_SAMPLES);
        return (0..n)
            .step_by(stride)
            .map(|t| {
                let [a, b, c] = corners(t);
                Sample {
                    p: (a + b + c) / 3.0,
                    area: mesh.triangle_area(t) * stride as f64,
                    n: normal([a, b, c]),
                }
            })
            .collect();
    }
    let total = mesh.total_area();
    let mut out = Vec::new();
    for t in 0..n {
        let area = mesh.triangle_area(t);
        if !(area.is_finite() && area > 0.0) {
            continue;
        }
        let k = ((area / total * MAX_FOOTPRINT_SAMPLES as f64).ceil() as usize)
            .clamp(1, MAX_FOOTPRINT_SAMPLES);
        let [a, b, c] = corners(t);
        for j in 0..k {
            // R2 sequence (Roberts 2018), warped uniformly onto the triangle
            let r1 = (0.5 + (j as f64 + 0.5) * 0.754_877_666_246_692_7).fract();
            let r2 = (0.5 + (j as f64 + 0.5) * 0.569_840_290_998_053_3).fract();
            let s = r1.sqrt();
            out.push(Sample {
                p: a * (1.0 - s) + b * (s * (1.0 - r2)) + c * (s * r2),
                area: area / k as f64,
                n: normal([a, b, c]),
            });
        }
    }
    out
}

/// What the photographs see of a site: their cameras, and the whole site as the occluder of
/// every visibility test (a piece of a mesh is hidden by the rest of the site too).
pub struct Views<'a> {
    cameras: &'a [Camera],
    scene: RtScene,
    /// The solver's grazing limit (`WeightRules::min_cos`): a photograph that sees a point
    /// more obliquely gives it no observation, so it resolves nothing there.
    min_cos: f64,
}

impl<'a> Views<'a> {
    /// The views of `cameras` on the site made of `site` (every mesh, cut or not).
    pub fn new(cameras: &'a [Camera], site: &[&TriMesh]) -> Result<Self, ReflectError> {
        let refs: Vec<MeshRef> = site
            .iter()
            .map(|m| (&m.positions[..], &m.indices[..]))
            .collect();
        Ok(Views {
            cameras,
            scene: RtScene::new(&refs)?,
            min_cos: crate::weights::WeightRules::default().min_cos as f64,
        })
    }

    /// The finest footprint on the surface at `p` (face normal `n`) of the photographs that
    /// see it, `None` when none does.
    fn finest(&self, p: DVec3, n: DVec3) -> Option<f64> {
        self.cameras
            .iter()
            .filter_map(|cam| self.surface_footprint(cam, p, n))
            .min_by(f64::total_cmp)
    }

    /// The footprint of one pixel of `cam` on the surface at `p` (normal `n`, either side
    /// facing): [`point_footprint`] / sqrt(cos), `None` when `cam` does not see `p`, sees it
    /// beyond the grazing limit or through the site.
    fn surface_footprint(&self, cam: &Camera, p: DVec3, n: DVec3) -> Option<f64> {
        let fp = point_footprint(cam, p)?;
        let to_cam = cam.center_world() - p;
        let dist = to_cam.length();
        let facing = n.dot(to_cam) / dist;
        if !(facing.abs() >= self.min_cos) {
            return None;
        }
        let side = if facing > 0.0 { n } else { -n };
        let origin = offset_origin(p.as_vec3(), side.as_vec3());
        let ray = cam.center_world().as_vec3() - origin;
        let len = ray.length();
        let hidden = self
            .scene
            .occluded(origin, ray / len, 0.0, len * (1.0 - 1e-4));
        (!hidden).then(|| fp / facing.abs().sqrt())
    }
}

/// How the photographs resolve a mesh: the texel that matches texels to resolving pixels, and
/// the texels that texel misplaces.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Resolved {
    /// [`pixel_footprint`]'s texel; `None` when no photograph sees the mesh.
    texel: Option<f64>,
    /// Half the sum over the seen surface of |1 / texel^2 - 1 / footprint^2| x area: the
    /// texels finer than the photographs there plus the pixels coarser than the atlas, halved
    /// (the two are equal).
    misplaced: f64,
}

/// The resolution of `mesh` in the photographs of `views` ([`Resolved`]).
fn resolve(mesh: &TriMesh, views: &Views) -> Resolved {
    let seen: Vec<(f64, f64)> = surface_samples(mesh)
        .par_iter()
        .filter_map(|s| Some((views.finest(s.p, s.n)?, s.area)))
        .collect();
    let area: f64 = seen.iter().map(|s| s.1).sum();
    let pixels: f64 = seen.iter().map(|(f, a)| a / (f * f)).sum();
    if !(pixels > 0.0 && area > 0.0) {
        return Resolved::default();
    }
    let texel = (area / pixels).sqrt();
    let misplaced = 0.5
        * seen
            .iter()
            .map(|(f, a)| a * (1.0 / (texel * texel) - 1.0 / (f * f)).abs())
            .sum::<f64>();
    Resolved {
        texel: Some(texel),
        misplaced,
    }
}

/// The pixel footprint that decides a mesh's texel size, in metres, `None` when no photograph
/// sees any of it: sqrt(seen area / sum of area / footprint^2) over points spread by area
/// (about 20 000, at least one per triangle), each at the finest footprint on the surface of
/// the photographs that see it ([`Views`]), so that the atlas holds as many texels as the
/// pixels that resolve the mesh. Lens distortion's change of scale is ignored.
pub fn pixel_footprint(mesh: &TriMesh, views: &Views) -> Option<f64> {
    resolve(mesh, views).texel
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

/// The atlas resolution of one part for `--atlas auto`: one texel per resolving pixel
/// ([`pixel_footprint`]), in an atlas large enough for the part's surface area at the packing
/// efficiency measured on a trial atlas of 128 texels per side (its covered fraction). A part
/// no camera sees gets [`AUTO_ATLAS_MIN`]. `mesh` needs normals (for the trial atlas).
pub fn auto_resolution(
    mesh: &TriMesh,
    views: &Views,
    max: u32,
) -> Result<AtlasChoice, ReflectError> {
    choice_at(mesh, pixel_footprint(mesh, views), max)
}

/// [`auto_resolution`] for a mesh whose footprint is already known.
fn choice_at(
    mesh: &TriMesh,
    footprint: Option<f64>,
    max: u32,
) -> Result<AtlasChoice, ReflectError> {
    let Some(footprint) = footprint else {
        return Ok(AtlasChoice {
            resolution: AUTO_ATLAS_MIN,
            footprint_m: None,
            max: AUTO_ATLAS_MIN,
        });
    };
    let trial = build_atlas(
        mesh,
        AtlasOptions {
            resolution: TRIAL_RESOLUTION,
            ..AtlasOptions::default()
        },
    )
    .map_err(|e| ReflectError::TrialAtlas(Box::new(e)))?;
    let efficiency = trial.coverage_fraction();
    Ok(AtlasChoice {
        resolution: resolution_for(mesh.total_area(), footprint, efficiency, max),
        footprint_m: Some(footprint),
        max,
    })
}

/// Texels a mesh needs at texels of `footprint` (before packing), 0 when no camera sees it.
fn texels_needed(mesh: &TriMesh, footprint: Option<f64>) -> f64 {
    footprint.map_or(0.0, |f| mesh.total_area() / (f * f))
}

/// The mesh cut in two along its longest extent (and along any other extent at least half as
/// long): the non-empty pieces of an exact partition, in the partition's order.
fn halve(mesh: &TriMesh) -> Vec<TriMesh> {
    let Some((lo, hi)) = mesh.bounds() else {
        return Vec::new();
    };
    let ext: [f64; 3] = std::array::from_fn(|k| (hi[k] - lo[k]) as f64);
    let longest = ext.iter().copied().fold(0.0, f64::max);
    if !(longest.is_finite() && longest > 0.0) {
        return Vec::new();
    }
    // cells of half the longest extent, centred on the box: 2 cells along the longest axis
    // (and along any axis at least half as long), 1 along the others
    let size = 0.5 * longest * (1.0 + 1e-4);
    let origin: [f64; 3] = std::array::from_fn(|k| {
        let c = 0.5 * (lo[k] as f64 + hi[k] as f64);
        if ext[k] > 0.5 * longest {
            c - size
        } else {
            c - 0.5 * size
        }
    });
    let Ok(grid) = VoxelGrid::new(origin, size) else {
        return Vec::new();
    };
    partition(mesh, &grid)
        .into_values()
        .filter(|m| m.triangle_count() > 0)
        .collect()
}

/// Cuts each named mesh into parts and chooses every part's resolution (`--atlas auto`); see
/// the module overview for the rule. Meshes get normals when they have none. Fails when a
/// piece's name is taken by another mesh.
pub fn plan_parts(
    meshes: Vec<(String, TriMesh)>,
    cameras: &[Camera],
    max: u32,
) -> Result<Vec<PlannedPart>, ReflectError> {
    check_names(meshes.iter().map(|(n, _)| n.as_str()), "site meshes")?;
    let site: Vec<&TriMesh> = meshes.iter().map(|(_, m)| m).collect();
    let views = Views::new(cameras, &site)?;
    let mut out = Vec::new();
    for (name, mut mesh) in meshes {
        if mesh.normals.is_none() {
            mesh.compute_vertex_normals();
        }
        let resolved = resolve(&mesh, &views);
        plan_mesh(name, mesh, resolved, &views, max, 0, &mut out)?;
    }
    check_names(out.iter().map(|p| p.name.as_str()), "parts").map_err(|e| {
        ReflectError::PieceName {
            source: Box::new(e),
        }
    })?;
    Ok(out)
}

/// [`plan_parts`] for one mesh (resolved as `resolved`) at cut depth `depth`, appending to
/// `out`.
fn plan_mesh(
    name: String,
    mesh: TriMesh,
    resolved: Resolved,
    views: &Views,
    max: u32,
    depth: u32,
    out: &mut Vec<PlannedPart>,
) -> Result<(), ReflectError> {
    let need = texels_needed(&mesh, resolved.texel);
    let over_budget = need / PLANNING_EFFICIENCY > (max as f64) * (max as f64);
    let misplaced = resolved.misplaced > MISPLACED_LIMIT * need;
    if depth < MAX_SPLIT_DEPTH && (over_budget || (need > MIN_SPLIT_TEXELS && misplaced)) {
        let pieces: Vec<(TriMesh, Resolved)> = halve(&mesh)
            .into_iter()
            .map(|m| {
                let r = resolve(&m, views);
                (m, r)
            })
            .collect();
        let pieces_misplaced: f64 = pieces.iter().map(|(_, r)| r.misplaced).sum();
        if pieces.len() > 1 && (over_budget || pieces_misplaced < SPLIT_GAIN * resolved.misplaced) {
            tracing::info!(
                "cutting {name} into {} pieces: {need:.0} texels, {:.0} of them misplaced whole, {pieces_misplaced:.0} cut",
                pieces.len(),
                resolved.misplaced
            );
            for (k, (piece, r)) in pieces.into_iter().enumerate() {
                plan_mesh(format!("{name}-{k}"), piece, r, views, max, depth + 1, out)?;
            }
            return Ok(());
        }
    }
    let choice = choice_at(&mesh, resolved.texel, max)?;
    out.push(PlannedPart { name, mesh, choice });
    Ok(())
}

/// Refuses part names that repeat or cannot name files; `what` names them in the message
/// ("site meshes", "parts of the result").
pub(crate) fn check_names<'a>(
    names: impl Iterator<Item = &'a str>,
    what: &'static str,
) -> Result<(), ReflectError> {
    let mut seen = std::collections::HashSet::new();
    for a in names {
        if a.is_empty() || a.contains(['/', '\\']) {
            return Err(ReflectError::UnnamablePart(a.to_string()));
        }
        if !seen.insert(a) {
            return Err(ReflectError::DuplicatePart {
                what,
                name: a.to_string(),
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use igi_camera::WorldToCamera;

    /// The views of `cameras` on a site of `mesh` alone.
    fn views<'a>(mesh: &TriMesh, cameras: &'a [Camera]) -> Views<'a> {
        Views::new(cameras, &[mesh]).unwrap()
    }

    /// [`pixel_footprint`] of `mesh` alone in `cameras`.
    fn footprint(mesh: &TriMesh, cameras: &[Camera]) -> Option<f64> {
        pixel_footprint(mesh, &views(mesh, cameras))
    }

    /// Misplaced texels of `mesh` in the views of `site`.
    fn misplaced_in(mesh: &TriMesh, views: &Views) -> f64 {
        resolve(mesh, views).misplaced
    }

    /// Relative difference.
    fn rel(a: f64, b: f64) -> f64 {
        (a / b - 1.0).abs()
    }

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
        // a 0.4 m square: seen from 3 m or more, cos >= 0.996 everywhere on it
        let plane = square(0.4, 0.0, 8);
        for (d, f) in [(10.0, 500.0), (3.0, 1200.0), (250.0, 800.0)] {
            let fp = footprint(&plane, &[camera_above(0.0, d, f)]).unwrap();
            assert!(fp >= d / f && rel(fp, d / f) < 2e-3, "{fp} vs {}", d / f);
        }
        // the finest camera decides; one that does not see the plane is ignored
        let cams = [
            camera_above(0.0, 20.0, 500.0),
            camera_above(0.0, 10.0, 500.0),
            // from below, coarser (the solver sees both sides of a surface)
            camera_above(0.0, -5.0, 100.0),
            camera_above(500.0, 10.0, 5000.0),
        ];
        let fp = footprint(&plane, &cams).unwrap();
        assert!(rel(fp, 10.0 / 500.0) < 2e-3, "{fp}");
        let below = footprint(&plane, &[camera_above(0.0, -5.0, 100.0)]).unwrap();
        assert!(rel(below, 5.0 / 100.0) < 2e-3, "{below}");
    }

    #[test]
    fn a_plane_seen_obliquely_has_its_footprint_stretched_by_one_over_sqrt_cos() {
        // a 0.2 m square at the origin seen from 10 m away at 60 degrees from its normal
        let plane = square(0.2, 0.0, 4);
        let eye = DVec3::new(10.0 * 60f64.to_radians().sin(), 0.0, 5.0);
        let cam = camera_at(eye, DVec3::ZERO);
        let fp = footprint(&plane, std::slice::from_ref(&cam)).unwrap();
        let expected = 10.0 / 400.0 / 0.5f64.sqrt();
        assert!(rel(fp, expected) < 0.02, "{fp} vs {expected}");
        // beyond the solver's grazing limit (cos 0.1) the camera resolves nothing
        let grazing = camera_at(DVec3::new(10.0, 0.0, 0.5), DVec3::ZERO);
        assert_eq!(footprint(&plane, &[grazing]), None);
    }

    #[test]
    fn a_camera_that_sees_a_part_only_through_a_wall_does_not_decide_its_texel() {
        let plane = square(1.0, 0.0, 4);
        let near = camera_above(0.0, 2.0, 500.0);
        let far = camera_above(0.0, 10.0, 500.0);
        let mut wall = square(3.0, 0.0, 2);
        wall.positions.iter_mut().for_each(|p| p[2] = 1.0);
        let cams = [near, far.clone()];
        // the near camera sits between the wall and the plane: it sees the plane
        let open = pixel_footprint(&plane, &Views::new(&cams, &[&plane]).unwrap()).unwrap();
        assert!(rel(open, 2.0 / 500.0) < 0.02, "{open}");
        // with the wall between both cameras and the plane, nothing sees it
        let walled = Views::new(&cams, &[&plane, &wall]).unwrap();
        assert_eq!(pixel_footprint(&plane, &walled), None);
        // a wall at 5 m hides it from the far camera only... which is the coarser one
        wall.positions.iter_mut().for_each(|p| p[2] = 5.0);
        let high = Views::new(&cams, &[&plane, &wall]).unwrap();
        let fp = pixel_footprint(&plane, &high).unwrap();
        assert!(rel(fp, open) < 1e-9, "{fp}");
        // ...and hides the far camera when the near one is gone
        let only_far = [far];
        let hidden = Views::new(&only_far, &[&plane, &wall]).unwrap();
        assert_eq!(pixel_footprint(&plane, &hidden), None);
    }

    #[test]
    fn the_texel_matches_texels_to_the_pixels_that_resolve_the_part() {
        // two 1 m squares, one seen at 0.01 m per pixel, the other at 0.03 m: 10 000 + 1 111
        // pixels on 2 m^2, a texel of sqrt(2 / 11 111) = 0.0134 m
        let mut two = square(1.0, 0.0, 4);
        two.append(&square(1.0, 5.0, 4));
        let cams = [
            camera_above(0.0, 5.0, 500.0),
            camera_above(5.0, 15.0, 500.0),
        ];
        // each camera's 640 x 480 frame at its height: 6.4 x 4.8 m and 19.2 x 14.4 m; the far
        // one also sees the first square, coarser than the near one
        let fp = footprint(&two, &cams).unwrap();
        let expected = (2.0f64 / (1.0 / 1e-4 + 1.0 / 9e-4)).sqrt();
        assert!(rel(fp, expected) < 0.01, "{fp} vs {expected}");
        // half of the 11 111 texels lie where the atlas is finer than the photographs:
        // 1 / 0.0134^2 - 1 / 0.03^2 = 4 444 texels there (and as many pixels missing on the
        // near square)
        let v = views(&two, &cams);
        let m = misplaced_in(&two, &v);
        assert!(
            rel(m, 1.0 / (expected * expected) - 1.0 / 9e-4) < 0.02,
            "{m}"
        );
    }

    #[test]
    fn a_point_behind_or_outside_the_frame_has_no_footprint() {
        let cam = camera_above(0.0, 10.0, 500.0);
        assert!(point_footprint(&cam, DVec3::new(0.0, 0.0, 0.0)).is_some());
        assert!(point_footprint(&cam, DVec3::new(0.0, 0.0, 20.0)).is_none());
        // 500 * 7 / 10 = 350 px from the centre, beyond the 320 px half width
        assert!(point_footprint(&cam, DVec3::new(7.0, 0.0, 0.0)).is_none());
        assert!(footprint(&square(4.0, 100.0, 4), &[cam]).is_none());
        assert!(footprint(&square(4.0, 0.0, 4), &[]).is_none());
    }

    #[test]
    fn a_part_seen_twice_as_close_gets_twice_the_resolution() {
        let plane = square(4.0, 0.0, 8);
        let resolution = |cam: Camera, max: u32| {
            let cams = [cam];
            auto_resolution(&plane, &views(&plane, &cams), max).unwrap()
        };
        let far = resolution(camera_above(0.0, 20.0, 500.0), 4096);
        let near = resolution(camera_above(0.0, 10.0, 500.0), 4096);
        assert!(rel(far.footprint_m.unwrap(), 0.04) < 0.01, "{far:?}");
        // 4 m at 0.04 m per texel is 100 texels per side before the packing efficiency
        assert!((100..=160).contains(&far.resolution), "{far:?}");
        let ratio = near.resolution as f64 / far.resolution as f64;
        assert!((ratio - 2.0).abs() < 0.15, "{near:?} vs {far:?}");
        assert_eq!(near.resolution % 16, 0);
        // the budget caps it; an unseen part gets the minimum
        let capped = resolution(camera_above(0.0, 2.0, 1000.0), 256);
        assert!(rel(capped.footprint_m.unwrap(), 0.002) < 0.1, "{capped:?}");
        assert_eq!(capped.resolution, 256);
        let unseen = resolution(camera_above(100.0, 10.0, 500.0), 4096);
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

    /// A `len` x `width` metre strip along x from x = 0, in the plane z = 0, as two triangles.
    fn strip(len: f32, width: f32) -> TriMesh {
        let mut m = TriMesh {
            positions: vec![
                [0.0, -width / 2.0, 0.0],
                [len, -width / 2.0, 0.0],
                [len, width / 2.0, 0.0],
                [0.0, width / 2.0, 0.0],
            ],
            indices: vec![[0, 1, 2], [0, 2, 3]],
            ..TriMesh::default()
        };
        m.compute_vertex_normals();
        m
    }

    /// A wide 640 x 480 camera (focal length 400 px) at `eye` looking at `target`.
    fn camera_at(eye: DVec3, target: DVec3) -> Camera {
        let mut cam = Camera::pinhole(640, 480, 400.0, 400.0, 319.5, 239.5);
        cam.pose = WorldToCamera::look_at(eye, target, DVec3::Z).unwrap();
        cam
    }

    #[test]
    fn a_two_triangle_plane_is_sampled_over_its_area_not_at_two_centroids() {
        // a 4 m square of two triangles under a camera 10 m above one corner: the finest
        // footprint lies at that corner, where neither centroid is
        let mut plane = strip(4.0, 4.0);
        plane.positions.iter_mut().for_each(|p| p[1] += 2.0);
        let cam = camera_above(0.0, 10.0, 500.0);
        let fp = footprint(&plane, &[cam]).unwrap();
        // straight down, every point has depth 10: footprint 10 / 500 / sqrt(cos), cos from 1
        // at the corner below the camera to 10 / sqrt(132) at the far one
        assert!(
            fp > 0.02 && fp < 0.02 / (10.0 / 132f64.sqrt()).sqrt(),
            "{fp}"
        );
        let samples = surface_samples(&plane);
        let area: f64 = samples.iter().map(|s| s.area).sum();
        assert!((area - 16.0).abs() < 1e-6, "{area}");
        assert!(samples.len() >= MAX_FOOTPRINT_SAMPLES, "{}", samples.len());
        // the points cover the square: each 1 m cell holds about 1/16 of them
        let mut cells = [0usize; 16];
        for Sample { p, .. } in &samples {
            let (i, j) = ((p.x.floor() as usize).min(3), (p.y.floor() as usize).min(3));
            cells[j * 4 + i] += 1;
        }
        let n = samples.len() as f64 / 16.0;
        assert!(
            cells.iter().all(|&c| (c as f64 - n).abs() < 0.05 * n),
            "{cells:?}"
        );
    }

    #[test]
    fn a_long_strip_seen_from_one_end_is_cut_and_each_piece_sized_by_its_own_footprint() {
        let cams = [camera_at(
            DVec3::new(-4.0, 0.0, 3.0),
            DVec3::new(8.0, 0.0, 0.0),
        )];
        let v = views(&strip(40.0, 4.0), &cams);
        let whole = resolve(&strip(40.0, 4.0), &v);
        let need = texels_needed(&strip(40.0, 4.0), whole.texel);
        assert!(
            whole.misplaced > MISPLACED_LIMIT * need,
            "{whole:?} of {need}"
        );
        let parts = plan_parts(vec![("strip".into(), strip(40.0, 4.0))], &cams, 2048).unwrap();
        assert!(parts.len() > 2, "{}", parts.len());
        let area: f64 = parts.iter().map(|p| p.mesh.total_area()).sum();
        assert!((area - 160.0).abs() < 1e-3, "an exact partition: {area}");
        let cut: f64 = parts.iter().map(|p| misplaced_in(&p.mesh, &v)).sum();
        assert!(cut < SPLIT_GAIN * whole.misplaced, "{cut} vs {whole:?}");
        for p in &parts {
            assert!(p.name.starts_with("strip-"), "{}", p.name);
        }
        // the piece nearest the camera has the finest footprint, the farthest the coarsest
        let x_of = |p: &PlannedPart| p.mesh.bounds().unwrap().0[0];
        let near = parts
            .iter()
            .min_by(|a, b| x_of(a).total_cmp(&x_of(b)))
            .unwrap();
        let far = parts
            .iter()
            .max_by(|a, b| x_of(a).total_cmp(&x_of(b)))
            .unwrap();
        let (fn_, ff) = (
            near.choice.footprint_m.unwrap(),
            far.choice.footprint_m.unwrap(),
        );
        assert!(ff > 2.0 * fn_, "near {fn_} far {ff}");
        assert!(
            near.mesh.total_area() / (near.choice.resolution as f64).powi(2)
                < far.mesh.total_area() / (far.choice.resolution as f64).powi(2)
        );
    }

    #[test]
    fn a_mesh_over_the_budget_is_cut_until_its_pieces_fit() {
        // an 8 m square at 0.02 m per pixel everywhere needs 400^2 texels; the budget is 256
        let cams: Vec<Camera> = [(2.0, -2.0), (6.0, -2.0), (2.0, 2.0), (6.0, 2.0)]
            .iter()
            .map(|&(x, y)| {
                let mut cam = Camera::pinhole(640, 480, 500.0, 500.0, 319.5, 239.5);
                cam.pose =
                    WorldToCamera::look_at(DVec3::new(x, y, 10.0), DVec3::new(x, y, 0.0), DVec3::Y)
                        .unwrap();
                cam
            })
            .collect();
        let parts = plan_parts(vec![("field".into(), strip(8.0, 8.0))], &cams, 256).unwrap();
        assert_eq!(parts.len(), 16, "8 m cut to 4 m (still over), then to 2 m");
        let v = views(&strip(8.0, 8.0), &cams);
        for p in &parts {
            let need = texels_needed(&p.mesh, pixel_footprint(&p.mesh, &v)) / PLANNING_EFFICIENCY;
            assert!(need <= 256.0 * 256.0, "{}: {need}", p.name);
            assert!(p.choice.resolution <= 256);
            // straight down from 10 m, at most 2.9 m off the axis: cos >= 0.96
            let fp = p.choice.footprint_m.unwrap();
            assert!(fp >= 0.02 && rel(fp, 0.02) < 0.02, "{}: {fp}", p.name);
        }
        // a small part near the camera is not cut: the gain is not worth the atlases
        let small = plan_parts(vec![("s".into(), strip(2.0, 2.0))], &cams, 2048).unwrap();
        assert_eq!(small.len(), 1);
        assert_eq!(small[0].name, "s");
    }

    #[test]
    fn a_piece_named_like_another_mesh_is_refused() {
        let cams = [camera_at(
            DVec3::new(-4.0, 0.0, 3.0),
            DVec3::new(8.0, 0.0, 0.0),
        )];
        let err = plan_parts(
            vec![
                ("strip".into(), strip(40.0, 4.0)),
                ("strip-1".into(), strip(1.0, 1.0)),
            ],
            &cams,
            2048,
        )
        .unwrap_err()
        .to_string();
        assert!(err.contains("`strip-1`") && err.contains("rename"), "{err}");
        let twice = plan_parts(
            vec![("a".into(), strip(1.0, 1.0)), ("a".into(), strip(1.0, 1.0))],
            &cams,
            2048,
        )
        .unwrap_err()
        .to_string();
        assert!(
            twice.contains("two site meshes are both named `a`"),
            "{twice}"
        );
    }
}
