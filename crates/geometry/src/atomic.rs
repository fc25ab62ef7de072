//! Atomic file writing through `igi_files::write_atomic` with a buffered writer.

use crate::error::GeometryError;
use igi_files::FilesError;
use std::io::{BufWriter, Write};
use std::path::Path;

/// Create `path` atomically (temp file in the same folder, then rename); `write` fills a
/// buffered writer. The temp file is removed on error.
pub(crate) fn write_atomic_with(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> Result<(), GeometryError> {
    igi_files::write_atomic(path, |tmp| {
        let io = |source| FilesError::io(path, source);
        let f = std::fs::File::create(tmp).map_err(io)?;
        let mut w = BufWriter::with_capacity(1 << 20, f);
        write(&mut w).map_err(io)?;
        w.flush().map_err(io)?;
        let f = w.into_inner().map_err(|e| io(e.into_error()))?;
        f.sync_all().map_err(io)?;
        Ok::<(), FilesError>(())
    })?;
    Ok(())
}
