//! Atomic file writing: write a temporary file in the target's folder, then rename it.
//!
//! A private stand-in until `igi_imaging::io::write_atomic` exists; same contract.

use crate::error::GeometryError;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

fn tmp_path(path: &Path) -> PathBuf {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let unique = format!(".{name}.tmp{}", std::process::id());
    path.with_file_name(unique)
}

/// Create `path` atomically; `write` fills a buffered writer. The temp file is removed on error.
pub(crate) fn write_atomic_with(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> Result<(), GeometryError> {
    let tmp = tmp_path(path);
    let result = (|| {
        let f = std::fs::File::create(&tmp)?;
        let mut w = BufWriter::with_capacity(1 << 20, f);
        write(&mut w)?;
        w.flush()?;
        let f = w.into_inner().map_err(|e| e.into_error())?;
        f.sync_all()?;
        drop(f);
        std::fs::rename(&tmp, path)
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(GeometryError::io(path, e));
    }
    Ok(())
}
