//! Atomic file writing (a temporary file in the same folder, renamed into place) and the
//! cleanup of the temporary files of killed writers.

use crate::host::{safe_name_part, this_host};
use crate::FilesError;
use std::path::{Path, PathBuf};

/// Write a file atomically: `write` receives a temporary path in the same folder as `path`;
/// on success the temporary file is renamed to `path`, on error it is removed.
pub fn write_atomic<E: From<FilesError>>(
    path: &Path,
    write: impl FnOnce(&Path) -> Result<(), E>,
) -> Result<(), E> {
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let name = path
        .file_name()
        .ok_or_else(|| FilesError::NotAFilePath(path.to_path_buf()))?
        .to_string_lossy()
        .into_owned();
    check_folder_path(&dir)?;
    // Keep the extension last so extension-sniffing writers still work.
    static COUNTER: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let n = COUNTER.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let tmp = dir.join(format!(
        ".{}.tmp{}-{}_{}_{}.{}",
        name,
        std::process::id(),
        n,
        this_host(),
        std::env::var("SLURM_JOB_ID").map_or("0".into(), |j| safe_name_part(&j)),
        ext_of(path)
    ));
    // create it first, so an unwritable folder is reported as such (not as an encoder error)
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&tmp)
        .map_err(|e| FilesError::NotWritable {
            path: dir.clone(),
            source: e,
        })?;
    let result = write(&tmp).and_then(|()| Ok(sync_if_shared(&tmp)?));
    match result {
        Ok(()) => std::fs::rename(&tmp, path).map_err(|e| {
            let _ = std::fs::remove_file(&tmp);
            FilesError::io(path, e).into()
        }),
        Err(e) => {
            let _ = std::fs::remove_file(&tmp);
            Err(e)
        }
    }
}

/// Flushes a finished temporary file to stable storage before it is renamed into place, when
/// running under Slurm (`SLURM_JOB_ID`) or with `IGI_FSYNC=1`: on a shared file system another
/// host may read the renamed file at once, and a crash of this node must not leave a renamed
/// but empty file. Elsewhere the rename alone is atomic against a killed process, and skipping
/// the flush keeps a prepare of thousands of files fast.
fn sync_if_shared(tmp: &Path) -> Result<(), FilesError> {
    let wanted = std::env::var_os("SLURM_JOB_ID").is_some()
        || std::env::var("IGI_FSYNC").is_ok_and(|v| v == "1");
    if !wanted {
        return Ok(());
    }
    std::fs::File::open(tmp)
        .and_then(|f| f.sync_all())
        .map_err(|e| FilesError::io(tmp, e))
}

/// Removes the temporary files that [`write_atomic`] left in `dir` (and, with `recursive`, in
/// its sub-folders) when its process was killed: names `.NAME.tmpPID-N_HOST_JOB.EXT` of this
/// host whose process is no longer running (judged by `/proc/PID`; where there is no `/proc`,
/// every such file counts as dead, except those of this process). Files of other hosts (a
/// shared file system) are left alone. Returns how many were removed.
pub fn remove_dead_temps(dir: &Path, recursive: bool) -> Result<usize, FilesError> {
    let mut removed = 0;
    let entries = match std::fs::read_dir(dir) {
        Ok(e) => e,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(0),
        Err(e) => return Err(FilesError::io(dir, e)),
    };
    for entry in entries {
        let entry = entry.map_err(|e| FilesError::io(dir, e))?;
        let path = entry.path();
        let kind = entry.file_type().map_err(|e| FilesError::io(&path, e))?;
        if kind.is_dir() {
            if recursive {
                removed += remove_dead_temps(&path, true)?;
            }
            continue;
        }
        let name = entry.file_name().to_string_lossy().into_owned();
        if let Some((pid, host)) = temp_owner(&name) {
            // another host's writer cannot be judged from here: its file is left alone
            let elsewhere = host.is_some_and(|h| h != this_host());
            let alive = elsewhere
                || pid == std::process::id()
                || Path::new("/proc").join(pid.to_string()).exists();
            if !alive {
                std::fs::remove_file(&path).map_err(|e| FilesError::io(&path, e))?;
                removed += 1;
            }
        }
    }
    Ok(removed)
}

/// The process id and host in a [`write_atomic`] temp name `.NAME.tmpPID-N_HOST_JOB.EXT` (or
/// the older `.NAME.tmpPID-N.EXT`, host `None`), if `name` is one.
fn temp_owner(name: &str) -> Option<(u32, Option<String>)> {
    if !name.starts_with('.') {
        return None;
    }
    let at = name.rfind(".tmp")?;
    let rest = &name[at + 4..];
    let (pid, rest) = rest.split_once('-')?;
    let tail = rest.split('.').next()?;
    let mut parts = tail.split('_');
    let n = parts.next()?;
    let host = parts.next().map(str::to_string);
    if pid.is_empty() || n.is_empty() || !n.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    Some((pid.parse().ok()?, host))
}

/// Write text to `path` atomically (see [`write_atomic`]).
pub fn write_text_atomic(path: &Path, text: &str) -> Result<(), FilesError> {
    write_atomic(path, |tmp| {
        std::fs::write(tmp, text).map_err(|e| FilesError::io(path, e))
    })
}

/// The lower-case extension of `path` (empty without one).
fn ext_of(path: &Path) -> String {
    path.extension()
        .map(|e| e.to_string_lossy().to_lowercase())
        .unwrap_or_default()
}

/// The folder a file is written into must exist and be a folder.
pub(crate) fn check_folder_path(dir: &Path) -> Result<(), FilesError> {
    if dir.is_dir() {
        return Ok(());
    }
    let mut at = dir;
    while let Some(p) = at.parent() {
        if p.as_os_str().is_empty() {
            break;
        }
        if p.exists() && !p.is_dir() {
            return Err(FilesError::NotAFolder {
                path: p.to_path_buf(),
                wanted: dir.to_path_buf(),
            });
        }
        at = p;
    }
    if dir.exists() {
        return Err(FilesError::NotAFolder {
            path: dir.to_path_buf(),
            wanted: dir.to_path_buf(),
        });
    }
    Err(FilesError::NoFolder {
        path: dir.to_path_buf(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dead_temps_are_removed_and_live_ones_kept() {
        let dir = tempfile::tempdir().unwrap();
        let sub = dir.path().join("voxels/0_0_0");
        std::fs::create_dir_all(&sub).unwrap();
        // pid 4194305 exceeds Linux's pid_max (2^22), so it is never running
        let host = this_host();
        let dead_old = sub.join(".level0.ply.tmp4194305-3.ply");
        let dead = sub.join(format!(".level1.ply.tmp4194305-4_{host}_77.ply"));
        let mine = sub.join(format!(".a.exr.tmp{}-0_{host}_0.exr", std::process::id()));
        // a dead pid, but on another host of a shared file system: not ours to judge
        let remote = sub.join(".b.exr.tmp4194305-1_elsewhere-node7_123.exr");
        let other = sub.join(".notes.tmp-draft");
        for p in [&dead_old, &dead, &mine, &remote, &other] {
            std::fs::write(p, "x").unwrap();
        }
        assert_eq!(remove_dead_temps(dir.path(), false).unwrap(), 0);
        assert_eq!(remove_dead_temps(dir.path(), true).unwrap(), 2);
        assert!(!dead_old.exists() && !dead.exists());
        assert!(mine.exists() && remote.exists() && other.exists());
        assert_eq!(temp_owner(".x.tmp12-7."), Some((12, None)));
        assert_eq!(
            temp_owner(".x.exr.tmp12-7_node-3_991.exr"),
            Some((12, Some("node-3".into())))
        );
        assert_eq!(temp_owner("x.tmp12-7.exr"), None);
    }

    #[test]
    fn temporary_names_carry_host_and_job_and_the_file_is_whole_after_a_flush() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.txt");
        let mut seen = None;
        write_atomic(&p, |tmp| {
            seen = Some(tmp.file_name().unwrap().to_string_lossy().into_owned());
            std::fs::write(tmp, "whole").map_err(|e| FilesError::io(tmp, e))
        })
        .unwrap();
        let name = seen.unwrap();
        let (pid, host) = temp_owner(&name).expect("a temp name");
        assert_eq!(pid, std::process::id());
        assert_eq!(host.as_deref(), Some(this_host().as_str()), "{name}");
        assert!(name.ends_with(".txt"), "{name}");
        sync_if_shared(&p).unwrap();
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "whole");
        assert_eq!(safe_name_part("a.b_c/d-1"), "axbxcxd-1");
    }

    #[test]
    fn write_atomic_cleans_up_on_error() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.txt");
        let r = write_atomic(&p, |tmp| {
            std::fs::write(tmp, "partial").unwrap();
            Err(FilesError::NotAFilePath("boom".into()))
        });
        assert!(r.is_err());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
        write_atomic(&p, |tmp| {
            std::fs::write(tmp, "ok").map_err(|e| FilesError::io(tmp, e))
        })
        .unwrap();
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "ok");
    }
}
