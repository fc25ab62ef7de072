//! Output files and folders checked before the first byte of work.

use crate::FilesError;
use std::path::{Path, PathBuf};

/// Checks that `dir` is, or can become, a writable folder, without creating anything: an
/// existing `dir` must be a folder we can create files in; otherwise its nearest existing
/// ancestor must be a writable folder (not a file). Call it before the first byte of work.
pub fn check_output_folder(dir: &Path) -> Result<(), FilesError> {
    let dir = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    let mut at = dir;
    loop {
        if at.exists() {
            break;
        }
        match at.parent() {
            Some(p) if !p.as_os_str().is_empty() => at = p,
            _ => {
                at = Path::new(".");
                break;
            }
        }
    }
    if !at.is_dir() {
        return Err(FilesError::NotAFolder {
            path: at.to_path_buf(),
            wanted: dir.to_path_buf(),
        });
    }
    let probe = at.join(format!(".igi-probe.tmp{}-0.", std::process::id()));
    match std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)
    {
        Ok(_) => {
            let _ = std::fs::remove_file(&probe);
            Ok(())
        }
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => Ok(()),
        Err(e) => Err(FilesError::NotWritable {
            path: at.to_path_buf(),
            source: e,
        }),
    }
}

/// Refuses an output file name whose extension (any case) is none of `exts` (without the dot):
/// "PATH: output must be .exr or .hdr".
pub fn check_output_extension(path: &Path, exts: &[&str]) -> Result<(), FilesError> {
    let found = path.extension().map(|e| e.to_string_lossy().to_lowercase());
    if found.is_some_and(|f| exts.contains(&f.as_str())) {
        return Ok(());
    }
    let expected: Vec<String> = exts.iter().map(|e| format!(".{e}")).collect();
    Err(FilesError::Extension {
        path: path.to_path_buf(),
        expected: expected.join(" or "),
    })
}

/// Checks, before any work, that a file can be written at `path`: its folder exists, is a
/// folder and is writable, and `path` is not itself a folder.
pub fn check_output_file(path: &Path) -> Result<(), FilesError> {
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    crate::atomic::check_folder_path(&dir)?;
    if path.is_dir() {
        return Err(FilesError::IsAFolder(path.to_path_buf()));
    }
    check_output_folder(&dir)
}

/// Refuses, before any work, two outputs that name one file, or an output that names one of the
/// inputs (which it would overwrite, or be read from half-written): each entry is what the
/// file is to the command (`--stderr`, `the scene`) and its path. Paths are compared as the
/// file system resolves them (`a/../b.exr` is `b.exr`; a symbolic link is its target).
pub fn check_distinct(
    outputs: &[(&str, &Path)],
    inputs: &[(&str, &Path)],
) -> Result<(), FilesError> {
    let keys: Vec<(&str, &Path, PathBuf)> = outputs
        .iter()
        .map(|&(what, p)| (what, p, file_identity(p)))
        .collect();
    for (i, (what, path, key)) in keys.iter().enumerate() {
        if let Some((other, _, _)) = keys[..i].iter().find(|(_, _, k)| k == key) {
            return Err(FilesError::SameFile {
                path: path.to_path_buf(),
                first: other.to_string(),
                second: what.to_string(),
            });
        }
        if let Some((input, _)) = inputs.iter().find(|(_, p)| file_identity(p) == *key) {
            return Err(FilesError::SameFile {
                path: path.to_path_buf(),
                first: format!("the input {input}"),
                second: format!("the output {what}"),
            });
        }
    }
    Ok(())
}

/// A file's path as the file system resolves it: the file itself when it exists, else its
/// folder's resolved path and its name, else the path as given.
fn file_identity(path: &Path) -> PathBuf {
    if let Ok(p) = std::fs::canonicalize(path) {
        return p;
    }
    let parent = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    match (std::fs::canonicalize(parent), path.file_name()) {
        (Ok(dir), Some(name)) => dir.join(name),
        _ => path.to_path_buf(),
    }
}

/// A whole output folder written under a staging name beside it and renamed into place (igi
/// hull build, igi slf build), so that it is never half-written, with the rules of every igi
/// output folder: one writer at a time (a [`crate::FolderLock`] on `.NAME.igi-lock` beside the
/// folder, held until the value is dropped), a staging name of this process and host
/// (`.NAME.partial-PID_HOST`, so two runs never share one), and the staging folders of killed
/// runs of this host removed when the next run begins. Dropped without [`Staging::commit`],
/// the staging folder is removed.
#[derive(Debug)]
pub struct Staging {
    out: PathBuf,
    tmp: PathBuf,
    done: bool,
    _lock: crate::FolderLock,
}

impl Staging {
    /// Claims `out` (refused while another igi run writes it), removes dead runs' staging
    /// folders beside it and creates this run's. Call it before the work: an output that
    /// cannot be written is found here.
    pub fn begin(out: &Path) -> Result<Staging, FilesError> {
        let (parent, name) = parent_and_name(out)?;
        crate::atomic::check_folder_path(&parent)?;
        check_output_folder(&parent)?;
        if out.exists() && !out.is_dir() {
            return Err(FilesError::NotAFolder {
                path: out.to_path_buf(),
                wanted: out.to_path_buf(),
            });
        }
        let lock =
            crate::FolderLock::acquire_beside(&parent.join(format!(".{name}.igi-lock")), out)?;
        remove_dead_staging(&parent, &name)?;
        let tmp = parent.join(format!(
            ".{name}.partial-{}_{}",
            std::process::id(),
            crate::host::this_host()
        ));
        if tmp.exists() {
            std::fs::remove_dir_all(&tmp).map_err(|e| FilesError::io(&tmp, e))?;
        }
        std::fs::create_dir_all(&tmp).map_err(|e| FilesError::io(&tmp, e))?;
        Ok(Staging {
            out: out.to_path_buf(),
            tmp,
            done: false,
            _lock: lock,
        })
    }

    /// The staging folder to fill.
    pub fn path(&self) -> &Path {
        &self.tmp
    }

    /// Renames the staging folder to the output. An existing output is removed first: an
    /// empty folder always, a full one only with `replace` (the caller has checked that it is
    /// an earlier output of the same kind); otherwise it is an error.
    pub fn commit(mut self, replace: bool) -> Result<(), FilesError> {
        let out = &self.out;
        if out.exists() {
            let empty = std::fs::read_dir(out)
                .map_err(|e| FilesError::io(out, e))?
                .next()
                .is_none();
            if empty {
                std::fs::remove_dir(out).map_err(|e| FilesError::io(out, e))?;
            } else if replace {
                std::fs::remove_dir_all(out).map_err(|e| FilesError::io(out, e))?;
            } else {
                return Err(FilesError::NotARunFolder {
                    path: out.clone(),
                    msg: "was filled by someone else during the build; choose another output"
                        .into(),
                });
            }
        }
        std::fs::rename(&self.tmp, out).map_err(|e| FilesError::io(out, e))?;
        self.done = true;
        Ok(())
    }
}

impl Drop for Staging {
    fn drop(&mut self) {
        if !self.done {
            let _ = std::fs::remove_dir_all(&self.tmp);
        }
    }
}

/// The folder `out` is in and its name.
fn parent_and_name(out: &Path) -> Result<(PathBuf, String), FilesError> {
    let name = out
        .file_name()
        .ok_or_else(|| FilesError::NotAFilePath(out.to_path_buf()))?
        .to_string_lossy()
        .into_owned();
    let parent = match out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    Ok((parent, name))
}

/// Removes the staging folders `.NAME.partial-PID_HOST` (and the older `.NAME.partial-PID`) in
/// `parent` whose process, on this host, no longer runs. Returns how many were removed.
pub fn remove_dead_staging(parent: &Path, name: &str) -> Result<usize, FilesError> {
    let prefix = format!(".{name}.partial-");
    let entries = match std::fs::read_dir(parent) {
        Ok(e) => e,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(0),
        Err(e) => return Err(FilesError::io(parent, e)),
    };
    let mut removed = 0;
    for entry in entries {
        let entry = entry.map_err(|e| FilesError::io(parent, e))?;
        let file = entry.file_name().to_string_lossy().into_owned();
        let Some(owner) = file.strip_prefix(&prefix) else {
            continue;
        };
        let (pid, host) = match owner.split_once('_') {
            Some((p, h)) => (p, Some(h)),
            None => (owner, None),
        };
        let Ok(pid) = pid.parse::<u32>() else {
            continue;
        };
        let elsewhere = host.is_some_and(|h| h != crate::host::this_host());
        let alive = elsewhere
            || pid == std::process::id()
            || Path::new("/proc").join(pid.to_string()).exists();
        if !alive {
            let p = entry.path();
            std::fs::remove_dir_all(&p).map_err(|e| FilesError::io(&p, e))?;
            removed += 1;
        }
    }
    Ok(removed)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outputs_may_not_name_each_other_or_an_input() {
        let tmp = tempfile::tempdir().unwrap();
        let d = tmp.path();
        let scene = d.join("scene.toml");
        std::fs::write(&scene, "x").unwrap();
        let out = d.join("out.exr");
        let other = d.join("sub/../out.exr");
        std::fs::create_dir(d.join("sub")).unwrap();
        let e = check_distinct(&[("--output", &out), ("--stderr", &other)], &[])
            .unwrap_err()
            .to_string();
        assert!(e.contains("both --output and --stderr"), "{e}");
        let e = check_distinct(
            &[("--output", &d.join("sub/../scene.toml"))],
            &[("the scene", &scene)],
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("both the input the scene and the output --output"),
            "{e}"
        );
        check_distinct(
            &[("--output", &out), ("--stderr", &d.join("se.exr"))],
            &[("the scene", &scene)],
        )
        .unwrap();
    }

    #[test]
    fn staging_is_per_process_locked_and_dead_runs_are_cleaned() {
        let tmp = tempfile::tempdir().unwrap();
        let out = tmp.path().join("hull");
        // a killed run's staging folder (pid 4194305 is above Linux's pid_max) and another
        // host's, which is not ours to judge
        let dead = tmp.path().join(".hull.partial-4194305");
        let dead_new = tmp.path().join(format!(
            ".hull.partial-4194305_{}",
            crate::host::this_host()
        ));
        let remote = tmp.path().join(".hull.partial-4194305_elsewhere-node7");
        for d in [&dead, &dead_new, &remote] {
            std::fs::create_dir_all(d.join("sub")).unwrap();
        }
        let st = Staging::begin(&out).unwrap();
        assert!(!dead.exists() && !dead_new.exists() && remote.exists());
        assert!(st.path().is_dir());
        let e = Staging::begin(&out).unwrap_err().to_string();
        assert!(e.contains("another igi run"), "{e}");
        std::fs::write(st.path().join("a.txt"), "a").unwrap();
        st.commit(false).unwrap();
        assert_eq!(std::fs::read_to_string(out.join("a.txt")).unwrap(), "a");
        // a full output is replaced only when asked; a dropped staging folder goes
        let st = Staging::begin(&out).unwrap();
        let staged = st.path().to_path_buf();
        assert!(st.commit(false).is_err());
        assert!(!staged.exists());
        let st = Staging::begin(&out).unwrap();
        std::fs::write(st.path().join("b.txt"), "b").unwrap();
        st.commit(true).unwrap();
        assert!(out.join("b.txt").exists() && !out.join("a.txt").exists());
        // nothing is left beside the output: no staging folder, no lock file
        let mut left: Vec<String> = std::fs::read_dir(tmp.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        left.sort();
        assert_eq!(left, [".hull.partial-4194305_elsewhere-node7", "hull"]);
        // an output that is a file is found before any work
        let file = tmp.path().join("f");
        std::fs::write(&file, "x").unwrap();
        assert!(Staging::begin(&file).is_err());
    }
}
