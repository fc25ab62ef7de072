//! The iteration of the inverse global illumination solve (see the crate overview).

use crate::atlas_size::point_footprint;
use crate::deblur::Footprint;
use crate::fill::fill_unseen;
use crate::lattice::{blend, reach, Lattice};
use crate::parts::{stored_part_name, Part};
use crate::photo::Photo;
use crate::record::Obs;
pub use crate::record::{
    IterationRecord, PartSummary, Pending, Schedule, SolveOptions, SolveReport,
};
use crate::result::{Albedos, PartResult, Snapshot, SolveResult, UNKNOWN_STDERR};
use crate::weights::{combine, Combined, Proposal};
use crate::ReflectError;
use glam::{DVec2, Vec2, Vec3};
use igi_brdf::{luminance, Basis, LafortuneRef, Lobe};
use igi_raycast::{offset_origin, RaySegment};
use igi_render::sampling::{hash2, Rng};
use igi_render::{Albedo, Material, PathTracer, RenderOptions, Scene, SurfacePoint, Texture};
use rayon::prelude::*;

use std::sync::Arc;
use std::time::Instant;

/// Bytes a solve of survey meshes holds per atlas texel besides its observations: the part's
/// texel cache, coverage and result arrays, and one photograph's pass (its raw observations,
/// the lattice, the shadow edges). Measured as peak resident memory of the fixture survey at
/// `--atlas 1024` and `2048` with one photograph: 197 bytes a texel between the two; each
/// further photograph adds its observations (`Obs`, 96 bytes, and a proposal, 28 bytes, per
/// texel it sees: about 50 bytes a texel per photograph on the fixture) (docs/RELIABILITY.md);
/// plus a byte a texel for each further sun whose visibility a group keeps ([`SUNS_KEPT`]).
pub const BYTES_PER_TEXEL: u128 = 192 + SUNS_KEPT as u128 - 1;

/// The memory estimate of a solve's atlases of `texels` texels in all ([`BYTES_PER_TEXEL`]
/// each), which a solve refuses before any work above the memory limit.
pub fn atlas_memory(texels: u128) -> u128 {
    texels * BYTES_PER_TEXEL
}

/// Bytes one observation holds until its group's albedo is combined: its record and its
/// proposal.
pub const BYTES_PER_OBSERVATION: u128 = (size_of::<Obs>() + size_of::<Proposal>()) as u128;

/// Refuses, before photograph `photo` is traced, a group whose observations could pass
/// `limit`: the `held` ones of the photographs before it and up to one per texel of the group
/// (`texels`) from this one, beside the group's atlases of `atlas_texels` texels in all
/// ([`atlas_memory`], which holds one photograph's pass).
fn check_observation_memory(
    atlas_texels: u128,
    held: usize,
    texels: usize,
    photo: &str,
    limit: u64,
) -> Result<(), ReflectError> {
    let bytes = atlas_memory(atlas_texels) + (held + texels) as u128 * BYTES_PER_OBSERVATION;
    let what = format!(
        "photograph {photo}'s observations (up to {texels}, beside {held} of the photographs before it, at {BYTES_PER_OBSERVATION} bytes each, and {atlas_texels} atlas texels at {BYTES_PER_TEXEL} bytes each)"
    );
    igi_files::check_alloc(&what, bytes, limit)?;
    Ok(())
}

/// Whether selection entry `sel` selects part `part`: the part's name, or the name of the mesh
/// `--atlas auto` cut it from (its pieces are named `sel-K`, `sel-K-L`, ...).
pub fn selects(sel: &str, part: &str) -> bool {
    part == sel
        || part
            .strip_prefix(sel)
            .and_then(|r| r.strip_prefix('-'))
            .is_some_and(|r| {
                r.split('-')
                    .all(|k| !k.is_empty() && k.bytes().all(|b| b.is_ascii_digit()))
            })
}

/// Every name in the part selection must select a part ([`selects`]).
pub fn check_selection(
    parts: &[impl AsRef<Part>],
    opts: &SolveOptions,
) -> Result<(), ReflectError> {
    let names: Vec<&str> = parts.iter().map(|p| p.as_ref().name.as_str()).collect();
    for s in opts.parts.iter().flatten() {
        if !names.iter().any(|n| selects(s, n)) {
            return Err(ReflectError::UnknownPart {
                name: s.clone(),
                known: format!(
                    "{}{}",
                    names[..names.len().min(12)].join(", "),
                    if parts.len() > 12 { ", ..." } else { "" }
                ),
            });
        }
    }
    Ok(())
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

pub use crate::truth::{truth_from_scene, z_scores, Truth, TruthPoint, ZScores};

/// Everything the per-photo pass needs about one texel.
#[derive(Clone, Copy)]
struct TexelRef {
    part: u32,
    texel: u32,
    position: Vec3,
    normal: Vec3,
    uv: Vec2,
}

/// A group of parts solved together against one scene: every part of an in-memory site at
/// once, or one voxel (or the terrain) of a prepared site with the multiresolution load.
pub(crate) struct Group {
    name: String,
    /// Solved parts whose texels this group observes.
    pub(crate) parts: Vec<usize>,
    load: GroupLoad,
}

enum GroupLoad {
    /// Every part's own mesh, at full resolution.
    Meshes,
    /// The voxel at level 0, its neighbours at the given level (1 for Gauss-Seidel, 0 for
    /// Jacobi), the rest and the terrain at the lowest.
    Voxel(igi_geometry::VoxelId, usize),
    /// The terrain at level 0, the voxels at level 1.
    Terrain,
}

/// The scene of a group: every part with its current albedo atlas (one atlas serves every level
/// of a stored part) and lobes, in part order.
fn group_scene(
    state: &SolveResult,
    group: &Group,
    store: Option<&igi_geometry::SiteStore>,
    albedo: Albedos,
) -> Result<(Scene, u64, Vec<Option<usize>>), ReflectError> {
    let material = |i: usize| {
        let r = state.parts[i].resolution();
        let tex = Texture {
            width: r,
            height: r,
            texels: albedo.rho(i).to_vec(),
        };
        Material {
            lobe_map: None,
            albedo: Albedo::Texture(tex),
            lobes: albedo.lobes(i).to_vec(),
        }
    };
    let mut object_part = Vec::new();
    let objects = match (&group.load, store) {
        (GroupLoad::Meshes, _) => state
            .parts
            .iter()
            .enumerate()
            .map(|(i, p)| {
                object_part.push(Some(i));
                (p.name().to_string(), p.part.mesh.clone(), material(i))
            })
            .collect(),
        (load, Some(store)) => {
            let loaded = match load {
                GroupLoad::Voxel(v, n) => store.load_for_voxel(*v, *n)?,
                _ => store.load_for_terrain()?,
            };
            let mut objects = Vec::with_capacity(loaded.len());
            for lp in loaded {
                let name = stored_part_name(lp.voxel);
                let i = state
                    .parts
                    .iter()
                    .position(|p| p.name() == name)
                    .ok_or_else(|| ReflectError::UnknownVoxel(name.clone()))?;
                object_part.push(Some(i));
                objects.push((name, lp.mesh, material(i)));
            }
            objects
        }
        (_, None) => return Err(ReflectError::NoPreparedSite),
    };
    let triangles = objects
        .iter()
        .map(|(_, m, _): &(String, igi_geometry::TriMesh, Material)| m.indices.len() as u64)
        .sum();
    Ok((Scene::new(objects)?, triangles, object_part))
}

/// Lobes of one part: inferred from its mean albedo with the basis, or none.
pub(crate) fn part_lobes(part: &Part, rho: &[Vec3], basis: Option<&Basis>) -> Vec<Lobe> {
    match basis {
        None => Vec::new(),
        Some(b) => {
            let n = part.cache.texels.len().max(1) as f32;
            let mean = part
                .cache
                .texels
                .iter()
                .fold(Vec3::ZERO, |a, t| a + rho[t.index as usize])
                / n;
            b.infer(mean).lobes
        }
    }
}

/// The groups of a solve: one per solved stored part (voxels, then the terrain), or one holding
/// every solved in-memory part.
fn make_groups(
    parts: &[PartResult],
    solved: &[bool],
    schedule: Schedule,
) -> Result<Vec<Group>, ReflectError> {
    let parts: Vec<&Part> = parts.iter().map(|p| &p.part).collect();
    let stored = parts.iter().filter(|p| p.stored.is_some()).count();
    if stored == 0 {
        let ids: Vec<usize> = (0..parts.len()).filter(|&i| solved[i]).collect();
        return Ok(vec![Group {
            name: "site".into(),
            parts: ids,
            load: GroupLoad::Meshes,
        }]);
    }
    if stored != parts.len() {
        return Err(ReflectError::MixedSite);
    }
    Ok(parts
        .iter()
        .enumerate()
        .filter(|(i, _)| solved[*i])
        .map(|(i, p)| {
            let load = match p.stored.as_ref().and_then(|s| s.voxel) {
                Some(v) => GroupLoad::Voxel(v, schedule.neighbour_level()),
                None => GroupLoad::Terrain,
            };
            Group {
                name: p.name.clone(),
                parts: vec![i],
                load,
            }
        })
        .collect())
}

/// What a solve needs besides its state: the photographs, the BRDF basis, the ground truth.
pub struct SolveInputs<'a> {
    pub photos: &'a [Photo],
    pub basis: Option<&'a Basis>,
    pub truth: Option<&'a Truth>,
}

/// A solve's state prepared for iterating: the groups, which parts are solved, the store.
pub(crate) struct Plan {
    groups: Vec<Group>,
    pub(crate) solved: Vec<bool>,
    store: Option<igi_geometry::SiteStore>,
}

impl Plan {
    /// The names of the groups with parts to solve, in solve order.
    pub(crate) fn group_names(&self) -> Vec<String> {
        self.groups
            .iter()
            .filter(|g| !g.parts.is_empty())
            .map(|g| g.name.clone())
            .collect()
    }

    /// The group named `name`, or an error listing a few of the names.
    pub(crate) fn group(&self, name: &str) -> Result<&Group, ReflectError> {
        self.groups
            .iter()
            .find(|g| g.name == name && !g.parts.is_empty())
            .ok_or_else(|| {
                let names = self.group_names();
                ReflectError::UnknownGroup {
                    name: name.to_string(),
                    count: names.len(),
                    known: format!(
                        "{}{}",
                        names.iter().take(8).cloned().collect::<Vec<_>>().join(", "),
                        if names.len() > 8 { ", ..." } else { "" }
                    ),
                }
            })
    }
}

/// Checks the inputs and prepares `start` for iterating: lobes inferred from the current
/// albedo, a summary for every part, the groups of the part selection.
pub(crate) fn plan(
    start: &mut SolveResult,
    inputs: &SolveInputs,
    opts: &SolveOptions,
) -> Result<Plan, ReflectError> {
    if inputs.photos.is_empty() {
        return Err(ReflectError::NoPhotos);
    }
    opts.validate()?;
    check_selection(&start.parts, opts)?;
    let solved: Vec<bool> = start
        .parts
        .iter()
        .map(|p| {
            opts.parts
                .as_ref()
                .is_none_or(|sel| sel.iter().any(|s| selects(s, p.name())))
        })
        .collect();
    let groups = make_groups(&start.parts, &solved, opts.schedule)?;
    start.basis = inputs.basis.cloned();
    // kept current: the parts a group updates get new lobes right after it
    for p in &mut start.parts {
        p.lobes = part_lobes(&p.part, &p.rho, inputs.basis);
    }
    let store = match start.parts.iter().find_map(|p| p.part.stored.as_ref()) {
        Some(s) => Some(igi_geometry::SiteStore::open(&s.site)?),
        None => None,
    };
    // every part has a summary (kept for parts this run does not solve)
    let summaries: Vec<PartSummary> = start
        .parts
        .iter()
        .map(|p| {
            start
                .report
                .parts
                .iter()
                .find(|s| s.name == p.name())
                .cloned()
                .unwrap_or_else(|| PartSummary::unsolved(&p.part))
        })
        .collect();
    start.report.parts = summaries;
    Ok(Plan {
        groups,
        solved,
        store,
    })
}

/// Runs the solve. `start` is the state to continue from (a fresh state or one resumed from a
/// result folder); `checkpoint` is called after every iteration with the current result (the
/// CLI writes it atomically, which is what makes a killed run resumable). A prepared site is
/// solved voxel by voxel, each against the multiresolution load of the site (the voxel at full
/// resolution, its neighbours at medium, the rest at low), with a checkpoint after every voxel
/// (Gauss-Seidel) or after every iteration (Jacobi).
pub fn solve(
    mut start: SolveResult,
    photos: &[Photo],
    basis: Option<&Basis>,
    truth: Option<&Truth>,
    opts: &SolveOptions,
    progress: &dyn Progress,
    checkpoint: &mut dyn FnMut(&SolveResult) -> Result<(), ReflectError>,
) -> Result<SolveResult, ReflectError> {
    let inputs = SolveInputs {
        photos,
        basis,
        truth,
    };
    let plan = plan(&mut start, &inputs, opts)?;
    let t0 = Instant::now();
    let already = start
        .report
        .iterations
        .last()
        .map_or(0.0, |r| r.cumulative_s);
    let first_k = start.report.iterations.len() as u32;
    for k in first_k..opts.max_iterations {
        let (acc, wall, already_in_iteration) =
            solve_iteration(&mut start, k, &plan, &inputs, opts, progress, checkpoint)?;
        let cumulative = already + t0.elapsed().as_secs_f64() + already_in_iteration;
        let done = finish_iteration(
            &mut start,
            &acc,
            &plan.solved,
            truth,
            opts,
            wall,
            cumulative,
        )?;
        checkpoint(&start)?;
        start.set_changed(false);
        if done {
            break;
        }
    }
    Ok(start)
}

/// Solves the groups of iteration `k` that a killed run left undone (all of them in a fresh
/// iteration), with a checkpoint after each group under Gauss-Seidel. Returns the iteration's
/// statistics, its wall time, and the part of that time spent before a resume.
fn solve_iteration(
    start: &mut SolveResult,
    k: u32,
    plan: &Plan,
    inputs: &SolveInputs,
    opts: &SolveOptions,
    progress: &dyn Progress,
    checkpoint: &mut dyn FnMut(&SolveResult) -> Result<(), ReflectError>,
) -> Result<(Pending, f64, f64), ReflectError> {
    let mut acc = resumed_pending(start, k);
    let already_in_iteration = acc.wall_s;
    let ti = Instant::now();
    let todo: Vec<&Group> = plan
        .groups
        .iter()
        .filter(|g| !g.parts.is_empty() && !acc.done.contains(&g.name))
        .collect();
    let total = texels_of(start, &todo) * inputs.photos.len() as u64;
    progress.begin(&format!("iteration {}", k + 1), total);
    // Jacobi: every group of this iteration sees the albedo of the previous one
    let snapshot = (opts.schedule == Schedule::Jacobi).then(|| Albedos::snapshot(&start.parts));
    for g in todo {
        let sums = solve_group(start, g, plan, snapshot.as_ref(), inputs, opts, k, progress)?;
        acc.add(&sums);
        acc.done.push(g.name.clone());
        if plan.groups.len() > 1 && opts.schedule == Schedule::GaussSeidel {
            acc.wall_s = already_in_iteration + ti.elapsed().as_secs_f64();
            start.report.pending = Some(acc.clone());
            checkpoint(start)?;
            start.set_changed(false);
        }
    }
    progress.finish();
    let wall = already_in_iteration + ti.elapsed().as_secs_f64();
    Ok((acc, wall, already_in_iteration))
}

/// [`solve`] without progress reports or checkpoints: the in-memory solve of the tests and
/// benchmarks.
pub fn solve_in_memory(
    start: SolveResult,
    photos: &[Photo],
    basis: Option<&Basis>,
    truth: Option<&Truth>,
    opts: &SolveOptions,
) -> Result<SolveResult, ReflectError> {
    solve(start, photos, basis, truth, opts, &NoProgress, &mut |_| {
        Ok(())
    })
}

/// The running statistics of iteration `k` (counted from 0): those a killed run left pending
/// for the same iteration (taken from the report), else fresh ones.
fn resumed_pending(start: &mut SolveResult, k: u32) -> Pending {
    match start.report.pending.take() {
        Some(p) if p.iteration == k + 1 => p,
        _ => Pending {
            iteration: k + 1,
            ..Pending::default()
        },
    }
}

/// The number of covered texels in the parts of `groups`.
fn texels_of(start: &SolveResult, groups: &[&Group]) -> u64 {
    groups
        .iter()
        .map(|g| {
            g.parts
                .iter()
                .map(|&i| start.parts[i].part.cache.texels.len() as u64)
                .sum::<u64>()
        })
        .sum::<u64>()
}

/// The samples per estimate of iteration `k` (counted from 0), after the iterations `done`
/// (the report's records): level `k` of the schedule, or with `adaptive_spp` the level reached
/// by [`rises`].
fn spp_of(opts: &SolveOptions, done: &[IterationRecord], k: u32) -> u32 {
    spp_at(opts, level(opts, done, k))
}

/// The samples of schedule level `level` (the last repeats).
fn spp_at(opts: &SolveOptions, level: usize) -> u32 {
    opts.spp[level.min(opts.spp.len() - 1)]
}

/// The schedule level of iteration `k`: `k`, or with `adaptive_spp` the number of earlier
/// iterations after which the level rose (a missing record counts as a rise), the last of a
/// coarse stage that ended settled ([`coarse_settled`]) among them.
fn level(opts: &SolveOptions, done: &[IterationRecord], k: u32) -> usize {
    if !opts.adaptive_spp {
        return k as usize;
    }
    let ends_settled_coarse_stage = |i: usize| {
        done[i].coarse
            && done.get(i + 1).is_none_or(|next| !next.coarse)
            && coarse_settled(&done[..i], &done[i])
    };
    (0..k as usize)
        .filter(|&i| done.get(i).is_none_or(rises) || ends_settled_coarse_stage(i))
        .count()
}

/// Whether the level rises after iteration `r`: its change beyond the Monte-Carlo noise was
/// within that noise (the albedo has settled to what these samples tell apart), or it has no
/// Monte-Carlo noise on record.
fn rises(r: &IterationRecord) -> bool {
    r.mc_noise_rho
        .is_none_or(|mc| r.systematic_change_rho <= mc)
}

/// Whether a coarse stage (`crate::coarse`) has settled with `rec`, the iteration after the
/// records `before`: the level rises after it ([`rises`]), or the next iteration's change
/// beyond the Monte-Carlo noise, predicted as a fixed-point iteration's (the last change
/// times its ratio to the one before), is within that noise. The bounces converge
/// geometrically, so on the large survey of docs/BENCHMARKS.md the second iteration predicts
/// 0.0015 against a noise of 0.0052, and a third changed the albedo by nothing beyond it.
fn coarse_settled(before: &[IterationRecord], rec: &IterationRecord) -> bool {
    let predicted = match before.last() {
        Some(prev) if prev.systematic_change_rho > 0.0 => {
            let ratio = rec.systematic_change_rho / prev.systematic_change_rho;
            if ratio <= 1.0 {
                rec.systematic_change_rho * ratio
            } else {
                f32::INFINITY
            }
        }
        _ => f32::INFINITY,
    };
    rises(rec) || rec.mc_noise_rho.is_some_and(|mc| predicted <= mc)
}

/// Solves one group in iteration `k` (counted from 0): traces its texels in every photograph
/// against its scene (built from `snapshot`, or from the current state without one), updates
/// its parts' albedo, weights, observation counts, summaries and lobes in `start`, and returns
/// the group's statistics.
#[allow(clippy::too_many_arguments)]
pub(crate) fn solve_group(
    start: &mut SolveResult,
    g: &Group,
    plan: &Plan,
    snapshot: Option<&Snapshot>,
    inputs: &SolveInputs,
    opts: &SolveOptions,
    k: u32,
    progress: &dyn Progress,
) -> Result<Pending, ReflectError> {
    let spp = spp_of(opts, &start.report.iterations, k);
    let albedo = match snapshot {
        Some(s) => Albedos::Snapshot(s),
        None => Albedos::Current(&start.parts),
    };
    let (scene, triangles, object_part) = group_scene(start, g, plan.store.as_ref(), albedo)?;
    for &i in &g.parts {
        start.report.parts[i].scene_triangles = triangles;
    }
    // texel streams are numbered across groups so no two texels share one
    let offset: u64 = start.parts[..g.parts[0]]
        .iter()
        .map(|p| p.part.cache.texels.len() as u64)
        .sum();
    let texels = group_texels(start, g);
    // the fine iteration after a coarse stage reads its shading from a lattice
    let after_coarse = start.report.iterations.last().is_some_and(|r| r.coarse);
    let shading_step = if after_coarse && opts.lattice_shading {
        crate::lattice::LATTICE_STEP
    } else {
        1
    };
    let mut obs: Vec<Obs> = Vec::new();
    let limit = igi_files::max_alloc()?;
    // a prepared site's other parts were sized by `igi prepare`: the group's atlases only
    let atlas_texels: u128 = g
        .parts
        .iter()
        .map(|&i| (start.parts[i].resolution() as u128).pow(2))
        .sum();
    let mut suns = SunVisibility::new(&start.parts, &texels);
    for (pi, photo) in inputs.photos.iter().enumerate() {
        if pi > 0 {
            check_observation_memory(atlas_texels, obs.len(), texels.len(), &photo.id, limit)?;
        }
        let shadow = suns.edges(&scene, &start.parts, photo);
        let pass = PhotoPass {
            scene: &scene,
            photo,
            photo_index: pi,
            texels: &texels,
            offset,
            state: start,
            basis: inputs.basis,
            opts,
            iteration: k,
            spp,
            shading_step,
            shadow,
        };
        obs.extend(pass.observe(progress));
    }
    if opts.smooth_shading {
        crate::smooth::smooth_shading(&mut obs, &start.parts);
    }
    let footprint = Footprint {
        scene: &scene,
        object_part: &object_part,
        photos: inputs.photos,
        parts: &start.parts,
        albedo,
    };
    footprint.deblur(&mut obs, opts.deblur);
    drop(scene);
    let mut sums = Pending::default();
    update_parts(start, &g.parts, &obs, opts, &mut sums);
    for &i in &g.parts {
        let p = &mut start.parts[i];
        p.lobes = part_lobes(&p.part, &p.rho, inputs.basis);
    }
    Ok(sums)
}

/// Every texel of a group's parts, with what the per-photo pass needs.
fn group_texels(start: &SolveResult, g: &Group) -> Vec<TexelRef> {
    g.parts
        .iter()
        .flat_map(|&i| {
            let p = &start.parts[i].part;
            p.cache
                .texels
                .iter()
                .enumerate()
                .map(move |(k, t)| TexelRef {
                    part: i as u32,
                    texel: k as u32,
                    position: t.position,
                    normal: t.normal,
                    uv: p.cache.uv(t.index),
                })
        })
        .collect()
}

/// Ends an iteration: its record from the summed statistics `acc` (with the truth error),
/// appended to the report with the convergence decision, which is returned. An iteration
/// without any observation is an error (an albedo from nothing cannot mean what was asked).
pub(crate) fn finish_iteration(
    start: &mut SolveResult,
    acc: &Pending,
    solved: &[bool],
    truth: Option<&Truth>,
    opts: &SolveOptions,
    wall_s: f64,
    cumulative_s: f64,
) -> Result<bool, ReflectError> {
    start.report.pending = None;
    let (truth_mae, truth_rms) = match truth {
        Some(t) => crate::truth::texel_error(start, t, solved),
        None => (None, None),
    };
    let truth_surface_mae = truth.and_then(|t| crate::truth::surface_error(start, t, solved).0);
    let k = acc.iteration - 1;
    let per_seen = |sum: f64| {
        if acc.seen_texels > 0 {
            (sum / acc.seen_texels as f64) as f32
        } else {
            0.0
        }
    };
    let level = level(opts, &start.report.iterations, k);
    let rec = IterationRecord {
        iteration: acc.iteration,
        spp: spp_at(opts, level),
        wall_s,
        cumulative_s,
        observations: acc.observations,
        residual_rms: ratio_sqrt(acc.residual_sq, acc.residual_channels as f64),
        residual_rel_rms: ratio_sqrt(acc.residual_sq, acc.pixel_sq),
        delta_rho: per_seen(acc.delta),
        noise_rho: per_seen(acc.noise2).sqrt(),
        systematic_change_rho: per_seen(acc.systematic2.max(0.0)).sqrt(),
        mc_noise_rho: Some(per_seen(acc.mc2).sqrt()),
        truth_mae,
        truth_rms,
        truth_surface_mae,
        seen_texels: acc.seen_texels,
        stale: Vec::new(),
        coarse: false,
    };
    tracing::info!(
        "iteration {}: {} spp, {:.1} s, {} observations, residual {:.4} ({:.2}% rel), change {:.5} ({:.5} beyond Monte-Carlo noise), photographs' noise {:.5}",
        rec.iteration,
        rec.spp,
        wall_s,
        rec.observations,
        rec.residual_rms,
        100.0 * rec.residual_rel_rms,
        rec.delta_rho,
        rec.systematic_change_rho,
        rec.noise_rho
    );
    if rec.observations == 0 {
        return Err(ReflectError::NoObservations(rec.iteration));
    }
    let next_level = level + usize::from(!opts.adaptive_spp || rises(&rec));
    let settled = acc.iteration >= opts.min_iterations
        && (rec.delta_rho < opts.tolerance
            || (rec.systematic_change_rho < rec.noise_rho && spp_at(opts, next_level) <= rec.spp));
    // after a coarse stage (crate::coarse) one iteration on the fine atlases ends the solve,
    // converged when the coarse stage was
    let after_coarse = start.report.iterations.last().is_some_and(|r| r.coarse);
    let converged = settled || (after_coarse && start.report.converged);
    let coarse_done = opts.coarse_stage
        && opts.adaptive_spp
        && acc.iteration >= opts.min_iterations
        && coarse_settled(&start.report.iterations, &rec);
    start.report.iterations.push(rec);
    start.report.converged = converged;
    Ok(settled || after_coarse || coarse_done)
}

/// sqrt(a / b), or 0 when b is not positive.
fn ratio_sqrt(a: f64, b: f64) -> f32 {
    if b > 0.0 {
        (a / b).sqrt() as f32
    } else {
        0.0
    }
}

/// Combines the observations of a group's parts into their new albedo (outlier rejection and
/// the weighted mean per texel, then the fill of unseen texels), updating the part summaries
/// and the iteration's running statistics.
fn update_parts(
    start: &mut SolveResult,
    group: &[usize],
    obs: &[Obs],
    opts: &SolveOptions,
    acc: &mut Pending,
) {
    let mut per_texel: Vec<Vec<Vec<Proposal>>> = start.parts.iter().map(|_| Vec::new()).collect();
    let mut any_clean: Vec<Vec<bool>> = start.parts.iter().map(|_| Vec::new()).collect();
    for &pi in group {
        let n = start.parts[pi].part.cache.texels.len();
        per_texel[pi] = vec![Vec::new(); n];
        any_clean[pi] = vec![false; n];
    }
    for o in obs {
        per_texel[o.part as usize][o.texel as usize].push(Proposal {
            value: o.proposal,
            weight: o.weight,
            mc_var: o.mc_var,
        });
        any_clean[o.part as usize][o.texel as usize] |= o.clean;
        acc.residual_sq += o.residual.length_squared() as f64;
        acc.pixel_sq += o.pixel.length_squared() as f64;
        acc.residual_channels += 3;
    }
    acc.observations += obs.len() as u64;
    for &pi in group {
        update_part(start, pi, &per_texel[pi], &any_clean[pi], opts, acc);
    }
}

/// The new state of part `pi` from its texels' proposals `per_texel` (`any_clean`: the texel has
/// a proposal away from occlusion boundaries and shadow edges): each combined texel's albedo,
/// weight, standard error and observation count, the unseen texels filled, the part summary.
fn update_part(
    start: &mut SolveResult,
    pi: usize,
    per_texel: &[Vec<Proposal>],
    any_clean: &[bool],
    opts: &SolveOptions,
    acc: &mut Pending,
) {
    let pr = &mut start.parts[pi];
    let p = &pr.part;
    let res = p.resolution();
    let mut seen = vec![false; res * res];
    let covered: Vec<bool> = p.coverage.pixels.iter().map(|c| c[0] == 1.0).collect();
    let gutter: Vec<bool> = p.coverage.pixels.iter().map(|c| c[0] > 0.0).collect();
    let (mut nseen_p, mut twice) = (0usize, 0usize);
    let mut new_rho = pr.rho.clone();
    for (ti, t) in p.cache.texels.iter().enumerate() {
        let i = t.index as usize;
        let props = &per_texel[ti];
        // seen only through occlusion boundaries or shadow edges: not reliable; filled
        let combined = if any_clean[ti] {
            combine(props, &opts.rules)
        } else {
            None
        };
        pr.observations[i] = if combined.is_some() {
            props.iter().filter(|p| p.weight > 0.0).count() as u32
        } else {
            0
        };
        match combined {
            Some(c) => {
                let v = c.value;
                acc.delta += (v - pr.rho[i]).abs().max_element() as f64;
                let (noise2, systematic2, mc2) = change_against_noise(pr.rho[i], pr.stderr[i], &c);
                acc.noise2 += noise2;
                acc.systematic2 += systematic2;
                acc.mc2 += mc2;
                acc.seen_texels += 1;
                nseen_p += 1;
                if pr.observations[i] >= 2 {
                    twice += 1;
                }
                new_rho[i] = v;
                pr.weight_sum[i] = c.weight;
                pr.stderr[i] = c.stderr;
                seen[i] = true;
            }
            None => {
                pr.weight_sum[i] = 0.0;
                pr.stderr[i] = UNKNOWN_STDERR;
            }
        }
    }
    let fallback = Vec3::from_array(opts.initial_albedo);
    let filled = fill_unseen(&mut new_rho, &seen, &covered, &gutter, res, fallback, 8);
    pr.rho = new_rho;
    pr.changed = true;
    let s = &mut start.report.parts[pi];
    s.seen_texels = nseen_p;
    s.seen_twice_texels = twice;
    s.filled_texels = filled;
}

/// A seen texel's squared photograph noise, its squared change beyond the Monte-Carlo noise
/// (unclamped) and its squared Monte-Carlo noise, each averaged over the channels, for the
/// stopping rule and the samples' schedule: `old` and `old_se` are
/// the texel's albedo and standard error before this iteration (`old_se` negative when
/// unknown: no Monte-Carlo noise is subtracted for it), `c` its new combination. The previous
/// estimate's Monte-Carlo variance is its squared standard error less this iteration's squared
/// photograph noise (the photographs are the same).
fn change_against_noise(old: Vec3, old_se: Vec3, c: &Combined) -> (f64, f64, f64) {
    let photo2 = c.photo_noise * c.photo_noise;
    let mc_new2 = (c.stderr * c.stderr - photo2).max(Vec3::ZERO);
    let mc_old2 = if old_se.min_element() >= 0.0 {
        (old_se * old_se - photo2).max(Vec3::ZERO)
    } else {
        Vec3::ZERO
    };
    let d = c.value - old;
    let excess = d * d - mc_new2 - mc_old2;
    (
        photo2.element_sum() as f64 / 3.0,
        excess.element_sum() as f64 / 3.0,
        mc_new2.element_sum() as f64 / 3.0,
    )
}

/// One texel's raw observation in a photo: what the ratio update needs (see [`PhotoPass`]).
#[derive(Clone, Copy)]
struct RawObservation {
    /// The texel's number in the group.
    gi: u32,
    /// The radiance was traced for this texel (else it is still to be read from the lattice
    /// around it, `crate::lattice`, or traced).
    traced: bool,
    /// The texel's normal facing the camera, and the direction to the camera.
    n: Vec3,
    wo: Vec3,
    /// The photograph at the texel's projection (bilinear).
    pixel: Vec3,
    /// The radiance rendered toward the camera with the evaluation albedo, and its standard
    /// error.
    radiance: Vec3,
    stderr: Vec3,
    weight: f32,
    /// Neither at an occlusion boundary nor at a shadow edge.
    clean: bool,
    /// At a shadow edge (so its shading stands for no other texel).
    shadow_edge: bool,
    /// The evaluation albedo the radiance was rendered with.
    rho_eval: Vec3,
    /// The texel's projection (pixels).
    px: Vec2,
    /// See [`PhotoPass::deblur_gain`].
    deblur_gain: f32,
}

/// The per-photo pass of a group: everything it reads, in one context. [`PhotoPass::observe`]
/// traces every texel of the group toward the photograph's camera under its lighting and
/// returns the texels' ratio proposals.
struct PhotoPass<'a> {
    scene: &'a Scene,
    photo: &'a Photo,
    photo_index: usize,
    texels: &'a [TexelRef],
    /// The first texel stream number of the group (streams are numbered across groups).
    offset: u64,
    state: &'a SolveResult,
    basis: Option<&'a Basis>,
    opts: &'a SolveOptions,
    iteration: u32,
    spp: u32,
    /// Trace every `shading_step`-th texel per atlas row and column and read the rest from them
    /// (`crate::lattice`; 1: trace every texel).
    shading_step: u32,
    /// The shadow edges under the photograph's sun (`None` without a sun).
    shadow: Option<ShadowEdges>,
}

/// Texels whose sun visibility differs from an atlas neighbour's (the shadow-edge rule).
struct ShadowEdges {
    /// Sun visibility per part and texel (empty for the parts outside the group).
    visible: Arc<Vec<Vec<bool>>>,
    /// Atlas index -> texel number per part, for neighbour lookups (empty outside the group).
    texel_of: Arc<Vec<Vec<u32>>>,
}

/// The sun visibility of a group's texels, traced once per sun direction: photographs taken
/// under one lighting share it (the large survey's 32 photographs have 3 suns).
struct SunVisibility {
    in_group: Vec<bool>,
    /// [`ShadowEdges::texel_of`], made for the first sun (never without one).
    texel_of: Option<Arc<Vec<Vec<u32>>>>,
    /// The latest suns traced, at most [`SUNS_KEPT`].
    traced: Vec<(Vec3, Arc<Vec<Vec<bool>>>)>,
}

/// How many suns' visibility a group keeps (a byte per texel each).
pub const SUNS_KEPT: usize = 4;

impl SunVisibility {
    fn new(parts: &[PartResult], texels: &[TexelRef]) -> SunVisibility {
        let mut in_group = vec![false; parts.len()];
        for t in texels {
            in_group[t.part as usize] = true;
        }
        SunVisibility {
            in_group,
            texel_of: None,
            traced: Vec::new(),
        }
    }

    /// Atlas index -> texel number for each part of the group.
    fn atlas_texels(&self, parts: &[PartResult]) -> Vec<Vec<u32>> {
        parts
            .iter()
            .zip(&self.in_group)
            .map(|(p, &g)| {
                if !g {
                    return Vec::new();
                }
                p.part.cache.numbers()
            })
            .collect()
    }

    /// The shadow edges under `photo`'s sun (`None` without one), traced in `scene` for the
    /// group's parts only: a texel's neighbours are in its own part, and tracing the whole site
    /// for every group made a prepared site's solve grow with the square of its voxels.
    fn edges(&mut self, scene: &Scene, parts: &[PartResult], photo: &Photo) -> Option<ShadowEdges> {
        let dir = photo.lighting.sun.as_ref()?.direction;
        let visible = match self.traced.iter().find(|(d, _)| *d == dir) {
            Some((_, v)) => v.clone(),
            None => {
                let v = Arc::new(self.trace(scene, parts, dir));
                if self.traced.len() == SUNS_KEPT {
                    self.traced.remove(0);
                }
                self.traced.push((dir, v.clone()));
                v
            }
        };
        let texel_of = match &self.texel_of {
            Some(m) => m.clone(),
            None => {
                let m = Arc::new(self.atlas_texels(parts));
                self.texel_of.insert(m).clone()
            }
        };
        Some(ShadowEdges { visible, texel_of })
    }

    fn trace(&self, scene: &Scene, parts: &[PartResult], dir: Vec3) -> Vec<Vec<bool>> {
        parts
            .iter()
            .zip(&self.in_group)
            .map(|(p, &g)| {
                if !g {
                    return Vec::new();
                }
                p.part
                    .cache
                    .texels
                    .par_iter()
                    .map(|t| {
                        let n = if t.normal.dot(dir) < 0.0 {
                            -t.normal
                        } else {
                            t.normal
                        };
                        !scene.occluded(offset_origin(t.position, n), dir, f32::INFINITY)
                    })
                    .collect()
            })
            .collect()
    }
}

impl ShadowEdges {
    /// Whether texel `t` lies on a shadow edge: a 4-neighbour in the atlas sees the sun
    /// differently.
    fn at(&self, parts: &[PartResult], t: &TexelRef) -> bool {
        let (pi, vis, map) = (
            t.part as usize,
            &self.visible[t.part as usize],
            &self.texel_of[t.part as usize],
        );
        let r = parts[pi].resolution() as i64;
        let idx = parts[pi].part.cache.texels[t.texel as usize].index as i64;
        let (x, y) = (idx % r, idx / r);
        let me = vis[t.texel as usize];
        [(-1, 0), (1, 0), (0, -1), (0, 1)].iter().any(|&(dx, dy)| {
            let (xx, yy) = (x + dx, y + dy);
            if xx < 0 || yy < 0 || xx >= r || yy >= r {
                return false;
            }
            let k = map[(yy * r + xx) as usize];
            k != u32::MAX && vis[k as usize] != me
        })
    }
}

impl PhotoPass<'_> {
    /// The observations of every texel of the group in this photograph.
    fn observe(&self, progress: &dyn Progress) -> Vec<Obs> {
        let shadow = &self.shadow;
        let render_opts = RenderOptions {
            spp: self.spp,
            seed: self.opts.seed,
            indirect: self.opts.indirect,
            russian_roulette: false,
            // the first vertex's light and bounce numbers spread evenly over the samples
            stratified: true,
            adaptive: false,
        };
        let pt = PathTracer::new(self.scene, &self.photo.lighting, &render_opts);
        let parts = &self.state.parts;
        let lattice = (self.shading_step > 1).then(|| {
            let keys = self.texels.iter().map(|t| (t.part, t.texel));
            Lattice::new(parts, keys, self.shading_step)
        });
        let chunk = 4096;
        let raw: Vec<Option<RawObservation>> = self
            .texels
            .par_chunks(chunk)
            .enumerate()
            .flat_map_iter(|(ci, ch)| {
                let out: Vec<_> = ch
                    .iter()
                    .enumerate()
                    .map(|(j, t)| {
                        let trace = lattice
                            .as_ref()
                            .is_none_or(|l| l.traced(parts, t.part, t.texel));
                        self.observe_texel(t, (ci * chunk + j) as u64, &pt, shadow, trace)
                    })
                    .collect();
                progress.advance(ch.len() as u64);
                out
            })
            .collect();
        let raw = match &lattice {
            Some(l) => self.between_lattice(raw, l, &pt, shadow),
            None => raw,
        };
        self.proposals(raw)
    }

    /// The observations off the lattice given their radiance: the blend of the lattice texels
    /// around them where those stand for them, else traced (`crate::lattice`).
    fn between_lattice(
        &self,
        raw: Vec<Option<RawObservation>>,
        lattice: &Lattice,
        pt: &PathTracer,
        shadow: &Option<ShadowEdges>,
    ) -> Vec<Option<RawObservation>> {
        let parts = &self.state.parts;
        raw.par_iter()
            .map(|r| {
                let mut r = (*r)?;
                if r.traced {
                    return Some(r);
                }
                let t = &self.texels[r.gi as usize];
                let corners = lattice.corners(parts, t.part, t.texel);
                let of = |n: u32| self.stands_for(&raw, n, t, shadow);
                match corners.and_then(|cs| blend(&cs, of)) {
                    Some((shading, se)) => {
                        r.radiance = shading * r.rho_eval;
                        r.stderr = se * r.rho_eval;
                    }
                    None => {
                        let (est, rho_eval) = self.estimate(t, r.n, r.wo, r.gi as u64, pt);
                        (r.radiance, r.stderr, r.rho_eval) = (est.mean, est.stderr, rho_eval);
                    }
                }
                r.traced = true;
                Some(r)
            })
            .collect()
    }

    /// The shading and its standard error per unit albedo of lattice texel number `n`, when
    /// it can stand for texel `t`: traced, not at a shadow edge, in the same sunlight, the same
    /// surface. (An occlusion boundary in the photograph lowers the weight of a texel's pixel,
    /// not the trust in its shading, which is traced at the texel itself.)
    fn stands_for(
        &self,
        raw: &[Option<RawObservation>],
        n: u32,
        t: &TexelRef,
        shadow: &Option<ShadowEdges>,
    ) -> Option<(Vec3, Vec3)> {
        let c = raw[n as usize]
            .as_ref()
            .filter(|c| c.traced && !c.shadow_edge)?;
        let ct = &self.texels[n as usize];
        let texel_size = self.state.parts[t.part as usize].part.texel_size;
        let same_light = shadow.as_ref().is_none_or(|s| {
            let v = &s.visible[t.part as usize];
            v[t.texel as usize] == s.visible[ct.part as usize][ct.texel as usize]
        });
        let one_surface = ct.part == t.part
            && ct.normal.dot(t.normal) >= crate::lattice::MIN_NORMAL_DOT
            && ct.position.distance(t.position) <= reach(self.shading_step, texel_size);
        (same_light && one_surface).then(|| (c.radiance / c.rho_eval, c.stderr / c.rho_eval))
    }

    /// The albedo texel `t`'s radiance is rendered with: its current one, at least
    /// `min_eval_albedo` per channel.
    fn rho_eval(&self, t: &TexelRef) -> Vec3 {
        self.rho(t).max(Vec3::splat(self.opts.min_eval_albedo))
    }

    /// The current albedo of texel `t`.
    fn rho(&self, t: &TexelRef) -> Vec3 {
        let p = &self.state.parts[t.part as usize];
        p.rho[p.part.cache.texels[t.texel as usize].index as usize]
    }

    /// Geometric tests and the radiance estimate of texel `t` (number `gi` in the group):
    /// `None` when the photograph does not see it.
    fn observe_texel(
        &self,
        t: &TexelRef,
        gi: u64,
        pt: &PathTracer,
        shadow: &Option<ShadowEdges>,
        trace: bool,
    ) -> Option<RawObservation> {
        let (rules, cam) = (&self.opts.rules, &self.photo.camera);
        let c = cam.center_world().as_vec3();
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
        if self
            .scene
            .occluded(origin, wo, (c - origin).length() * (1.0 - 1e-4))
        {
            return None;
        }
        let pixel = Vec3::from_array(self.photo.image.bilinear(px.x as f32, px.y as f32)?);
        let mut clean = self.on_tangent_plane(t, n, px, dist);
        let mut weight = if clean {
            cos
        } else {
            cos * rules.boundary_factor
        };
        let shadow_edge = shadow.as_ref().is_some_and(|s| s.at(&self.state.parts, t));
        if shadow_edge {
            weight *= rules.shadow_edge_factor;
            clean = false;
        }
        let (radiance, stderr, rho_eval) = if trace {
            let (est, rho_eval) = self.estimate(t, n, wo, gi, pt);
            (est.mean, est.stderr, rho_eval)
        } else {
            (Vec3::ZERO, Vec3::ZERO, self.rho_eval(t))
        };
        Some(RawObservation {
            gi: gi as u32,
            traced: trace,
            n,
            wo,
            pixel,
            radiance,
            stderr,
            weight,
            clean,
            shadow_edge,
            rho_eval,
            px: px.as_vec2(),
            deblur_gain: self.deblur_gain(t, cos),
        })
    }

    /// The share of the deblurring correction texel `t` takes in this photograph (seen at
    /// `cos` to its normal): (texel / pixel footprint)^2 at most 1, the footprint taken as the
    /// pixel's depth over the focal length divided by sqrt(cos) (the geometric mean of its two
    /// sides on the surface).
    fn deblur_gain(&self, t: &TexelRef, cos: f32) -> f32 {
        let texel = self.state.parts[t.part as usize].part.texel_size;
        match point_footprint(&self.photo.camera, t.position.as_dvec3()) {
            Some(f) => ((texel * (cos as f64).sqrt() / f).min(1.0).powi(2)) as f32,
            None => 0.0,
        }
    }

    /// The occlusion-boundary / misregistration test: rays through the pixels around the
    /// texel's projection `px` must land on the texel's tangent plane (not merely at its depth:
    /// on a surface seen at a grazing angle the depth changes by several percent per pixel).
    fn on_tangent_plane(&self, t: &TexelRef, n: Vec3, px: DVec2, dist: f32) -> bool {
        let (rules, cam) = (&self.opts.rules, &self.photo.camera);
        let o = rules.boundary_offset_px;
        // the four rays start at the camera a pixel apart: one coherent packet
        let rays = [(o, 0.0), (-o, 0.0), (0.0, o), (0.0, -o)].map(|(dx, dy)| {
            let (ro, rd) = cam.pixel_ray(px.x + dx, px.y + dy);
            RaySegment {
                origin: ro.as_vec3(),
                dir: rd.as_vec3(),
                tnear: 0.0,
                tfar: f32::INFINITY,
            }
        });
        let mut hits = [None; 4];
        self.scene.rt().intersect_packet(&rays, true, &mut hits);
        rays.iter().zip(&hits).all(|(r, hit)| {
            let denom = n.dot(r.dir);
            let t_plane = if denom.abs() > 1e-6 {
                n.dot(t.position - r.origin) / denom
            } else {
                f32::INFINITY
            };
            hit.is_some_and(|h| {
                (h.t - t_plane).abs() <= rules.depth_tolerance * dist
                    && h.ng.normalize_or_zero().dot(n).abs() >= rules.min_normal_agreement
            })
        })
    }

    /// The radiance leaving texel `t` toward the camera (direction `wo`, normal `n` facing
    /// it) with the evaluation albedo at the texel, and that albedo. The texel carries its own
    /// lobes, inferred from its albedo; other surfaces, met by the bounces, carry their part's.
    fn estimate(
        &self,
        t: &TexelRef,
        n: Vec3,
        wo: Vec3,
        gi: u64,
        pt: &PathTracer,
    ) -> (igi_render::integrator::Estimate, Vec3) {
        let rho_eval = self.rho_eval(t);
        let inferred = self.basis.map(|b| b.infer(rho_eval).lobes);
        let brdf = LafortuneRef {
            rho_d: rho_eval,
            lobes: inferred
                .as_deref()
                .unwrap_or(&self.state.parts[t.part as usize].lobes),
        };
        let sp = SurfacePoint {
            position: t.position,
            ng: n,
            ns: n,
            uv: t.uv,
            object: t.part,
            prim: 0,
        };
        let stream = hash2(
            self.opts.seed,
            ((self.iteration as u64) << 32) | self.photo_index as u64,
        );
        let mut rng = Rng::new(stream, self.offset + gi);
        (
            pt.lo_estimate(&sp, wo, Some(brdf), self.spp, &mut rng),
            rho_eval,
        )
    }

    /// The ratio proposals of the raw observations, dropping those rendered below the
    /// near-zero floor (relative to the photograph's median rendered luminance) or too noisy.
    fn proposals(&self, raw: Vec<Option<RawObservation>>) -> Vec<Obs> {
        let rules = &self.opts.rules;
        let mut lums: Vec<f32> = raw
            .iter()
            .flatten()
            .map(|r| luminance(r.radiance))
            .filter(|l| *l > 0.0)
            .collect();
        let median = if lums.is_empty() {
            0.0
        } else {
            let m = lums.len() / 2;
            *lums.select_nth_unstable_by(m, |a, b| a.total_cmp(b)).1
        };
        let floor = (median * rules.min_radiance_fraction).max(1e-12);
        raw.into_iter()
            .flatten()
            .filter_map(|r| {
                let (ll, se) = (luminance(r.radiance), luminance(r.stderr));
                if !(ll > floor) || se > rules.max_rel_stderr * ll {
                    return None;
                }
                Some(self.proposal(r, floor))
            })
            .collect()
    }

    /// One texel's proposal `rho_eval * pixel / L` per channel (a channel rendered at zero
    /// keeps the current value), its Monte-Carlo variance (the relative error of `L`), and the
    /// residual of the rendering with the current albedo.
    fn proposal(&self, r: RawObservation, floor: f32) -> Obs {
        let RawObservation {
            gi,
            traced: _,
            n: _,
            wo: _,
            pixel,
            radiance: l,
            stderr: se,
            weight,
            clean,
            shadow_edge: _,
            rho_eval,
            px,
            deblur_gain,
        } = r;
        let t = &self.texels[gi as usize];
        let rho = self.rho(t);
        let lit = |ch: usize| l[ch] > floor * 1e-3;
        let proposal = Vec3::from_array(std::array::from_fn(|ch| {
            if lit(ch) {
                rho_eval[ch] * pixel[ch] / l[ch]
            } else {
                rho[ch]
            }
        }));
        let mc_var = Vec3::from_array(std::array::from_fn(|ch| {
            if lit(ch) {
                (proposal[ch] * se[ch] / l[ch]).powi(2)
            } else {
                0.0
            }
        }));
        let shading = Vec3::from_array(std::array::from_fn(|ch| {
            if lit(ch) {
                l[ch] / rho_eval[ch]
            } else {
                0.0
            }
        }));
        // rendered radiance with the current albedo (linear in the first vertex's albedo)
        let current = l * (rho / rho_eval);
        let part = &self.state.parts[t.part as usize].part;
        Obs {
            part: t.part,
            texel: t.texel,
            atlas: part.cache.texels[t.texel as usize].index,
            photo: self.photo_index as u32,
            px,
            shading,
            deblur_gain,
            proposal,
            weight,
            mc_var,
            clean,
            residual: current - pixel,
            pixel,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Results written before the field names were spelled out still resume.
    #[test]
    fn pending_reads_the_old_field_names() {
        let p: Pending = serde_json::from_str(
            r#"{"iteration":2,"done":["a"],"wall_s":1.0,"observations":7,"res2":1.5,"rel2":2.5,"nres":3,"delta":0.25,"nseen":4}"#,
        )
        .unwrap();
        assert_eq!(
            (
                p.residual_sq,
                p.pixel_sq,
                p.residual_channels,
                p.seen_texels
            ),
            (1.5, 2.5, 3, 4)
        );
        let again: Pending = serde_json::from_str(&serde_json::to_string(&p).unwrap()).unwrap();
        assert_eq!(again.seen_texels, 4);
    }

    /// The observations' check: a photograph is refused exactly when the observations held
    /// and one per texel of the group from it, beside the atlases, pass the limit; the message
    /// names the photograph and the limit's variable.
    #[test]
    fn a_photograph_whose_observations_could_pass_the_limit_is_refused_before_it_is_traced() {
        let (atlas, texels) = (1000u128, 300usize);
        let at =
            |held: usize| atlas_memory(atlas) + (held + texels) as u128 * BYTES_PER_OBSERVATION;
        assert_eq!(
            BYTES_PER_OBSERVATION,
            96 + 28,
            "docs/RELIABILITY.md says 124 bytes"
        );
        let limit = at(500) as u64;
        assert!(check_observation_memory(atlas, 500, texels, "v03", limit).is_ok());
        let e = check_observation_memory(atlas, 501, texels, "v03", limit).unwrap_err();
        let m = e.to_string();
        assert!(
            m.contains("photograph v03's observations")
                && m.contains(&format!("({} bytes)", limit + BYTES_PER_OBSERVATION as u64))
                && m.contains("IGI_MAX_MEMORY"),
            "{m}"
        );
    }

    /// `finish_iteration` on an empty result after iteration `it` with mean change `delta`,
    /// RMS change beyond the Monte-Carlo noise `delta` and RMS photograph noise `noise` per
    /// seen texel: whether the solve stops.
    fn stops(it: u32, delta: f64, noise: f64, tolerance: f32) -> (bool, IterationRecord) {
        let opts = SolveOptions {
            tolerance,
            ..SolveOptions::default()
        };
        let mut r = SolveResult::fresh(Vec::new(), vec!["p".into()], &opts);
        let acc = Pending {
            iteration: it,
            observations: 10,
            seen_texels: 10,
            delta: 10.0 * delta,
            systematic2: 10.0 * delta * delta,
            noise2: 10.0 * noise * noise,
            ..Pending::default()
        };
        let done = finish_iteration(&mut r, &acc, &[], None, &opts, 1.0, 1.0).unwrap();
        (done, r.report.iterations.pop().unwrap())
    }

    #[test]
    fn the_solve_stops_once_an_iteration_moves_the_albedo_less_than_the_photographs_noise() {
        // iteration 3 of the default 16, 64, 256: the samples stop growing
        let (done, rec) = stops(3, 0.004, 0.005, 0.0);
        assert!(done);
        assert!((rec.systematic_change_rho - 0.004).abs() < 1e-7);
        assert!((rec.noise_rho - 0.005).abs() < 1e-7);
        // while the samples still grow (iteration 2 at 64 of 16, 64, 256), it goes on: the
        // next iteration's Monte-Carlo noise is smaller
        assert!(!stops(2, 0.004, 0.005, 0.0).0);
        // a change above the noise goes on, unless below the tolerance
        assert!(!stops(3, 0.006, 0.005, 0.0).0);
        assert!(stops(3, 0.006, 0.005, 0.01).0);
        // never before the second iteration
        assert!(!stops(1, 0.001, 0.005, 0.01).0);
        // noiseless photographs (every texel seen once): only the tolerance stops it
        assert!(!stops(3, 1e-4, 0.0, 0.0).0);
    }

    /// Runs iterations on an empty result, each (change beyond the Monte-Carlo noise,
    /// Monte-Carlo noise) with photograph noise 0.001: each iteration's samples and whether the
    /// solve stopped after it.
    fn schedule(adaptive: bool, iterations: &[(f64, f64)]) -> Vec<(u32, bool)> {
        let opts = SolveOptions {
            tolerance: 0.0,
            adaptive_spp: adaptive,
            ..SolveOptions::default()
        };
        run_schedule(&opts, iterations).0
    }

    /// [`schedule`] under `opts`, and the result with its records.
    fn run_schedule(
        opts: &SolveOptions,
        iterations: &[(f64, f64)],
    ) -> (Vec<(u32, bool)>, SolveResult) {
        let mut r = SolveResult::fresh(Vec::new(), vec!["p".into()], opts);
        let mut out = Vec::new();
        for (k, &(systematic, mc)) in iterations.iter().enumerate() {
            let acc = Pending {
                iteration: k as u32 + 1,
                observations: 10,
                seen_texels: 10,
                delta: 10.0 * systematic,
                systematic2: 10.0 * systematic * systematic,
                noise2: 10.0 * 1e-6,
                mc2: 10.0 * mc * mc,
                ..Pending::default()
            };
            let done = finish_iteration(&mut r, &acc, &[], None, opts, 1.0, 1.0).unwrap();
            let rec = r.report.iterations.last().unwrap();
            assert!((rec.mc_noise_rho.unwrap() as f64 - mc).abs() < 1e-6);
            out.push((rec.spp, done));
        }
        (out, r)
    }

    #[test]
    fn a_coarse_stage_ends_once_its_next_change_is_predicted_within_the_noise() {
        let coarse = SolveOptions {
            tolerance: 0.0,
            adaptive_spp: true,
            coarse_stage: true,
            ..SolveOptions::default()
        };
        // the large survey's coarse stage (docs/BENCHMARKS.md): 0.139, then 0.0144 against a
        // noise of 0.0052 predicts 0.0015 next, so it ends after its second iteration
        let survey = [(0.139, 0.0049), (0.0144, 0.0052)];
        let (sched, mut r) = run_schedule(&coarse, &survey);
        assert_eq!(sched, [(16, false), (16, true)]);
        // a slower contraction goes on (0.05 after 0.1 predicts 0.025), and so does a growing
        // change; a change within the noise ends it as the level would rise
        let slow = [(0.1, 0.005), (0.05, 0.005), (0.02, 0.005), (0.004, 0.005)];
        let sched_slow = run_schedule(&coarse, &slow).0;
        assert_eq!(
            sched_slow,
            [(16, false), (16, false), (16, false), (16, true)]
        );
        let growing = [(0.01, 0.005), (0.02, 0.005)];
        assert_eq!(
            run_schedule(&coarse, &growing).0,
            [(16, false), (16, false)]
        );
        // a solve on its own atlases does not stop on the prediction
        assert_eq!(schedule(true, &survey), [(16, false), (16, false)]);
        // the fine iteration after a stage that ended settled takes the next level of samples,
        // as after a coarse iteration that rose; after one ended unsettled (by its iterations'
        // limit) it keeps the level
        for rec in &mut r.report.iterations {
            rec.coarse = true;
        }
        assert_eq!(spp_of(&coarse, &r.report.iterations, 2), 64);
        r.report.iterations.truncate(1);
        assert_eq!(spp_of(&coarse, &r.report.iterations, 1), 16);
    }

    #[test]
    fn the_adaptive_schedule_holds_the_samples_while_the_albedo_moves_more_than_their_noise() {
        let run = [(0.1, 0.01), (0.005, 0.01), (0.0005, 0.005), (0.0005, 0.002)];
        // iteration 1 moved the albedo 10 x its Monte-Carlo noise: iteration 2 keeps 16;
        // iteration 2 moved it less than its noise: 64, then 256, and the solve stops once the
        // change is below the photographs' noise at the last level
        assert_eq!(
            schedule(true, &run),
            [(16, false), (16, false), (64, false), (256, true)]
        );
        // the fixed schedule follows the levels iteration by iteration
        assert_eq!(
            schedule(false, &run),
            [(16, false), (64, false), (256, true), (256, true)]
        );
        // a record without Monte-Carlo noise (a report from before it was recorded) rises
        let opts = SolveOptions {
            adaptive_spp: true,
            ..SolveOptions::default()
        };
        let mut r = SolveResult::fresh(Vec::new(), vec!["p".into()], &opts);
        let acc = Pending {
            iteration: 1,
            observations: 10,
            seen_texels: 10,
            systematic2: 10.0,
            ..Pending::default()
        };
        finish_iteration(&mut r, &acc, &[], None, &opts, 1.0, 1.0).unwrap();
        assert_eq!(spp_of(&opts, &r.report.iterations, 1), 16);
        r.report.iterations[0].mc_noise_rho = None;
        assert_eq!(spp_of(&opts, &r.report.iterations, 1), 64);
    }

    #[test]
    fn the_change_the_monte_carlo_noise_explains_is_not_counted_against_the_noise() {
        let c = |value: f32, stderr: f32, photo: f32| Combined {
            value: Vec3::splat(value),
            weight: 1.0,
            stderr: Vec3::splat(stderr),
            photo_noise: Vec3::splat(photo),
        };
        // stderr 0.05 of which photographs 0.03: Monte-Carlo 0.04 now and before
        let (n2, s2, mc2) =
            change_against_noise(Vec3::splat(0.5), Vec3::splat(0.05), &c(0.6, 0.05, 0.03));
        assert!((mc2 - 0.0016).abs() < 1e-9, "{mc2}");
        assert!((n2 - 0.0009).abs() < 1e-9, "{n2}");
        assert!((s2 - (0.01 - 0.0016 - 0.0016)).abs() < 1e-7, "{s2}");
        // a change smaller than the Monte-Carlo noise counts negative (summed, then clamped)
        let (_, s2, _) =
            change_against_noise(Vec3::splat(0.5), Vec3::splat(0.05), &c(0.51, 0.05, 0.03));
        assert!(s2 < 0.0, "{s2}");
        // unknown previous standard error: only this estimate's noise is subtracted
        let (_, s2, _) =
            change_against_noise(Vec3::splat(0.5), UNKNOWN_STDERR, &c(0.6, 0.05, 0.03));
        assert!((s2 - (0.01 - 0.0016)).abs() < 1e-7, "{s2}");
    }

    #[test]
    fn a_mesh_name_selects_the_pieces_cut_from_it_and_nothing_else() {
        for part in ["ground", "ground-0", "ground-3-12", "ground-0-0-1"] {
            assert!(selects("ground", part), "{part}");
        }
        for part in [
            "grounds",
            "ground-",
            "ground-a",
            "ground-0-",
            "ground--1",
            "groun",
        ] {
            assert!(!selects("ground", part), "{part}");
        }
        assert!(selects("ground-0", "ground-0-2"));
        assert!(!selects("ground-0", "ground-1"));
    }
}
