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
