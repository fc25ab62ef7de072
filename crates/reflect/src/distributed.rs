//! A Jacobi iteration split into independent tasks and a merge, the unit of work a cluster
//! runs (issue 15; the Slurm submission is not built yet).
//!
//! A result folder holding the committed checkpoint of iteration k-1 is the snapshot every
//! task of iteration k reads. [`run_task`] solves one group (a voxel `I_J_K` or `terrain`)
//! exactly as `solve` with [`Schedule::Jacobi`] would, and writes its parts' new atlases and
//! then, last, `done.json` (its statistics and part summaries) into
//! `WORK/iter_K/GROUP/`. [`merge`] requires every group's `done.json`, applies them in group
//! order (so the iteration's sums are added in the same order as in a local run) and writes
//! the result folder's next checkpoint. A local `igi solve --schedule jacobi` and tasks plus
//! merge therefore write the same bytes (wall-clock fields and the plot of error against time
//! aside): `crates/reflect/tests/integration/prepared.rs`.
//!
//! ```text
//! WORK/iter_K/GROUP/NAME_rho_d.exr, NAME_weight.exr, NAME_observations.exr,
//!                   NAME_stderr.exr                                           per part
//! WORK/iter_K/GROUP/done.json                                                 written last
//! ```

use crate::result::SolveResult;
use crate::solver::{
    finish_iteration, part_lobes, plan, solve_group, PartSummary, Pending, Plan, Schedule,
    SolveInputs, SolveOptions,
};
use crate::ReflectError;
use glam::Vec3;
use igi_files::run::ProcessUsage;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What a finished task reports (`done.json`).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct TaskDone {
    pub group: String,
    /// The iteration it solved (from 1).
    pub iteration: u32,
    /// The group's statistics (observations, residual and change sums).
    pub sums: Pending,
    /// The summaries of the group's parts after the update.
    pub parts: Vec<PartSummary>,
    pub wall_s: f64,
    /// Where and as what it ran (empty for in-process tasks).
    #[serde(default)]
    pub meta: TaskMeta,
    /// Not solved: the group keeps its previous albedo ([`write_stale`]).
    #[serde(default)]
    pub stale: bool,
    /// The task process's peak memory and bytes read when it finished (what `--mem` and the
    /// shared file system must serve).
    #[serde(default)]
    pub usage: ProcessUsage,
}

/// Who ran a task: host, batch job, attempt, and the fingerprint of the frozen run it belongs
/// to (a task of another run must never count as done).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TaskMeta {
    pub host: String,
    pub job: String,
    pub attempt: u32,
    pub fingerprint: String,
}

/// The folder of one task's output.
pub fn task_dir(work: &Path, iteration: u32, group: &str) -> PathBuf {
    work.join(format!("iter_{iteration}")).join(group)
}

/// Writes the first checkpoint of a distributed solve into `result` (a folder holding
/// `start`'s geometry): the state before iteration 1, with every part's summary and lobes, as
/// a local solve holds it when it begins.
pub fn initialise(
    result: &Path,
    mut start: SolveResult,
    inputs: &SolveInputs,
    opts: &SolveOptions,
) -> Result<(), ReflectError> {
    plan(&mut start, inputs, &jacobi(opts)?)?;
    start.write_state(result)
}

/// The groups of a solve of `result` with `opts`, in solve order (what a task array indexes).
pub fn groups(
    result: &Path,
    inputs: &SolveInputs,
    opts: &SolveOptions,
) -> Result<Vec<String>, ReflectError> {
    Ok(Checkpoint::load(result, inputs, opts)?.plan.group_names())
}

/// The committed checkpoint in a result folder, planned for its next Jacobi iteration.
struct Checkpoint {
    opts: SolveOptions,
    state: SolveResult,
    /// The iterations it holds (the next one is `k + 1`).
    k: u32,
    plan: Plan,
}

impl Checkpoint {
    fn load(
        result: &Path,
        inputs: &SolveInputs,
        opts: &SolveOptions,
    ) -> Result<Checkpoint, ReflectError> {
        Self::load_solving(result, inputs, opts, &|_| true)
    }

    /// The checkpoint as the task of `group` needs it: the whole state of the group's parts
    /// and, of the others, what its scene shows ([`SolveResult::load_solving`]), so a task
    /// reads and holds the weights, counts and standard errors of its own parts only. (A
    /// prepared site's group is the part of its name; any other group is loaded whole.)
    fn for_group(
        result: &Path,
        inputs: &SolveInputs,
        opts: &SolveOptions,
        group: &str,
    ) -> Result<Checkpoint, ReflectError> {
        let c = Self::load_solving(result, inputs, opts, &|name| name == group)?;
        let g = c.plan.group(group)?;
        if g.parts.iter().all(|&i| c.state.parts[i].has_statistics()) {
            return Ok(c);
        }
        Self::load(result, inputs, opts)
    }

    fn load_solving(
        result: &Path,
        inputs: &SolveInputs,
        opts: &SolveOptions,
        solving: &dyn Fn(&str) -> bool,
    ) -> Result<Checkpoint, ReflectError> {
        let opts = jacobi(opts)?;
        let mut state = SolveResult::load_solving(result, solving)?;
        let k = state.report.iterations.len() as u32;
        let plan = plan(&mut state, inputs, &opts)?;
        Ok(Checkpoint {
            opts,
            state,
            k,
            plan,
        })
    }
}

fn jacobi(opts: &SolveOptions) -> Result<SolveOptions, ReflectError> {
    if opts.schedule != Schedule::Jacobi {
        return Err(ReflectError::NotJacobi);
    }
    Ok(opts.clone())
}

/// Solves `group` for the iteration after the checkpoint in `result` and writes its output
/// into [`task_dir`] (`done.json` last). Returns the task folder.
pub fn run_task(
    result: &Path,
    work: &Path,
    inputs: &SolveInputs,
    opts: &SolveOptions,
    group: &str,
    meta: &TaskMeta,
) -> Result<PathBuf, ReflectError> {
    let t0 = Instant::now();
    let Checkpoint {
        opts,
        mut state,
        k,
        plan,
    } = Checkpoint::for_group(result, inputs, opts, group)?;
    let g = plan.group(group)?;
    let progress = crate::solver::NoProgress;
    // no snapshot: the checkpoint just loaded is iteration k's albedo, and only this group's
    // parts change, after its scene is built (a copy of every part's atlas would double them)
    let sums = solve_group(&mut state, g, &plan, None, inputs, &opts, k, &progress)?;
    let dir = task_dir(work, k + 1, group);
    let done = TaskDone {
        group: group.to_string(),
        iteration: k + 1,
        sums,
        parts: Vec::new(),
        wall_s: t0.elapsed().as_secs_f64(),
        meta: meta.clone(),
        stale: false,
        usage: ProcessUsage::now(),
    };
    write_task(&state, &g.parts, &dir, done)?;
    Ok(dir)
}

/// Stands in for a task that cannot finish: writes `group`'s current atlases and summaries
/// unchanged, with no statistics, as a stale `done.json`, so that the merge can go on; the
/// iteration records the group as stale and does not count as converged.
pub fn write_stale(
    result: &Path,
    work: &Path,
    inputs: &SolveInputs,
    opts: &SolveOptions,
    group: &str,
    meta: &TaskMeta,
) -> Result<PathBuf, ReflectError> {
    let Checkpoint { state, k, plan, .. } = Checkpoint::for_group(result, inputs, opts, group)?;
    let g = plan.group(group)?;
    let dir = task_dir(work, k + 1, group);
    let done = TaskDone {
        group: group.to_string(),
        iteration: k + 1,
        sums: Pending::default(),
        parts: Vec::new(),
        wall_s: 0.0,
        meta: meta.clone(),
        stale: true,
        usage: ProcessUsage::default(),
    };
    write_task(&state, &g.parts, &dir, done)?;
    Ok(dir)
}

/// Writes a task's output into `dir`: the atlases and summaries of its `parts`, then, last,
/// `done.json`.
fn write_task(
    state: &SolveResult,
    parts: &[usize],
    dir: &Path,
    mut done: TaskDone,
) -> Result<(), ReflectError> {
    std::fs::create_dir_all(dir).map_err(|e| ReflectError::io(dir, "create folder", e))?;
    for &i in parts {
        state.parts[i].write_atlases(dir)?;
        done.parts.push(state.report.parts[i].clone());
    }
    let json = serde_json::to_string_pretty(&done).expect("task report serialises");
    Ok(igi_files::write_text_atomic(&dir.join("done.json"), &json)?)
}

/// Reads part `i`'s atlases from a task folder into the state.
fn read_atlases(state: &mut SolveResult, i: usize, dir: &Path) -> Result<(), ReflectError> {
    let p = &mut state.parts[i];
    let r = p.resolution();
    let name = p.name().to_string();
    let read = |what: &str| crate::result::read_atlas(dir, &name, what, r);
    p.rho = read("rho_d")?
        .pixels
        .iter()
        .map(|p| Vec3::from_array(*p))
        .collect();
    p.weight_sum = read("weight")?.pixels.iter().map(|px| px[0]).collect();
    p.observations = read("observations")?
        .pixels
        .iter()
        .map(|px| px[0] as u32)
        .collect();
    let se = dir.join(format!("{name}_stderr.exr"));
    if !se.exists() {
        return Err(ReflectError::MissingTaskFile(se));
    }
    p.stderr = crate::result::read_stderr(dir, &name, r)?;
    p.changed = true;
    Ok(())
}

/// Merges the tasks of the iteration after the checkpoint in `result`: every group's
/// `done.json` must exist (otherwise [`ReflectError::MissingTasks`] names the missing groups
/// and nothing is written); the groups are applied in order and the next checkpoint is
/// written. Returns whether the solve has converged.
pub fn merge(
    result: &Path,
    work: &Path,
    inputs: &SolveInputs,
    opts: &SolveOptions,
) -> Result<bool, ReflectError> {
    let Checkpoint {
        opts,
        mut state,
        k,
        plan,
    } = Checkpoint::load(result, inputs, opts)?;
    let mut dones = Vec::new();
    let mut missing = Vec::new();
    for name in plan.group_names() {
        let dir = task_dir(work, k + 1, &name);
        match read_done(&dir)? {
            Some(d) if d.iteration == k + 1 && d.group == name => dones.push((dir, d)),
            _ => missing.push(name),
        }
    }
    if !missing.is_empty() {
        return Err(ReflectError::MissingTasks {
            iteration: k + 1,
            groups: missing,
        });
    }
    let mut acc = Pending {
        iteration: k + 1,
        ..Pending::default()
    };
    let mut wall = 0.0;
    for (dir, done) in &dones {
        let g = plan.group(&done.group)?;
        for (&i, summary) in g.parts.iter().zip(&done.parts) {
            read_atlases(&mut state, i, dir)?;
            state.report.parts[i] = summary.clone();
            let p = &mut state.parts[i];
            p.lobes = part_lobes(&p.part, &p.rho, inputs.basis);
        }
        acc.add(&done.sums);
        acc.done.push(done.group.clone());
        wall += done.wall_s;
    }
    let cumulative = state
        .report
        .iterations
        .last()
        .map_or(0.0, |r| r.cumulative_s)
        + wall;
    let mut converged = finish_iteration(
        &mut state,
        &acc,
        &plan.solved,
        inputs.truth,
        &opts,
        wall,
        cumulative,
    )?;
    let stale: Vec<String> = dones
        .iter()
        .filter(|(_, d)| d.stale)
        .map(|(_, d)| d.group.clone())
        .collect();
    if !stale.is_empty() {
        // an iteration that skipped groups cannot mean the solve has converged
        converged = false;
        state.report.converged = false;
        if let Some(rec) = state.report.iterations.last_mut() {
            rec.stale = stale;
        }
    }
    state.write_state(result)?;
    Ok(converged)
}

/// The iteration a result folder's next tasks solve (its committed iterations plus one).
pub fn next_iteration(result: &Path) -> Result<u32, ReflectError> {
    let rp = result.join("report.json");
    let text = std::fs::read_to_string(&rp).map_err(|e| ReflectError::io(&rp, "read", e))?;
    let v: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| ReflectError::json(&rp, "solve report", e))?;
    Ok(v["iterations"].as_array().map_or(0, |a| a.len()) as u32 + 1)
}

/// A task's `done.json`, or `None` when it has not finished.
pub fn read_done(dir: &Path) -> Result<Option<TaskDone>, ReflectError> {
    let p = dir.join("done.json");
    if !p.is_file() {
        return Ok(None);
    }
    let text = std::fs::read_to_string(&p).map_err(|e| ReflectError::io(&p, "read", e))?;
    serde_json::from_str(&text)
        .map(Some)
        .map_err(|e| ReflectError::json(&p, "task report", e))
}
