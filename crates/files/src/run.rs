//! Run manifests: what a resumable command was started with, so a resume never mixes work.
//!
//! A resumable command (`igi prepare`, `igi solve`) writes a [`RunManifest`] (`run.json`) into
//! its output folder before the first byte of work: the command, a [`Fingerprint`] of every
//! input file, every option that changes the result (as text, formatted deterministically:
//! Rust's shortest round-trip float formatting), and, for a shard, the parts it owns. A later
//! run on the same folder resumes only when its own manifest is equal; otherwise
//! [`RunManifest::check_resume`] fails with [`FilesError::RunMismatch`] naming the first
//! differing option or input and suggesting `--restart`.
//!
//! Shards: a run that solves only some parts records them in `owns`. Two shards never share a
//! folder (their `owns` differ, so the second is refused): each shard writes its own folder,
//! and a merge step (not here) combines folders whose `owns` are disjoint.
//!
//! One writer at a time: a run that writes into a folder holds a [`FolderLock`] (an advisory
//! `flock` on `FOLDER/.igi-lock`, released when the process ends, however it ends) from its
//! first byte of output to its last, so a second run on the same folder, started by mistake
//! beside the first, is refused with the first one's process and host named instead of
//! mixing the two runs' files. The lock file stays behind (removing it would race with a
//! waiting opener); [`RunManifest::check_folder`] ignores it.
//!
//! Fingerprints: files up to [`HASH_LIMIT`] bytes are hashed (64-bit FNV-1a of the content);
//! larger files are recorded by size and modification time. Paths are recorded as given
//! (for messages) but compared only when no content hash is available.

use crate::FilesError;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// Files up to this size are fingerprinted by a content hash; larger ones by size and mtime.
pub const HASH_LIMIT: u64 = 64 << 20;

/// The file name of a run manifest inside an output folder.
pub const RUN_FILE: &str = "run.json";

/// The lock file a running writer holds inside its output folder (see [`FolderLock`]).
pub const LOCK_FILE: &str = ".igi-lock";

/// An exclusive claim on an output folder for as long as the value lives (see the module
/// overview). Advisory: it keeps igi runs apart, not other programs.
#[derive(Debug)]
pub struct FolderLock {
    file: std::fs::File,
    /// The lock file to remove on release ([`FolderLock::acquire_beside`]).
    remove: Option<std::path::PathBuf>,
}

impl Drop for FolderLock {
    fn drop(&mut self) {
        // unlinked while still held: an opener of the old file then finds it replaced (see
        // `acquire_file`) and is refused instead of locking a file nobody else sees
        if let Some(p) = &self.remove {
            let _ = std::fs::remove_file(p);
        }
        let _ = self.file.unlock();
    }
}

impl FolderLock {
    /// Claims the existing folder `dir`, or fails with [`FilesError::FolderBusy`] naming the
    /// process and host that hold it. Never waits.
    pub fn acquire(dir: &Path) -> Result<FolderLock, FilesError> {
        FolderLock::acquire_file(&dir.join(LOCK_FILE), dir)
    }

    /// Claims `folder` (which need not exist yet) through the lock file `path` beside it,
    /// removed again when the lock is released so that nothing is left next to the output.
    pub fn acquire_beside(path: &Path, folder: &Path) -> Result<FolderLock, FilesError> {
        let mut lock = FolderLock::acquire_file(path, folder)?;
        lock.remove = Some(path.to_path_buf());
        Ok(lock)
    }

    /// Claims `folder` through the lock file `path`, or fails with [`FilesError::FolderBusy`]
    /// naming the holder.
    fn acquire_file(path: &Path, folder: &Path) -> Result<FolderLock, FilesError> {
        use std::io::Write;
        let dir = folder;
        let path = path.to_path_buf();
        let mut file = std::fs::OpenOptions::new()
            .create(true)
            .truncate(false)
            .read(true)
            .write(true)
            .open(&path)
            .map_err(|e| FilesError::io(&path, e))?;
        match file.try_lock() {
            Ok(()) => {}
            Err(std::fs::TryLockError::WouldBlock) => {
                let holder = std::fs::read_to_string(&path).unwrap_or_default();
                let holder = match holder.trim() {
                    "" => "holder unknown".to_string(),
                    h => h.to_string(),
                };
                return Err(FilesError::FolderBusy {
                    path: dir.to_path_buf(),
                    holder,
                });
            }
            Err(std::fs::TryLockError::Error(e)) => return Err(FilesError::io(&path, e)),
        }
        // a holder that removes its lock file on release may have done so between our open
        // and our lock: then the file we hold is no longer the one at `path`
        if !same_file(&file, &path) {
            return Err(FilesError::FolderBusy {
                path: dir.to_path_buf(),
                holder: "a run that has just finished; run again".into(),
            });
        }
        let holder = format!(
            "process {} on host {}",
            std::process::id(),
            crate::host::this_host()
        );
        file.set_len(0)
            .and_then(|()| file.write_all(holder.as_bytes()))
            .map_err(|e| FilesError::io(&path, e))?;
        Ok(FolderLock { file, remove: None })
    }
}

/// Whether the open `file` is the file now at `path` (same device and inode).
#[cfg(unix)]
fn same_file(file: &std::fs::File, path: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (file.metadata(), std::fs::metadata(path)) {
        (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
        _ => false,
    }
}

#[cfg(not(unix))]
fn same_file(_file: &std::fs::File, path: &Path) -> bool {
    path.exists()
}

/// The identity of one input file.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Fingerprint {
    /// What the file is to the command (`mesh`, `photo v00 image`, ...).
    pub role: String,
    pub path: String,
    pub size: u64,
    /// `fnv1a64:HEX` of the content, for files up to [`HASH_LIMIT`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hash: Option<String>,
    /// Modification time in whole seconds since the epoch, for larger files.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mtime_s: Option<u64>,
}

impl Fingerprint {
    /// Fingerprints the file at `path` (an error names the file when it cannot be read).
    pub fn of(role: &str, path: &Path) -> Result<Fingerprint, FilesError> {
        let meta = std::fs::metadata(path).map_err(|e| FilesError::io(path, e))?;
        let size = meta.len();
        let (hash, mtime_s) = if size <= HASH_LIMIT {
            let bytes = std::fs::read(path).map_err(|e| FilesError::io(path, e))?;
            (Some(format!("fnv1a64:{:016x}", fnv1a64(&bytes))), None)
        } else {
            let t = meta
                .modified()
                .ok()
                .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
                .map(|d| d.as_secs());
            (None, t)
        };
        Ok(Fingerprint {
            role: role.to_string(),
            path: path.display().to_string(),
            size,
            hash,
            mtime_s,
        })
    }

    /// Whether two fingerprints name the same content.
    pub fn same_content(&self, other: &Fingerprint) -> bool {
        match (&self.hash, &other.hash) {
            (Some(a), Some(b)) => a == b && self.size == other.size,
            _ => {
                self.size == other.size && self.mtime_s == other.mtime_s && self.path == other.path
            }
        }
    }

    /// Path and size, for messages.
    pub fn describe(&self) -> String {
        format!("{} ({} bytes)", self.path, self.size)
    }
}

/// 64-bit FNV-1a of `bytes` (8 bytes at a time would not be FNV; this is the plain byte loop).
pub fn fnv1a64(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

/// What [`RunManifest::check_folder`] found in an output folder.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FolderState {
    /// Nothing of an earlier run (or `--restart`): start afresh.
    Fresh,
    /// An identical run's manifest: continue its work.
    Resume,
}

/// Removes, as a `--restart` does, the files of `dir` that a command writes: those matching
/// one of `patterns`, each a path relative to `dir` with `/` between folders and `*` standing
/// for any run of characters within one name (`parts/*_rho_d.exr`, `voxels/*_*_*/level*.ply`),
/// and the temporary files of [`crate::atomic::write_atomic`] writing such a name
/// (`.NAME.tmp...`). A folder on a pattern's path is removed when that leaves it empty;
/// everything else (a user's `parts/notes.txt`) stays. Symbolic links are never followed.
/// Returns how many files were removed.
pub fn remove_own(dir: &Path, patterns: &[&str]) -> Result<usize, FilesError> {
    let mut removed = 0;
    for pattern in patterns {
        let parts: Vec<&str> = pattern.split('/').filter(|p| !p.is_empty()).collect();
        removed += remove_matching(dir, &parts)?;
    }
    Ok(removed)
}

fn remove_matching(dir: &Path, parts: &[&str]) -> Result<usize, FilesError> {
    let Some((first, rest)) = parts.split_first() else {
        return Ok(0);
    };
    let entries = match std::fs::read_dir(dir) {
        Ok(e) => e,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(0),
        Err(e) => return Err(FilesError::io(dir, e)),
    };
    let mut removed = 0;
    for entry in entries {
        let entry = entry.map_err(|e| FilesError::io(dir, e))?;
        let name = entry.file_name().to_string_lossy().into_owned();
        let path = entry.path();
        let kind = entry.file_type().map_err(|e| FilesError::io(&path, e))?;
        if rest.is_empty() {
            if !kind.is_dir() && (glob(first, &name) || is_temp_of(first, &name)) {
                std::fs::remove_file(&path).map_err(|e| FilesError::io(&path, e))?;
                removed += 1;
            }
        } else if kind.is_dir() && glob(first, &name) {
            removed += remove_matching(&path, rest)?;
            // a folder only igi's files were in goes too; one holding anything else stays
            let empty = std::fs::read_dir(&path)
                .map_err(|e| FilesError::io(&path, e))?
                .next()
                .is_none();
            if empty {
                std::fs::remove_dir(&path).map_err(|e| FilesError::io(&path, e))?;
            }
        }
    }
    Ok(removed)
}

/// Whether `name` matches `pattern`, where `*` is any run of characters (none included).
pub fn glob(pattern: &str, name: &str) -> bool {
    match pattern.split_once('*') {
        None => pattern == name,
        Some((head, tail)) => {
            let Some(rest) = name.strip_prefix(head) else {
                return false;
            };
            (0..=rest.len())
                .filter(|&i| rest.is_char_boundary(i))
                .any(|i| glob(tail, &rest[i..]))
        }
    }
}

/// Whether `name` is a temporary file of `write_atomic` writing a name that matches `pattern`
/// (`.NAME.tmpPID-N_HOST_JOB.EXT`).
fn is_temp_of(pattern: &str, name: &str) -> bool {
    let Some(inner) = name.strip_prefix('.') else {
        return false;
    };
    inner
        .match_indices(".tmp")
        .any(|(i, _)| glob(pattern, &inner[..i]))
}

/// What a resumable run was started with (see the module overview).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct RunManifest {
    pub command: String,
    pub inputs: Vec<Fingerprint>,
    /// Every result-changing option, keyed by its command-line name (`--spp`).
    pub options: BTreeMap<String, String>,
    /// For a shard: the parts (or voxels) this folder's run solves; `None` for all.
    #[serde(default)]
    pub owns: Option<Vec<String>>,
    /// Options that say how far to go, which a resume may raise but never lower
    /// (`--iterations`: more iterations continue the same run; fewer would leave a result of
    /// more iterations than asked for). Absent in manifests of older igi versions.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub raisable: BTreeMap<String, u64>,
}

impl RunManifest {
    pub fn new(command: &str) -> RunManifest {
        RunManifest {
            command: command.to_string(),
            inputs: Vec::new(),
            options: BTreeMap::new(),
            owns: None,
            raisable: BTreeMap::new(),
        }
    }

    /// Records an option a resume may raise but not lower (see [`RunManifest::raisable`]).
    pub fn raisable(&mut self, name: &str, value: u64) -> &mut Self {
        self.raisable.insert(name.to_string(), value);
        self
    }

    /// Records a result-changing option under its command-line name; floats should be given
    /// as numbers formatted with `{}` or `{:?}` (shortest round-trip, deterministic).
    pub fn option(&mut self, name: &str, value: impl std::fmt::Display) -> &mut Self {
        self.options.insert(name.to_string(), value.to_string());
        self
    }

    /// Fingerprints an input file and records it under `role`.
    pub fn input(&mut self, role: &str, path: &Path) -> Result<&mut Self, FilesError> {
        self.inputs.push(Fingerprint::of(role, path)?);
        Ok(self)
    }

    /// Reads `dir/run.json`, or `None` when there is none.
    pub fn read(dir: &Path) -> Result<Option<RunManifest>, FilesError> {
        let path = dir.join(RUN_FILE);
        if !path.exists() {
            return Ok(None);
        }
        let text = std::fs::read_to_string(&path).map_err(|e| FilesError::io(&path, e))?;
        let m = serde_json::from_str(&text).map_err(|e| FilesError::BadManifest {
            path: path.clone(),
            source: e,
        })?;
        Ok(Some(m))
    }

    /// Writes `dir/run.json` atomically.
    pub fn write(&self, dir: &Path) -> Result<(), FilesError> {
        let text = serde_json::to_string_pretty(self).expect("serialisable") + "\n";
        crate::atomic::write_text_atomic(&dir.join(RUN_FILE), &text)
    }

    /// Checks an existing output folder `dir` for this run (call after
    /// [`crate::folder::check_output_folder`]): a folder holding an identical manifest resumes
    /// ([`FolderState::Resume`]), a different manifest is an error naming the difference; a
    /// folder without a manifest must be empty, and one holding `legacy` (the result of an
    /// older igi, which wrote no manifest) is refused with a `--restart` hint. A missing or
    /// empty folder is [`FolderState::Fresh`].
    ///
    /// With `restart` the answer is [`FolderState::Fresh`] only for a folder this command may
    /// clear (with [`remove_own`]): one whose manifest names the same command, or an older
    /// igi's (`legacy`, no manifest). A folder of another command, one with an unreadable
    /// manifest and one that holds neither (not igi's) are refused as without `restart`:
    /// `--restart` never touches a folder igi cannot tell is its own. `kind` names the folder
    /// in messages ("site").
    pub fn check_folder(
        &self,
        dir: &Path,
        restart: bool,
        legacy: &str,
        kind: &str,
    ) -> Result<FolderState, FilesError> {
        if !dir.exists() {
            return Ok(FolderState::Fresh);
        }
        if let Some(old) = RunManifest::read(dir)? {
            if old.command != self.command {
                return Err(FilesError::OtherCommand {
                    path: dir.to_path_buf(),
                    was: old.command,
                    now: self.command.clone(),
                });
            }
            if restart {
                return Ok(FolderState::Fresh);
            }
            self.check_resume(&old, dir)?;
            return Ok(FolderState::Resume);
        }
        let refuse = |msg: String| FilesError::NotARunFolder {
            path: dir.to_path_buf(),
            msg,
        };
        if dir.join(legacy).exists() {
            if restart {
                return Ok(FolderState::Fresh);
            }
            return Err(refuse(format!(
                "holds a {kind} without a run manifest (another command or an older igi); use --restart to start afresh"
            )));
        }
        let empty = dir
            .read_dir()
            .map_err(|e| FilesError::io(dir, e))?
            .all(|e| e.is_ok_and(|e| e.file_name() == LOCK_FILE));
        if !empty {
            let hint = if restart {
                " (--restart clears only a folder that igi wrote)"
            } else {
                ""
            };
            return Err(refuse(format!(
                "exists and is not a {kind} folder; choose another output{hint}"
            )));
        }
        Ok(FolderState::Fresh)
    }

    /// `Ok` when `old` (the manifest found in `dir`) was made by an identical run; otherwise
    /// the first difference, in the order command, owned parts, options, inputs.
    pub fn check_resume(&self, old: &RunManifest, dir: &Path) -> Result<(), FilesError> {
        let mismatch = |what: String, was: String, now: String| FilesError::RunMismatch {
            path: dir.to_path_buf(),
            what,
            was,
            now,
        };
        if old.command != self.command {
            return Err(mismatch(
                "command".into(),
                old.command.clone(),
                self.command.clone(),
            ));
        }
        if old.owns != self.owns {
            let show = |o: &Option<Vec<String>>| {
                o.as_ref().map_or("all parts".to_string(), |v| v.join(","))
            };
            return Err(mismatch(
                "shard (--parts: a folder belongs to one shard)".into(),
                show(&old.owns),
                show(&self.owns),
            ));
        }
        let keys: std::collections::BTreeSet<&String> =
            old.options.keys().chain(self.options.keys()).collect();
        for k in keys {
            let (a, b) = (old.options.get(k), self.options.get(k));
            if a != b {
                let show = |v: Option<&String>| v.cloned().unwrap_or_else(|| "(unset)".into());
                return Err(mismatch(format!("option {k}"), show(a), show(b)));
            }
        }
        for (k, &now) in &self.raisable {
            if let Some(&was) = old.raisable.get(k) {
                if now < was {
                    return Err(mismatch(
                        format!("option {k} (a resume may raise it, not lower it)"),
                        was.to_string(),
                        now.to_string(),
                    ));
                }
            }
        }
        let roles: std::collections::BTreeSet<&String> = old
            .inputs
            .iter()
            .chain(&self.inputs)
            .map(|f| &f.role)
            .collect();
        for r in roles {
            let a = old.inputs.iter().find(|f| &f.role == r);
            let b = self.inputs.iter().find(|f| &f.role == r);
            let same = match (a, b) {
                (Some(a), Some(b)) => a.same_content(b),
                _ => false,
            };
            if !same {
                let show =
                    |f: Option<&Fingerprint>| f.map_or("(none)".to_string(), |f| f.describe());
                let changed = matches!((a, b), (Some(x), Some(y)) if x.path == y.path);
                let what = if changed {
                    format!("input {r} (the file changed)")
                } else {
                    format!("input {r}")
                };
                return Err(mismatch(what, show(a), show(b)));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_folder_has_one_writer_at_a_time_and_the_busy_error_names_it() {
        let dir = tempfile::tempdir().unwrap();
        let first = FolderLock::acquire(dir.path()).unwrap();
        // flock locks belong to open files: a second open, even in this process, is refused
        let e = FolderLock::acquire(dir.path()).unwrap_err();
        let msg = e.to_string();
        assert!(matches!(e, FilesError::FolderBusy { .. }), "{msg}");
        let me = format!("process {} on host", std::process::id());
        assert!(
            msg.contains(&me) && msg.contains("another igi run"),
            "{msg}"
        );
        drop(first);
        let again = FolderLock::acquire(dir.path()).unwrap();
        // the lock file alone does not make a folder someone else's
        let m = RunManifest::new("solve");
        let state = m.check_folder(dir.path(), false, "report.json", "result");
        assert_eq!(state.unwrap(), FolderState::Fresh);
        drop(again);
    }

    #[test]
    fn restart_clears_only_a_folder_of_the_same_command_and_only_its_names() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("res");
        std::fs::create_dir_all(dir.join("parts")).unwrap();
        std::fs::write(dir.join("parts/notes.txt"), "mine").unwrap();
        let solve = RunManifest::new("solve");
        // not igi's folder: refused with and without --restart, nothing touched
        for restart in [false, true] {
            let e = solve
                .check_folder(&dir, restart, "report.json", "result")
                .unwrap_err()
                .to_string();
            assert!(e.contains("is not a result folder"), "{e}");
        }
        // another command's folder: refused with and without --restart
        RunManifest::new("prepare").write(&dir).unwrap();
        for restart in [false, true] {
            let e = solve
                .check_folder(&dir, restart, "report.json", "result")
                .unwrap_err()
                .to_string();
            assert!(e.contains("`igi prepare`, not of `igi solve`"), "{e}");
        }
        solve.write(&dir).unwrap();
        let state = solve.check_folder(&dir, true, "report.json", "result");
        assert_eq!(state.unwrap(), FolderState::Fresh);
        for f in [
            "parts/a_rho_d.exr",
            "parts/a.ply",
            "parts/b_lobe2_rho.exr",
            "report.json",
        ] {
            std::fs::write(dir.join(f), "igi").unwrap();
        }
        std::fs::write(dir.join("parts/.a_rho_d.exr.tmp99-0_h_0.exr"), "t").unwrap();
        std::fs::create_dir_all(dir.join("staged/parts")).unwrap();
        std::fs::write(dir.join("staged/parts/a_rho_d.exr"), "igi").unwrap();
        let patterns = [
            "parts/*.ply",
            "parts/*_rho_d.exr",
            "parts/*_lobe*_rho.exr",
            "staged/parts/*_rho_d.exr",
            "report.json",
            RUN_FILE,
        ];
        assert_eq!(remove_own(&dir, &patterns).unwrap(), 7);
        let mut left: Vec<String> = walk(&dir);
        left.sort();
        assert_eq!(left, ["parts", "parts/notes.txt"]);
    }

    fn walk(dir: &Path) -> Vec<String> {
        let mut v = Vec::new();
        for e in std::fs::read_dir(dir).unwrap() {
            let e = e.unwrap();
            let name = e.file_name().to_string_lossy().into_owned();
            if e.file_type().unwrap().is_dir() {
                v.extend(walk(&e.path()).into_iter().map(|n| format!("{name}/{n}")));
            }
            v.push(name);
        }
        v
    }

    #[test]
    fn glob_matches_stars_within_a_name() {
        assert!(glob("*_rho_d.exr", "wall_rho_d.exr"));
        assert!(glob("*_lobe*_rho.exr", "a_b_lobe12_rho.exr"));
        assert!(glob("level*.ply", "level0.ply"));
        assert!(glob("*_*_*", "1_-2_3"));
        assert!(!glob("*_*_*", "notes"));
        assert!(!glob("*.ply", "notes.txt"));
        assert!(!glob("report.json", "report.json.bak"));
        assert!(is_temp_of("*.ply", ".a.ply.tmp12-0_h_0.ply"));
        assert!(!is_temp_of("*.ply", ".notes.txt.tmp12-0_h_0.txt"));
    }

    #[test]
    fn fnv_matches_reference_values() {
        // reference values of the FNV-1a 64 specification
        assert_eq!(fnv1a64(b""), 0xcbf29ce484222325);
        assert_eq!(fnv1a64(b"a"), 0xaf63dc4c8601ec8c);
        assert_eq!(fnv1a64(b"foobar"), 0x85944171f73967e8);
    }

    #[test]
    fn resume_only_on_exact_match_with_the_difference_named() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("mesh.ply");
        std::fs::write(&f, "ply one").unwrap();
        let mut a = RunManifest::new("solve");
        a.option("--spp", "16,64")
            .option("--seed", 1)
            .input("mesh", &f)
            .unwrap();
        a.write(dir.path()).unwrap();
        let old = RunManifest::read(dir.path()).unwrap().unwrap();
        assert_eq!(old, a);
        a.check_resume(&old, dir.path()).unwrap();

        let mut b = a.clone();
        b.option("--spp", "16,65");
        let e = b.check_resume(&old, dir.path()).unwrap_err().to_string();
        assert!(
            e.contains("--spp")
                && e.contains("16,64")
                && e.contains("16,65")
                && e.contains("--restart"),
            "{e}"
        );

        let mut c = a.clone();
        c.owns = Some(vec!["ground".into()]);
        let e = c.check_resume(&old, dir.path()).unwrap_err().to_string();
        assert!(e.contains("shard") && e.contains("ground"), "{e}");

        std::fs::write(&f, "ply two").unwrap();
        let mut d = RunManifest::new("solve");
        d.option("--spp", "16,64")
            .option("--seed", 1)
            .input("mesh", &f)
            .unwrap();
        let e = d.check_resume(&old, dir.path()).unwrap_err().to_string();
        assert!(e.contains("input mesh (the file changed)"), "{e}");
    }

    #[test]
    fn a_raisable_option_resumes_when_raised_and_is_refused_when_lowered() {
        let dir = tempfile::tempdir().unwrap();
        let mut a = RunManifest::new("solve");
        a.raisable("--iterations", 4);
        let mut more = a.clone();
        more.raisable("--iterations", 6);
        more.check_resume(&a, dir.path()).unwrap();
        a.check_resume(&a, dir.path()).unwrap();
        let e = a.check_resume(&more, dir.path()).unwrap_err().to_string();
        assert!(
            e.contains("option --iterations (a resume may raise it, not lower it)")
                && e.contains("there: 6; now: 4"),
            "{e}"
        );
        // a manifest of an igi that did not record it resumes
        a.check_resume(&RunManifest::new("solve"), dir.path())
            .unwrap();
        let text = serde_json::to_string(&RunManifest::new("x")).unwrap();
        assert!(!text.contains("raisable"), "{text}");
    }

    #[test]
    fn a_moved_but_identical_input_still_resumes() {
        let dir = tempfile::tempdir().unwrap();
        let (f, g) = (dir.path().join("a.ply"), dir.path().join("b.ply"));
        std::fs::write(&f, "same").unwrap();
        std::fs::write(&g, "same").unwrap();
        let mut a = RunManifest::new("prepare");
        a.input("mesh", &f).unwrap();
        let mut b = RunManifest::new("prepare");
        b.input("mesh", &g).unwrap();
        b.check_resume(&a, dir.path()).unwrap();
    }

    #[test]
    fn folders_without_a_manifest_must_be_empty_and_restart_clears_only_our_names() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("out");
        let mut m = RunManifest::new("solve");
        m.option("--spp", 4);
        let check =
            |m: &RunManifest, restart| m.check_folder(&dir, restart, "report.json", "result");
        assert_eq!(
            check(&m, false).unwrap(),
            FolderState::Fresh,
            "missing folder"
        );
        std::fs::create_dir(&dir).unwrap();
        assert_eq!(
            check(&m, false).unwrap(),
            FolderState::Fresh,
            "empty folder"
        );
        std::fs::write(dir.join("notes.txt"), "mine").unwrap();
        let e = check(&m, false).unwrap_err().to_string();
        assert!(e.contains("is not a result folder"), "{e}");
        std::fs::write(dir.join("report.json"), "{}").unwrap();
        let e = check(&m, false).unwrap_err().to_string();
        assert!(
            e.contains("without a run manifest") && e.contains("--restart"),
            "{e}"
        );
        assert_eq!(check(&m, true).unwrap(), FolderState::Fresh, "restart");
        m.write(&dir).unwrap();
        assert_eq!(check(&m, false).unwrap(), FolderState::Resume);
        let mut other = m.clone();
        other.option("--spp", 8);
        let e = check(&other, false).unwrap_err().to_string();
        assert!(
            e.contains("option --spp") && e.contains("there: 4; now: 8"),
            "{e}"
        );
        remove_own(&dir, &["report.json", RUN_FILE, "absent"]).unwrap();
        assert!(dir.join("notes.txt").exists() && !dir.join("report.json").exists());
        assert!(!dir.join(RUN_FILE).exists());
    }
}

/// What this process has used so far: its peak resident memory and the bytes it read
/// (Linux `/proc/self/status` `VmHWM` and `/proc/self/io` `rchar`: every byte returned by read
/// calls, cached or not, which is what a shared file system serves). Zeros where `/proc` is not
/// available.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct ProcessUsage {
    pub peak_rss_bytes: u64,
    pub read_bytes: u64,
}

impl ProcessUsage {
    /// The usage of the calling process until now.
    pub fn now() -> ProcessUsage {
        let field = |file: &str, key: &str| -> Option<u64> {
            let text = std::fs::read_to_string(file).ok()?;
            let line = text.lines().find(|l| l.starts_with(key))?;
            line[key.len()..].split_whitespace().next()?.parse().ok()
        };
        ProcessUsage {
            peak_rss_bytes: field("/proc/self/status", "VmHWM:").unwrap_or(0) * 1024,
            read_bytes: field("/proc/self/io", "rchar:").unwrap_or(0),
        }
    }
}

#[cfg(all(test, target_os = "linux"))]
mod usage_tests {
    use super::ProcessUsage;

    #[test]
    fn usage_counts_a_read_and_a_peak() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("blob");
        std::fs::write(&f, vec![7u8; 3 << 20]).unwrap();
        let before = ProcessUsage::now();
        let bytes = std::fs::read(&f).unwrap();
        let after = ProcessUsage::now();
        assert_eq!(bytes.len(), 3 << 20);
        assert!(
            after.read_bytes - before.read_bytes >= 3 << 20,
            "{before:?} -> {after:?}"
        );
        assert!(after.peak_rss_bytes >= 3 << 20, "{after:?}");
    }
}
