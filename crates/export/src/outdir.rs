//! The output folder of `igi export` (docs/EXPORT.md, "Output folder"): checked before the first
//! byte, written whole through a staging folder, and marked by `export.json`.
//!
//! * `-o` must not be the result folder or lie inside it (an export there would overwrite the
//!   result's own `scene.toml`).
//! * `-o` must be new, empty, or hold an earlier igi export and nothing else: its `export.json`
//!   lists every file it wrote. Such a folder is replaced whole (only the names the earlier
//!   export wrote are removed), so two results' files never mix. Any other file refuses it.
//! * The export is written into a staging folder beside `-o`
//!   (`.NAME.igi-export-HOST-PID.partial`) and moved into place once complete, `export.json`
//!   last. A staging folder of this host whose process is gone (a killed export) is removed by
//!   the next export to the same `-o`.

use crate::ExportError;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The manifest an export writes into its folder.
pub const MANIFEST: &str = "export.json";

/// `export.json`.
#[derive(Debug, Serialize, Deserialize)]
pub struct ExportManifest {
    /// Always "igi export".
    pub written_by: String,
    pub format: String,
    /// The result folder exported (as given).
    pub result: String,
    /// The names of the files written into the folder (without `export.json`).
    pub files: Vec<String>,
}

/// The output folder, checked: where to stage, and what an earlier export left.
pub(crate) struct OutPlan {
    pub out: PathBuf,
    pub staging: PathBuf,
    /// The files of the earlier export in `out` (removed at commit).
    pub earlier: Vec<String>,
}

/// `path` made absolute with its existing ancestors resolved (symbolic links and `..`).
fn resolved(path: &Path) -> Result<PathBuf, ExportError> {
    let abs = if path.is_absolute() {
        path.to_path_buf()
    } else {
        std::env::current_dir()
            .map_err(|e| ExportError::file(path, format!("cannot resolve: {e}")))?
            .join(path)
    };
    let mut tail = Vec::new();
    let mut at = abs.as_path();
    loop {
        if let Ok(c) = at.canonicalize() {
            let mut r = c;
            for t in tail.iter().rev() {
                r.push(t);
            }
            return Ok(r);
        }
        match (at.parent(), at.file_name()) {
            (Some(p), Some(n)) => {
                tail.push(n.to_os_string());
                at = p;
            }
            _ => return Ok(abs),
        }
    }
}

/// Checks `out` for an export of `result_dir` (module overview); creates nothing.
pub(crate) fn check(result_dir: &Path, out: &Path) -> Result<OutPlan, ExportError> {
    let result_abs = resolved(result_dir)?;
    let out_abs = resolved(out)?;
    if out_abs.starts_with(&result_abs) {
        let place = if out_abs == result_abs {
            "is the result folder"
        } else {
            "lies inside the result folder"
        };
        return Err(ExportError::file(
            out,
            format!(
                "{place} {}: export into a folder outside the result (it would overwrite the result's own files)",
                result_dir.display()
            ),
        ));
    }
    igi_files::check_output_folder(out)?;
    let mut earlier = Vec::new();
    if out.exists() {
        let mut names: Vec<String> = std::fs::read_dir(out)
            .map_err(|e| ExportError::file(out, format!("cannot read the folder: {e}")))?
            .filter_map(|e| e.ok())
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        if !names.is_empty() {
            let mp = out.join(MANIFEST);
            let manifest = std::fs::read_to_string(&mp)
                .ok()
                .and_then(|t| serde_json::from_str::<ExportManifest>(&t).ok())
                .filter(|m| m.written_by == "igi export");
            let Some(m) = manifest else {
                return Err(ExportError::file(
                    out,
                    format!(
                        "is not empty and holds no earlier igi export ({MANIFEST}): export into a new or empty folder (it holds {})",
                        shown(&names)
                    ),
                ));
            };
            let foreign: Vec<String> = names
                .iter()
                .filter(|n| n.as_str() != MANIFEST && !m.files.contains(n))
                .cloned()
                .collect();
            if !foreign.is_empty() {
                return Err(ExportError::file(
                    out,
                    format!(
                        "holds an earlier igi export and other files ({}): igi replaces only a folder holding nothing but its own export; choose a new or empty folder",
                        shown(&foreign)
                    ),
                ));
            }
            if let Some(d) = names.iter().find(|n| !out.join(n).is_file()) {
                return Err(ExportError::file(
                    out.join(d),
                    "is not a file, but the earlier export's export.json names it",
                ));
            }
            earlier = m.files.into_iter().filter(|n| names.contains(n)).collect();
        }
    }
    let name = out_abs
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "export".into());
    let parent = out_abs.parent().unwrap_or(Path::new("/")).to_path_buf();
    Ok(OutPlan {
        out: out.to_path_buf(),
        staging: parent.join(format!(
            ".{name}.igi-export-{}-{}.partial",
            igi_files::host::this_host(),
            std::process::id()
        )),
        earlier,
    })
}

/// At most three names, and how many more.
fn shown(names: &[String]) -> String {
    let mut s = names.iter().take(3).cloned().collect::<Vec<_>>().join(", ");
    if names.len() > 3 {
        s.push_str(&format!(" and {} more", names.len() - 3));
    }
    s
}

impl OutPlan {
    /// Creates the staging folder, after removing those that killed exports of this host to
    /// the same folder left (their process is gone, judged by `/proc/PID`).
    pub fn begin(&self) -> Result<(), ExportError> {
        let _ = std::fs::remove_dir_all(&self.staging);
        let own = self
            .staging
            .file_name()
            .map(|n| n.to_string_lossy().into_owned());
        let own = own.unwrap_or_default();
        // `.NAME.igi-export-HOST-` and the process id after it
        let prefix = own[..own.len() - ".partial".len()]
            .trim_end_matches(|c: char| c.is_ascii_digit())
            .to_string();
        if let (Some(dir), true) = (self.staging.parent(), Path::new("/proc/self").exists()) {
            for e in std::fs::read_dir(dir).into_iter().flatten().flatten() {
                let n = e.file_name().to_string_lossy().into_owned();
                let pid = n
                    .strip_prefix(&prefix)
                    .and_then(|r| r.strip_suffix(".partial"))
                    .and_then(|p| p.parse::<u32>().ok());
                if pid.is_some_and(|p| !Path::new("/proc").join(p.to_string()).exists()) {
                    let _ = std::fs::remove_dir_all(e.path());
                }
            }
        }
        std::fs::create_dir_all(&self.staging).map_err(|e| {
            ExportError::file(
                &self.staging,
                format!("cannot create the staging folder: {e}"),
            )
        })
    }

    /// Drops the staging folder after a failure.
    pub fn abandon(&self) {
        let _ = std::fs::remove_dir_all(&self.staging);
    }

    /// Moves the staged export into `out`: the earlier export's files are removed, the new ones
    /// renamed into place, `export.json` last. Returns the paths written, `export.json` last.
    pub fn commit(&self, format: &str, result: &Path) -> Result<Vec<PathBuf>, ExportError> {
        let mut names: Vec<String> = std::fs::read_dir(&self.staging)
            .map_err(|e| ExportError::file(&self.staging, format!("cannot read: {e}")))?
            .filter_map(|e| e.ok())
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        let manifest = ExportManifest {
            written_by: "igi export".into(),
            format: format.into(),
            result: result.display().to_string(),
            files: names.clone(),
        };
        let text = serde_json::to_string_pretty(&manifest).unwrap_or_default() + "\n";
        std::fs::create_dir_all(&self.out)
            .map_err(|e| ExportError::file(&self.out, format!("cannot create folder: {e}")))?;
        let mp = self.out.join(MANIFEST);
        // the folder stops being a complete export while the files move
        if mp.exists() {
            std::fs::remove_file(&mp)
                .map_err(|e| ExportError::file(&mp, format!("cannot remove: {e}")))?;
        }
        for n in &self.earlier {
            let p = self.out.join(n);
            std::fs::remove_file(&p).map_err(|e| {
                ExportError::file(&p, format!("cannot remove the earlier export's file: {e}"))
            })?;
        }
        for n in &names {
            let (from, to) = (self.staging.join(n), self.out.join(n));
            std::fs::rename(&from, &to)
                .map_err(|e| ExportError::file(&to, format!("cannot move into place: {e}")))?;
        }
        igi_files::write_text_atomic(&mp, &text)?;
        self.abandon();
        let mut files: Vec<PathBuf> = names.iter().map(|n| self.out.join(n)).collect();
        files.push(mp);
        Ok(files)
    }
}
