//! How a file one command writes names a file another wrote, so that folders that belong
//! together can move together (FORMATS.md: a relative path is relative to the folder of the
//! file that names it).

use std::path::{Component, Path, PathBuf};

/// `path` made absolute with its folder resolved by the file system (symlinks and `..`) and
/// its own name kept, so that a link is named as given rather than by its target. The error is
/// the file system's for the folder.
pub fn resolve_folder_of(path: &Path) -> std::io::Result<PathBuf> {
    let (dir, name) = match (path.parent(), path.file_name()) {
        (Some(d), Some(n)) if !d.as_os_str().is_empty() => (d, Some(n)),
        (_, Some(n)) => (Path::new("."), Some(n)),
        _ => (path, None),
    };
    let dir = std::fs::canonicalize(dir)?;
    Ok(name.map_or(dir.clone(), |n| dir.join(n)))
}

/// `target` relative to the folder `base` (both absolute and resolved, as by
/// [`resolve_folder_of`]) when the two share more than the root; `None` when they share only
/// the root (then a file in `base` names `target` by its absolute path).
pub fn relative_to(target: &Path, base: &Path) -> Option<PathBuf> {
    let (t, b): (Vec<Component>, Vec<Component>) =
        (target.components().collect(), base.components().collect());
    let common = t.iter().zip(&b).take_while(|(x, y)| x == y).count();
    let shares = t[..common]
        .iter()
        .any(|c| matches!(c, Component::Normal(_)));
    if !shares {
        return None;
    }
    let mut out = PathBuf::new();
    b[common..].iter().for_each(|_| out.push(".."));
    t[common..].iter().for_each(|c| out.push(c));
    Some(out)
}

/// How a file in `folder` names `target`: relative to `folder` when the two, resolved, share
/// more than the root ([`relative_to`]), else `target` resolved and absolute. `folder` need
/// not exist yet (an output about to be written); its parent must.
pub fn named_from(target: &Path, folder: &Path) -> std::io::Result<PathBuf> {
    let target = resolve_folder_of(target)?;
    let folder = std::fs::canonicalize(folder).or_else(|_| resolve_folder_of(folder))?;
    Ok(relative_to(&target, &folder).unwrap_or(target))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_path_is_named_from_a_folder_it_shares_more_than_the_root_with() {
        let rel = |t: &str, b: &str| relative_to(Path::new(t), Path::new(b));
        assert_eq!(
            rel("/data/cap/rig.toml", "/data/cap/hull"),
            Some("../rig.toml".into())
        );
        assert_eq!(
            rel("/data/cap/photos/a.exr", "/data/out/s1"),
            Some("../../cap/photos/a.exr".into())
        );
        assert_eq!(rel("/data/cap/a.exr", "/data/cap"), Some("a.exr".into()));
        // only the root in common: absolute
        assert_eq!(rel("/mnt/rig.toml", "/data/hull"), None);
        assert_eq!(rel("/rig.toml", "/data"), None);
    }

    #[test]
    fn a_folder_is_resolved_and_a_link_keeps_its_own_name() {
        let tmp = tempfile::tempdir().unwrap();
        let real = std::fs::canonicalize(tmp.path()).unwrap();
        std::fs::create_dir(real.join("a")).unwrap();
        std::fs::write(real.join("a/x.toml"), "").unwrap();
        let via_dots = real.join("a/../a/x.toml");
        assert_eq!(resolve_folder_of(&via_dots).unwrap(), real.join("a/x.toml"));
        // a folder that does not exist yet is named by its resolved parent and its name
        assert_eq!(
            resolve_folder_of(&real.join("a/new")).unwrap(),
            real.join("a/new")
        );
        #[cfg(unix)]
        {
            std::os::unix::fs::symlink(real.join("a/x.toml"), real.join("link.toml")).unwrap();
            assert_eq!(
                resolve_folder_of(&real.join("link.toml")).unwrap(),
                real.join("link.toml")
            );
        }
        assert!(resolve_folder_of(&real.join("missing/x.toml")).is_err());
        // named from a folder that exists, and from one about to be written
        assert_eq!(
            named_from(&via_dots, &real.join("a")).unwrap(),
            Path::new("x.toml")
        );
        assert_eq!(
            named_from(&real.join("a/x.toml"), &real.join("hull")).unwrap(),
            Path::new("../a/x.toml")
        );
    }
}
