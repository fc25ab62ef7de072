//! # igi-files
//!
//! The files and folders a run writes, at the bottom of the igi dependency graph (no other igi
//! crate):
//!
//! * [`atomic`]: atomic writes ([`write_atomic`], [`write_text_atomic`]: a temporary file in
//!   the same folder, renamed into place, flushed first on shared file systems) and the
//!   cleanup of killed writers' temporary files ([`remove_dead_temps`]).
//! * [`disk`]: the disk space and file entries a run will write, checked before its work
//!   ([`check_disk`]).
//! * [`folder`]: output files and folders checked before the first byte of work
//!   ([`check_output_folder`], [`check_output_file`], [`check_output_extension`], and
//!   [`check_distinct`]: no two outputs, and no output and input, naming one file), and
//!   [`Staging`]: a whole folder written beside its output and renamed into place, under the
//!   lock, with per-process staging names and dead ones removed.
//! * [`host`]: this machine's name as temporary and staging names carry it ([`host::this_host`]),
//!   so writers on several hosts of a shared file system never collide.
//! * [`memory`]: every size-driven allocation estimated and refused above a limit before it
//!   happens ([`check_alloc`], [`max_alloc`]: 8 GiB or `IGI_MAX_MEMORY`).
//! * [`paths`]: how one output names another command's file ([`named_from`]: relative to its
//!   folder when they share more than the root, through [`resolve_folder_of`] and
//!   [`relative_to`]), so folders that belong together move together.
//! * [`run`]: run manifests (`run.json`: input fingerprints and result-changing options, so a
//!   resumed command never mixes two runs' work), the one-writer folder lock ([`FolderLock`])
//!   and what `--restart` removes ([`remove_own`]: only the names the command writes, only
//!   in a folder whose manifest names the same command).

pub mod atomic;
pub mod disk;
pub mod folder;
pub mod host;
pub mod memory;
pub mod paths;
pub mod run;

pub use atomic::{remove_dead_temps, write_atomic, write_text_atomic};
pub use disk::{check_disk, DiskNeed};
pub use folder::{
    check_distinct, check_output_extension, check_output_file, check_output_folder, Staging,
};
pub use memory::{check_alloc, check_alloc_default, check_input_file, max_alloc};
pub use paths::{named_from, relative_to, resolve_folder_of};
pub use run::{remove_own, Fingerprint, FolderLock, FolderState, RunManifest, RUN_FILE};

use std::path::PathBuf;

/// Errors of output files and folders, run manifests and the folder lock; each names its path.
#[derive(Debug, thiserror::Error)]
pub enum FilesError {
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A path that names no file (it ends in `..` or is empty).
    #[error("invalid input: {}: not a file path", .0.display())]
    NotAFilePath(PathBuf),
    /// An output file name without the extension of the format written (`expected`: ".exr",
    /// ".exr or .hdr").
    #[error("{}: output must be {expected}", path.display())]
    Extension { path: PathBuf, expected: String },
    /// An output file name that is a folder.
    #[error("invalid input: {}: is a folder, not a file name", .0.display())]
    IsAFolder(PathBuf),
    #[error("{}: is a file, not a folder (cannot write into {})", path.display(), wanted.display())]
    NotAFolder { path: PathBuf, wanted: PathBuf },
    /// Two outputs, or an output and an input, that name one file.
    #[error("invalid input: {}: is both {first} and {second}; give each its own file", path.display())]
    SameFile {
        path: PathBuf,
        first: String,
        second: String,
    },
    /// A size-driven allocation estimated above the limit (`memory`).
    #[error("invalid input: {what} would need about {} ({bytes} bytes) of memory, more than the limit of {} (set IGI_MAX_MEMORY to allow more)", crate::memory::show_bytes(*bytes as u128), crate::memory::show_bytes(*limit as u128))]
    TooLarge {
        what: String,
        bytes: u64,
        limit: u64,
    },
    /// An input to be read whole that is no regular file (a device, a pipe, a folder).
    #[error("invalid input: {}: {what} must be a regular file (not a device, pipe or folder)", path.display())]
    NotAFile { path: PathBuf, what: String },
    /// `IGI_MAX_MEMORY` that is no byte count.
    /// A run's output estimated beyond the free space of its file system (`disk`).
    #[error("{}: {what} would need at least {entries} files and folders and {bytes} bytes ({}), but its file system has {} free and {} free file entries; free some space or choose another output folder", path.display(), crate::memory::show_bytes(*bytes as u128), crate::memory::show_bytes(*free_bytes as u128), if *free_entries == u64::MAX { "unlimited".to_string() } else { free_entries.to_string() })]
    NoSpace {
        path: PathBuf,
        what: String,
        entries: u64,
        bytes: u64,
        free_entries: u64,
        free_bytes: u64,
    },
    #[error("invalid input: IGI_MAX_MEMORY={0:?} is not a byte count (e.g. 16G)")]
    BadMemoryLimit(String),
    #[error("{}: output folder does not exist", path.display())]
    NoFolder { path: PathBuf },
    #[error("{}: cannot write into this folder", path.display())]
    NotWritable {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{}: holds a run with a different {what} (there: {was}; now: {now}); use --restart to start afresh, or another output folder", path.display())]
    RunMismatch {
        path: PathBuf,
        what: String,
        was: String,
        now: String,
    },
    /// A folder whose run manifest names another command: neither resumed nor, with
    /// `--restart`, cleared.
    #[error("{}: holds the output of `igi {was}`, not of `igi {now}`; choose another output folder", path.display())]
    OtherCommand {
        path: PathBuf,
        was: String,
        now: String,
    },
    #[error("{}: {msg}", path.display())]
    NotARunFolder { path: PathBuf, msg: String },
    #[error("{}: another igi run ({holder}) is writing this folder; wait for it to finish, or choose another output", path.display())]
    FolderBusy { path: PathBuf, holder: String },
    #[error("{}: unreadable run manifest: {source}; igi cannot tell whose folder this is: choose another output folder (or remove this one yourself)", path.display())]
    BadManifest {
        path: PathBuf,
        #[source]
        source: serde_json::Error,
    },
}

impl FilesError {
    /// [`FilesError::Io`] for `path`.
    pub fn io(path: &std::path::Path, source: std::io::Error) -> Self {
        FilesError::Io {
            path: path.to_path_buf(),
            source,
        }
    }
}
