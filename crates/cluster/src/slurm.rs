//! Every call of a Slurm command: `sbatch`, `squeue`, `scancel`, `scontrol` (subprocesses).

use crate::ClusterError;
use std::io::Read;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// How long a Slurm command may take before it is given up (`IGI_SLURM_TIMEOUT` seconds,
/// default 120): a controller that cannot be reached makes `squeue` retry for minutes.
fn timeout() -> Duration {
    let s = std::env::var("IGI_SLURM_TIMEOUT")
        .ok()
        .and_then(|v| v.trim().parse::<f64>().ok())
        .filter(|s| s.is_finite() && *s > 0.0)
        .unwrap_or(120.0);
    Duration::from_secs_f64(s)
}

fn run(cmd: &mut Command) -> Result<String, ClusterError> {
    let shown = format!("{cmd:?}").replace('"', "");
    let mut child = cmd
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| ClusterError::Slurm {
            command: shown.clone(),
            msg: if e.kind() == std::io::ErrorKind::NotFound {
                "not found: is Slurm installed and on PATH? (Debian: slurm-wlm)".into()
            } else {
                e.to_string()
            },
        })?;
    let pipe = |r: Option<Box<dyn Read + Send>>| {
        std::thread::spawn(move || {
            let mut v = Vec::new();
            if let Some(mut r) = r {
                let _ = r.read_to_end(&mut v);
            }
            v
        })
    };
    let out = pipe(
        child
            .stdout
            .take()
            .map(|r| Box::new(r) as Box<dyn Read + Send>),
    );
    let err = pipe(
        child
            .stderr
            .take()
            .map(|r| Box::new(r) as Box<dyn Read + Send>),
    );
    let limit = timeout();
    let start = Instant::now();
    let status = loop {
        match child.try_wait() {
            Ok(Some(status)) => break status,
            Ok(None) if start.elapsed() < limit => std::thread::sleep(Duration::from_millis(20)),
            Ok(None) => {
                let _ = child.kill();
                let _ = child.wait();
                return Err(ClusterError::Slurm {
                    command: shown,
                    msg: format!(
                        "no answer within {:.0} s: is the Slurm controller reachable? (IGI_SLURM_TIMEOUT sets the limit)",
                        limit.as_secs_f64()
                    ),
                });
            }
            Err(e) => {
                return Err(ClusterError::Slurm {
                    command: shown,
                    msg: e.to_string(),
                })
            }
        }
    };
    let stdout = out.join().unwrap_or_default();
    let stderr = err.join().unwrap_or_default();
    if !status.success() {
        return Err(ClusterError::Slurm {
            command: shown,
            msg: String::from_utf8_lossy(&stderr).trim().to_string(),
        });
    }
    Ok(String::from_utf8_lossy(&stdout).into_owned())
}

/// Whether `sbatch` can be run at all (checked before a submission writes anything).
pub fn check_available() -> Result<(), ClusterError> {
    run(Command::new("sbatch").arg("--version")).map(drop)
}

/// Submits `script` with `args` (`--parsable`): the job id.
pub fn sbatch(script: &Path, args: &[String]) -> Result<String, ClusterError> {
    let out = run(Command::new("sbatch")
        .arg("--parsable")
        .args(args)
        .arg(script))?;
    // --parsable prints `ID` or `ID;CLUSTER`
    let id = out.trim().split(';').next().unwrap_or("").to_string();
    if id.is_empty() || !id.chars().all(|c| c.is_ascii_digit()) {
        return Err(ClusterError::Slurm {
            command: format!("sbatch {}", script.display()),
            msg: format!("unexpected output {out:?}"),
        });
    }
    Ok(id)
}

/// The cluster's MaxArraySize (`scontrol show config`), 1001 (Slurm's default) when it cannot
/// be read.
pub fn max_array_size() -> usize {
    run(Command::new("scontrol").args(["show", "config"]))
        .ok()
        .and_then(|text| {
            text.lines()
                .find(|l| l.trim_start().starts_with("MaxArraySize"))
                .and_then(|l| l.split('=').nth(1))
                .and_then(|v| v.trim().parse().ok())
        })
        .unwrap_or(1001)
}

/// State of a queued or running job or array task.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum QueueState {
    Pending,
    Running,
}

/// The queued and running array tasks of `jobs`: (job id, array index, state), one line per
/// task (`squeue -r`). Jobs that have left the queue are simply absent.
pub fn queued(jobs: &[String]) -> Result<Vec<(String, Option<usize>, QueueState)>, ClusterError> {
    if jobs.is_empty() {
        return Ok(Vec::new());
    }
    let out = run(Command::new("squeue")
        .args(["-h", "-r", "-o", "%F %K %t", "-j"])
        .arg(jobs.join(",")))
    .or_else(|e| match &e {
        // squeue refuses ids it no longer knows
        ClusterError::Slurm { msg, .. } if msg.contains("Invalid job id") => Ok(String::new()),
        _ => Err(e),
    })?;
    let mut v = Vec::new();
    for line in out.lines() {
        let f: Vec<&str> = line.split_whitespace().collect();
        if f.len() < 3 {
            continue;
        }
        let state = match f[2] {
            "PD" | "CF" | "RQ" | "RS" | "S" => QueueState::Pending,
            _ => QueueState::Running,
        };
        v.push((f[0].to_string(), f[1].parse().ok(), state));
    }
    Ok(v)
}

/// Cancels `jobs` (`scancel`).
pub fn scancel(jobs: &[String]) -> Result<(), ClusterError> {
    if jobs.is_empty() {
        return Ok(());
    }
    run(Command::new("scancel").args(jobs)).map(drop)
}
