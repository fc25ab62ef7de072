//! Submit, task, merge, status, resume, cancel: what `igi cluster` runs.

use crate::config::{
    check_sbatch_value, sbatch_quote, ClusterConfig, IterationJobs, SlurmOptions, FORMAT,
};
use crate::slurm::{self, QueueState};
use crate::ClusterError;
use igi_files::run::Fingerprint;
use igi_reflect::distributed::{self, TaskDone, TaskMeta};
use igi_reflect::solver::{NoProgress, SolveInputs};
use igi_reflect::{Schedule, SolveOptions};
use igi_workflow::{AtlasRequest, SolveJob, SolveRequest, Survey};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// What `submit` is asked for.
pub struct SubmitRequest {
    pub survey: PathBuf,
    pub result: PathBuf,
    pub options: SolveOptions,
    pub slurm: SlurmOptions,
    pub max_attempts: u32,
    /// Write the scripts of the first iteration but submit nothing.
    pub dry_run: bool,
    /// The igi binary the scripts run.
    pub binary: PathBuf,
}

/// Freezes a run and submits its first iteration (or, with `dry_run`, only writes its
/// scripts). Everything is checked before the first byte is written: the survey names a
/// prepared site, `sbatch` runs, the result folder is new.
pub fn submit(req: SubmitRequest) -> Result<(ClusterConfig, Vec<PathBuf>), ClusterError> {
    req.slurm.check()?;
    for (what, p) in [
        ("the result folder", &req.result),
        ("the igi binary", &req.binary),
    ] {
        check_sbatch_value(what, &p.display().to_string())?;
    }
    let survey = Survey::load(&req.survey)?;
    if survey.prepared.is_none() {
        return Err(ClusterError::file(
            &req.survey,
            "names no prepared site ([site] prepared = \"SITE\"): a cluster solve runs voxel by voxel; run `igi prepare` first",
        ));
    }
    if req.max_attempts == 0 {
        return Err(ClusterError::NoAttempts);
    }
    if ClusterConfig::path(&req.result).exists() {
        return Err(ClusterError::file(
            &req.result,
            "already holds a cluster run; use `igi cluster status`, `resume` or `cancel` on it",
        ));
    }
    if !req.dry_run {
        slurm::check_available()?;
    }
    // the job `igi solve` runs, started but not iterated (a prepared site keeps its atlases)
    let request = SolveRequest {
        survey: req.survey.clone(),
        output: req.result.clone(),
        atlas: AtlasRequest::Fixed(req.options.atlas_resolution),
        options: SolveOptions {
            schedule: Schedule::Jacobi,
            ..req.options.clone()
        },
        truth: None,
        restart: false,
    };
    let started = SolveJob::check_survey(survey, &request)?.start(&NoProgress)?;
    let opts = started.options.clone();
    let inputs = SolveInputs {
        photos: &started.photos,
        basis: started.basis.as_ref(),
        truth: None,
    };
    distributed::initialise(&req.result, started.state, &inputs, &opts)?;
    let groups = distributed::groups(&req.result, &inputs, &opts)?;
    let config = freeze(&req, opts, groups)?;
    config.write()?;
    let indices = all(&config);
    if req.dry_run {
        let scripts = write_scripts(&config, 1, &indices)?.all();
        return Ok((config, scripts));
    }
    let mut config = config;
    let scripts = submit_iteration(&mut config, 1, indices)?;
    Ok((config, scripts))
}

fn all(config: &ClusterConfig) -> Vec<usize> {
    (0..config.groups.len()).collect()
}

/// The frozen run: absolute paths, the binary's fingerprint, and a fingerprint of the whole.
fn freeze(
    req: &SubmitRequest,
    options: SolveOptions,
    groups: Vec<String>,
) -> Result<ClusterConfig, ClusterError> {
    let abs = |p: &Path| std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf());
    let binary = abs(&req.binary);
    let binary_fingerprint = Fingerprint::of("igi binary", &binary)?;
    let run = std::fs::read(req.result.join(igi_files::run::RUN_FILE))
        .map_err(|e| ClusterError::file(&req.result, format!("cannot read run.json: {e}")))?;
    let mut ident = run;
    ident.extend(serde_json::to_vec(&binary_fingerprint).expect("serialisable"));
    ident.extend(serde_json::to_vec(&options).expect("serialisable"));
    Ok(ClusterConfig {
        format: FORMAT.into(),
        survey: abs(&req.survey),
        result: abs(&req.result),
        binary,
        binary_fingerprint,
        version: env!("CARGO_PKG_VERSION").into(),
        options,
        fingerprint: format!("{:016x}", igi_files::run::fnv1a64(&ident)),
        groups,
        slurm: req.slurm.clone(),
        max_attempts: req.max_attempts,
        submit: !req.dry_run,
        max_array_size: if req.dry_run {
            1001
        } else {
            slurm::max_array_size()
        },
        jobs: Vec::new(),
    })
}

/// A path quoted for a POSIX shell.
fn sh(p: &Path) -> String {
    format!("'{}'", p.display().to_string().replace('\'', r"'\''"))
}

/// The scripts of one submission: the task arrays with the first index of their chunk, and
/// the merge.
struct Scripts {
    tasks: Vec<(PathBuf, usize)>,
    merge: PathBuf,
}

impl Scripts {
    fn all(&self) -> Vec<PathBuf> {
        let mut v: Vec<PathBuf> = self.tasks.iter().map(|(p, _)| p.clone()).collect();
        v.push(self.merge.clone());
        v
    }
}

/// Writes iteration `k`'s task array scripts (one per chunk of MaxArraySize indices) for
/// `indices` and its merge script.
fn write_scripts(
    config: &ClusterConfig,
    k: u32,
    indices: &[usize],
) -> Result<Scripts, ClusterError> {
    let dir = config.iteration_dir(k);
    let logs = dir.join("logs");
    std::fs::create_dir_all(&logs)
        .map_err(|e| ClusterError::file(&logs, format!("cannot create folder: {e}")))?;
    let m = config.max_array_size.max(1);
    let mut tasks = Vec::new();
    let mut chunks: Vec<usize> = indices.iter().map(|i| i / m).collect();
    chunks.dedup();
    for c in chunks {
        let list: Vec<String> = indices
            .iter()
            .filter(|i| *i / m == c)
            .map(|i| (i - c * m).to_string())
            .collect();
        let limit = config
            .slurm
            .max_parallel
            .map_or(String::new(), |p| format!("%{p}"));
        let mut s = header(config, &format!("igi-{k}-tasks-{c}"));
        let _ = writeln!(s, "#SBATCH --array={}{limit}", list.join(","));
        let _ = writeln!(
            s,
            "#SBATCH --output={}",
            sbatch_quote(&logs.join(format!("task-{c}-%a.out")).display().to_string())
        );
        let _ = writeln!(
            s,
            "exec {} cluster task {} --index $((SLURM_ARRAY_TASK_ID + {}))",
            sh(&config.binary),
            sh(&config.result),
            c * m
        );
        let p = dir.join(format!("tasks-{c}.sh"));
        igi_files::write_text_atomic(&p, &s)?;
        tasks.push((p, c * m));
    }
    let mut s = header(config, &format!("igi-{k}-merge"));
    let _ = writeln!(
        s,
        "#SBATCH --output={}",
        sbatch_quote(&logs.join("merge-%j.out").display().to_string())
    );
    let _ = writeln!(
        s,
        "exec {} cluster merge {}",
        sh(&config.binary),
        sh(&config.result)
    );
    let merge = dir.join("merge.sh");
    igi_files::write_text_atomic(&merge, &s)?;
    Ok(Scripts { tasks, merge })
}

/// The shebang and sbatch lines every script shares.
fn header(config: &ClusterConfig, name: &str) -> String {
    let o = &config.slurm;
    let mut s = format!(
        "#!/bin/sh\n# written by `igi cluster`; run {}\n#SBATCH --job-name={name}\n",
        config.fingerprint
    );
    for (flag, v) in [
        ("partition", o.partition.clone()),
        ("account", o.account.clone()),
        ("time", o.time.clone()),
        ("mem", o.mem.clone()),
        ("cpus-per-task", o.cpus_per_task.map(|c| c.to_string())),
    ] {
        if let Some(v) = v {
            let _ = writeln!(s, "#SBATCH --{flag}={}", sbatch_quote(&v));
        }
    }
    for a in &o.extra {
        let _ = writeln!(s, "#SBATCH {}", sbatch_quote(a));
    }
    s
}

/// Writes and submits iteration `k` for `indices`: the arrays, then the merge after them.
fn submit_iteration(
    config: &mut ClusterConfig,
    k: u32,
    indices: Vec<usize>,
) -> Result<Vec<PathBuf>, ClusterError> {
    let scripts = write_scripts(config, k, &indices)?;
    let mut arrays: Vec<(String, usize)> = Vec::new();
    for (script, first) in &scripts.tasks {
        // `%P` limits one array: with --max-parallel, chunks run one after another so that the
        // bound holds for the whole iteration
        let after = match (arrays.last(), config.slurm.max_parallel) {
            (Some((prev, _)), Some(_)) => vec![format!("--dependency=afterany:{prev}")],
            _ => Vec::new(),
        };
        arrays.push((slurm::sbatch(script, &after)?, *first));
    }
    let deps: Vec<&str> = arrays.iter().map(|(id, _)| id.as_str()).collect();
    let mut args = Vec::new();
    if !deps.is_empty() {
        args.push(format!("--dependency=afterany:{}", deps.join(":")));
    }
    let merge = slurm::sbatch(&scripts.merge, &args)?;
    let attempt = config.jobs.iter().filter(|j| j.iteration == k).count() as u32 + 1;
    config.jobs.push(IterationJobs {
        iteration: k,
        attempt,
        arrays,
        indices,
        merge,
    });
    config.write()?;
    Ok(scripts.all())
}

/// The photographs and basis of a frozen run, after checking that the binary and the inputs
/// are those submitted (the run manifest names a difference).
fn reopen(
    config: &ClusterConfig,
) -> Result<(Vec<igi_reflect::Photo>, Option<igi_brdf::Basis>), ClusterError> {
    config.check_binary()?;
    Ok(igi_workflow::reopen(
        &config.survey,
        &config.result,
        &config.options,
    )?)
}

/// Runs array index `index` of the current iteration (`igi cluster task`). A task whose
/// `done.json` of this run already exists returns at once (resubmitting is harmless).
pub fn run_task(result: &Path, index: usize) -> Result<PathBuf, ClusterError> {
    let config = ClusterConfig::read(result)?;
    let k = distributed::next_iteration(result)?;
    let group = config
        .groups
        .get(index)
        .ok_or(ClusterError::IndexOutOfRange {
            index,
            tasks: config.groups.len(),
        })?;
    let work = result.join("cluster");
    let dir = distributed::task_dir(&work, k, group);
    if let Some(d) = distributed::read_done(&dir)? {
        if d.meta.fingerprint == config.fingerprint && d.iteration == k {
            return Ok(dir);
        }
    }
    let (photos, basis) = reopen(&config)?;
    let inputs = SolveInputs {
        photos: &photos,
        basis: basis.as_ref(),
        truth: None,
    };
    let env = |k: &str| std::env::var(k).unwrap_or_default();
    let meta = TaskMeta {
        host: std::fs::read_to_string("/proc/sys/kernel/hostname")
            .map(|h| h.trim().to_string())
            .unwrap_or_default(),
        job: match (env("SLURM_ARRAY_JOB_ID"), env("SLURM_ARRAY_TASK_ID")) {
            (j, t) if !j.is_empty() => format!("{j}_{t}"),
            _ => env("SLURM_JOB_ID"),
        },
        attempt: config.jobs.iter().filter(|j| j.iteration == k).count() as u32,
        fingerprint: config.fingerprint.clone(),
    };
    Ok(distributed::run_task(
        result,
        &work,
        &inputs,
        &config.options,
        group,
        &meta,
    )?)
}

/// What a merge did.
#[derive(Clone, Debug, Serialize)]
pub struct MergeOutcome {
    pub iteration: u32,
    pub converged: bool,
    /// The next iteration's jobs, when one was submitted.
    pub next: Option<u32>,
}

/// Merges the current iteration (`igi cluster merge`): every task of this run must have
/// finished, otherwise `missing.txt` lists them and nothing else is written; then the next
/// iteration is submitted unless the solve converged or reached its iterations.
pub fn merge(result: &Path) -> Result<MergeOutcome, ClusterError> {
    let mut config = ClusterConfig::read(result)?;
    let k = distributed::next_iteration(result)?;
    let work = result.join("cluster");
    let missing: Vec<usize> = (0..config.groups.len())
        .filter(|&i| !task_done(&config, &work, k, i))
        .collect();
    let list = config.iteration_dir(k).join("missing.txt");
    if !missing.is_empty() {
        write_missing(&config, k, &missing, &list)?;
        return Err(ClusterError::Missing {
            iteration: k,
            count: missing.len(),
            list,
        });
    }
    let (photos, basis) = reopen(&config)?;
    let inputs = SolveInputs {
        photos: &photos,
        basis: basis.as_ref(),
        truth: None,
    };
    let converged = distributed::merge(result, &work, &inputs, &config.options)?;
    let _ = std::fs::remove_file(&list);
    let next = if !converged && k < config.options.max_iterations && config.submit {
        let indices = all(&config);
        submit_iteration(&mut config, k + 1, indices)?;
        Some(k + 1)
    } else {
        None
    };
    Ok(MergeOutcome {
        iteration: k,
        converged,
        next,
    })
}

fn task_done(config: &ClusterConfig, work: &Path, k: u32, i: usize) -> bool {
    done_report(config, work, k, i).is_some()
}

/// The `done.json` of task `i` of iteration `k`, when it belongs to this run.
fn done_report(config: &ClusterConfig, work: &Path, k: u32, i: usize) -> Option<TaskDone> {
    let dir = distributed::task_dir(work, k, &config.groups[i]);
    match distributed::read_done(&dir) {
        Ok(Some(d)) if d.meta.fingerprint == config.fingerprint && d.iteration == k => Some(d),
        _ => None,
    }
}

/// `missing.txt`: per unfinished task its group, index, log and the log's last line.
fn write_missing(
    config: &ClusterConfig,
    k: u32,
    missing: &[usize],
    list: &Path,
) -> Result<(), ClusterError> {
    let mut s = String::from("# group\tindex\tlog\tlast line of the log\n");
    for &i in missing {
        let log = config.task_log(k, i);
        let _ = writeln!(
            s,
            "{}\t{i}\t{}\t{}",
            config.groups[i],
            log.display(),
            last_line(&log).unwrap_or_else(|| "(no log: the task never ran)".into())
        );
    }
    Ok(igi_files::write_text_atomic(list, &s)?)
}

fn last_line(log: &Path) -> Option<String> {
    let text = std::fs::read_to_string(log).ok()?;
    text.lines()
        .rev()
        .find(|l| !l.trim().is_empty())
        .map(|l| l.trim().to_string())
}

/// Where one task of the current iteration stands.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum GroupState {
    Done,
    Running,
    Pending,
    /// Not queued, not done, and its log ends in an error.
    Failed,
    /// Not queued, not done, and no error of its own (cancelled, killed with its node, never
    /// started).
    Lost,
    /// No job of the iteration was ever submitted for it (a `--dry-run`): nothing to ask
    /// Slurm about.
    Unsubmitted,
}

/// The state of a run (`igi cluster status`).
#[derive(Clone, Debug, Serialize)]
pub struct Status {
    /// The iteration in progress (the committed ones plus one).
    pub iteration: u32,
    pub max_iterations: u32,
    pub converged: bool,
    /// Converged or reached its iterations: nothing more to run.
    pub finished: bool,
    pub groups: Vec<(String, GroupState)>,
    /// The merge of the iteration: pending, running, or absent from the queue.
    pub merge: Option<String>,
    /// What the iteration's finished tasks used.
    pub tasks: TaskTotals,
}

/// Totals over the finished (not stale) tasks of one iteration, from their `done.json`: what
/// to ask for with `--mem` and `--time`, and what the shared file system served.
#[derive(Clone, Debug, Default, Serialize)]
pub struct TaskTotals {
    pub finished: usize,
    /// The largest peak resident memory of a task.
    pub peak_rss_bytes: u64,
    /// Bytes read by all tasks together.
    pub read_bytes: u64,
    /// Task time summed over tasks, and the slowest task.
    pub task_s: f64,
    pub slowest_s: f64,
}

impl TaskTotals {
    fn add(&mut self, d: &TaskDone) {
        if d.stale {
            return;
        }
        self.finished += 1;
        self.peak_rss_bytes = self.peak_rss_bytes.max(d.usage.peak_rss_bytes);
        self.read_bytes += d.usage.read_bytes;
        self.task_s += d.wall_s;
        self.slowest_s = self.slowest_s.max(d.wall_s);
    }
}

/// Reads the result folder and `squeue` (never accounting). When tasks were submitted,
/// `squeue` must answer: not found, failing or silent for `IGI_SLURM_TIMEOUT` seconds (120) is
/// an error naming it, never a run of "lost" tasks. Tasks never submitted (a `--dry-run`) are
/// [`GroupState::Unsubmitted`].
pub fn status(result: &Path) -> Result<Status, ClusterError> {
    let config = ClusterConfig::read(result)?;
    let report = std::fs::read_to_string(result.join("report.json")).unwrap_or_default();
    let converged = serde_json::from_str::<serde_json::Value>(&report)
        .ok()
        .and_then(|v| v["converged"].as_bool())
        .unwrap_or(false);
    let next = distributed::next_iteration(result)?;
    let finished = converged || next > config.options.max_iterations;
    // a finished run shows its last iteration, every task of it done
    let k = if finished { next - 1 } else { next };
    let work = result.join("cluster");
    let jobs: Vec<&IterationJobs> = config.jobs.iter().filter(|j| j.iteration == k).collect();
    let mut ids: Vec<String> = jobs
        .iter()
        .flat_map(|j| j.arrays.iter().map(|(id, _)| id.clone()))
        .collect();
    let merges: Vec<String> = jobs.iter().map(|j| j.merge.clone()).collect();
    ids.extend(merges.iter().cloned());
    let queue = if ids.is_empty() {
        Vec::new()
    } else {
        slurm::queued(&ids)?
    };
    let mut groups = Vec::new();
    let mut tasks = TaskTotals::default();
    for (i, name) in config.groups.iter().enumerate() {
        let state = if let Some(d) = done_report(&config, &work, k, i) {
            tasks.add(&d);
            GroupState::Done
        } else {
            let submitted = jobs.iter().any(|j| j.indices.contains(&i));
            if !submitted {
                groups.push((name.clone(), GroupState::Unsubmitted));
                continue;
            }
            queued_state(&jobs, &queue, i).unwrap_or_else(|| {
                match last_line(&config.task_log(k, i)) {
                    Some(l) if l.contains("CANCELLED") => GroupState::Lost,
                    Some(l) if l.to_lowercase().contains("error") => GroupState::Failed,
                    _ => GroupState::Lost,
                }
            })
        };
        groups.push((name.clone(), state));
    }
    let merge = queue
        .iter()
        .find(|(id, _, _)| merges.contains(id))
        .map(|(_, _, s)| format!("{s:?}").to_lowercase());
    Ok(Status {
        iteration: k,
        max_iterations: config.options.max_iterations,
        converged,
        finished,
        groups,
        merge,
        tasks,
    })
}

/// The queue state of array index `i`, if any job of the iteration holds it.
fn queued_state(
    jobs: &[&IterationJobs],
    queue: &[(String, Option<usize>, QueueState)],
    i: usize,
) -> Option<GroupState> {
    for j in jobs.iter().rev() {
        for (id, first) in &j.arrays {
            let hit = queue
                .iter()
                .find(|(qid, a, _)| qid == id && a.map(|a| a + first) == Some(i));
            if let Some((_, _, s)) = hit {
                return Some(match s {
                    QueueState::Pending => GroupState::Pending,
                    QueueState::Running => GroupState::Running,
                });
            }
        }
    }
    None
}

/// Resubmits the current iteration's unfinished tasks that are not queued, and a merge
/// after them (`igi cluster resume`). Tasks that already ran `max_attempts` times are refused,
/// or with `skip` keep their previous albedo (a stale `done.json`; the iteration records them
/// and never counts as converged).
pub fn resume(result: &Path, skip: bool) -> Result<Option<IterationJobs>, ClusterError> {
    let st = status(result)?;
    let mut config = ClusterConfig::read(result)?;
    config.check_binary()?;
    if st.finished {
        return Ok(None);
    }
    let k = st.iteration;
    let redo: Vec<usize> = st
        .groups
        .iter()
        .enumerate()
        .filter(|(_, (_, s))| {
            matches!(
                s,
                GroupState::Failed | GroupState::Lost | GroupState::Unsubmitted
            )
        })
        .map(|(i, _)| i)
        .collect();
    let tried = |i: usize| {
        config
            .jobs
            .iter()
            .filter(|j| j.iteration == k && j.indices.contains(&i))
            .count() as u32
    };
    let (spent, redo): (Vec<usize>, Vec<usize>) = redo
        .into_iter()
        .partition(|&i| tried(i) >= config.max_attempts);
    if !spent.is_empty() && !skip {
        return Err(ClusterError::AttemptsSpent {
            iteration: k,
            attempts: config.max_attempts,
            groups: spent.iter().map(|&i| config.groups[i].clone()).collect(),
            list: config.iteration_dir(k).join("missing.txt"),
        });
    }
    if !spent.is_empty() {
        skip_groups(&config, k, &spent)?;
    }
    if redo.is_empty() && st.merge.is_some() {
        return Ok(None); // everything is queued or done, and a merge waits
    }
    submit_iteration(&mut config, k, redo)?;
    Ok(config.jobs.last().cloned())
}

/// Writes stale stand-ins for the tasks `indices` of iteration `k`.
fn skip_groups(config: &ClusterConfig, k: u32, indices: &[usize]) -> Result<(), ClusterError> {
    let (photos, basis) = reopen(config)?;
    let inputs = SolveInputs {
        photos: &photos,
        basis: basis.as_ref(),
        truth: None,
    };
    let meta = TaskMeta {
        fingerprint: config.fingerprint.clone(),
        ..TaskMeta::default()
    };
    let work = config.result.join("cluster");
    for &i in indices {
        let g = &config.groups[i];
        tracing::warn!("iteration {k}: {g} keeps its previous albedo (stale)");
        distributed::write_stale(&config.result, &work, &inputs, &config.options, g, &meta)?;
    }
    Ok(())
}

/// Cancels the queued and running jobs of the run (`igi cluster cancel`); returns their ids.
pub fn cancel(result: &Path) -> Result<Vec<String>, ClusterError> {
    let config = ClusterConfig::read(result)?;
    let ids: Vec<String> = config
        .jobs
        .iter()
        .flat_map(|j| {
            j.arrays
                .iter()
                .map(|(id, _)| id.clone())
                .chain(std::iter::once(j.merge.clone()))
        })
        .filter(|id| !id.is_empty())
        .collect();
    let queued: Vec<String> = slurm::queued(&ids)?
        .into_iter()
        .map(|(id, _, _)| id)
        .collect::<std::collections::BTreeSet<_>>()
        .into_iter()
        .collect();
    slurm::scancel(&queued)?;
    Ok(queued)
}
