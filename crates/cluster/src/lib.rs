//! Solving a prepared site across a Slurm cluster (`igi cluster`).
//!
//! A cluster run is a Jacobi solve ([`igi_reflect::Schedule::Jacobi`]) whose iterations are
//! Slurm job arrays: one array task per voxel (and the terrain) runs
//! [`igi_reflect::distributed::run_task`], and a merge job that depends on the array
//! (`afterany`) runs [`igi_reflect::distributed::merge`] and submits the next iteration. The
//! result folder has today's layout (so `igi render`, `sample` and `export` read it) plus
//! `cluster/`:
//!
//! ```text
//! RESULT/run.json                      the solve's run manifest (inputs and options)
//! RESULT/cluster/cluster.json          the frozen run: options, binary, fingerprint, groups, jobs
//! RESULT/cluster/iter_K/tasks-C.sh     the task array script(s) of iteration K (chunk C)
//! RESULT/cluster/iter_K/merge.sh       its merge script
//! RESULT/cluster/iter_K/logs/          Slurm output of every task and the merge
//! RESULT/cluster/iter_K/GROUP/         a task's atlases and done.json (written last)
//! RESULT/cluster/iter_K/missing.txt    written by a merge that found tasks unfinished
//! ```
//!
//! Every Slurm call (`sbatch`, `squeue`, `scancel`, `scontrol`) is a subprocess in [`slurm`];
//! accounting (`sacct`) is never used, since clusters often run without it.

pub mod config;
pub mod slurm;
pub mod workflow;

pub use config::{ClusterConfig, SlurmOptions};
pub use workflow::{
    cancel, merge, resume, run_task, status, submit, GroupState, Status, TaskTotals,
};

use std::path::PathBuf;

/// Errors of a cluster run.
#[derive(Debug, thiserror::Error)]
pub enum ClusterError {
    #[error("{}: {msg}", path.display())]
    File { path: PathBuf, msg: String },
    /// `--max-attempts 0`.
    #[error("--max-attempts must be at least 1")]
    NoAttempts,
    /// A task index outside the run's tasks.
    #[error("--index {index} is out of range: the run has {tasks} tasks (0..={})", tasks.saturating_sub(1))]
    IndexOutOfRange { index: usize, tasks: usize },
    /// Tasks that failed `attempts` times already; `list` is the iteration's missing.txt.
    #[error("iteration {iteration}: {} task(s) failed {attempts} time(s) already ({}); see {}; `--skip-voxels` keeps their previous albedo, marked stale", groups.len(), groups.join(", "), list.display())]
    AttemptsSpent {
        iteration: u32,
        attempts: u32,
        groups: Vec<String>,
        list: PathBuf,
    },
    /// The path of the running binary cannot be found.
    #[error("cannot find the running binary: {0}")]
    CurrentExe(#[source] std::io::Error),
    /// An sbatch option's value that cannot be written into an `#SBATCH` line.
    #[error("{option} {value:?}: {msg}")]
    SbatchValue {
        option: String,
        value: String,
        msg: String,
    },
    /// A Slurm command could not run or failed.
    #[error("`{command}`: {msg}")]
    Slurm { command: String, msg: String },
    /// A task or merge belongs to another run (binary or inputs changed since submission).
    #[error("{}: {what} differs from the submitted run (there: {was}; now: {now}); submit afresh into a new folder", path.display())]
    Mismatch {
        path: PathBuf,
        what: String,
        was: String,
        now: String,
    },
    /// A merge found tasks unfinished; `missing.txt` lists them.
    #[error("iteration {iteration}: {count} task(s) did not finish (listed in {})", list.display())]
    Missing {
        iteration: u32,
        count: usize,
        list: PathBuf,
    },
    #[error(transparent)]
    Reflect(#[from] igi_reflect::ReflectError),
    #[error(transparent)]
    Workflow(#[from] igi_workflow::WorkflowError),
    #[error(transparent)]
    Imaging(#[from] igi_imaging::ImagingError),
    /// An output file or folder, a run manifest or the folder lock.
    #[error(transparent)]
    Files(#[from] igi_files::FilesError),
    #[error(transparent)]
    Geometry(#[from] igi_geometry::GeometryError),
}

impl ClusterError {
    pub(crate) fn file(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        ClusterError::File {
            path: path.into(),
            msg: msg.into(),
        }
    }
}
