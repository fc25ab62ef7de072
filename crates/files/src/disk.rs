//! Disk space checked before the first byte of a run's work: [`check_disk`] refuses a run
//! whose output would need more blocks or more files than the file system holding it has free,
//! with a message naming the folder, what would be written and what is free, instead of the
//! run failing with "No space left on device" hours into its work.
//!
//! The need is counted as files and folders of at least one block each (the file system's
//! fragment size, 4 KiB on ext4 and XFS) plus the bytes beyond that which the caller knows for
//! certain: a lower bound on every file system that does not store small files inside their
//! metadata (btrfs can; then the check asks for more than is used).

use crate::FilesError;
use std::path::Path;

/// What a run will write into a folder: `entries` files and folders, and `bytes` of content
/// beyond their first block each.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DiskNeed {
    pub entries: u64,
    pub bytes: u64,
}

/// Free space for an unprivileged writer of a file system.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FreeSpace {
    /// Bytes in free blocks.
    pub bytes: u64,
    /// Free file entries (inodes); `u64::MAX` where the file system has no such limit.
    pub files: u64,
    /// The block (fragment) size.
    pub block: u64,
}

/// The free space of the file system holding `path` (or its nearest existing ancestor: the
/// output folder of a fresh run does not exist yet).
pub fn free_space(path: &Path) -> Result<FreeSpace, FilesError> {
    let mut at = path;
    while !at.exists() {
        match at.parent() {
            Some(p) if !p.as_os_str().is_empty() => at = p,
            _ => {
                at = Path::new(".");
                break;
            }
        }
    }
    let s = rustix::fs::statvfs(at).map_err(|e| FilesError::io(at, e.into()))?;
    let block = s.f_frsize.max(1);
    let files = if s.f_files == 0 { u64::MAX } else { s.f_favail };
    Ok(FreeSpace {
        bytes: s.f_bavail.saturating_mul(block),
        files,
        block,
    })
}

/// Refuses `need` in `dir` when it is more than `free`: more bytes than the free blocks hold,
/// or more entries than there are free file entries. `what` names what would be written.
pub fn check_need(
    dir: &Path,
    what: &str,
    need: DiskNeed,
    free: FreeSpace,
) -> Result<(), FilesError> {
    let bytes = need
        .entries
        .saturating_mul(free.block)
        .saturating_add(need.bytes);
    if bytes > free.bytes || need.entries > free.files {
        return Err(FilesError::NoSpace {
            path: dir.to_path_buf(),
            what: what.to_string(),
            entries: need.entries,
            bytes,
            free_entries: free.files,
            free_bytes: free.bytes,
        });
    }
    Ok(())
}

/// [`check_need`] against the [`free_space`] of the file system holding `dir`.
pub fn check_disk(dir: &Path, what: &str, need: DiskNeed) -> Result<(), FilesError> {
    check_need(dir, what, need, free_space(dir)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    const FREE: FreeSpace = FreeSpace {
        bytes: 100 * 4096,
        files: 50,
        block: 4096,
    };

    /// Entries take a block each: 100 free blocks hold 90 entries and 40 KiB more, not a
    /// byte beyond; 51 entries pass the 50 free file entries however small they are.
    #[test]
    fn a_need_past_the_free_blocks_or_files_is_refused_naming_both() {
        let dir = Path::new("/site");
        let fits = DiskNeed {
            entries: 40,
            bytes: 60 * 4096,
        };
        assert!(check_need(dir, "v", fits, FREE).is_ok());
        let over = DiskNeed {
            bytes: fits.bytes + 1,
            ..fits
        };
        let m = check_need(dir, "7 files a voxel", over, FREE)
            .unwrap_err()
            .to_string();
        assert!(
            m.contains("/site") && m.contains("7 files a voxel") && m.contains("409601 bytes"),
            "{m}"
        );
        let many = DiskNeed {
            entries: 51,
            bytes: 0,
        };
        let m = check_need(dir, "v", many, FREE).unwrap_err().to_string();
        assert!(
            m.contains("51 files and folders") && m.contains("50 free"),
            "{m}"
        );
    }

    /// A folder that does not exist yet is measured on its nearest existing ancestor, which
    /// is the file system `df` reports for it.
    #[test]
    fn the_free_space_of_a_folder_to_be_made_is_its_file_systems() {
        let d = tempfile::tempdir().unwrap();
        let deep = d.path().join("a/b/c");
        let (here, there) = (free_space(d.path()).unwrap(), free_space(&deep).unwrap());
        assert_eq!(here.block, there.block);
        assert!(here.block >= 512 && here.bytes > 0);
        // the free bytes move with other writers; 64 MiB of slack
        assert!(here.bytes.abs_diff(there.bytes) < 64 << 20);
    }
}
