//! Ground truth for synthetic surveys, and the two errors a solve reports against it.
//!
//! - **The truth itself**: a part's atlas filled from a function of position ([`truth_atlas`])
//!   and the scene of parts with given albedo atlases ([`scene_with_albedo`]), from which
//!   [`truth_from_scene`] reads the truth of a solve (the synthetic surveys of `igi-synth` are
//!   rendered from the same scene).
//! - **Per texel** ([`Truth::texels`]): the true albedo at every covered texel centre of the
//!   solved parts; the *texel MAE* is the mean absolute error over the texels seen by two or
//!   more photographs. It weighs every texel alike, so a small part with a full atlas counts as
//!   much as a large one, and it depends on where the texels lie: the same result read between
//!   its texel centres (where the renderer blends four texels) has a different error.
//! - **Over the surface** ([`Truth::points`]): the albedo as the result is rendered (the
//!   bilinear lookup of its atlases) at area-uniform random points of the true surface, against
//!   the true albedo there, over the points whose texel was seen by two or more photographs: the
//!   *surface MAE*. It is the mean error over the site's area, the same whatever the atlases'
//!   resolution, and what `igi sample` at random survey points measures.

use crate::fill::dilate;
use crate::parts::Part;
use crate::result::SolveResult;
use crate::ReflectError;
use glam::{DVec3, Vec2, Vec3};
use igi_render::sampling::Rng;
use igi_render::Scene;
use rayon::prelude::*;

/// Random points of the true surface [`truth_from_scene`] draws (fewer on a smaller surface: at
/// most one per square millimetre).
pub const SURFACE_POINTS: usize = 200_000;

/// The true albedo atlas of a part: `f(position)` on covered texels, dilated into the gutters.
pub fn truth_atlas(part: &Part, f: impl Fn(Vec3) -> Vec3) -> Vec<Vec3> {
    let r = part.resolution();
    let mut v = vec![Vec3::ZERO; r * r];
    let mut known = vec![false; r * r];
    for t in &part.cache.texels {
        v[t.index as usize] = f(t.position);
        known[t.index as usize] = true;
    }
    let gutter: Vec<bool> = part.coverage.pixels.iter().map(|c| c[0] > 0.0).collect();
    dilate(&mut v, &mut known, &gutter, r, 4);
    v
}

/// The scene of the parts with the given albedo atlases (and no lobes).
pub fn scene_with_albedo(
    parts: &[impl AsRef<Part>],
    albedo: &[Vec<Vec3>],
) -> Result<Scene, ReflectError> {
    let atlases = albedo.iter().map(Vec::as_slice);
    crate::result::scene_of_atlases(parts.iter().map(AsRef::as_ref).zip(atlases))
}

/// Ground truth for a solve over the same geometry.
#[derive(Clone, Debug, Default)]
pub struct Truth {
    /// Per part and covered texel (same order as `Part::cache.texels`): the true albedo at the
    /// texel centre (`None` where no true surface lies there).
    pub texels: Vec<Vec<Option<Vec3>>>,
    /// Area-uniform points of the true surface, located on the solved parts.
    pub points: Vec<TruthPoint>,
}

/// One point of the true surface, located on a solved part.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TruthPoint {
    pub part: u32,
    /// The point's UV in the part's atlas.
    pub uv: Vec2,
    /// Atlas index of the texel whose square holds the point.
    pub texel: u32,
    /// The true albedo there.
    pub rho: Vec3,
}

impl Truth {
    /// Truth per texel only (no surface points: [`surface_error`] reports nothing).
    pub fn from_texels(texels: Vec<Vec<Option<Vec3>>>) -> Truth {
        Truth {
            texels,
            points: Vec::new(),
        }
    }
}

/// Ground truth from a scene with known albedo over the same geometry as `parts`: per texel,
/// the albedo where a short ray along the texel's normal (both ways) meets the truth scene; and
/// [`SURFACE_POINTS`] area-uniform points of the truth scene's surface (seeded, the same every
/// run), each located on the part a short ray along its normal meets. Parts of a prepared site,
/// whose meshes stay on disk, get no surface points.
pub fn truth_from_scene(parts: &[impl AsRef<Part>], truth: &Scene) -> Truth {
    Truth {
        texels: parts
            .iter()
            .map(|p| albedo_at_texels(p.as_ref(), truth))
            .collect(),
        points: surface_points(parts, truth, SURFACE_POINTS, 1),
    }
}

/// The albedo of `scene` (the truth, or another result over the same surface) at part `p`'s
/// covered texel centres, as rendered (its atlases' bilinear lookup): `None` where no surface of
/// `scene` lies within half a texel along the texel's normal.
pub(crate) fn albedo_at_texels(p: &Part, truth: &Scene) -> Vec<Option<Vec3>> {
    let eps = (p.texel_size as f32 * 0.5).max(1e-3);
    p.cache
        .texels
        .par_iter()
        .map(|t| {
            let sp = truth.surface_near(t.position, t.normal, eps)?;
            Some(
                truth.objects[sp.object as usize]
                    .material
                    .brdf_at(sp.uv)
                    .rho_d,
            )
        })
        .collect()
}

/// About `count` area-uniform points of `truth`'s surface located on `parts` (triangle by
/// triangle: `area * density` points, the fraction drawn at random; stream per triangle).
pub(crate) fn surface_points(
    parts: &[impl AsRef<Part>],
    truth: &Scene,
    count: usize,
    seed: u64,
) -> Vec<TruthPoint> {
    let parts: Vec<&Part> = parts.iter().map(AsRef::as_ref).collect();
    if parts.is_empty() || parts.iter().any(|p| p.mesh.indices.is_empty()) {
        return Vec::new();
    }
    let zeros: Vec<Vec<Vec3>> = parts
        .iter()
        .map(|p| vec![Vec3::ZERO; p.resolution().pow(2)])
        .collect();
    let Ok(site) = scene_with_albedo(&parts, &zeros) else {
        return Vec::new();
    };
    let finest = parts
        .iter()
        .map(|p| p.texel_size as f32)
        .fold(f32::INFINITY, f32::min);
    let eps = (0.5 * finest).clamp(1e-3, 0.05);
    let area: f64 = truth
        .objects
        .iter()
        .flat_map(|o| o.triangles.iter().map(|t| triangle(o, t).2 as f64))
        .sum();
    let density = (count as f64 / area.max(1e-12)).min(1e6);
    let mut first = 0u64;
    let mut points = Vec::new();
    for o in &truth.objects {
        let streams = first;
        first += o.triangles.len() as u64;
        points.par_extend(o.triangles.par_iter().enumerate().flat_map_iter(|(k, t)| {
            let mut rng = Rng::new(seed, streams + k as u64);
            let (p, uv, a) = triangle(o, t);
            let expected = a as f64 * density;
            let n =
                expected.floor() as usize + usize::from((rng.uniform() as f64) < expected.fract());
            let normal = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
            (0..n)
                .filter_map(|_| {
                    let (mut u, mut v) = (rng.uniform(), rng.uniform());
                    if u + v > 1.0 {
                        (u, v) = (1.0 - u, 1.0 - v);
                    }
                    let w = 1.0 - u - v;
                    let x = p[0] * w + p[1] * u + p[2] * v;
                    let rho = o.material.brdf_at(uv[0] * w + uv[1] * u + uv[2] * v).rho_d;
                    locate(&site, &parts, x, normal, eps, rho)
                })
                .collect::<Vec<_>>()
        }));
    }
    points
}

/// A triangle's corners, corner UVs (0 without UVs) and area.
fn triangle(o: &igi_render::Object, t: &[u32; 3]) -> ([Vec3; 3], [Vec2; 3], f32) {
    let p = t.map(|i| o.positions[i as usize]);
    let uv = t.map(|i| o.uvs.as_ref().map_or(Vec2::ZERO, |u| u[i as usize]));
    (p, uv, 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length())
}

/// The part, UV and texel of the solved surface at `x` (true albedo `rho`).
fn locate(
    site: &Scene,
    parts: &[&Part],
    x: Vec3,
    normal: Vec3,
    eps: f32,
    rho: Vec3,
) -> Option<TruthPoint> {
    let sp = site.surface_near(x, normal, eps)?;
    let r = parts[sp.object as usize].resolution();
    let texel = igi_geometry::texels::texel_at(sp.uv, r, r);
    Some(TruthPoint {
        part: sp.object,
        uv: sp.uv,
        texel: texel as u32,
        rho,
    })
}

/// Texel MAE per channel and RMS (over channels) of the solved parts' texels seen twice.
pub fn texel_error(
    state: &SolveResult,
    truth: &Truth,
    solved: &[bool],
) -> (Option<[f32; 3]>, Option<f32>) {
    let mut errors = Vec::new();
    for (pi, p) in state.parts.iter().enumerate() {
        if !solved[pi] {
            continue;
        }
        for (ti, t) in p.part.cache.texels.iter().enumerate() {
            let i = t.index as usize;
            if p.observations[i] < 2 {
                continue;
            }
            if let Some(Some(gt)) = truth.texels.get(pi).and_then(|v| v.get(ti)) {
                errors.push(p.rho[i] - *gt);
            }
        }
    }
    mean_errors(&errors)
}

/// Surface MAE per channel and RMS (over channels): the result as rendered at the truth's
/// surface points on solved parts whose texel was seen twice.
pub fn surface_error(
    state: &SolveResult,
    truth: &Truth,
    solved: &[bool],
) -> (Option<[f32; 3]>, Option<f32>) {
    if truth.points.is_empty() {
        return (None, None);
    }
    let textures = state.albedo_textures();
    let errors: Vec<Vec3> = truth
        .points
        .iter()
        .filter(|q| {
            let pi = q.part as usize;
            solved.get(pi) == Some(&true) && state.parts[pi].observations[q.texel as usize] >= 2
        })
        .map(|q| textures[q.part as usize].lookup(q.uv) - q.rho)
        .collect();
    mean_errors(&errors)
}

/// MAE per channel and RMS over channels of `errors` (`None` without any).
fn mean_errors(errors: &[Vec3]) -> (Option<[f32; 3]>, Option<f32>) {
    if errors.is_empty() {
        return (None, None);
    }
    let (s, s2) = errors.iter().fold((DVec3::ZERO, 0.0f64), |(s, s2), e| {
        let d = e.as_dvec3();
        (s + d.abs(), s2 + d.length_squared() / 3.0)
    });
    let n = errors.len() as f64;
    let m = s / n;
    (
        Some([m.x as f32, m.y as f32, m.z as f32]),
        Some((s2 / n).sqrt() as f32),
    )
}

/// How well the standard errors explain the error against ground truth: the z-scores
/// `(rho_d - truth) / stderr` of every channel of the texels seen at least twice.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ZScores {
    /// Number of z-scores (texel channels with a positive standard error).
    pub count: usize,
    /// 1.4826 x the median |z| (1 for a standard normal; robust to heavy tails).
    pub robust_spread: f64,
    /// sqrt(mean z^2).
    pub rms: f64,
    /// 95th percentile of |z| (1.96 for a standard normal).
    pub p95_abs: f64,
}

/// The [`ZScores`] of a result against ground truth, or `None` without any.
pub fn z_scores(state: &SolveResult, truth: &Truth) -> Option<ZScores> {
    let mut z = Vec::new();
    for (pi, p) in state.parts.iter().enumerate() {
        for (ti, t) in p.part.cache.texels.iter().enumerate() {
            let i = t.index as usize;
            let (Some(Some(gt)), true) = (
                truth.texels.get(pi).and_then(|v| v.get(ti)),
                p.observations[i] >= 2,
            ) else {
                continue;
            };
            let se = p.stderr[i];
            for ch in 0..3 {
                if se[ch] > 0.0 {
                    z.push(((p.rho[i][ch] - gt[ch]) as f64 / se[ch] as f64).abs());
                }
            }
        }
    }
    if z.is_empty() {
        return None;
    }
    z.sort_by(f64::total_cmp);
    let n = z.len();
    Some(ZScores {
        count: n,
        robust_spread: 1.4826 * z[n / 2],
        rms: (z.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt(),
        p95_abs: z[(n * 95 / 100).min(n - 1)],
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::parts::build_parts;
    use crate::solver::SolveOptions;
    use igi_geometry::TriMesh;

    /// A `w x h` m rectangle in z = 0 with its corner at `x0` along x.
    fn rectangle(x0: f32, w: f32, h: f32) -> TriMesh {
        let mut m = TriMesh::default();
        for [x, y] in [[x0, 0.0], [x0 + w, 0.0], [x0 + w, h], [x0, h]] {
            m.positions.push([x, y, 0.0]);
        }
        m.indices = vec![[0, 1, 2], [0, 2, 3]];
        m.compute_vertex_normals();
        m
    }

    /// A 4 m square (atlas 32) whose true albedo is 0.5 everywhere, and a result whose texels
    /// are `value(x, y)`, all seen by two photographs.
    fn plane_and_result(value: impl Fn(usize, usize) -> Vec3) -> (SolveResult, Truth) {
        let parts = build_parts(vec![("ground".into(), rectangle(0.0, 4.0, 4.0))], 32).unwrap();
        let flat = vec![vec![Vec3::splat(0.5); 32 * 32]];
        let scene = scene_with_albedo(&parts, &flat).unwrap();
        let truth = truth_from_scene(&parts, &scene);
        let mut state = SolveResult::fresh(parts, vec!["a".into()], &SolveOptions::default());
        state.parts[0].rho = (0..32 * 32).map(|i| value(i % 32, i / 32)).collect();
        state.parts[0].observations = vec![2; 32 * 32];
        (state, truth)
    }

    /// A constant error is the same per texel and over the surface.
    #[test]
    fn a_constant_error_is_the_same_over_texels_and_surface() {
        let (state, truth) = plane_and_result(|_, _| Vec3::splat(0.51));
        let (texel, _) = texel_error(&state, &truth, &[true]);
        let (surface, _) = surface_error(&state, &truth, &[true]);
        for c in 0..3 {
            assert!((texel.unwrap()[c] - 0.01).abs() < 1e-5, "{texel:?}");
            assert!((surface.unwrap()[c] - 0.01).abs() < 1e-5, "{surface:?}");
        }
        assert!(truth.points.len() > 190_000, "{}", truth.points.len());
    }

    /// Errors alternating +-a from texel to texel (a checker at the atlas's Nyquist frequency)
    /// are a in every texel, but the renderer's bilinear blend of four texels shrinks them
    /// between the centres: over the surface the mean is a E|1 - 2u| E|1 - 2v| = a / 4.
    #[test]
    fn a_texel_checker_of_errors_is_a_quarter_of_its_texel_mae_over_the_surface() {
        let a = 0.02;
        let sign = |x: usize, y: usize| if (x + y).is_multiple_of(2) { 1.0 } else { -1.0 };
        let (state, truth) = plane_and_result(|x, y| Vec3::splat(0.5 + a * sign(x, y)));
        let texel = texel_error(&state, &truth, &[true]).0.unwrap();
        let surface = surface_error(&state, &truth, &[true]).0.unwrap();
        eprintln!("texel MAE {texel:?}, surface MAE {surface:?}");
        assert!((texel[0] - a).abs() < 1e-6, "{texel:?}");
        assert!((surface[0] - a / 4.0).abs() < 0.03 * a / 4.0, "{surface:?}");
    }

    /// Texels seen once are left out; parts not solved are left out.
    #[test]
    fn points_on_texels_seen_once_or_unsolved_parts_do_not_count() {
        let (mut state, truth) =
            plane_and_result(|x, _| Vec3::splat(if x < 16 { 0.6 } else { 0.5 }));
        state.parts[0].observations = (0..32 * 32)
            .map(|i| if i % 32 < 16 { 1 } else { 2 })
            .collect();
        let surface = surface_error(&state, &truth, &[true]).0.unwrap();
        assert!(surface[0] < 0.1 * 0.1, "{surface:?}");
        assert_eq!(surface_error(&state, &truth, &[false]).0, None);
    }

    /// Points fall on each surface in proportion to its area, the same points every run.
    #[test]
    fn surface_points_are_area_uniform_and_reproducible() {
        let meshes = vec![
            ("small".to_string(), rectangle(0.0, 1.0, 1.0)),
            ("large".to_string(), rectangle(2.0, 3.0, 1.0)),
        ];
        let parts = build_parts(meshes, 32).unwrap();
        let flat: Vec<Vec<Vec3>> = vec![vec![Vec3::splat(0.5); 32 * 32]; 2];
        let scene = scene_with_albedo(&parts, &flat).unwrap();
        let a = surface_points(&parts, &scene, 40_000, 3);
        let b = surface_points(&parts, &scene, 40_000, 3);
        assert_eq!(a, b);
        let on_small = a.iter().filter(|q| q.part == 0).count() as f64;
        let n = a.len() as f64;
        assert!((n - 40_000.0).abs() < 400.0, "{n}");
        assert!((on_small / n - 0.25).abs() < 0.01, "{}", on_small / n);
    }
}
