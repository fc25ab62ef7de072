//! `igi cluster`: a prepared site solved across Slurm (Jacobi iterations as job arrays of voxel
//! tasks with a merge; docs/SOLVER.md "Solving across a cluster").
use crate::report::{print_json, Ctx};
use igi_cluster::{GroupState, SlurmOptions};
use igi_reflect::{Schedule, SolveOptions};
use std::path::PathBuf;

#[derive(clap::Subcommand, Debug)]
pub enum ClusterCmd {
    /// Freeze a Jacobi solve of a prepared site and submit its first iteration: a task array
    /// (one task per voxel and the terrain) and a merge that submits the next iteration.
    Submit(Box<SubmitArgs>),
    /// Where each voxel of the iteration in progress stands (from the result folder and
    /// squeue; never accounting).
    Status(StatusArgs),
    /// Resubmit the iteration's failed or lost tasks and a merge after them.
    Resume(ResumeArgs),
    /// Cancel the run's queued and running jobs.
    Cancel(FolderArgs),
    /// (Run by the task array.) Solve array index INDEX of the iteration in progress.
    #[command(hide = true)]
    Task(TaskArgs),
    /// (Run by the merge job.) Merge the iteration in progress and submit the next.
    #[command(hide = true)]
    Merge(FolderArgs),
}

#[derive(clap::Args, Debug)]
pub struct SubmitArgs {
    /// Survey folder (or survey.toml) whose `[site] prepared` names an `igi prepare` folder.
    pub survey: PathBuf,
    /// Result folder (new): today's result layout plus cluster/.
    #[arg(short, long)]
    pub output: PathBuf,
    #[command(flatten)]
    pub iteration: crate::cmd::solve::IterationArgs,
    #[arg(long)]
    pub partition: Option<String>,
    #[arg(long)]
    pub account: Option<String>,
    /// Time limit of one task (sbatch --time).
    #[arg(long)]
    pub time: Option<String>,
    /// Memory of one task (sbatch --mem).
    #[arg(long)]
    pub mem: Option<String>,
    #[arg(long)]
    pub cpus_per_task: Option<u32>,
    /// Tasks of an iteration running at once (an array larger than the cluster's MaxArraySize
    /// is split in chunks, which then run one after another).
    #[arg(long)]
    pub max_parallel: Option<u32>,
    /// A further sbatch argument (repeatable), e.g. --sbatch-arg=--qos=long.
    #[arg(long, allow_hyphen_values = true)]
    pub sbatch_arg: Vec<String>,
    /// Attempts per task before `resume` refuses it.
    #[arg(long, default_value_t = 3)]
    pub max_attempts: u32,
    /// Write the first iteration's scripts and print them; submit nothing.
    #[arg(long)]
    pub dry_run: bool,
}

#[derive(clap::Args, Debug)]
pub struct FolderArgs {
    /// Result folder of `igi cluster submit`.
    pub result: PathBuf,
}

#[derive(clap::Args, Debug)]
pub struct ResumeArgs {
    /// Result folder of `igi cluster submit`.
    pub result: PathBuf,
    /// Tasks that failed --max-attempts times keep their previous albedo, marked stale in the
    /// report (such an iteration never counts as converged), instead of stopping the run.
    #[arg(long)]
    pub skip_voxels: bool,
}

#[derive(clap::Args, Debug)]
pub struct StatusArgs {
    /// Result folder of `igi cluster submit`.
    pub result: PathBuf,
    /// Print the status as JSON.
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Args, Debug)]
pub struct TaskArgs {
    pub result: PathBuf,
    #[arg(long)]
    pub index: usize,
}

pub fn run(c: ClusterCmd, _ctx: &Ctx) -> anyhow::Result<()> {
    match c {
        ClusterCmd::Submit(a) => submit(*a),
        ClusterCmd::Status(a) => status(a),
        ClusterCmd::Resume(a) => {
            match igi_cluster::resume(&a.result, a.skip_voxels)? {
                Some(j) => println!(
                    "iteration {}: resubmitted {} task(s) (jobs {}), merge {}",
                    j.iteration,
                    j.indices.len(),
                    j.arrays
                        .iter()
                        .map(|(id, _)| id.as_str())
                        .collect::<Vec<_>>()
                        .join(","),
                    j.merge
                ),
                None => println!("nothing to resume"),
            }
            Ok(())
        }
        ClusterCmd::Cancel(a) => {
            let ids = igi_cluster::cancel(&a.result)?;
            println!("cancelled {} job(s): {}", ids.len(), ids.join(" "));
            Ok(())
        }
        ClusterCmd::Task(a) => {
            let dir = igi_cluster::run_task(&a.result, a.index)?;
            println!("done: {}", dir.display());
            Ok(())
        }
        ClusterCmd::Merge(a) => {
            let m = igi_cluster::merge(&a.result)?;
            println!(
                "iteration {} merged{}{}",
                m.iteration,
                if m.converged { ", converged" } else { "" },
                m.next
                    .map_or(String::new(), |n| format!("; iteration {n} submitted"))
            );
            Ok(())
        }
    }
}

fn submit(a: SubmitArgs) -> anyhow::Result<()> {
    let req = igi_cluster::workflow::SubmitRequest {
        survey: a.survey,
        result: a.output,
        options: SolveOptions {
            schedule: Schedule::Jacobi,
            ..a.iteration.options()?
        },
        slurm: SlurmOptions {
            partition: a.partition,
            account: a.account,
            time: a.time,
            mem: a.mem,
            cpus_per_task: a.cpus_per_task,
            max_parallel: a.max_parallel,
            extra: a.sbatch_arg,
        },
        max_attempts: a.max_attempts,
        dry_run: a.dry_run,
        binary: std::env::current_exe()?,
    };
    let (config, scripts) = igi_cluster::submit(req)?;
    if a.dry_run {
        for s in &scripts {
            println!("# {}\n{}", s.display(), std::fs::read_to_string(s)?);
        }
        println!(
            "dry run: {} task(s) per iteration, nothing submitted",
            config.groups.len()
        );
    } else {
        let j = config.jobs.last().expect("submitted");
        println!(
            "submitted iteration 1: {} task(s) in job(s) {}, merge {}",
            config.groups.len(),
            j.arrays
                .iter()
                .map(|(id, _)| id.as_str())
                .collect::<Vec<_>>()
                .join(","),
            j.merge
        );
    }
    Ok(())
}

fn status(a: StatusArgs) -> anyhow::Result<()> {
    let st = igi_cluster::status(&a.result)?;
    if a.json {
        return print_json(&st);
    }
    let count = |s: GroupState| st.groups.iter().filter(|(_, g)| *g == s).count();
    println!(
        "iteration {} of at most {}{}: {} done, {} running, {} pending, {} failed, {} lost, {} not submitted; merge {}",
        st.iteration,
        st.max_iterations,
        if st.converged {
            " (converged, finished)"
        } else if st.finished {
            " (finished)"
        } else {
            ""
        },
        count(GroupState::Done),
        count(GroupState::Running),
        count(GroupState::Pending),
        count(GroupState::Failed),
        count(GroupState::Lost),
        count(GroupState::Unsubmitted),
        st.merge.as_deref().unwrap_or("not queued")
    );
    let t = &st.tasks;
    if t.finished > 0 {
        let mib = |b: u64| b as f64 / (1u64 << 20) as f64;
        println!(
            "finished tasks: {}, slowest {:.1} s, {:.1} s in all; peak memory of a task {:.0} MiB; {:.1} MiB read",
            t.finished,
            t.slowest_s,
            t.task_s,
            mib(t.peak_rss_bytes),
            mib(t.read_bytes)
        );
    }
    for (name, s) in &st.groups {
        if !matches!(s, GroupState::Done) {
            println!("  {name}: {s:?}");
        }
    }
    Ok(())
}
