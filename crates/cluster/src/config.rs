//! `cluster/cluster.json`: what a cluster run froze at submission.

use crate::ClusterError;
use igi_files::run::Fingerprint;
use igi_reflect::SolveOptions;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The sbatch knobs of a run.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct SlurmOptions {
    pub partition: Option<String>,
    pub account: Option<String>,
    /// Time limit of one task (sbatch `--time`).
    pub time: Option<String>,
    /// Memory of one task (sbatch `--mem`).
    pub mem: Option<String>,
    pub cpus_per_task: Option<u32>,
    /// Tasks of an iteration running at once (`%N` on each array; chunks of an array larger
    /// than MaxArraySize then run one after another); none for no limit.
    pub max_parallel: Option<u32>,
    /// Further sbatch arguments, passed as given.
    pub extra: Vec<String>,
}

/// The jobs of one iteration (and attempt).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct IterationJobs {
    pub iteration: u32,
    pub attempt: u32,
    /// Job ids of the task arrays, one per chunk, with the first index of each chunk.
    pub arrays: Vec<(String, usize)>,
    /// The indices this submission runs (all groups on the first attempt).
    pub indices: Vec<usize>,
    pub merge: String,
}

/// A frozen cluster run.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ClusterConfig {
    pub format: String,
    pub survey: PathBuf,
    pub result: PathBuf,
    /// The igi binary the scripts run, and its fingerprint.
    pub binary: PathBuf,
    pub binary_fingerprint: Fingerprint,
    pub version: String,
    pub options: SolveOptions,
    /// Identifies this run: tasks of another run never count as done.
    pub fingerprint: String,
    /// The groups (voxels `I_J_K`, then `terrain`): array index i solves `groups[i]`.
    pub groups: Vec<String>,
    pub slurm: SlurmOptions,
    pub max_attempts: u32,
    /// Whether merges submit the next iteration (false after `--dry-run`).
    pub submit: bool,
    /// The cluster's MaxArraySize when submitted: larger arrays are split in chunks.
    pub max_array_size: usize,
    pub jobs: Vec<IterationJobs>,
}

pub const FORMAT: &str = "igi-cluster-1";

impl ClusterConfig {
    /// `RESULT/cluster/cluster.json`.
    pub fn path(result: &Path) -> PathBuf {
        result.join("cluster").join("cluster.json")
    }

    pub fn read(result: &Path) -> Result<ClusterConfig, ClusterError> {
        let p = Self::path(result);
        let text = std::fs::read_to_string(&p).map_err(|e| {
            ClusterError::file(
                &p,
                format!("cannot read ({e}); is this a folder of `igi cluster submit`?"),
            )
        })?;
        let c: ClusterConfig = serde_json::from_str(&text)
            .map_err(|e| ClusterError::file(&p, format!("not a cluster file: {e}")))?;
        if c.format != FORMAT {
            return Err(ClusterError::file(
                &p,
                format!("format {:?}, expected {FORMAT:?}", c.format),
            ));
        }
        Ok(c)
    }

    pub fn write(&self) -> Result<(), ClusterError> {
        let dir = self.result.join("cluster");
        std::fs::create_dir_all(&dir)
            .map_err(|e| ClusterError::file(&dir, format!("cannot create folder: {e}")))?;
        let text = serde_json::to_string_pretty(self).expect("cluster file serialises") + "\n";
        Ok(igi_files::write_text_atomic(
            &Self::path(&self.result),
            &text,
        )?)
    }

    /// The folder of iteration `k`'s scripts, logs and task outputs.
    pub fn iteration_dir(&self, k: u32) -> PathBuf {
        self.result.join("cluster").join(format!("iter_{k}"))
    }

    /// The log file of array index `i` in iteration `k` (Slurm's `%a` within its chunk).
    pub fn task_log(&self, k: u32, i: usize) -> PathBuf {
        let chunk = i / self.max_array_size;
        let a = i % self.max_array_size;
        self.iteration_dir(k)
            .join("logs")
            .join(format!("task-{chunk}-{a}.out"))
    }

    /// Refuses to go on when the running binary is not the one submitted.
    pub fn check_binary(&self) -> Result<(), ClusterError> {
        let exe = std::env::current_exe().map_err(ClusterError::CurrentExe)?;
        let now = Fingerprint::of("igi binary", &exe)?;
        if !now.same_content(&self.binary_fingerprint) {
            return Err(ClusterError::Mismatch {
                path: Self::path(&self.result),
                what: "igi binary".into(),
                was: self.binary_fingerprint.describe(),
                now: now.describe(),
            });
        }
        Ok(())
    }
}
