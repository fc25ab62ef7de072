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

#[path = "architecture/handlers.rs"]
mod handlers;

/// Every `.rs` file under `dir`, sorted.
fn rust_files(dir: &std::path::Path, out: &mut Vec<std::path::PathBuf>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            out.push(p);
        }
    }
}

fn parse(path: &std::path::Path) -> syn::File {
    let text = std::fs::read_to_string(path).unwrap();
    syn::parse_file(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The public method names of the library crates (`crates/*/src`).
fn library_methods() -> BTreeSet<String> {
    let mut files = Vec::new();
    for c in std::fs::read_dir(repo_root().join("crates")).unwrap() {
        let src = c.unwrap().path().join("src");
        if src.is_dir() {
            rust_files(&src, &mut files);
        }
    }
    let mut methods = BTreeSet::new();
    for f in &files {
        handlers::public_methods(&parse(f), &mut methods);
    }
    methods
}

/// `src/main.rs`, `src/report.rs`, `src/cmd/mod.rs` and every `src/cmd/*.rs`, by module name.
fn binary_files() -> Vec<handlers::BinaryFile> {
    let src = repo_root().join("src");
    let mut files = vec![
        ("main".to_string(), src.join("main.rs")),
        ("report".to_string(), src.join("report.rs")),
    ];
    let mut cmd = Vec::new();
    rust_files(&src.join("cmd"), &mut cmd);
    for p in cmd {
        let stem = p.file_stem().unwrap().to_str().unwrap();
        let module = if stem == "mod" { "cmd" } else { stem };
        files.push((module.to_string(), p));
    }
    files
        .into_iter()
        .map(|(module, p)| handlers::BinaryFile {
            module,
            file: parse(&p),
        })
        .collect()
}

#[test]
fn each_handler_makes_one_library_call() {
    let methods = library_methods();
    for name in handlers::STD_ACCESSORS {
        assert!(
            methods.contains(*name),
            "STD_ACCESSORS: no library method `{name}`"
        );
    }
    let found = handlers::handlers(&binary_files(), &methods).unwrap();
    assert!(found.len() >= 30, "expected every handler, found {found:?}");
    let wrong: Vec<String> = found
        .iter()
        .filter(|h| h.calls.len() != 1)
        .map(|h| format!("{}: {} library calls {:?}", h.name, h.calls.len(), h.calls))
        .collect();
    assert!(
        wrong.is_empty(),
        "each handler of src/cmd must make exactly one library call:\n{}",
        wrong.join("\n")
    );
}

/// The checker on small sources: `main` dispatching to `cmd::demo::run`, whose body `body` is
/// one handler (or a `match` of several); `save` is a library method.
fn check_source(cmd_src: &str) -> Result<Vec<handlers::Handler>, String> {
    let main = "mod cmd; fn main() { let r = match c { C::Demo(a) => cmd::demo::run(a, &ctx) }; }";
    let report =
        "pub fn print_json<T>(v: &T) { println!(\"{}\", serde_json::to_string(v).unwrap()); }";
    let files = [("main", main), ("report", report), ("demo", cmd_src)]
        .into_iter()
        .map(|(m, s)| handlers::BinaryFile {
            module: m.to_string(),
            file: syn::parse_file(s).unwrap(),
        })
        .collect::<Vec<_>>();
    let methods = ["save", "len"].into_iter().map(String::from).collect();
    handlers::handlers(&files, &methods)
}

fn counts(cmd_src: &str) -> Vec<usize> {
    let found = check_source(cmd_src).unwrap();
    found.iter().map(|h| h.calls.len()).collect()
}

#[test]
fn library_calls_are_counted_exactly() {
    // one call, written out or through `use`; constructors, defaults and reporting do not count
    let one = "use igi_x::job::{run_job, Request};
        pub fn run(a: Args, ctx: &Ctx) -> Result<()> {
            let req = Request { mode: igi_x::Mode::Fast, opts: Opts::default(), k: Kind(2), o: igi_x::Opts::default() };
            let r = run_job(&req)?;
            crate::report::print_json(&r);
            println!(\"{} {}\", r.items.len(), a.output.display());
            Ok(())
        }";
    assert_eq!(counts(one), [1]);
    // two calls fail, however written: a path, a method, inside a macro, through a helper
    let two = [
        "pub fn run(a: A) { let c = igi_camera::Camera::load(&a.c)?; igi_x::go(&c)?; }",
        "use igi_x::go; pub fn run(a: A) { let c = go(&a)?; c.save(&a.o)?; }",
        "pub fn run(a: A) { igi_x::go(&a)?; println!(\"{}\", igi_x::name(&a)); }",
        "pub fn run(a: A) { igi_x::go(&a)?; helper(&a); } fn helper(a: &A) { igi_y::more(a); }",
        "pub fn run(a: A) { igi_x::go(&a)?; let m: Vec<_> = a.p.iter().map(igi_g::read_mesh).collect(); }",
        "pub fn run(a: A) { igi_x::go(&a)?; serde_json::json!({\"k\": igi_x::f(&a)}); }",
        "use igi_x as x; pub fn run(a: A) { x::go(&a)?; x::sub::more(&a)?; }",
    ];
    for src in two {
        assert_eq!(counts(src), [2], "{src}");
    }
    assert_eq!(counts("pub fn run(a: A) { println!(\"{}\", a.x); }"), [0]);
    // sub-subcommands: one handler per arm, each counted on its own
    let arms = "pub fn run(c: Cmd) -> R { match c {
            Cmd::A(a) => first(a),
            Cmd::B(b) => { igi_x::b(&b)?; Ok(()) }
            Cmd::C(c) => { igi_x::c1(&c)?; igi_x::c2(&c) }
        } }
        fn first(a: A) -> R { igi_x::a(&a) }";
    assert_eq!(counts(arms), [1, 1, 2]);
    // the binary's own methods are followed, and a glob import of a library is refused
    let method = "impl Args { fn request(&self) -> R { igi_x::check(self)?; R {} } }
        pub fn run(a: Args) { let r = a.request()?; igi_x::go(&r); }";
    assert_eq!(counts(method), [2]);
    assert!(check_source("use igi_x::*; pub fn run(a: A) { go(&a); }").is_err());
    assert!(check_source("pub fn run(a: A) { igi_x::go(&a); custom!(a => igi_x::f()); }").is_err());
}
