//! docs/ARCHITECTURE.md matches the Cargo files: every crate under `crates/` has a row in the
//! crate table with its path, and the row's "depends on" column names exactly the igi crates of
//! its `[dependencies]` (dev-dependencies are not layering and are not listed; a word after a
//! crate's name, such as "imaging (plot fonts)", is a comment).

use igi_testkit::repo_root;
use std::collections::BTreeSet;

/// (name, path, depends-on cell) of each crate-table row of docs/ARCHITECTURE.md.
fn table_rows() -> Vec<(String, String, String)> {
    let doc = std::fs::read_to_string(repo_root().join("docs/ARCHITECTURE.md")).unwrap();
    doc.lines()
        .filter(|l| l.starts_with("| `igi"))
        .map(|l| {
            let cells: Vec<&str> = l.trim_matches('|').split(" | ").map(str::trim).collect();
            let unquote = |s: &str| s.trim_matches('`').to_string();
            (
                unquote(cells[0]),
                unquote(cells[1]),
                cells[cells.len() - 1].to_string(),
            )
        })
        .collect()
}

/// The igi crates named in the `[dependencies]` section of a Cargo.toml, by short name
/// (`igi-imaging` -> `imaging`).
fn igi_dependencies(manifest: &str) -> BTreeSet<String> {
    let mut in_deps = false;
    let mut deps = BTreeSet::new();
    for line in manifest.lines().map(str::trim) {
        if line.starts_with('[') {
            in_deps = line == "[dependencies]";
        } else if in_deps && line.starts_with("igi-") {
            let name = line.split(['.', ' ', '=']).next().unwrap();
            deps.insert(name.trim_start_matches("igi-").to_string());
        }
    }
    deps
}

fn package_name(manifest: &str) -> String {
    let line = manifest
        .lines()
        .find(|l| l.trim_start().starts_with("name = "))
        .unwrap();
    line.split('"').nth(1).unwrap().to_string()
}

#[test]
fn architecture_md_matches_the_cargo_files() {
    let rows = table_rows();
    let mut crates: Vec<_> = std::fs::read_dir(repo_root().join("crates"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.join("Cargo.toml").exists())
        .collect();
    crates.sort();
    assert!(
        crates.len() >= 6,
        "expected the workspace crates, found {crates:?}"
    );
    for dir in crates {
        let manifest = std::fs::read_to_string(dir.join("Cargo.toml")).unwrap();
        let name = package_name(&manifest);
        let path = format!("crates/{}", dir.file_name().unwrap().to_str().unwrap());
        let row = rows.iter().find(|r| r.0 == name);
        let (_, doc_path, doc_deps) =
            row.unwrap_or_else(|| panic!("docs/ARCHITECTURE.md has no row for {name}"));
        assert_eq!(
            doc_path, &path,
            "docs/ARCHITECTURE.md gives {name} the wrong path"
        );
        let doc_deps: BTreeSet<String> = doc_deps
            .split(',')
            .map(|s| s.split_whitespace().next().unwrap_or("").trim_matches('`'))
            .map(|s| s.trim_start_matches("igi-").to_string())
            .filter(|s| !s.is_empty() && s != "—")
            .collect();
        assert_eq!(
            doc_deps,
            igi_dependencies(&manifest),
            "docs/ARCHITECTURE.md lists the wrong dependencies for {name}"
        );
    }
}

#[test]
fn dependency_parser_reads_sections() {
    let m = "[package]\nname = \"x\"\n[dependencies]\nigi-imaging.workspace = true\nigi-geometry = { path = \"a\" }\nglam = \"1\"\n[dev-dependencies]\nigi-render.workspace = true\n";
    let d: Vec<_> = igi_dependencies(m).into_iter().collect();
    assert_eq!(d, ["geometry", "imaging"]);
}
