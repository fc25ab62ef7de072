//! Coarse to fine: the first iterations of a solve on atlases [`COARSE_FACTOR`] times coarser,
//! then one on the solve's own.
//!
//! The solve's cost is one path-traced estimate per (texel, photograph), so it grows with the
//! texel count; what the first iterations must settle is the light between the surfaces (the
//! bounces start from the initial grey), which varies at the scale of the geometry, not of the
//! albedo's detail. On the coarse atlases those iterations cost about `COARSE_FACTOR`^2 times
//! less and reach the error of the coarse atlas; the albedo they settle is then read at the fine
//! texels (the coarse atlases' bilinear lookup), and one iteration on the fine atlases divides
//! each photograph by the shading of that settled albedo, which brings in the detail the finer
//! texels resolve. A second fine iteration would only redo the bounces with the detail added,
//! which average it out (docs/SOLVER.md, "Coarse to fine", measures it).
//!
//! The coarse stage runs up to `max_iterations - 1` iterations and ends by the solve's own
//! rule, or, with adaptive samples, once it has settled: the level of samples would rise, or
//! the next iteration's change is predicted within the Monte-Carlo noise (the bounces converge
//! geometrically). Its end then counts as a rise, so the fine iteration takes the next level
//! of samples as it did after a coarse iteration that rose. Its records stay in the report
//! (marked `coarse`), and the solver ends the run after the first fine iteration that follows
//! them (converged when the coarse stage was). It is not checkpointed: a run killed before the
//! first fine iteration redoes it.

use crate::atlas_size::AtlasChoice;
use crate::fill::dilate;
use crate::parts::{build_parts_with, Part};
use crate::result::SolveResult;
use crate::solver::{solve, Progress};
use crate::truth::{albedo_at_texels, Truth};
use crate::{ReflectError, SolveOptions};
use igi_brdf::Basis;
use std::collections::HashMap;

use crate::photo::Photo;

pub use crate::record::COARSE_FACTOR;

/// The coarse stage pays only when it has at most this share of the fine atlases' texels.
const MAX_COARSE_SHARE: f64 = 0.25;

/// The coarsest atlas of a part in the coarse stage (texels per side).
const MIN_COARSE_RESOLUTION: u32 = 16;

/// The parts of `fine` on atlases [`COARSE_FACTOR`] times coarser (rounded up to 16 texels per
/// side), or `None` when they would not have at most a quarter of the fine atlases' covered
/// texels (no gain), or when the solve has fewer than two iterations or any part is a prepared
/// site's (whose atlases are its own).
pub fn coarse_parts(
    fine: &[impl AsRef<Part>],
    opts: &SolveOptions,
) -> Result<Option<Vec<Part>>, ReflectError> {
    let fine: Vec<&Part> = fine.iter().map(AsRef::as_ref).collect();
    if opts.max_iterations < 2 || fine.is_empty() || fine.iter().any(|p| p.stored.is_some()) {
        return Ok(None);
    }
    let resolution: HashMap<String, u32> = fine
        .iter()
        .map(|p| {
            let r = (p.resolution() as u32).div_ceil(COARSE_FACTOR);
            (p.name.clone(), r.div_ceil(16).max(1) * 16)
        })
        .map(|(n, r)| (n, r.max(MIN_COARSE_RESOLUTION)))
        .collect();
    let meshes = fine
        .iter()
        .map(|p| (p.name.clone(), p.mesh.clone()))
        .collect();
    let coarse = build_parts_with(meshes, |name, _| {
        let r = resolution[name];
        Ok(AtlasChoice {
            resolution: r,
            footprint_m: None,
            max: r,
        })
    })?;
    let count = |ps: &[&Part]| ps.iter().map(|p| p.cache.texels.len()).sum::<usize>() as f64;
    let coarse_refs: Vec<&Part> = coarse.iter().collect();
    Ok((count(&coarse_refs) <= MAX_COARSE_SHARE * count(&fine)).then_some(coarse))
}

/// What the coarse stage reads besides its parts.
pub struct CoarseInputs<'a> {
    pub photos: &'a [Photo],
    pub basis: Option<&'a Basis>,
    /// The truth on the coarse parts (its errors go into the coarse records).
    pub truth: Option<&'a Truth>,
}

/// Solves `coarse` (the parts of [`coarse_parts`]) for up to `opts.max_iterations - 1`
/// iterations, then returns `fine` (a fresh state on the fine parts) with the coarse albedo read
/// at its texels and the coarse records in its report.
pub fn solve_coarse_first(
    fine: SolveResult,
    coarse: Vec<Part>,
    inputs: &CoarseInputs,
    opts: &SolveOptions,
    progress: &dyn Progress,
) -> Result<SolveResult, ReflectError> {
    let coarse_opts = SolveOptions {
        max_iterations: opts.max_iterations - 1,
        min_iterations: opts.min_iterations.min(opts.max_iterations - 1),
        coarse_stage: true,
        ..opts.clone()
    };
    let start = SolveResult::fresh(coarse, fine.report.photos.clone(), &coarse_opts);
    let done = solve(
        start,
        inputs.photos,
        inputs.basis,
        inputs.truth,
        &coarse_opts,
        progress,
        &mut |_| Ok(()),
    )?;
    refine(&done, fine)
}

/// `fine` with the albedo of `coarse` (a solve over the same surfaces) read at its covered
/// texels and dilated into its gutters, and `coarse`'s iteration records (marked coarse) and
/// convergence.
pub fn refine(coarse: &SolveResult, mut fine: SolveResult) -> Result<SolveResult, ReflectError> {
    let scene = coarse.albedo_scene()?;
    for pr in &mut fine.parts {
        let p = &pr.part;
        let r = p.resolution();
        let mut known = vec![false; r * r];
        let values = albedo_at_texels(p, &scene);
        for (t, v) in p.cache.texels.iter().zip(values) {
            if let Some(v) = v.filter(|v| v.is_finite()) {
                pr.rho[t.index as usize] = v;
                known[t.index as usize] = true;
            }
        }
        let gutter: Vec<bool> = p.coverage.pixels.iter().map(|c| c[0] > 0.0).collect();
        dilate(&mut pr.rho, &mut known, &gutter, r, 4);
    }
    fine.report.iterations = coarse.report.iterations.clone();
    for r in &mut fine.report.iterations {
        r.coarse = true;
    }
    fine.report.converged = coarse.report.converged;
    fine.set_changed(true);
    Ok(fine)
}

/// The mean albedo over the covered texels of `parts` (a check of [`refine`]).
#[cfg(test)]
fn mean_albedo(parts: &[crate::result::PartResult]) -> glam::Vec3 {
    let (mut sum, mut n) = (glam::Vec3::ZERO, 0usize);
    for p in parts {
        for t in &p.part.cache.texels {
            sum += p.rho[t.index as usize];
            n += 1;
        }
    }
    sum / n.max(1) as f32
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn ground(res: u32) -> Vec<Part> {
        crate::parts::square_part(res)
    }

    /// The coarse parts have a ninth of the texels; a part already small gets no coarse stage.
    #[test]
    fn coarse_parts_are_three_times_coarser_and_only_where_it_pays() {
        let opts = SolveOptions::default();
        let fine = ground(192);
        let coarse = coarse_parts(&fine, &opts).unwrap().expect("a coarse stage");
        assert_eq!(coarse[0].resolution(), 64);
        let ratio = coarse[0].texel_size / fine[0].texel_size;
        // the gutters around the charts take a larger share of a smaller atlas
        assert!((ratio - 3.0).abs() < 0.3, "texel ratio {ratio}");
        let share = coarse[0].cache.texels.len() as f64 / fine[0].cache.texels.len() as f64;
        assert!((share - 1.0 / 9.0).abs() < 0.03, "texel share {share}");
        // 24 -> 8, rounded up to 16 texels per side: 0.44 of the texels, no coarse stage
        assert!(coarse_parts(&ground(24), &opts).unwrap().is_none());
        let once = SolveOptions {
            max_iterations: 1,
            ..opts
        };
        assert!(coarse_parts(&fine, &once).unwrap().is_none());
    }

    /// An albedo linear in x on the coarse atlas is read back at the fine texels to within the
    /// bilinear lookup's exactness for a linear field (1e-3), and the records come across
    /// marked coarse.
    #[test]
    fn refine_reads_the_coarse_albedo_at_the_fine_texels() {
        let opts = SolveOptions::default();
        let fine = ground(96);
        let coarse = coarse_parts(&fine, &opts).unwrap().unwrap();
        let f = |p: Vec3| Vec3::new(0.3 + 0.1 * p.x, 0.5, 0.2 + 0.05 * p.y);
        let mut c = SolveResult::fresh(coarse, vec!["a".into()], &opts);
        c.parts[0].rho = crate::truth::truth_atlas(&c.parts[0].part, f);
        c.report.iterations.push(crate::record::IterationRecord {
            iteration: 1,
            spp: 16,
            wall_s: 1.0,
            cumulative_s: 1.0,
            observations: 10,
            residual_rms: 0.0,
            residual_rel_rms: 0.0,
            delta_rho: 0.1,
            noise_rho: 0.0,
            systematic_change_rho: 0.0,
            mc_noise_rho: None,
            truth_mae: None,
            truth_rms: None,
            truth_surface_mae: None,
            seen_texels: 10,
            stale: Vec::new(),
            coarse: false,
        });
        c.report.converged = true;
        let fresh = SolveResult::fresh(fine, vec!["a".into()], &opts);
        let r = refine(&c, fresh).unwrap();
        let mut worst = 0.0f32;
        for t in &r.parts[0].part.cache.texels {
            let e = (r.parts[0].rho[t.index as usize] - f(t.position))
                .abs()
                .max_element();
            worst = worst.max(e);
        }
        // texels within half a coarse texel of the square's edge read the dilated border
        assert!(worst < 0.01, "largest error {worst}");
        let m = mean_albedo(&r.parts);
        assert!(
            (m - Vec3::new(0.3, 0.5, 0.2)).abs().max_element() < 2e-3,
            "{m}"
        );
        assert!(r.report.converged);
        assert!(r.report.iterations.iter().all(|i| i.coarse));
    }
}
