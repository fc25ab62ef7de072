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

impl SlurmOptions {
    /// Refuses a value that cannot be written into an `#SBATCH` line: control characters
    /// (a newline would end the line and start a shell command of the script) or an empty
    /// value. Spaces, quotes, `#`, `$` and the like are quoted by [`sbatch_quote`].
    pub fn check(&self) -> Result<(), ClusterError> {
        let named = [
            ("--partition", &self.partition),
            ("--account", &self.account),
            ("--time", &self.time),
            ("--mem", &self.mem),
        ];
        for (option, v) in named {
            if let Some(v) = v {
                check_sbatch_value(option, v)?;
            }
        }
        for v in &self.extra {
            check_sbatch_value("--sbatch-arg", v)?;
            if !v.starts_with('-') {
                return Err(ClusterError::SbatchValue {
                    option: "--sbatch-arg".into(),
                    value: v.clone(),
                    msg:
                        "must be one sbatch option starting with '-', e.g. --sbatch-arg=--qos=long"
                            .into(),
                });
            }
        }
        if self.cpus_per_task == Some(0) {
            return Err(ClusterError::SbatchValue {
                option: "--cpus-per-task".into(),
                value: "0".into(),
                msg: "must be at least 1".into(),
            });
        }
        if self.max_parallel == Some(0) {
            return Err(ClusterError::SbatchValue {
                option: "--max-parallel".into(),
                value: "0".into(),
                msg: "must be at least 1 (leave it out for no limit)".into(),
            });
        }
        Ok(())
    }
}

/// Refuses `value` of `option` when it is empty or holds a control character.
pub fn check_sbatch_value(option: &str, value: &str) -> Result<(), ClusterError> {
    let msg = if value.trim().is_empty() {
        "is empty"
    } else if value.chars().any(char::is_control) {
        "holds a control character (a newline would end the #SBATCH line)"
    } else {
        return Ok(());
    };
    Err(ClusterError::SbatchValue {
        option: option.into(),
        value: value.into(),
        msg: msg.into(),
    })
}

/// `value` as one argument of an `#SBATCH` line: in double quotes, `\` and `"` escaped with a
/// backslash. sbatch splits these lines at unquoted white space, reads an unquoted `#` as the
/// start of a comment and removes quotes and escapes, so the option gets `value` verbatim; the
/// shell never reads these lines. `value` must have passed [`check_sbatch_value`].
pub fn sbatch_quote(value: &str) -> String {
    let mut s = String::with_capacity(value.len() + 2);
    s.push('"');
    for c in value.chars() {
        if c == '\\' || c == '"' {
            s.push('\\');
        }
        s.push(c);
    }
    s.push('"');
    s
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The arguments sbatch reads from the text after `#SBATCH`: a transcription of
    /// `_get_argument` in Slurm's src/sbatch/opt.c (white space splits unless quoted, a
    /// backslash escapes the next character, quotes are removed, an unquoted `#` ends the line).
    fn slurm_args(line: &str) -> Vec<String> {
        let mut args = Vec::new();
        let mut chars = line.chars().peekable();
        loop {
            while chars.peek().is_some_and(|c| c.is_whitespace()) {
                chars.next();
            }
            if chars.peek().is_none() {
                return args;
            }
            let (mut arg, mut quote, mut escape) = (String::new(), None, false);
            while let Some(&c) = chars.peek() {
                if quote.is_none() && c.is_whitespace() || c == '\n' {
                    break;
                }
                chars.next();
                if escape {
                    escape = false;
                } else if c == '\\' {
                    escape = true;
                    continue;
                } else if let Some(q) = quote {
                    if c == q {
                        quote = None;
                        continue;
                    }
                } else if c == '"' || c == '\'' {
                    quote = Some(c);
                    continue;
                } else if c == '#' {
                    args.push(arg);
                    return args;
                }
                arg.push(c);
            }
            args.push(arg);
        }
    }

    #[test]
    fn sbatch_values_reach_sbatch_verbatim_as_one_argument() {
        for v in [
            "debug",
            "gpu long",
            "a --wrap=rm -rf ~",
            "x\" --output=/etc/passwd \"",
            "p#comment",
            "it's $(touch pwned); `id` \\ end\\",
            "'single' \"double\"",
        ] {
            check_sbatch_value("--partition", v).unwrap();
            let line = format!("--partition={}", sbatch_quote(v));
            assert_eq!(
                slurm_args(&line),
                vec![format!("--partition={v}")],
                "{line}"
            );
        }
        // unquoted, the same values would have split or been cut
        assert_eq!(slurm_args("--partition=a --wrap=x").len(), 2);
        assert_eq!(slurm_args("--partition=p#c"), vec!["--partition=p"]);
    }

    #[test]
    fn control_characters_and_empty_values_are_refused_naming_the_option() {
        for v in ["debug\nrm -rf ~", "a\rb", "tab\there", "", "  "] {
            let e = check_sbatch_value("--partition", v)
                .unwrap_err()
                .to_string();
            assert!(e.starts_with("--partition "), "{e}");
        }
        let o = SlurmOptions {
            extra: vec!["--qos=long\necho injected".into()],
            ..SlurmOptions::default()
        };
        let e = o.check().unwrap_err().to_string();
        assert!(
            e.contains("--sbatch-arg") && e.contains("control character"),
            "{e}"
        );
        let o = SlurmOptions {
            extra: vec!["qos=long".into()],
            ..SlurmOptions::default()
        };
        assert!(o
            .check()
            .unwrap_err()
            .to_string()
            .contains("starting with '-'"));
    }
}
