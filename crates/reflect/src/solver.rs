//! The iteration of the inverse global illumination solve (see the crate overview).

use crate::fill::fill_unseen;
use crate::parts::Part;
use crate::result::SolveResult;
use crate::survey::Photo;
use crate::weights::{combine, WeightRules};
use crate::ReflectError;
use glam::{DVec3, Vec2, Vec3};
use igi_brdf::{luminance, Basis, LafortuneRef, Lobe};
use igi_render::integrator::offset_origin;
use igi_render::sampling::{hash2, Rng};
use igi_render::{Albedo, Material, PathTracer, RenderOptions, Scene, SurfacePoint, Texture};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// Options of a solve.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SolveOptions {
    /// Atlas resolution per part (texels per side).
    pub atlas_resolution: u32,
    /// Iterations at most; the solve stops earlier when the mean change of `rho_d` over seen
    /// texels drops below `tolerance` (after `min_iterations`).
    pub max_iterations: u32,
    pub min_iterations: u32,
    pub tolerance: f32,
    /// Samples per radiance estimate in iteration k (the last entry repeats): later iterations
    /// use more samples, as in the paper.
    pub spp: Vec<u32>,
    /// Indirect bounces after direct lighting (2 as at the site).
    pub indirect: u32,
    pub seed: u64,
    /// Initial diffuse albedo of every texel.
    pub initial_albedo: [f32; 3],
    /// The evaluation albedo is at least this per channel, so a texel that is currently black
    /// can still become brighter (the ratio update is multiplicative).
    pub min_eval_albedo: f32,
    pub rules: WeightRules,
    /// Parts to solve (all when `None`); the others keep their current albedo.
    pub parts: Option<Vec<String>>,
}

impl Default for SolveOptions {
    fn default() -> Self {
        SolveOptions {
            atlas_resolution: 512,
            max_iterations: 4,
            min_iterations: 2,
            tolerance: 0.002,
            spp: vec![16, 64, 256],
            indirect: 2,
            seed: 1,
            initial_albedo: [0.5; 3],
            min_eval_albedo: 0.02,
            rules: WeightRules::default(),
            parts: None,
        }
    }
}

/// Progress reporting (the CLI maps it to progress bars).
pub trait Progress: Sync {
    fn begin(&self, _what: &str, _total: u64) {}
    fn advance(&self, _n: u64) {}
    fn finish(&self) {}
}

/// Reports nothing.
pub struct NoProgress;
impl Progress for NoProgress {}

/// One iteration in the report.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct IterationRecord {
    pub iteration: u32,
    pub spp: u32,
    /// Wall time of this iteration and since the start of the solve, in seconds.
    pub wall_s: f64,
    pub cumulative_s: f64,
    /// Observations (texel, photo) that entered the update.
    pub observations: u64,
    /// RMS of rendered minus photographed radiance over the observations, with the reflectance
    /// of the start of the iteration; and that RMS divided by the RMS of the photographed values.
    pub residual_rms: f32,
    pub residual_rel_rms: f32,
    /// Mean over seen texels of the largest per-channel change of `rho_d`.
    pub delta_rho: f32,
    /// With ground truth: mean absolute error of `rho_d` per channel over texels seen in at
    /// least two photos, and its RMS.
    pub truth_mae: Option<[f32; 3]>,
    pub truth_rms: Option<f32>,
    pub seen_texels: u64,
}

/// Per-part summary in the report.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PartSummary {
    pub name: String,
    pub resolution: usize,
    pub texel_size_m: f64,
    pub covered_texels: usize,
    pub seen_texels: usize,
    pub seen_twice_texels: usize,
    pub filled_texels: usize,
}

/// The report of a solve (`report.json`).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SolveReport {
    pub options: SolveOptions,
    pub photos: Vec<String>,
    pub iterations: Vec<IterationRecord>,
    pub parts: Vec<PartSummary>,
    pub converged: bool,
}

/// Ground-truth albedo per part and covered texel (same order as `Part::cache.texels`).
pub type Truth = Vec<Vec<Option<Vec3>>>;

struct Obs {
    part: u32,
    texel: u32,
    proposal: Vec3,
    weight: f32,
    /// Neither near an occlusion boundary nor on a shadow edge.
    clean: bool,
    residual: Vec3,
    pixel: Vec3,
}

/// Everything the per-photo pass needs about one texel.
#[derive(Clone, Copy)]
struct TexelRef {
    part: u32,
    texel: u32,
    position: Vec3,
    normal: Vec3,
    uv: Vec2,
}

fn build_scene(parts: &[Part], rho: &[Vec<Vec3>], lobes: &[Vec<Lobe>]) -> Result<Scene, ReflectError> {
    let objects = parts
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let r = p.resolution();
            let tex = Texture { width: r, height: r, texels: rho[i].clone() };
            (p.name.clone(), p.mesh.clone(), Material { albedo: Albedo::Texture(tex), lobes: lobes[i].clone() })
        })
        .collect();
    Ok(Scene::new(objects)?)
}

/// Lobes of each part: inferred from the part's mean albedo with the basis, or none.
fn infer_lobes(parts: &[Part], rho: &[Vec<Vec3>], basis: Option<&Basis>) -> Vec<Vec<Lobe>> {
    parts
        .iter()
        .enumerate()
        .map(|(i, p)| match basis {
            None => Vec::new(),
            Some(b) => {
                let n = p.cache.texels.len().max(1) as f32;
                let mean = p.cache.texels.iter().fold(Vec3::ZERO, |a, t| a + rho[i][t.index as usize]) / n;
                b.infer(mean).lobes
            }
        })
        .collect()
}

/// Runs the solve. `start` is the state to continue from (a fresh state or one resumed from a
/// result folder); `checkpoint` is called after every iteration with the current result (the
/// CLI writes it atomically, which is what makes a killed run resumable).
pub fn solve(
    mut start: SolveResult,
    photos: &[Photo],
    basis: Option<&Basis>,
    truth: Option<&Truth>,
    opts: &SolveOptions,
    progress: &dyn Progress,
    checkpoint: &mut dyn FnMut(&SolveResult) -> Result<(), ReflectError>,
) -> Result<SolveResult, ReflectError> {
    if photos.is_empty() {
        return Err(ReflectError::Invalid("no photographs to solve from".into()));
    }
    if opts.spp.is_empty() || opts.spp.contains(&0) {
        return Err(ReflectError::Invalid("the spp schedule must be non-empty and positive".into()));
    }
    let parts = &start.parts;
    let solved: Vec<bool> = parts
        .iter()
        .map(|p| opts.parts.as_ref().is_none_or(|sel| sel.iter().any(|s| s == &p.name)))
        .collect();
    if let Some(sel) = &opts.parts {
        for s in sel {
            if !parts.iter().any(|p| &p.name == s) {
                return Err(ReflectError::Invalid(format!("no part named `{s}` in the site")));
            }
        }
    }
    let texels: Vec<TexelRef> = parts
        .iter()
        .enumerate()
        .filter(|(i, _)| solved[*i])
        .flat_map(|(i, p)| {
            p.cache.texels.iter().enumerate().map(move |(k, t)| TexelRef {
                part: i as u32,
                texel: k as u32,
                position: t.position,
                normal: t.normal,
                uv: p.cache.uv(t.index),
            })
        })
        .collect();
    let t0 = Instant::now();
    let already = start.report.iterations.last().map_or(0.0, |r| r.cumulative_s);
    let first_k = start.report.iterations.len() as u32;
    for k in first_k..opts.max_iterations {
        let ti = Instant::now();
        let spp = opts.spp[(k as usize).min(opts.spp.len() - 1)];
        let lobes = infer_lobes(&start.parts, &start.rho, basis);
        let scene = build_scene(&start.parts, &start.rho, &lobes)?;
        progress.begin(&format!("iteration {}", k + 1), (photos.len() * texels.len()) as u64);
        let mut obs: Vec<Obs> = Vec::new();
        for (pi, photo) in photos.iter().enumerate() {
            let o = observe_photo(&scene, photo, pi, &texels, &start, &lobes, opts, k, spp, progress);
            obs.extend(o);
        }
        progress.finish();
        // combine per texel
        let parts = &start.parts;
        let mut per_texel: Vec<Vec<Vec<(Vec3, f32)>>> = parts.iter().map(|p| vec![Vec::new(); p.cache.texels.len()]).collect();
        let mut any_clean: Vec<Vec<bool>> = parts.iter().map(|p| vec![false; p.cache.texels.len()]).collect();
        let (mut res2, mut rel2, mut nres) = (0.0f64, 0.0f64, 0u64);
        for o in &obs {
            per_texel[o.part as usize][o.texel as usize].push((o.proposal, o.weight));
            any_clean[o.part as usize][o.texel as usize] |= o.clean;
            res2 += o.residual.length_squared() as f64;
            rel2 += o.pixel.length_squared() as f64;
            nres += 3;
        }
        let mut new_rho = start.rho.clone();
        let mut weight_sum = start.weight_sum.clone();
        let mut observations = start.observations.clone();
        let (mut delta, mut nseen) = (0.0f64, 0u64);
        let mut summaries = Vec::new();
        for (pi, p) in parts.iter().enumerate() {
            let res = p.resolution();
            if !solved[pi] {
                summaries.push(start.report.parts.get(pi).cloned().unwrap_or_else(|| PartSummary {
                    name: p.name.clone(),
                    resolution: res,
                    texel_size_m: p.texel_size,
                    covered_texels: p.cache.texels.len(),
                    seen_texels: 0,
                    seen_twice_texels: 0,
                    filled_texels: 0,
                }));
                continue;
            }
            let mut seen = vec![false; res * res];
            let covered: Vec<bool> = p.coverage.pixels.iter().map(|c| c[0] == 1.0).collect();
            let gutter: Vec<bool> = p.coverage.pixels.iter().map(|c| c[0] > 0.0).collect();
            let (mut nseen_p, mut twice) = (0usize, 0usize);
            for (ti, t) in p.cache.texels.iter().enumerate() {
                let i = t.index as usize;
                let props = &mut per_texel[pi][ti];
                // seen only through occlusion boundaries or shadow edges: not reliable; filled
                let combined = if any_clean[pi][ti] { combine(props, &opts.rules) } else { None };
                observations[pi][i] = if combined.is_some() { props.iter().filter(|(_, w)| *w > 0.0).count() as u32 } else { 0 };
                match combined {
                    Some((v, w)) => {
                        delta += (v - start.rho[pi][i]).abs().max_element() as f64;
                        nseen += 1;
                        nseen_p += 1;
                        if observations[pi][i] >= 2 {
                            twice += 1;
                        }
                        new_rho[pi][i] = v;
                        weight_sum[pi][i] = w;
                        seen[i] = true;
                    }
                    None => {
                        weight_sum[pi][i] = 0.0;
                    }
                }
            }
            let fallback = Vec3::from_array(opts.initial_albedo);
            let filled = fill_unseen(&mut new_rho[pi], &seen, &covered, &gutter, res, fallback, 8);
            summaries.push(PartSummary {
                name: p.name.clone(),
                resolution: res,
                texel_size_m: p.texel_size,
                covered_texels: p.cache.texels.len(),
                seen_texels: nseen_p,
                seen_twice_texels: twice,
                filled_texels: filled,
            });
        }
        let delta_rho = if nseen > 0 { (delta / nseen as f64) as f32 } else { 0.0 };
        start.rho = new_rho;
        start.weight_sum = weight_sum;
        start.observations = observations;
        start.lobes = infer_lobes(&start.parts, &start.rho, basis);
        let (truth_mae, truth_rms) = match truth {
            Some(t) => truth_error(&start, t, &solved),
            None => (None, None),
        };
        let wall = ti.elapsed().as_secs_f64();
        let rec = IterationRecord {
            iteration: k + 1,
            spp,
            wall_s: wall,
            cumulative_s: already + t0.elapsed().as_secs_f64(),
            observations: obs.len() as u64,
            residual_rms: if nres > 0 { (res2 / nres as f64).sqrt() as f32 } else { 0.0 },
            residual_rel_rms: if rel2 > 0.0 { (res2 / rel2).sqrt() as f32 } else { 0.0 },
            delta_rho,
            truth_mae,
            truth_rms,
            seen_texels: nseen,
        };
        tracing::info!(
            "iteration {}: {} spp, {:.1} s, {} observations, residual {:.4} ({:.2}% rel), change {:.5}",
            rec.iteration,
            spp,
            wall,
            rec.observations,
            rec.residual_rms,
            100.0 * rec.residual_rel_rms,
            delta_rho
        );
        start.report.parts = summaries;
        start.report.iterations.push(rec);
        let done = k + 1 >= opts.min_iterations && delta_rho < opts.tolerance;
        start.report.converged = done;
        checkpoint(&start)?;
        if done {
            break;
        }
    }
    Ok(start)
}

#[allow(clippy::too_many_arguments)]
fn observe_photo(
    scene: &Scene,
    photo: &Photo,
    photo_index: usize,
    texels: &[TexelRef],
    state: &SolveResult,
    lobes: &[Vec<Lobe>],
    opts: &SolveOptions,
    iteration: u32,
    spp: u32,
    progress: &dyn Progress,
) -> Vec<Obs> {
    let rules = &opts.rules;
    let cam = &photo.camera;
    let c = cam.center_world().as_vec3();
    let sun = photo.lighting.sun.as_ref();
    // Sun visibility per texel, for the shadow-edge rule (skipped without a sun).
    let sun_vis: Option<Vec<Vec<bool>>> = sun.map(|s| {
        state
            .parts
            .iter()
            .map(|p| {
                p.cache
                    .texels
                    .par_iter()
                    .map(|t| {
                        let n = if t.normal.dot(s.direction) < 0.0 { -t.normal } else { t.normal };
                        !scene.occluded(offset_origin(t.position, n), s.direction, f32::INFINITY)
                    })
                    .collect()
            })
            .collect()
    });
    // atlas index -> texel number, for neighbour lookups
    let index_maps: Option<Vec<Vec<u32>>> = sun_vis.as_ref().map(|_| {
        state
            .parts
            .iter()
            .map(|p| {
                let r = p.resolution();
                let mut m = vec![u32::MAX; r * r];
                for (k, t) in p.cache.texels.iter().enumerate() {
                    m[t.index as usize] = k as u32;
                }
                m
            })
            .collect()
    });
    let shadow_edge = |t: &TexelRef| -> bool {
        let (Some(vis), Some(maps)) = (&sun_vis, &index_maps) else { return false };
        let p = &state.parts[t.part as usize];
        let r = p.resolution() as i64;
        let idx = p.cache.texels[t.texel as usize].index as i64;
        let (x, y) = (idx % r, idx / r);
        let me = vis[t.part as usize][t.texel as usize];
        for (dx, dy) in [(-1, 0), (1, 0), (0, -1), (0, 1)] {
            let (xx, yy) = (x + dx, y + dy);
            if xx < 0 || yy < 0 || xx >= r || yy >= r {
                continue;
            }
            let k = maps[t.part as usize][(yy * r + xx) as usize];
            if k != u32::MAX && vis[t.part as usize][k as usize] != me {
                return true;
            }
        }
        false
    };
    let render_opts = RenderOptions { spp, seed: opts.seed, indirect: opts.indirect, russian_roulette: false };
    let pt = PathTracer::new(scene, &photo.lighting, &render_opts);
    let stream_seed = hash2(opts.seed, ((iteration as u64) << 32) | photo_index as u64);
    let min_eval = Vec3::splat(opts.min_eval_albedo);
    // Geometric tests and radiance estimates, texel by texel.
    let chunk = 4096;
    let raw: Vec<Option<(u32, Vec3, Vec3, Vec3, f32, bool, Vec3)>> = texels
        .par_chunks(chunk)
        .enumerate()
        .flat_map_iter(|(ci, ch)| {
            let out: Vec<_> = ch
                .iter()
                .enumerate()
                .map(|(j, t)| {
                    let gi = (ci * chunk + j) as u64;
                    let to_cam = c - t.position;
                    let dist = to_cam.length();
                    if !(dist > 0.0) {
                        return None;
                    }
                    let wo = to_cam / dist;
                    let mut n = t.normal;
                    let mut cos = n.dot(wo);
                    if cos < 0.0 {
                        n = -n;
                        cos = -cos;
                    }
                    if cos < rules.min_cos {
                        return None;
                    }
                    let px = cam.project(t.position.as_dvec3())?;
                    let origin = offset_origin(t.position, n);
                    if scene.occluded(origin, wo, (c - origin).length() * (1.0 - 1e-4)) {
                        return None;
                    }
                    let pixel = Vec3::from_array(photo.image.bilinear(px.x as f32, px.y as f32)?);
                    let mut weight = cos;
                    let mut clean = true;
                    // occlusion boundary / misregistration: depth agreement of neighbouring rays
                    let o = rules.boundary_offset_px;
                    for (dx, dy) in [(o, 0.0), (-o, 0.0), (0.0, o), (0.0, -o)] {
                        let (ro, rd) = cam.pixel_ray(px.x + dx, px.y + dy);
                        let hit = scene.intersect(ro.as_vec3(), rd.as_vec3());
                        let ok = hit.is_some_and(|h| {
                            (h.t - dist).abs() <= rules.depth_tolerance * dist && h.ng.normalize_or_zero().dot(n).abs() >= rules.min_normal_agreement
                        });
                        if !ok {
                            weight *= rules.boundary_factor;
                            clean = false;
                            break;
                        }
                    }
                    if shadow_edge(t) {
                        weight *= rules.shadow_edge_factor;
                        clean = false;
                    }
                    // radiance toward the camera with the evaluation albedo at this texel
                    let rho = state.rho[t.part as usize][state.parts[t.part as usize].cache.texels[t.texel as usize].index as usize];
                    let rho_eval = rho.max(min_eval);
                    let brdf = LafortuneRef { rho_d: rho_eval, lobes: &lobes[t.part as usize] };
                    let sp = SurfacePoint { position: t.position, ng: n, ns: n, uv: t.uv, object: t.part, prim: 0 };
                    let est = pt.lo_estimate(&sp, wo, Some(brdf), spp, &mut Rng::new(stream_seed, gi));
                    Some((gi as u32, pixel, est.mean, est.stderr, weight, clean, rho_eval))
                })
                .collect();
            progress.advance(ch.len() as u64);
            out
        })
        .collect();
    // near-zero floor relative to the photo's median rendered luminance
    let mut lums: Vec<f32> = raw.iter().flatten().map(|r| luminance(r.2)).filter(|l| *l > 0.0).collect();
    let median = if lums.is_empty() {
        0.0
    } else {
        let m = lums.len() / 2;
        *lums.select_nth_unstable_by(m, |a, b| a.total_cmp(b)).1
    };
    let floor = (median * rules.min_radiance_fraction).max(1e-12);
    raw.into_iter()
        .flatten()
        .filter_map(|(gi, pixel, l, se, weight, clean, rho_eval)| {
            let ll = luminance(l);
            if !(ll > floor) || luminance(se) > rules.max_rel_stderr * ll {
                return None;
            }
            let t = &texels[gi as usize];
            let rho = state.rho[t.part as usize][state.parts[t.part as usize].cache.texels[t.texel as usize].index as usize];
            // per channel; a channel rendered at zero keeps the current value
            let proposal = Vec3::from_array(std::array::from_fn(|ch| {
                if l[ch] > floor * 1e-3 {
                    rho_eval[ch] * pixel[ch] / l[ch]
                } else {
                    rho[ch]
                }
            }));
            // rendered radiance with the current albedo (linear in the first vertex's albedo)
            let current = l * (rho / rho_eval);
            let residual = current - pixel;
            Some(Obs { part: t.part, texel: t.texel, proposal, weight, clean, residual, pixel })
        })
        .collect()
}

/// Mean absolute error per channel and RMS error of `rho_d` against ground truth over covered
/// texels seen at least twice.
fn truth_error(state: &SolveResult, truth: &Truth, solved: &[bool]) -> (Option<[f32; 3]>, Option<f32>) {
    let (mut s, mut s2, mut n) = (DVec3::ZERO, 0.0f64, 0u64);
    for (pi, p) in state.parts.iter().enumerate() {
        if !solved[pi] {
            continue;
        }
        for (ti, t) in p.cache.texels.iter().enumerate() {
            let i = t.index as usize;
            if state.observations[pi][i] < 2 {
                continue;
            }
            if let Some(gt) = truth[pi][ti] {
                let d = (state.rho[pi][i] - gt).as_dvec3();
                s += d.abs();
                s2 += d.length_squared() / 3.0;
                n += 1;
            }
        }
    }
    if n == 0 {
        return (None, None);
    }
    let m = s / n as f64;
    (Some([m.x as f32, m.y as f32, m.z as f32]), Some((s2 / n as f64).sqrt() as f32))
}

/// Ground truth per texel from a scene with known albedo over the same geometry: the albedo
/// where a short ray along the texel's normal (both ways) meets the truth scene's surface.
pub fn truth_from_scene(parts: &[Part], truth: &Scene) -> Truth {
    parts
        .iter()
        .map(|p| {
            let eps = (p.texel_size as f32 * 0.5).max(1e-3);
            p.cache
                .texels
                .par_iter()
                .map(|t| {
                    for n in [t.normal, -t.normal] {
                        let o = t.position + n * eps;
                        if let Some(h) = truth.intersect(o, -n) {
                            if h.t <= 2.0 * eps {
                                let sp = truth.surface_point(&h);
                                return Some(truth.objects[sp.object as usize].material.brdf_at(sp.uv).rho_d);
                            }
                        }
                    }
                    None
                })
                .collect()
        })
        .collect()
}

