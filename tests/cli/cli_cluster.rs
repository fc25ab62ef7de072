//! `igi cluster` against a real one-node Slurm (scripts/slurm-loopback.sh), and its bad input.
//!
//! The Slurm test fails with the reason when the cluster cannot start (Slurm or munge not
//! installed, not root): it never passes without having run on Slurm.

use igi_testkit::{assert_failed, fixture, repo_root, s, Cli};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

fn igi() -> Cli {
    Cli::new(env!("CARGO_BIN_EXE_igi"))
}

/// The fixture survey's block prepared in 12 voxels (1.5 m) plus its ground as terrain, and a
/// survey naming it with the fixture's 8 photographs.
fn prepared_survey(dir: &Path) -> PathBuf {
    let f = fixture("survey");
    let site = dir.join("site");
    igi().ok(&[
        "prepare",
        s(&f.join("geometry/block.ply")),
        "--terrain",
        s(&f.join("geometry/ground.ply")),
        "--voxel",
        "1.5",
        "--atlas",
        "16",
        "-o",
        s(&site),
    ]);
    let text = std::fs::read_to_string(f.join("survey.toml")).unwrap();
    let photos = &text[text.find("[[photo]]").unwrap()..];
    let photos = photos.replace("= \"", &format!("= \"{}/", f.display()));
    let survey = dir.join("survey.toml");
    std::fs::write(
        &survey,
        format!("[site]\nprepared = {:?}\n\n{photos}", s(&site)),
    )
    .unwrap();
    survey
}

const SOLVE: [&str; 8] = [
    "--iterations",
    "2",
    "--spp",
    "4,8",
    "--tolerance",
    "0",
    "--indirect",
    "1",
];

/// A running loopback cluster, stopped on drop.
struct Slurm {
    state: PathBuf,
    conf: String,
}

/// The loopback cluster's MaxArraySize: small, so that the fixture's 13 tasks are split in two
/// arrays (indices 0-7 and 8-12).
const MAX_ARRAY_SIZE: usize = 8;

impl Slurm {
    fn start(state: &Path) -> Slurm {
        let script = repo_root().join("scripts/slurm-loopback.sh");
        // a port of its own, so a cluster someone runs on this machine does not answer
        let port = 20000 + std::process::id() % 20000;
        let out = std::process::Command::new("bash")
            .arg(&script)
            .arg("start")
            .arg(state)
            .env("IGI_SLURM_PORT", port.to_string())
            .env("IGI_SLURM_MAX_ARRAY_SIZE", MAX_ARRAY_SIZE.to_string())
            .output()
            .expect("run scripts/slurm-loopback.sh");
        assert!(
            out.status.success(),
            "the Slurm loopback cluster did not start, so igi cluster cannot be tested: {}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        Slurm {
            state: state.to_path_buf(),
            conf: s(&state.join("slurm.conf")).to_string(),
        }
    }

    fn igi(&self) -> Cli {
        igi().with_env("SLURM_CONF", &self.conf)
    }

    fn status(&self, result: &Path) -> serde_json::Value {
        let o = self.igi().ok(&["cluster", "status", s(result), "--json"]);
        serde_json::from_slice(&o.stdout).unwrap()
    }

    /// Waits until nothing of the run is queued (tasks and merge), at most `limit`.
    fn settle(&self, result: &Path, limit: Duration) -> serde_json::Value {
        let t0 = Instant::now();
        loop {
            let st = self.status(result);
            let busy = st["merge"].is_string()
                || st["groups"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .any(|g| g[1] == "running" || g[1] == "pending");
            if !busy {
                return st;
            }
            assert!(
                t0.elapsed() < limit,
                "the cluster run did not settle in {limit:?}: {st}"
            );
            std::thread::sleep(Duration::from_millis(500));
        }
    }

    fn squeue(&self, args: &[&str]) -> String {
        let o = std::process::Command::new("squeue")
            .env("SLURM_CONF", &self.conf)
            .args(args)
            .output()
            .unwrap();
        String::from_utf8_lossy(&o.stdout).into_owned()
    }
}

impl Slurm {
    /// Cancels a task of iteration `k` while it runs; one that finished before the cancel
    /// reached it (its log holds no CANCELLED, or its done report was already written, so
    /// that status counts it done) does not count, and another is tried.
    fn cancel_a_running_task(&self, result: &Path, k: u32, limit: Duration) {
        let logs = result.join(format!("cluster/iter_{k}/logs"));
        let t0 = Instant::now();
        let mut tried = Vec::new();
        loop {
            assert!(
                t0.elapsed() < limit,
                "no running task of iteration {k} to cancel"
            );
            let q = self.squeue(&["-h", "-r", "-t", "R", "-o", "%i %j"]);
            let running = q.lines().find_map(|l| {
                let (id, name) = l.trim().split_once(' ')?;
                let chunk = name.strip_prefix(&format!("igi-{k}-tasks-"))?;
                let a = id.split_once('_')?.1;
                (!tried.contains(&id.to_string()))
                    .then(|| (id.to_string(), chunk.to_string(), a.to_string()))
            });
            let Some((id, chunk, a)) = running else {
                std::thread::sleep(Duration::from_millis(50));
                continue;
            };
            let out = std::process::Command::new("scancel")
                .env("SLURM_CONF", &self.conf)
                .arg(&id)
                .output()
                .unwrap();
            assert!(out.status.success(), "scancel {id}");
            tried.push(id.clone());
            while self
                .squeue(&["-h", "-r", "-j", &id, "-o", "%i"])
                .contains(&id)
            {
                std::thread::sleep(Duration::from_millis(100));
            }
            let log = logs.join(format!("task-{chunk}-{a}.out"));
            let text = std::fs::read_to_string(&log).unwrap_or_default();
            if text.contains("CANCELLED") && !states(&self.status(result), "lost").is_empty() {
                return;
            }
        }
    }
}

impl Drop for Slurm {
    fn drop(&mut self) {
        let _ = std::process::Command::new("bash")
            .arg(repo_root().join("scripts/slurm-loopback.sh"))
            .arg("stop")
            .arg(&self.state)
            .status();
    }
}

fn states(st: &serde_json::Value, want: &str) -> Vec<String> {
    st["groups"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|g| g[1] == want)
        .map(|g| g[0].as_str().unwrap().to_string())
        .collect()
}

/// Every file of the local Jacobi result equals the cluster's, the report but for wall times.
fn assert_same_result(local: &Path, cluster: &Path) {
    let mut n = 0;
    for e in std::fs::read_dir(local.join("parts")).unwrap() {
        let name = e.unwrap().file_name();
        let a = std::fs::read(local.join("parts").join(&name)).unwrap();
        let b = std::fs::read(cluster.join("parts").join(&name)).unwrap();
        assert!(a == b, "parts/{name:?} differs from the local Jacobi solve");
        n += 1;
    }
    assert!(n >= 13 * 6, "{n} part files: 6 per voxel and the terrain");
    for f in ["scene.toml", "run.json"] {
        assert_eq!(
            std::fs::read(local.join(f)).unwrap(),
            std::fs::read(cluster.join(f)).unwrap(),
            "{f}"
        );
    }
    let report = |d: &Path| {
        let mut r: serde_json::Value =
            serde_json::from_slice(&std::fs::read(d.join("report.json")).unwrap()).unwrap();
        for it in r["iterations"].as_array_mut().unwrap() {
            it["wall_s"] = 0.into();
            it["cumulative_s"] = 0.into();
        }
        r
    };
    assert_eq!(report(local), report(cluster));
}

#[test]
fn a_cluster_run_on_slurm_equals_the_local_jacobi_solve_and_recovers_failed_and_lost_tasks() {
    let tmp = tempfile::tempdir().unwrap();
    let slurm = Slurm::start(&tmp.path().join("slurm"));
    let survey = prepared_survey(tmp.path());
    let local = tmp.path().join("local");
    let mut args = vec!["solve", s(&survey), "-o", s(&local), "--schedule", "jacobi"];
    args.extend(SOLVE);
    igi().ok(&args);
    let b = break_a_voxel(&tmp.path().join("site"));
    let result = tmp.path().join("cluster");
    let limit = Duration::from_secs(240);
    first_iteration_fails(&slurm, &survey, &result, &b, limit);
    // restored, resume finishes iteration 1; the merge submits iteration 2, in which a running
    // task is cancelled (lost); resume repairs that too
    std::fs::write(&b.level, &b.good).unwrap();
    resume_repairs_failed_and_lost_tasks(&slurm, &result, limit);
    assert_same_result(&local, &result);
    skipped_voxel_stays_stale(
        &slurm,
        &survey,
        &tmp.path().join("skipped"),
        &local,
        &b,
        limit,
    );
}

/// A voxel whose full-resolution level was truncated: its file, its good bytes, its name, and
/// the (sorted) groups whose tasks fail for it.
struct Broken {
    level: PathBuf,
    good: Vec<u8>,
    broken: String,
    failing: Vec<String>,
}

/// The failed tasks of a status, sorted.
fn failed(st: &serde_json::Value) -> Vec<String> {
    let mut f = states(st, "failed");
    f.sort();
    f
}

/// Tasks made to fail: one voxel's full-resolution level truncated, which fails its own task
/// and those of its neighbours (a Jacobi task loads its 26 neighbours at level 0).
fn break_a_voxel(site: &Path) -> Broken {
    let man: serde_json::Value =
        serde_json::from_slice(&std::fs::read(site.join("manifest.json")).unwrap()).unwrap();
    let ids: Vec<[i64; 3]> = man["voxels"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|e| serde_json::from_value(e["voxel"].clone()).ok())
        .collect();
    let v = ids[2];
    let name = |u: [i64; 3]| format!("{}_{}_{}", u[0], u[1], u[2]);
    let broken = name(v);
    let mut failing: Vec<String> = ids
        .iter()
        .filter(|u| (0..3).all(|k| (u[k] - v[k]).abs() <= 1))
        .map(|&u| name(u))
        .collect();
    failing.sort();
    assert!(
        failing.len() > 1 && failing.len() < ids.len(),
        "{failing:?}"
    );
    let level = site.join("voxels").join(&broken).join("level0.ply");
    assert!(level.is_file(), "{}", level.display());
    let good = std::fs::read(&level).unwrap();
    std::fs::write(&level, &good[..good.len() / 2]).unwrap();
    Broken {
        level,
        good,
        broken,
        failing,
    }
}

/// Submits the run with the voxel broken: iteration 1 settles with exactly the failing tasks
/// failed, named in missing.txt, and iteration 2 is not submitted.
fn first_iteration_fails(slurm: &Slurm, survey: &Path, result: &Path, b: &Broken, limit: Duration) {
    let failing = &b.failing;
    let mut args = vec!["cluster", "submit", s(survey), "-o", s(result)];
    args.extend(SOLVE);
    args.extend(["--max-parallel", "2"]);
    slurm.igi().ok(&args);
    let st = slurm.settle(result, limit);
    assert_eq!(st["iteration"], 1, "{st}");
    assert_eq!(&failed(&st), failing, "{st}");
    assert_eq!(states(&st, "done").len(), 13 - failing.len(), "{st}");
    let config: serde_json::Value =
        serde_json::from_slice(&std::fs::read(result.join("cluster/cluster.json")).unwrap())
            .unwrap();
    let arrays = &config["jobs"][0]["arrays"];
    assert_eq!(
        arrays.as_array().map(Vec::len),
        Some(13usize.div_ceil(MAX_ARRAY_SIZE)),
        "13 tasks in arrays of at most {MAX_ARRAY_SIZE}: {config}"
    );
    let missing = std::fs::read_to_string(result.join("cluster/iter_1/missing.txt")).unwrap();
    assert_eq!(missing.lines().count(), 1 + failing.len(), "{missing}");
    assert!(
        failing.iter().all(|g| missing.contains(g.as_str()))
            && missing.contains("task-0-")
            && missing.contains(".ply"),
        "{missing}"
    );
    assert!(
        !result.join("cluster/iter_2").exists(),
        "the next iteration is not submitted after a failed task"
    );
}

/// Resume finishes iteration 1; a task of iteration 2 is cancelled (lost) and resume repairs
/// that too, and the run finishes.
fn resume_repairs_failed_and_lost_tasks(slurm: &Slurm, result: &Path, limit: Duration) {
    slurm.igi().ok(&["cluster", "resume", s(result)]);
    slurm.cancel_a_running_task(result, 2, limit);
    let st = slurm.settle(result, limit);
    assert_eq!(st["iteration"], 2, "{st}");
    let lost = states(&st, "lost");
    assert_eq!(lost.len(), 1, "the cancelled task shows as lost: {st}");
    assert_eq!(states(&st, "done").len(), 12, "{st}");
    slurm.igi().ok(&["cluster", "resume", s(result)]);
    let st = slurm.settle(result, limit);
    assert_eq!(st["finished"], true, "{st}");
    let tasks = &st["tasks"];
    assert_eq!(tasks["finished"], 13, "{st}");
    let peak = tasks["peak_rss_bytes"].as_u64().unwrap();
    assert!(peak > 1 << 20 && peak < 4 << 30, "{st}");
    assert!(tasks["read_bytes"].as_u64().unwrap() > 13 << 10, "{st}");
}

/// A task that keeps failing: after --max-attempts, resume refuses it, and --skip-voxels
/// keeps its previous albedo, marked stale, in a run that then never counts as converged.
fn skipped_voxel_stays_stale(
    slurm: &Slurm,
    survey: &Path,
    skipped: &Path,
    local: &Path,
    b: &Broken,
    limit: Duration,
) {
    let (level, good, broken, failing) = (&b.level, &b.good, &b.broken, &b.failing);
    std::fs::write(level, &good[..good.len() / 2]).unwrap();
    let mut args = vec!["cluster", "submit", s(survey), "-o", s(skipped)];
    args.extend(["--iterations", "1", "--spp", "4", "--indirect", "1"]);
    args.extend(["--max-attempts", "1"]);
    slurm.igi().ok(&args);
    let st = slurm.settle(skipped, limit);
    assert_eq!(&failed(&st), failing, "{st}");
    let out = slurm.igi().run(&["cluster", "resume", s(skipped)]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains(broken.as_str()) && err.contains("--skip-voxels"),
        "{err}"
    );
    slurm
        .igi()
        .ok(&["cluster", "resume", s(skipped), "--skip-voxels"]);
    let st = slurm.settle(skipped, limit);
    assert_eq!(st["finished"], true, "{st}");
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(skipped.join("report.json")).unwrap()).unwrap();
    let it = &report["iterations"][0];
    let mut stale: Vec<String> = serde_json::from_value(it["stale"].clone()).unwrap();
    stale.sort();
    assert_eq!(&stale, failing, "{it}");
    assert_eq!(report["converged"], false, "{report}");
    let a = igi_imaging::read_image(&local.join(format!("parts/{broken}_rho_d.exr")));
    let b = igi_imaging::read_image(&skipped.join(format!("parts/{broken}_rho_d.exr")));
    assert_ne!(
        a.unwrap().pixels,
        b.unwrap().pixels,
        "the stale voxel was not solved"
    );
    std::fs::write(level, good).unwrap();
}

#[test]
fn bad_cluster_input_is_refused_clearly() {
    let tmp = tempfile::tempdir().unwrap();
    // a survey that is not prepared
    let plain = fixture("survey/survey.toml");
    let out = igi().run(&[
        "cluster",
        "submit",
        s(&plain),
        "-o",
        s(&tmp.path().join("r")),
    ]);
    assert_failed(
        &out,
        "survey.toml",
        "run `igi prepare` first",
        tmp.path(),
        &[],
    );
    // no sbatch on PATH: refused before anything is written
    let survey = prepared_survey(tmp.path());
    let keep: Vec<PathBuf> = std::fs::read_dir(tmp.path())
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    let result = tmp.path().join("r");
    let no_slurm = igi().with_env("PATH", "/nonexistent");
    let mut args = vec!["cluster", "submit", s(&survey), "-o", s(&result)];
    args.extend(SOLVE);
    let out = no_slurm.run(&args);
    assert_failed(&out, "sbatch", "is Slurm installed", tmp.path(), &keep);
    // a dry run writes the scripts; a second submission into the folder is refused
    let mut dry = args.clone();
    dry.push("--dry-run");
    let o = igi().ok(&dry);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("#SBATCH --array=0,1,2,3,4,5,6,7,8,9,10,11,12")
            && text.contains("cluster task")
            && text.contains("cluster merge"),
        "{text}"
    );
    let out = igi().run(&dry);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("already holds a cluster run"));
    // an index out of range, and a folder that is not a cluster run
    let out = igi().run(&["cluster", "task", s(&result), "--index", "13"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("--index 13 is out of range") && err.contains("13 tasks"),
        "{err}"
    );
    let out = igi().run(&["cluster", "status", s(tmp.path())]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("cluster.json") && err.contains("igi cluster submit"),
        "{err}"
    );
    task_of_another_binary_is_refused(tmp.path(), &survey);
    task_with_changed_inputs_is_refused(tmp.path(), &survey, &result);
}

/// A result submitted by another igi binary: a task of this one refuses to run (the copy gets
/// a trailing byte, so it differs whether binaries are told apart by content or by path and
/// time), and writes no output.
fn task_of_another_binary_is_refused(tmp: &Path, survey: &Path) {
    let other = tmp.join("igi-other");
    std::fs::copy(env!("CARGO_BIN_EXE_igi"), &other).unwrap();
    {
        use std::io::Write;
        let mut f = std::fs::OpenOptions::new()
            .append(true)
            .open(&other)
            .unwrap();
        f.write_all(b"\0").unwrap();
    }
    let by_other = tmp.join("by-other");
    let mut args = vec!["cluster", "submit", s(survey), "-o", s(&by_other)];
    args.extend(SOLVE);
    args.push("--dry-run");
    Cli::new(s(&other)).ok(&args);
    let out = igi().run(&["cluster", "task", s(&by_other), "--index", "0"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("igi binary"), "{err}");
    let written: Vec<_> = std::fs::read_dir(by_other.join("cluster/iter_1"))
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .filter(|n| n != "logs" && !n.to_string_lossy().ends_with(".sh"))
        .collect();
    assert!(written.is_empty(), "no task output: {written:?}");
}

/// A result whose inputs changed since submission: the task refuses to run.
fn task_with_changed_inputs_is_refused(tmp: &Path, survey: &Path, result: &Path) {
    let photo = fixture("survey/photos/v00-sunny.exr");
    let copy = tmp.join("v00.exr");
    std::fs::copy(&photo, &copy).unwrap();
    let text = std::fs::read_to_string(survey).unwrap();
    std::fs::write(survey, text.replace(s(&photo), s(&copy))).unwrap();
    let img = igi_imaging::read_image(&copy).unwrap();
    let mut brighter = img.clone();
    brighter.pixels.iter_mut().for_each(|p| p[0] *= 1.01);
    igi_imaging::write_exr(&copy, &brighter).unwrap();
    let out = igi().run(&["cluster", "task", s(result), "--index", "0"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--restart") || err.contains("differ"), "{err}");
}

/// Writes an executable `name` into `dir` that runs the shell `body`.
fn fake_tool(dir: &Path, name: &str, body: &str) {
    use std::os::unix::fs::PermissionsExt;
    let p = dir.join(name);
    std::fs::write(&p, format!("#!/bin/sh\n{body}\n")).unwrap();
    std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o755)).unwrap();
}

/// Issue 36 item 7: `cluster status` where Slurm is missing, failing or silent is an error
/// naming squeue (it called every task "Lost", exit 0); tasks of a dry run are "unsubmitted";
/// `#SBATCH` values are quoted and a newline in one is refused before anything is written.
#[test]
fn cluster_status_without_slurm_is_an_error_and_sbatch_values_cannot_inject() {
    let tmp = tempfile::tempdir().unwrap();
    let survey = prepared_survey(tmp.path());
    // a dry run: nothing was submitted, so nothing is lost and squeue is not asked
    let dry = tmp.path().join("dry");
    let mut args = vec!["cluster", "submit", s(&survey), "-o", s(&dry)];
    args.extend(SOLVE);
    let mut with_dry = args.clone();
    with_dry.extend([
        "--dry-run",
        "--partition",
        "gpu long#x",
        "--sbatch-arg=--comment=a \"b\" $(touch pwned)",
    ]);
    let o = igi().with_env("PATH", "/nonexistent").ok(&with_dry);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("#SBATCH --partition=\"gpu long#x\"\n")
            && text.contains("#SBATCH \"--comment=a \\\"b\\\" $(touch pwned)\"\n"),
        "{text}"
    );
    let st = igi()
        .with_env("PATH", "/nonexistent")
        .ok(&["cluster", "status", s(&dry), "--json"]);
    let st: serde_json::Value = serde_json::from_slice(&st.stdout).unwrap();
    assert_eq!(states(&st, "unsubmitted").len(), 13, "{st}");
    assert!(states(&st, "lost").is_empty(), "{st}");
    // a newline in a value is refused before anything is written
    let keep: Vec<PathBuf> = std::fs::read_dir(tmp.path())
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    let bad = tmp.path().join("bad");
    let mut nl = vec!["cluster", "submit", s(&survey), "-o", s(&bad)];
    nl.extend(["--partition", "debug\necho injected", "--dry-run"]);
    let out = igi().run(&nl);
    assert_failed(&out, "--partition", "control character", tmp.path(), &keep);
    // a run submitted through a stand-in sbatch (job 4242), then asked about without squeue
    let bin = tmp.path().join("bin");
    std::fs::create_dir(&bin).unwrap();
    fake_tool(&bin, "sbatch", "echo 4242");
    let run = tmp.path().join("run");
    let mut submit = vec!["cluster", "submit", s(&survey), "-o", s(&run)];
    submit.extend(SOLVE);
    igi().with_env("PATH", s(&bin)).ok(&submit);
    let no_squeue = igi().with_env("PATH", s(&bin));
    let out = no_squeue.run(&["cluster", "status", s(&run)]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(
        err.contains("squeue") && err.contains("is Slurm installed"),
        "{err}"
    );
    assert!(!String::from_utf8_lossy(&out.stdout).contains("lost"));
    // a controller that cannot be reached: squeue fails
    fake_tool(
        &bin,
        "squeue",
        "echo 'slurm_load_jobs error: Unable to contact slurm controller (connect failure)' >&2; exit 1",
    );
    let out = no_squeue.run(&["cluster", "status", s(&run)]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("Unable to contact slurm controller"),
        "{err}"
    );
    // ... or never answers: given up after IGI_SLURM_TIMEOUT seconds
    fake_tool(&bin, "squeue", "exec /bin/sleep 60");
    let t = Instant::now();
    let out = igi()
        .with_env("PATH", s(&bin))
        .with_env("IGI_SLURM_TIMEOUT", "1")
        .run(&["cluster", "status", s(&run)]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("no answer within 1 s"),
        "{err}"
    );
    assert!(t.elapsed() < Duration::from_secs(20), "{:?}", t.elapsed());
}
