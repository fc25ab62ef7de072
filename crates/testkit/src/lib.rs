//! Dev-only test kit shared by every crate's tests and the CLI tests.
//!
//! - [`shared_data`]: a path into `../shared/data` (the real third-party data beside the
//!   checkout). A test that needs it **fails** with the reason when it is missing; it never
//!   passes silently.
//! - [`fetched_data`]: a file `bash scripts/deps.sh test` fetched from a package registry (test
//!   data no repository file holds); missing, the test fails and says how to fetch it.
//! - [`Cli`]: runs the `igi` binary (`Cli::new(env!("CARGO_BIN_EXE_igi"))`) with `--quiet`.
//! - [`mitsuba_capture`]: a capture that a `datasets/mitsuba` script renders into the target
//!   folder, once per version of the script.
//! - [`assert_failed`]: a command failed, its stderr names the file and the problem, and the
//!   folder holds nothing it should not (no half-written output, no temporary file).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The repository root (the folder holding the workspace `Cargo.toml`).
pub fn repo_root() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
}

/// `../shared/data` beside the checkout.
pub fn shared_data_root() -> PathBuf {
    repo_root().join("../shared/data")
}

/// The path of `rel` under `../shared/data`; panics with the reason when it is missing, so a
/// test that needs real data can never pass without it.
pub fn shared_data(rel: &str) -> PathBuf {
    let p = shared_data_root().join(rel);
    assert!(
        p.exists(),
        "test data missing: {} (the real-data tests read ../shared/data beside the checkout; see shared/data/CATALOGUE.md)",
        p.display()
    );
    p
}

/// The path of `rel` under the folder where `bash scripts/deps.sh test` puts the test data it
/// fetches from package registries (`$IGI_DATA_DIR`, else `/opt/igi-data`); panics with the
/// reason when it is missing, so a test that needs it can never pass without it.
pub fn fetched_data(rel: &str) -> PathBuf {
    let root = std::env::var_os("IGI_DATA_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("/opt/igi-data"));
    let p = root.join(rel);
    assert!(
        p.exists(),
        "test data missing: {} (`bash scripts/deps.sh test` fetches it; set IGI_DATA_DIR to the \
         folder where it put it if not /opt/igi-data)",
        p.display()
    );
    p
}

/// A fixture committed under `datasets/fixtures`.
pub fn fixture(rel: &str) -> PathBuf {
    let p = repo_root().join("datasets/fixtures").join(rel);
    assert!(p.exists(), "fixture missing: {}", p.display());
    p
}

/// The folder a Mitsuba 3 script of `datasets/mitsuba` writes a capture into: `$ENV_VAR` when
/// set (a capture the script wrote), else `target/NAME`, rendered by `python3 SCRIPT --out` when
/// missing or made by another version of the script (its hash is kept in `script.stamp`, written
/// after the script succeeds). Without Python's `mitsuba` it panics and says so. Call it once per
/// test binary (from a `OnceLock`): two renders into one folder would collide.
pub fn mitsuba_capture(script: &str, name: &str, env_var: &str) -> PathBuf {
    if let Some(d) = std::env::var_os(env_var) {
        return PathBuf::from(d);
    }
    let root = repo_root();
    let text = std::fs::read(root.join(script))
        .unwrap_or_else(|e| panic!("reading the capture script {script}: {e}"));
    let stamp = format!("{:016x}", fnv1a(&text));
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| root.join("target"));
    let dir = target.join(name);
    let done = dir.join("script.stamp");
    if std::fs::read_to_string(&done).ok().as_deref() == Some(stamp.as_str()) {
        return dir;
    }
    let _ = std::fs::remove_dir_all(&dir);
    let out = Command::new("python3")
        .arg(root.join(script))
        .arg("--out")
        .arg(&dir)
        .output()
        .unwrap_or_else(|e| panic!("running python3 {script} (needs Python 3 and the mitsuba package, `bash scripts/deps.sh mitsuba`): {e}"));
    assert!(
        out.status.success(),
        "python3 {script} failed (it needs the mitsuba package: `bash scripts/deps.sh mitsuba`):\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    std::fs::write(&done, &stamp).unwrap_or_else(|e| panic!("writing {}: {e}", done.display()));
    dir
}

/// FNV-1a, 64 bits: a script's version stamp.
fn fnv1a(b: &[u8]) -> u64 {
    b.iter().fold(0xcbf29ce484222325u64, |h, x| {
        (h ^ *x as u64).wrapping_mul(0x100000001b3)
    })
}

/// The `igi` binary of the test run.
pub struct Cli {
    bin: PathBuf,
    env: Vec<(String, String)>,
}

impl Cli {
    /// `bin` is `env!("CARGO_BIN_EXE_igi")` of the calling integration test.
    pub fn new(bin: &str) -> Self {
        Self {
            bin: PathBuf::from(bin),
            env: Vec::new(),
        }
    }

    /// The same binary run with `key=value` in its environment (e.g. `SLURM_CONF`, `PATH`).
    pub fn with_env(mut self, key: &str, value: &str) -> Self {
        self.env.push((key.to_string(), value.to_string()));
        self
    }

    /// A command for the binary (with this runner's environment), to add arguments to.
    pub fn command(&self) -> Command {
        let mut c = Command::new(&self.bin);
        c.envs(self.env.iter().map(|(k, v)| (k, v)));
        c
    }

    /// Runs `igi --quiet ARGS...` and returns its output.
    pub fn run(&self, args: &[&str]) -> Output {
        Command::new(&self.bin)
            .envs(self.env.iter().map(|(k, v)| (k, v)))
            .arg("--quiet")
            .args(args)
            .output()
            .expect("run igi")
    }

    /// Runs it and panics with its stderr unless it succeeded.
    pub fn ok(&self, args: &[&str]) -> Output {
        let o = self.run(args);
        assert!(
            o.status.success(),
            "igi {args:?} failed: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        o
    }
}

/// Runs `cmd` and returns its stdout; panics with its stderr and stdout unless it succeeded.
pub fn run_ok(cmd: &mut Command) -> String {
    let out = cmd.output().expect("the command runs");
    assert!(
        out.status.success(),
        "{cmd:?} failed: {}\n{}",
        String::from_utf8_lossy(&out.stderr),
        String::from_utf8_lossy(&out.stdout)
    );
    String::from_utf8(out.stdout).expect("UTF-8 on stdout")
}

/// A path as `&str` (test paths are UTF-8).
pub fn s(p: &Path) -> &str {
    p.to_str().expect("UTF-8 path")
}

/// Fails unless the command failed, stderr names `file` and contains `problem`, and `dir`
/// holds nothing but `keep` (no output, no temp file).
pub fn assert_failed(out: &Output, file: &str, problem: &str, dir: &Path, keep: &[PathBuf]) {
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "expected failure, stderr: {err}");
    assert!(err.contains(file), "stderr does not name {file}: {err}");
    assert!(
        err.contains(problem),
        "stderr does not say {problem:?}: {err}"
    );
    for e in std::fs::read_dir(dir).expect("read dir") {
        let p = e.expect("dir entry").path();
        assert!(keep.contains(&p), "left behind: {}", p.display());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn repo_root_holds_the_workspace() {
        assert!(repo_root().join("Cargo.toml").exists());
        assert!(repo_root().join("crates/testkit/Cargo.toml").exists());
    }

    #[test]
    #[should_panic(expected = "test data missing")]
    fn missing_data_fails_loudly() {
        shared_data("no/such/file.bin");
    }
}
