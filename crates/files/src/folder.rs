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
    check_folder_path(&dir)?;
    if path.is_dir() {
        return Err(FilesError::IsAFolder(path.to_path_buf()));
    }
    check_output_folder(&dir)
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
}
