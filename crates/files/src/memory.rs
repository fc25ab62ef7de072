//! One check for every size-driven allocation: [`check_alloc`] refuses, before the allocation,
//! a buffer whose estimated size (from the options and headers that drive it) is above a limit,
//! with a message naming what would be allocated, the estimated bytes and the limit, instead
//! of the process aborting with "memory allocation failed".
//!
//! The limit is [`max_alloc`]: [`DEFAULT_MAX_ALLOC`] (8 GiB, as `igi prepare --max-memory`),
//! or the environment variable `IGI_MAX_MEMORY` (bytes, or with a `K`, `M`, `G` or `T`
//! suffix: `IGI_MAX_MEMORY=32G`) on a machine with more.

use crate::FilesError;

/// Bytes one size-driven allocation may take without `IGI_MAX_MEMORY`: 8 GiB.
pub const DEFAULT_MAX_ALLOC: u64 = 8 << 30;

/// The limit [`check_alloc`] is given by the commands: `IGI_MAX_MEMORY` when set (bytes, or
/// with a `K`, `M`, `G` or `T` suffix, powers of 1024), else [`DEFAULT_MAX_ALLOC`]. A value that
/// does not parse is an error naming it.
pub fn max_alloc() -> Result<u64, FilesError> {
    match std::env::var("IGI_MAX_MEMORY") {
        Ok(v) => parse_bytes(&v).ok_or(FilesError::BadMemoryLimit(v)),
        Err(_) => Ok(DEFAULT_MAX_ALLOC),
    }
}

/// `123`, `64K`, `512M`, `8G`, `1T` (powers of 1024; a trailing `B` or `iB` allowed).
pub fn parse_bytes(text: &str) -> Option<u64> {
    let t = text.trim();
    let t = t
        .strip_suffix("iB")
        .or_else(|| t.strip_suffix('B'))
        .unwrap_or(t);
    let (num, shift) = match t.char_indices().last()? {
        (i, 'K' | 'k') => (&t[..i], 10),
        (i, 'M' | 'm') => (&t[..i], 20),
        (i, 'G' | 'g') => (&t[..i], 30),
        (i, 'T' | 't') => (&t[..i], 40),
        _ => (t, 0),
    };
    let n: u64 = num.trim().parse().ok()?;
    n.checked_mul(1u64 << shift).filter(|&b| b > 0)
}

/// Refuses, before it happens, an allocation of an estimated `bytes` above `limit`: `what`
/// names it with the option or header that drives it (`"the board's corners (--board
/// 100000x100000)"`). `bytes` is a `u128` so that the estimate itself cannot overflow.
pub fn check_alloc(what: &str, bytes: u128, limit: u64) -> Result<(), FilesError> {
    if bytes > limit as u128 {
        return Err(FilesError::TooLarge {
            what: what.to_string(),
            bytes: u64::try_from(bytes).unwrap_or(u64::MAX),
            limit,
        });
    }
    Ok(())
}

/// [`check_alloc`] against [`max_alloc`].
pub fn check_alloc_default(what: &str, bytes: u128) -> Result<(), FilesError> {
    check_alloc(what, bytes, max_alloc()?)
}

/// Refuses, before it is read whole into memory, an input that is not a regular file (a
/// device such as `/dev/zero`, a pipe: they have no size to check) or whose size is above
/// [`max_alloc`]; `what` names it ("the samples file").
pub fn check_input_file(path: &std::path::Path, what: &str) -> Result<(), FilesError> {
    let meta = std::fs::metadata(path).map_err(|e| FilesError::io(path, e))?;
    if !meta.is_file() {
        return Err(FilesError::NotAFile {
            path: path.to_path_buf(),
            what: what.to_string(),
        });
    }
    check_alloc_default(&format!("{what} {}", path.display()), meta.len() as u128)
}

/// Bytes as `12.3 GiB` for messages.
pub fn show_bytes(bytes: u128) -> String {
    let gib = bytes as f64 / (1u64 << 30) as f64;
    if gib >= 0.1 {
        format!("{gib:.1} GiB")
    } else {
        format!("{:.1} MiB", bytes as f64 / (1u64 << 20) as f64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_over_the_limit_are_refused_naming_what_and_how_much() {
        check_alloc("x", 8 << 30, 8 << 30).unwrap();
        let e = check_alloc("the atlas (--atlas 100000)", 390_000_000_000, 8 << 30)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("the atlas (--atlas 100000)")
                && e.contains("363.2 GiB")
                && e.contains("390000000000 bytes")
                && e.contains("8.0 GiB")
                && e.contains("IGI_MAX_MEMORY"),
            "{e}"
        );
    }

    #[test]
    fn byte_counts_parse_with_binary_suffixes() {
        assert_eq!(parse_bytes("123"), Some(123));
        assert_eq!(parse_bytes("64K"), Some(64 << 10));
        assert_eq!(parse_bytes("8G"), Some(8 << 30));
        assert_eq!(parse_bytes("8GiB"), Some(8 << 30));
        assert_eq!(parse_bytes("1t"), Some(1 << 40));
        assert_eq!(parse_bytes("0"), None);
        assert_eq!(parse_bytes("lots"), None);
        assert_eq!(parse_bytes("99999999999T"), None);
    }
}
