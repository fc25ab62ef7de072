//! igi-geometry's own PLY and OBJ readers against ply-rs and tobj (issue 11, item 10).
//!
//! A plain `main` (`harness = false`), not criterion: one read of the 20.8 M-triangle field
//! takes seconds and hundreds of MiB, so a statistical sampler adds nothing but hours. Each
//! (file, reader) pair runs `MESH_READERS_RUNS` times (default 3) in a fresh child process
//! (this same binary with `--one READER FILE`), so every run's peak RSS (`VmHWM` of
//! /proc/self/status) is its own; the readers of one file take turns (round by round) so a
//! change in the machine's load hits them alike; the table reports the best wall time of the
//! read call and the largest peak RSS. Every reader must return the same number of triangles, the same number of
//! vertices used by them (tobj's `single_index` drops unreferenced ones; the bunny has 1,113)
//! and the same checksum over the triangles' corner positions, or the bench panics.
//!
//! ```sh
//! cargo bench -p igi-geometry --bench mesh_readers -- [FILE.ply ...]
//! ```
//!
//! With no file, the Stanford bunny (ASCII PLY, ../shared/data). For each PLY file an OBJ copy
//! (igi_geometry::write_obj) is made once under `$MESH_READERS_TMP` (default: the system temp
//! folder's `igi-mesh-readers`) and the OBJ readers run on it. The HashMap-per-element
//! `DefaultElement` path of ply-rs runs only on files below 64 MiB (about 4 GiB of maps per 10 M
//! vertices otherwise).

use igi_geometry::{read_obj, read_ply, write_obj, TriMesh};
use ply_rs::parser::Parser;
use ply_rs::ply::{DefaultElement, Property, PropertyAccess};
use std::io::BufReader;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// Files larger than this skip ply-rs's `DefaultElement` path.
const DEFAULT_ELEMENT_MAX_BYTES: u64 = 64 << 20;

#[derive(Clone, Copy, Debug, PartialEq)]
enum Reader {
    /// `igi_geometry::read_ply` (includes `TriMesh::validate`).
    OwnPly,
    /// ply-rs with `PropertyAccess` structs and `read_payload_for_element`.
    PlyRsStructs,
    /// ply-rs `read_ply` into `DefaultElement` (a LinkedHashMap per element).
    PlyRsDefault,
    /// `igi_geometry::read_obj` (includes `TriMesh::validate`).
    OwnObj,
    /// `tobj::load_obj` with `triangulate` and `single_index`.
    TobjSingleIndex,
    /// `tobj::load_obj` with `triangulate` only (positions-only faces index positions directly).
    TobjTriangulate,
}

const READERS: [Reader; 6] = [
    Reader::OwnPly,
    Reader::PlyRsStructs,
    Reader::PlyRsDefault,
    Reader::OwnObj,
    Reader::TobjSingleIndex,
    Reader::TobjTriangulate,
];

impl Reader {
    fn name(self) -> &'static str {
        match self {
            Reader::OwnPly => "igi_geometry::read_ply",
            Reader::PlyRsStructs => "ply-rs PropertyAccess structs",
            Reader::PlyRsDefault => "ply-rs DefaultElement",
            Reader::OwnObj => "igi_geometry::read_obj",
            Reader::TobjSingleIndex => "tobj triangulate+single_index",
            Reader::TobjTriangulate => "tobj triangulate",
        }
    }
    fn from_name(s: &str) -> Reader {
        *READERS
            .iter()
            .find(|r| r.name() == s)
            .unwrap_or_else(|| panic!("unknown reader `{s}`"))
    }
    fn is_obj(self) -> bool {
        matches!(
            self,
            Reader::OwnObj | Reader::TobjSingleIndex | Reader::TobjTriangulate
        )
    }
    /// Read `path` into positions and triangles.
    fn read(self, path: &Path) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
        match self {
            Reader::OwnPly => into_parts(read_ply(path).unwrap()),
            Reader::OwnObj => into_parts(read_obj(path).unwrap()),
            Reader::PlyRsStructs => ply_rs_structs(path),
            Reader::PlyRsDefault => ply_rs_default(path),
            Reader::TobjSingleIndex => tobj_read(path, true),
            Reader::TobjTriangulate => tobj_read(path, false),
        }
    }
}

fn into_parts(m: TriMesh) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    (m.positions, m.indices)
}

/// A PLY vertex for ply-rs: only the position is kept.
struct PlyVertex([f32; 3]);

impl PropertyAccess for PlyVertex {
    fn new() -> Self {
        PlyVertex([0.0; 3])
    }
    fn set_property(&mut self, key: String, property: Property) {
        let k = match key.as_str() {
            "x" => 0,
            "y" => 1,
            "z" => 2,
            _ => return,
        };
        self.0[k] = match property {
            Property::Float(v) => v,
            Property::Double(v) => v as f32,
            other => panic!("vertex {key}: unexpected {other:?}"),
        };
    }
}

/// A PLY face for ply-rs: the first three corners inline, any further corners in `more`
/// (empty, so unallocated, for a triangle).
struct PlyFace {
    first: [u32; 3],
    more: Vec<u32>,
    n: usize,
}

impl PropertyAccess for PlyFace {
    fn new() -> Self {
        PlyFace {
            first: [0; 3],
            more: Vec::new(),
            n: 0,
        }
    }
    fn set_property(&mut self, key: String, property: Property) {
        if key != "vertex_indices" && key != "vertex_index" {
            return;
        }
        let idx: Vec<u32> = match property {
            Property::ListInt(v) => v.into_iter().map(|i| i as u32).collect(),
            Property::ListUInt(v) => v,
            other => panic!("face {key}: unexpected {other:?}"),
        };
        assert!(idx.len() >= 3, "face with {} corners", idx.len());
        self.n = idx.len();
        self.first.copy_from_slice(&idx[..3]);
        if idx.len() > 3 {
            self.more = idx[3..].to_vec();
        }
    }
}

impl PlyFace {
    /// Fan-triangulate into `out`, as igi_geometry::read_ply does.
    fn triangulate(&self, out: &mut Vec<[u32; 3]>) {
        let corner = |j: usize| {
            if j < 3 {
                self.first[j]
            } else {
                self.more[j - 3]
            }
        };
        for j in 1..self.n - 1 {
            out.push([self.first[0], corner(j), corner(j + 1)]);
        }
    }
}

/// ply-rs's fastest path: a parser per element type, `read_header` then
/// `read_payload_for_element`, into the structs above.
fn ply_rs_structs(path: &Path) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let mut r = BufReader::with_capacity(1 << 20, std::fs::File::open(path).unwrap());
    let vp = Parser::<PlyVertex>::new();
    let fp = Parser::<PlyFace>::new();
    let header = vp.read_header(&mut r).unwrap();
    let (mut pos, mut tris) = (Vec::new(), Vec::new());
    for el in header.elements.values() {
        match el.name.as_str() {
            "vertex" => {
                let v = vp.read_payload_for_element(&mut r, el, &header).unwrap();
                pos = v.into_iter().map(|v| v.0).collect();
            }
            "face" => {
                let f = fp.read_payload_for_element(&mut r, el, &header).unwrap();
                tris.reserve(f.len());
                for face in &f {
                    face.triangulate(&mut tris);
                }
            }
            other => panic!("unexpected element {other}"),
        }
    }
    (pos, tris)
}

/// ply-rs's default path: the whole file into a `LinkedHashMap` per element.
fn ply_rs_default(path: &Path) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let mut f = std::fs::File::open(path).unwrap();
    let ply = Parser::<DefaultElement>::new().read_ply(&mut f).unwrap();
    let get = |e: &DefaultElement, k: &str| match e.get(k) {
        Some(Property::Float(v)) => *v,
        Some(Property::Double(v)) => *v as f32,
        other => panic!("vertex {k}: {other:?}"),
    };
    let pos = ply.payload["vertex"]
        .iter()
        .map(|e| [get(e, "x"), get(e, "y"), get(e, "z")])
        .collect();
    let mut tris = Vec::new();
    for e in &ply.payload["face"] {
        let idx: Vec<u32> = match e.get("vertex_indices").or_else(|| e.get("vertex_index")) {
            Some(Property::ListInt(v)) => v.iter().map(|&i| i as u32).collect(),
            Some(Property::ListUInt(v)) => v.clone(),
            other => panic!("face: {other:?}"),
        };
        for j in 1..idx.len() - 1 {
            tris.push([idx[0], idx[j], idx[j + 1]]);
        }
    }
    (pos, tris)
}

/// `tobj::load_obj` (one model: the files here have no `o` or `g`), triangulated.
fn tobj_read(path: &Path, single_index: bool) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let opts = tobj::LoadOptions {
        triangulate: true,
        single_index,
        ..Default::default()
    };
    let (models, _materials) = tobj::load_obj(path, &opts).unwrap();
    assert_eq!(models.len(), 1, "one model expected");
    let m = models.into_iter().next().unwrap().mesh;
    let pos = m
        .positions
        .chunks_exact(3)
        .map(|p| [p[0], p[1], p[2]])
        .collect();
    let tris = m
        .indices
        .chunks_exact(3)
        .map(|t| [t[0], t[1], t[2]])
        .collect();
    (pos, tris)
}

/// What one child run reports.
#[derive(Debug)]
struct Run {
    tris: usize,
    verts: usize,
    /// Vertices some triangle uses (tobj's `single_index` drops the others).
    used: usize,
    /// Sum over triangles of their corner coordinates: the same for any vertex order.
    checksum: f64,
    secs: f64,
    peak_kib: u64,
}

fn peak_rss_kib() -> u64 {
    let s = std::fs::read_to_string("/proc/self/status").unwrap();
    let line = s.lines().find(|l| l.starts_with("VmHWM:")).unwrap();
    line.split_whitespace().nth(1).unwrap().parse().unwrap()
}

/// Child mode: one timed read, printed as one `RUN` line.
fn run_one(reader: Reader, path: &Path) {
    let t = Instant::now();
    let (pos, tris) = reader.read(path);
    let secs = t.elapsed().as_secs_f64();
    let peak_kib = peak_rss_kib();
    let mut seen = vec![false; pos.len()];
    for &i in tris.iter().flatten() {
        seen[i as usize] = true;
    }
    let used = seen.iter().filter(|&&b| b).count();
    let checksum: f64 = tris
        .iter()
        .flat_map(|t| t.iter())
        .map(|&i| pos[i as usize].iter().map(|&c| c as f64).sum::<f64>())
        .sum();
    println!(
        "RUN {} {} {used} {checksum:e} {secs} {peak_kib}",
        tris.len(),
        pos.len()
    );
}

fn parse_run(stdout: &str) -> Run {
    let line = stdout
        .lines()
        .find(|l| l.starts_with("RUN "))
        .unwrap_or_else(|| panic!("no RUN line in {stdout:?}"));
    let f: Vec<&str> = line.split_whitespace().collect();
    Run {
        tris: f[1].parse().unwrap(),
        verts: f[2].parse().unwrap(),
        used: f[3].parse().unwrap(),
        checksum: f[4].parse().unwrap(),
        secs: f[5].parse().unwrap(),
        peak_kib: f[6].parse().unwrap(),
    }
}

/// One child run of `reader` on `path`.
fn run_child(reader: Reader, path: &Path) -> Run {
    let out = Command::new(std::env::current_exe().unwrap())
        .args(["--one", reader.name()])
        .arg(path)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{} on {}: {}",
        reader.name(),
        path.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    parse_run(&String::from_utf8_lossy(&out.stdout))
}

/// `runs` rounds of every reader on `path`, interleaved (a round runs each reader once) so a
/// change in the machine's load hits all readers alike: per reader the best time and the
/// largest peak RSS.
fn measure(readers: &[Reader], path: &Path, runs: usize) -> Vec<Run> {
    let mut best: Vec<Option<Run>> = readers.iter().map(|_| None).collect();
    for _ in 0..runs {
        for (slot, &reader) in best.iter_mut().zip(readers) {
            let r = run_child(reader, path);
            *slot = Some(match slot.take() {
                None => r,
                Some(b) => Run {
                    secs: b.secs.min(r.secs),
                    peak_kib: b.peak_kib.max(r.peak_kib),
                    ..b
                },
            });
        }
    }
    best.into_iter().map(Option::unwrap).collect()
}

/// The OBJ copy of `ply`, written once (igi_geometry::write_obj) under the temp folder.
fn obj_copy(ply: &Path) -> PathBuf {
    let dir = std::env::var_os("MESH_READERS_TMP")
        .map(PathBuf::from)
        .unwrap_or_else(|| std::env::temp_dir().join("igi-mesh-readers"));
    std::fs::create_dir_all(&dir).unwrap();
    let obj = dir.join(ply.with_extension("obj").file_name().unwrap());
    let fresh = |p: &Path| std::fs::metadata(p).and_then(|m| m.modified()).ok();
    if fresh(&obj).is_none() || fresh(&obj) < fresh(ply) {
        let t = Instant::now();
        write_obj(&obj, &read_ply(ply).unwrap()).unwrap();
        eprintln!(
            "wrote {} in {:.1} s",
            obj.display(),
            t.elapsed().as_secs_f64()
        );
    }
    obj
}

fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_default()
}

fn mib(path: &Path) -> f64 {
    std::fs::metadata(path).unwrap().len() as f64 / (1 << 20) as f64
}

/// All readers of one format on `path`, checked against each other (triangles,
/// used vertices, checksum), as table rows; returns the
/// first reader's run.
fn bench_file(path: &Path, readers: &[Reader], runs: usize) -> Run {
    let runs = measure(readers, path, runs);
    let f = &runs[0];
    for (r, &reader) in runs.iter().zip(readers) {
        assert_eq!(
            (r.tris, r.used),
            (f.tris, f.used),
            "{}: counts differ",
            reader.name()
        );
        assert_eq!(
            r.checksum,
            f.checksum,
            "{}: geometry differs",
            reader.name()
        );
        println!(
            "| {} ({:.0} MiB) | {} | {} | {} | {:.3} s | {:.0} MiB | {} |",
            path.file_name().unwrap().to_string_lossy(),
            mib(path),
            r.tris,
            r.verts,
            reader.name(),
            r.secs,
            r.peak_kib as f64 / 1024.0,
            load_average()
        );
    }
    runs.into_iter().next().unwrap()
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.first().map(String::as_str) == Some("--one") {
        return run_one(Reader::from_name(&args[1]), Path::new(&args[2]));
    }
    let runs: usize = std::env::var("MESH_READERS_RUNS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(3);
    let mut files: Vec<PathBuf> = args
        .iter()
        .filter(|a| !a.starts_with("--"))
        .map(PathBuf::from)
        .collect();
    if files.is_empty() {
        files.push(PathBuf::from(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../../shared/data/meshes/stanford_bunny/reconstruction/bun_zipper.ply"
        )));
    }
    println!("best of {runs} runs; load average (1, 5, 15 min) at the end of each row");
    println!("| file | triangles | vertices | reader | best wall | peak RSS | load |");
    println!("|---|---:|---:|---|---:|---:|---|");
    for ply in &files {
        let small = std::fs::metadata(ply).unwrap().len() < DEFAULT_ELEMENT_MAX_BYTES;
        let ply_readers: Vec<Reader> = READERS
            .into_iter()
            .filter(|r| !r.is_obj() && (small || *r != Reader::PlyRsDefault))
            .collect();
        let from_ply = bench_file(ply, &ply_readers, runs);
        let obj_readers: Vec<Reader> = READERS.into_iter().filter(|r| r.is_obj()).collect();
        let from_obj = bench_file(&obj_copy(ply), &obj_readers, runs);
        assert_eq!(
            (from_obj.tris, from_obj.used, from_obj.checksum),
            (from_ply.tris, from_ply.used, from_ply.checksum),
            "the OBJ copy of {} reads back different",
            ply.display()
        );
    }
}
