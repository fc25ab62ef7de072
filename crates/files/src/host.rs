//! The identity of the writing process's machine, as it goes into temporary and staging names.

/// This machine's host name, reduced to letters, digits and `-` (it goes into temporary names,
/// so that writers on several hosts of a shared file system never collide).
pub fn this_host() -> String {
    let h = std::fs::read_to_string("/proc/sys/kernel/hostname")
        .or_else(|_| std::env::var("HOSTNAME"))
        .unwrap_or_default();
    let h = safe_name_part(h.trim());
    if h.is_empty() {
        "host".into()
    } else {
        h
    }
}

pub(crate) fn safe_name_part(s: &str) -> String {
    s.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' {
                c
            } else {
                'x'
            }
        })
        .collect()
}
