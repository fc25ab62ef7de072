//! No module circles: within each crate, the modules of `src/` (files, one level) reference
//! each other without a cycle. A module references another when its non-test, non-comment
//! code names `crate::other`, `super::other`, `use crate::{.., other, ..}` or a name the crate
//! root re-exports from `other` (`pub use other::{Name, ..}` in lib.rs).

use igi_testkit::repo_root;
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// The identifiers that follow each occurrence of `prefix` in `code`.
fn idents_after<'a>(code: &'a str, prefix: &str) -> Vec<&'a str> {
    code.match_indices(prefix)
        .map(|(i, _)| {
            let rest = &code[i + prefix.len()..];
            let end = rest
                .find(|c: char| !(c.is_alphanumeric() || c == '_'))
                .unwrap_or(rest.len());
            &rest[..end]
        })
        .collect()
}

/// The code of a module file without its test module and without comment lines.
fn code_of(text: &str) -> String {
    let text = text.split("#[cfg(test)]").next().unwrap_or("");
    text.lines()
        .filter(|l| !l.trim_start().starts_with("//"))
        .collect::<Vec<_>>()
        .join("\n")
}

/// Names re-exported at the crate root, mapped to the module they come from.
fn root_exports(lib: &str) -> BTreeMap<String, String> {
    let mut out = BTreeMap::new();
    for stmt in code_of(lib).split(';') {
        let Some(rest) = stmt.trim().strip_prefix("pub use ") else {
            continue;
        };
        let Some((module, names)) = rest.split_once("::") else {
            continue;
        };
        for n in names.split(|c: char| !(c.is_alphanumeric() || c == '_')) {
            if !n.is_empty() {
                out.insert(n.to_string(), module.to_string());
            }
        }
    }
    out
}

/// Module -> modules it references, for one crate's `src/`.
fn module_graph(src: &Path) -> BTreeMap<String, BTreeSet<String>> {
    let lib = std::fs::read_to_string(src.join("lib.rs")).unwrap_or_default();
    let roots = root_exports(&lib);
    let mut codes = BTreeMap::new();
    for e in std::fs::read_dir(src).unwrap() {
        let p = e.unwrap().path();
        let stem = p.file_stem().unwrap().to_string_lossy().to_string();
        if p.extension().is_some_and(|x| x == "rs") && stem != "lib" && stem != "main" {
            codes.insert(stem, code_of(&std::fs::read_to_string(&p).unwrap()));
        }
    }
    let mut graph = BTreeMap::new();
    for (m, code) in &codes {
        let mut refs: Vec<&str> = idents_after(code, "crate::");
        refs.extend(idents_after(code, "super::"));
        for (i, _) in code.match_indices("use crate::{") {
            let inner = &code[i + 12..];
            let inner = &inner[..inner.find('}').unwrap_or(inner.len())];
            refs.extend(inner.split(|c: char| !(c.is_alphanumeric() || c == '_')));
        }
        let set = refs
            .into_iter()
            .map(|r| roots.get(r).map(String::as_str).unwrap_or(r).to_string())
            .filter(|r| r != m && codes.contains_key(r))
            .collect();
        graph.insert(m.clone(), set);
    }
    graph
}

/// A cycle in `graph` (its modules in order), if any.
fn find_cycle(graph: &BTreeMap<String, BTreeSet<String>>) -> Option<Vec<String>> {
    fn visit(
        v: &str,
        graph: &BTreeMap<String, BTreeSet<String>>,
        state: &mut BTreeMap<String, u8>,
        path: &mut Vec<String>,
    ) -> Option<Vec<String>> {
        state.insert(v.to_string(), 1);
        path.push(v.to_string());
        for w in &graph[v] {
            match state.get(w.as_str()).copied().unwrap_or(0) {
                1 => {
                    let start = path.iter().position(|p| p == w).unwrap();
                    return Some(path[start..].to_vec());
                }
                0 => {
                    if let Some(c) = visit(w, graph, state, path) {
                        return Some(c);
                    }
                }
                _ => {}
            }
        }
        path.pop();
        state.insert(v.to_string(), 2);
        None
    }
    let mut state = BTreeMap::new();
    for v in graph.keys() {
        if state.get(v.as_str()).copied().unwrap_or(0) == 0 {
            if let Some(c) = visit(v, graph, &mut state, &mut Vec::new()) {
                return Some(c);
            }
        }
    }
    None
}

#[test]
fn no_crate_has_a_module_circle() {
    let mut checked = 0;
    for e in std::fs::read_dir(repo_root().join("crates")).unwrap() {
        let src = e.unwrap().path().join("src");
        if !src.is_dir() {
            continue;
        }
        let graph = module_graph(&src);
        assert!(
            find_cycle(&graph).is_none(),
            "{}: module circle {:?}",
            src.display(),
            find_cycle(&graph)
        );
        checked += graph.len();
    }
    assert!(checked > 50, "only {checked} modules found");
}

#[test]
fn a_circle_is_found() {
    let g: BTreeMap<String, BTreeSet<String>> = [("a", "b"), ("b", "c"), ("c", "a"), ("d", "a")]
        .iter()
        .map(|(k, v)| (k.to_string(), BTreeSet::from([v.to_string()])))
        .collect();
    assert_eq!(find_cycle(&g).unwrap().len(), 3);
    let exports = root_exports("pub use camera::{Camera, Intrinsics};\npub use io::read_image;");
    assert_eq!(exports["Intrinsics"], "camera");
    assert_eq!(exports["read_image"], "io");
}
