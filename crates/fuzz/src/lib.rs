//! # igi-fuzz
//!
//! Mutation fuzzing of every parser a user feeds igi: PLY and OBJ meshes, EXR and Radiance HDR
//! images (through `igi_imaging::read_image`), camera JSON, lighting, scene and survey TOML,
//! board JSON and BRDF sample CSV, and the photogrammetry imports of `igi import colmap`:
//! COLMAP sparse models (text and binary, the three files of a model as one input split at
//! a marker line), Metashape's camera XML, nerfstudio's `transforms.json`, a photo's EXIF
//! (time and exposure) and ground control points (the CSV, then the alignment); and the folders
//! that `igi slf render` and `igi hull render` read back (a stored surface light field's header
//! and arrays, a hull's manifest and surfels; each then rendered).
//!
//! cargo-fuzz needs libFuzzer's compiler instrumentation (a nightly toolchain); this workspace
//! builds on stable only, so this crate is a self-contained mutational fuzzer instead: each
//! target's corpus is seeded from `datasets/fixtures` (and small files written by igi's own
//! writers), every execution mutates a corpus entry (bit flips, byte and token edits, numbers
//! replaced by extreme values, splices, truncations), writes it where the parser expects its
//! file and calls the parser in-process. An input whose outcome (the error message with its
//! numbers removed) was not seen before joins the corpus, a cheap stand-in for coverage.
//!
//! Per execution it records: a panic (a crash; the input is saved), the wall time (over 1 s is
//! a hang) and, with [`CountingAlloc`] installed as the global allocator, the peak of live heap
//! bytes (over the limit is a failure). A single allocation above [`HARD_ALLOC_LIMIT`] is
//! refused, which aborts the process with the input left in the work folder.
//!
//! Run with `scripts/fuzz.sh` (a fixed number of executions per target); the counts of the
//! last full run are in `docs/RELIABILITY.md`.

use igi_formats::TomlFile;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use std::alloc::{GlobalAlloc, Layout, System};
use std::collections::HashSet;
use std::panic::AssertUnwindSafe;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

/// Errors of the fuzzer itself (not of the parsers it runs).
#[derive(Debug, thiserror::Error)]
pub enum FuzzError {
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("unknown target `{0}` (targets: {1})")]
    UnknownTarget(String, String),
    #[error("setting up target {target}: {msg}")]
    Setup { target: String, msg: String },
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> FuzzError + '_ {
    move |source| FuzzError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// A single allocation above this many bytes is refused (the process aborts).
pub const HARD_ALLOC_LIMIT: usize = 8 << 30;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

/// A global allocator that counts live heap bytes and their peak (install it with
/// `#[global_allocator]` in the binary or test that fuzzes).
pub struct CountingAlloc;

unsafe impl GlobalAlloc for CountingAlloc {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        if l.size() > HARD_ALLOC_LIMIT {
            return std::ptr::null_mut();
        }
        let p = System.alloc(l);
        if !p.is_null() {
            let now = LIVE.fetch_add(l.size(), Ordering::Relaxed) + l.size();
            PEAK.fetch_max(now, Ordering::Relaxed);
        }
        p
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        LIVE.fetch_sub(l.size(), Ordering::Relaxed);
        System.dealloc(p, l)
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, new: usize) -> *mut u8 {
        if new > HARD_ALLOC_LIMIT {
            return std::ptr::null_mut();
        }
        let q = System.realloc(p, l, new);
        if !q.is_null() {
            if new >= l.size() {
                let now = LIVE.fetch_add(new - l.size(), Ordering::Relaxed) + new - l.size();
                PEAK.fetch_max(now, Ordering::Relaxed);
            } else {
                LIVE.fetch_sub(l.size() - new, Ordering::Relaxed);
            }
        }
        q
    }
}

/// One parser under test: where its input goes and how it is called.
/// Prepares a target's work folder (from the fixtures folder) and returns its seed corpus.
type SetupFn = fn(&Path, &Path) -> Result<Vec<Vec<u8>>, String>;

pub struct Target {
    pub name: &'static str,
    /// File name of the input inside the target's work folder (may be in a sub-folder).
    input: &'static str,
    setup: SetupFn,
    run: fn(&Path) -> Result<(), String>,
}

/// A parser's outcome as a target reports it: any value is a pass, an error its message.
fn checked<T, E: std::fmt::Display>(r: Result<T, E>) -> Result<(), String> {
    r.map(drop).map_err(|e| e.to_string())
}

/// Parse a lighting file (igi-formats), then build it (igi-render).
fn run_lighting(p: &Path) -> Result<(), String> {
    let f = igi_formats::LightingFile::read(p).map_err(|e| e.to_string())?;
    checked(igi_render::Lighting::from_file(&f, p))
}

/// Parse a scene file (igi-formats), then build it (igi-render).
fn run_scene(p: &Path) -> Result<(), String> {
    let f = igi_formats::SceneFile::read(p).map_err(|e| e.to_string())?;
    checked(igi_render::Scene::from_file(&f, p))
}

/// Every target, by name.
pub fn targets() -> Vec<Target> {
    type Run = fn(&Path) -> Result<(), String>;
    let t = |name, input, setup: SetupFn, run: Run| Target {
        name,
        input,
        setup,
        run,
    };
    vec![
        t("ply", "in.ply", setup_ply, |p| {
            checked(igi_geometry::read_ply(p))
        }),
        t("obj", "in.obj", setup_obj, |p| {
            checked(igi_geometry::read_obj(p))
        }),
        t("exr", "in.exr", setup_exr, run_image),
        t("hdr", "in.hdr", setup_hdr, run_image),
        t("camera", "in.json", setup_camera, |p| {
            checked(igi_camera::Camera::load(p))
        }),
        t("lighting", "light/in.toml", setup_lighting, run_lighting),
        t("scene", "scene/in.toml", setup_scene, run_scene),
        t("survey", "survey/survey.toml", setup_survey, |p| {
            checked(igi_workflow::Survey::load(p))
        }),
        t("board", "in.json", setup_board, run_board),
        t("brdf", "in.csv", setup_brdf, |p| {
            checked(igi_brdf::read_samples(p))
        }),
        t("colmap-txt", "bundle.txt", setup_colmap_txt, |p| {
            run_colmap(p, "txt")
        }),
        t("colmap-bin", "bundle.bin", setup_colmap_bin, |p| {
            run_colmap(p, "bin")
        }),
        t("metashape", "in.xml", setup_metashape, |p| {
            checked(igi_import::read_metashape(p))
        }),
        t("nerfstudio", "ns/transforms.json", setup_nerfstudio, |p| {
            checked(igi_import::read_nerfstudio(p))
        }),
        t("exif", "in.jpg", setup_exif, run_exif),
        t("control", "control/points.csv", setup_control, run_control),
        t("slf", "slf/bundle.bin", setup_slf, run_slf),
        t("hull", "hull/bundle.bin", setup_hull, run_hull),
    ]
}

/// The target named `name`.
pub fn target(name: &str) -> Result<Target, FuzzError> {
    let all = targets();
    let names: Vec<&str> = all.iter().map(|t| t.name).collect();
    let names = names.join(", ");
    all.into_iter()
        .find(|t| t.name == name)
        .ok_or_else(|| FuzzError::UnknownTarget(name.to_string(), names))
}

fn run_image(p: &Path) -> Result<(), String> {
    checked(igi_imaging::read_image(p))
}

fn run_board(p: &Path) -> Result<(), String> {
    igi_probe::board::BoardSpec::load(p).map_err(|e| e.to_string())?;
    checked(igi_probe::board::Board::load(p))
}

fn read(p: &Path) -> Result<Vec<u8>, String> {
    std::fs::read(p).map_err(|e| format!("{}: {e}", p.display()))
}

fn write(p: &Path, b: &[u8]) -> Result<(), String> {
    if let Some(d) = p.parent() {
        std::fs::create_dir_all(d).map_err(|e| format!("{}: {e}", d.display()))?;
    }
    std::fs::write(p, b).map_err(|e| format!("{}: {e}", p.display()))
}

fn small_image(w: usize, h: usize, masked: bool) -> igi_imaging::HdrImage {
    let mut im = igi_imaging::HdrImage::new(w, h);
    for (i, p) in im.pixels.iter_mut().enumerate() {
        *p = [i as f32 * 0.25, 1.0 / (1 + i) as f32, 1e3 * (i % 3) as f32];
    }
    if masked {
        im.valid[1] = false;
    }
    im
}

fn setup_ply(fx: &Path, work: &Path) -> Result<Vec<Vec<u8>>, String> {
    let mut seeds = Vec::new();
    for f in [
        "outdoor/ground.ply",
        "outdoor/wall.ply",
        "outdoor/colonnade.ply",
    ] {
        seeds.push(read(&fx.join(f))?);
    }
    seeds.push(b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nproperty float u\nproperty float v\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0 0 0\n1 0 0 1 0\n0 1 0 0 1\n3 0 1 2\n".to_vec());
    let _ = work;
    Ok(seeds)
}

fn setup_obj(fx: &Path, work: &Path) -> Result<Vec<Vec<u8>>, String> {
    let mut seeds = Vec::new();
    for f in ["outdoor/ground.ply", "outdoor/wall.ply"] {
        let m = igi_geometry::read_ply(&fx.join(f)).map_err(|e| e.to_string())?;
        let p = work.join("seed.obj");
        igi_geometry::write_obj(&p, &m).map_err(|e| e.to_string())?;
        seeds.push(read(&p)?);
    }
    seeds.push(b"# quad with uvs and normals, negative indices\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\nf -4/-4/1 -3/-3/1 -2/-2/1 -1/-1/1\ng part\nf 1 2 3\n".to_vec());
    Ok(seeds)
}

fn setup_exr(fx: &Path, work: &Path) -> Result<Vec<Vec<u8>>, String> {
    let mut seeds = vec![read(&fx.join("outdoor/sky.exr"))?];
    for (i, (w, h, m)) in [(6, 4, true), (3, 2, false)].into_iter().enumerate() {
        let p = work.join(format!("seed{i}.exr"));
        igi_imaging::write_exr(&p, &small_image(w, h, m)).map_err(|e| e.to_string())?;
        seeds.push(read(&p)?);
    }
    Ok(seeds)
}

fn setup_hdr(_fx: &Path, work: &Path) -> Result<Vec<Vec<u8>>, String> {
    let mut seeds = Vec::new();
    for (i, (w, h)) in [(16, 4), (4, 3)].into_iter().enumerate() {
        let p = work.join(format!("seed{i}.hdr"));
        igi_imaging::write_hdr(&p, &small_image(w, h, false)).map_err(|e| e.to_string())?;
        seeds.push(read(&p)?);
    }
    Ok(seeds)
}

fn setup_camera(fx: &Path, _work: &Path) -> Result<Vec<Vec<u8>>, String> {
    [
        "outdoor/camera.json",
        "survey/cameras/v00-sunny.json",
        "board/sunny/camera.json",
    ]
    .iter()
    .map(|f| read(&fx.join(f)))
    .collect()
}

/// Small stand-ins for the sky maps the fixture lighting files name (a fuzz execution reads
/// a 8x4 map, not a 60 kB one).
fn write_skies(dir: &Path) -> Result<(), String> {
    for n in [
        "sky.exr",
        "sunny_sky.exr",
        "lowsun_sky.exr",
        "overcast_sky.exr",
    ] {
        std::fs::create_dir_all(dir).map_err(|e| e.to_string())?;
        igi_imaging::write_exr(&dir.join(n), &small_image(8, 4, false))
            .map_err(|e| e.to_string())?;
    }
    Ok(())
}

fn setup_lighting(fx: &Path, work: &Path) -> Result<Vec<Vec<u8>>, String> {
    write_skies(&work.join("light"))?;
    [
        "outdoor/lighting.toml",
        "survey/lighting/sunny.toml",
        "survey/lighting/overcast.toml",
        "survey/heldout/lighting.toml",
    ]
    .iter()
    .map(|f| read(&fx.join(f)))
    .collect()
}

fn setup_scene(fx: &Path, work: &Path) -> Result<Vec<Vec<u8>>, String> {
    let dir = work.join("scene");
    write_skies(&dir)?;
    for f in ["ground.ply", "wall.ply", "colonnade.ply", "lighting.toml"] {
        write(&dir.join(f), &read(&fx.join("outdoor").join(f))?)?;
    }
    // an albedo texture: every texel in [0, 1] (the scene reader refuses more)
    let mut albedo = small_image(4, 4, false);
    for p in &mut albedo.pixels {
        *p = p.map(|c| c / (1.0 + c));
    }
    igi_imaging::write_exr(&dir.join("wall_albedo.exr"), &albedo).map_err(|e| e.to_string())?;
    Ok(vec![read(&fx.join("outdoor/scene.toml"))?])
}

fn setup_survey(fx: &Path, work: &Path) -> Result<Vec<Vec<u8>>, String> {
    // Survey::load checks that the named files exist and reads none: empty stand-ins will do
    let dir = work.join("survey");
    for sub in ["geometry", "photos", "cameras", "lighting"] {
        let from = fx.join("survey").join(sub);
        for e in std::fs::read_dir(&from).map_err(|e| format!("{}: {e}", from.display()))? {
            let e = e.map_err(|e| e.to_string())?;
            write(&dir.join(sub).join(e.file_name()), b"")?;
        }
    }
    let text = read(&fx.join("survey/survey.toml"))?;
    let mut with_brdf = text.clone();
    with_brdf.extend_from_slice(b"\n[brdf]\nsamples = \"geometry/ground.ply\"\n");
    Ok(vec![text, with_brdf])
}

fn setup_board(fx: &Path, _work: &Path) -> Result<Vec<Vec<u8>>, String> {
    ["board/sunny/board.json", "board/cloudy/board.json"]
        .iter()
        .map(|f| read(&fx.join(f)))
        .collect()
}

fn setup_brdf(fx: &Path, _work: &Path) -> Result<Vec<Vec<u8>>, String> {
    let text = read(&fx.join("brdf/samples.csv"))?;
    // the first 40 lines: a whole file per execution stays cheap
    let head: Vec<u8> = text
        .split(|&b| b == b'\n')
        .take(40)
        .collect::<Vec<_>>()
        .join(&b'\n');
    Ok(vec![head, text])
}

/// Separates the files of a COLMAP model in one fuzz input (`cameras`, `images`, `points3D`, in
/// that order; a missing part is a missing file).
const SPLIT: &[u8] = b"\n@@igi-fuzz-next-file@@\n";

/// Splits a fuzz input at [`SPLIT`].
fn split_bundle(data: &[u8]) -> Vec<&[u8]> {
    let mut parts = Vec::new();
    let mut rest = data;
    while let Some(i) = rest.windows(SPLIT.len()).position(|w| w == SPLIT) {
        parts.push(&rest[..i]);
        rest = &rest[i + SPLIT.len()..];
    }
    parts.push(rest);
    parts
}

/// A COLMAP sparse folder from a bundle of its files (`ext`: `txt` or `bin`), read whole and
/// turned into contract cameras as `igi import colmap` does.
fn run_colmap(p: &Path, ext: &str) -> Result<(), String> {
    let dir = p.with_extension("d");
    let names = ["cameras", "images", "points3D"].map(|n| format!("{n}.{ext}"));
    unbundle(&read(p)?, &dir, &names)?;
    checked(igi_import::read_cameras(
        igi_import::ModelFormat::Colmap,
        &dir,
    ))
}

/// Writes the parts of bundle `data` into `dir`, part i as `names[i]`; a name without a part
/// is removed (left by an earlier execution).
fn unbundle(data: &[u8], dir: &Path, names: &[impl AsRef<str>]) -> Result<(), String> {
    let parts = split_bundle(data);
    for (i, name) in names.iter().enumerate() {
        let f = dir.join(name.as_ref());
        match parts.get(i) {
            Some(b) => write(&f, b)?,
            None => {
                let _ = std::fs::remove_file(&f);
            }
        }
    }
    Ok(())
}

/// Panics (a crash the fuzzer keeps) when a render holds a value that is not finite.
fn assert_finite(image: &igi_imaging::HdrImage, alpha: &[f32]) {
    let bad = image
        .pixels
        .iter()
        .flatten()
        .chain(alpha)
        .find(|v| !v.is_finite());
    assert!(bad.is_none(), "the render holds {bad:?}");
}

fn bundle(parts: &[Vec<u8>]) -> Vec<u8> {
    parts.join(SPLIT)
}

fn setup_colmap_bin(fx: &Path, _work: &Path) -> Result<Vec<Vec<u8>>, String> {
    let dir = fx.join("import/pycolmap/sparse");
    let files: Vec<Vec<u8>> = ["cameras.bin", "images.bin", "points3D.bin"]
        .iter()
        .map(|f| read(&dir.join(f)))
        .collect::<Result<_, _>>()?;
    Ok(vec![bundle(&files), bundle(&files[..2])])
}

fn setup_colmap_txt(fx: &Path, _work: &Path) -> Result<Vec<Vec<u8>>, String> {
    let (model, _) =
        igi_import::read_model(&fx.join("import/pycolmap/sparse")).map_err(|e| e.to_string())?;
    let files: Vec<Vec<u8>> = igi_import::text::to_text(&model)
        .into_iter()
        .map(String::into_bytes)
        .collect();
    Ok(vec![bundle(&files), bundle(&files[..2])])
}

fn setup_metashape(fx: &Path, _work: &Path) -> Result<Vec<Vec<u8>>, String> {
    Ok(vec![read(&fx.join("import/metashape/cameras.xml"))?])
}

fn setup_nerfstudio(fx: &Path, work: &Path) -> Result<Vec<Vec<u8>>, String> {
    std::fs::create_dir_all(work.join("ns")).map_err(|e| e.to_string())?;
    Ok(vec![read(&fx.join("import/nerfstudio/transforms.json"))?])
}

/// A photo's EXIF as `igi import` reads it: the fields, the instant they name, the exposure.
fn run_exif(p: &Path) -> Result<(), String> {
    let e = igi_imaging::exif::read_exif(p).map_err(|e| e.to_string())?;
    let _ = e.exposure();
    checked(igi_formats::PhotoTime::from_photo_exif(&e))
}

/// A little-endian TIFF/EXIF block: IFD0 pointing at an Exif IFD (DateTimeOriginal,
/// OffsetTimeOriginal, ExposureTime, FNumber, ISO) and a GPS IFD (date and time stamps).
fn exif_tiff() -> Vec<u8> {
    // (tag, type, count, value bytes); type 2 ASCII, 3 SHORT, 4 LONG, 5 RATIONAL
    type Entry = (u16, u16, u32, Vec<u8>);
    let rational = |v: &[(u32, u32)]| -> Vec<u8> {
        v.iter()
            .flat_map(|(n, d)| n.to_le_bytes().into_iter().chain(d.to_le_bytes()))
            .collect()
    };
    let ascii = |s: &str| -> (u32, Vec<u8>) {
        let mut b = s.as_bytes().to_vec();
        b.push(0);
        (b.len() as u32, b)
    };
    // IFD layout: 2-byte count, 12 bytes per entry, 4-byte next offset, then the values
    fn ifd(start: u32, entries: &[Entry]) -> Vec<u8> {
        let mut out = (entries.len() as u16).to_le_bytes().to_vec();
        let mut data = Vec::new();
        let data_at = start + 2 + 12 * entries.len() as u32 + 4;
        for (tag, ty, count, v) in entries {
            out.extend_from_slice(&tag.to_le_bytes());
            out.extend_from_slice(&ty.to_le_bytes());
            out.extend_from_slice(&count.to_le_bytes());
            if v.len() <= 4 {
                let mut w = v.clone();
                w.resize(4, 0);
                out.extend_from_slice(&w);
            } else {
                out.extend_from_slice(&(data_at + data.len() as u32).to_le_bytes());
                data.extend_from_slice(v);
                if data.len() % 2 == 1 {
                    data.push(0);
                }
            }
        }
        out.extend_from_slice(&0u32.to_le_bytes());
        out.extend_from_slice(&data);
        out
    }
    let (n_dt, dt) = ascii("2026:06:21 09:30:00");
    let (n_off, off) = ascii("+03:00");
    let exif_entries: Vec<Entry> = vec![
        (0x829a, 5, 1, rational(&[(1, 250)])),
        (0x829d, 5, 1, rational(&[(56, 10)])),
        (0x8827, 3, 1, 200u16.to_le_bytes().to_vec()),
        (0x9003, 2, n_dt, dt),
        (0x9011, 2, n_off, off),
    ];
    let (n_gd, gd) = ascii("2026:06:21");
    let gps_entries: Vec<Entry> = vec![
        (0x0007, 5, 3, rational(&[(6, 1), (30, 1), (0, 1)])),
        (0x001d, 2, n_gd, gd),
    ];
    // IFD0 at 8 with two pointers; its size is 2 + 2 * 12 + 4 = 30
    let exif_at = 8 + 30;
    let exif = ifd(exif_at, &exif_entries);
    let gps_at = exif_at + exif.len() as u32;
    let gps = ifd(gps_at, &gps_entries);
    let ifd0 = ifd(
        8,
        &[
            (0x8769, 4, 1, exif_at.to_le_bytes().to_vec()),
            (0x8825, 4, 1, gps_at.to_le_bytes().to_vec()),
        ],
    );
    let mut t = b"II*\0".to_vec();
    t.extend_from_slice(&8u32.to_le_bytes());
    t.extend(ifd0);
    t.extend(exif);
    t.extend(gps);
    t
}

/// A JPEG holding only its APP1 `Exif` segment (enough for an EXIF reader).
fn exif_jpeg(tiff: &[u8]) -> Vec<u8> {
    let mut j = vec![0xff, 0xd8, 0xff, 0xe1];
    j.extend_from_slice(&((tiff.len() + 8) as u16).to_be_bytes());
    j.extend_from_slice(b"Exif\0\0");
    j.extend_from_slice(tiff);
    j.extend_from_slice(&[0xff, 0xd9]);
    j
}

/// The start of a real JPEG up to the end of its APP1 `Exif` segment, if it has one.
fn jpeg_head(b: &[u8]) -> Option<Vec<u8>> {
    let mut i = 2;
    while i + 4 <= b.len() && b[i] == 0xff {
        let len = u16::from_be_bytes([b[i + 2], b[i + 3]]) as usize;
        let end = i + 2 + len;
        if b[i + 1] == 0xe1 && b.get(i + 4..i + 10) == Some(b"Exif\0\0") && end <= b.len() {
            let mut head = b[..end].to_vec();
            head.extend_from_slice(&[0xff, 0xd9]);
            return Some(head);
        }
        i = end;
    }
    None
}

/// Seeds: a TIFF and a JPEG written here, and (when `../shared/data` is beside the checkout)
/// the EXIF of two real cameras' JPEGs (a Sony with OffsetTimeOriginal, an iPhone without),
/// read at run time.
fn setup_exif(fx: &Path, _work: &Path) -> Result<Vec<Vec<u8>>, String> {
    let tiff = exif_tiff();
    let mut seeds = vec![exif_jpeg(&tiff), tiff];
    // a Canon CR3's ftyp and moov boxes, its EXIF in Canon's CMT blocks
    seeds.push(read(&fx.join("raw/canon_r6_header.cr3"))?);
    let shared = fx.join("../../../shared/data/mirror_ball_ldr");
    for f in [
        "olapietka_sony_a6400/rec1.jpg",
        "olapietka_sony_a6400/raw2.jpg",
        "uiuc_cs445_kagrawal_iphone7/ball_40.JPG",
    ] {
        if let Some(head) = std::fs::read(shared.join(f))
            .ok()
            .and_then(|b| jpeg_head(&b))
        {
            seeds.push(head);
        }
    }
    Ok(seeds)
}

/// Ground control points as `igi import colmap --control` reads them: the CSV, then the
/// alignment against the survey fixture's cameras (named `vNN.jpg`).
fn run_control(p: &Path) -> Result<(), String> {
    let obs = igi_formats::control::read_control_points(p).map_err(|e| e.to_string())?;
    let dir = p.parent().unwrap_or(Path::new(".")).join("cameras");
    let mut cams = std::collections::HashMap::new();
    for i in 0..3 {
        let c = igi_camera::Camera::load(&dir.join(format!("v{i:02}.json")))
            .map_err(|e| e.to_string())?;
        cams.insert(format!("v{i:02}.jpg"), c);
    }
    checked(igi_import::align::align(
        p,
        &obs,
        &cams,
        igi_import::AlignOptions::default(),
    ))
}

fn setup_control(fx: &Path, work: &Path) -> Result<Vec<Vec<u8>>, String> {
    let names = ["v00-sunny.json", "v01-lowsun.json", "v02-overcast.json"];
    let mut cams = Vec::new();
    for (i, n) in names.iter().enumerate() {
        let b = read(&fx.join("survey/cameras").join(n))?;
        write(&work.join(format!("control/cameras/v{i:02}.json")), &b)?;
        cams.push(
            igi_camera::Camera::load(&fx.join("survey/cameras").join(n))
                .map_err(|e| e.to_string())?,
        );
    }
    // points on and above the survey fixture's site, which lies around the origin
    let mid = glam::DVec3::ZERO;
    let mut rows = String::from("name,x,y,z,image,u,v\n");
    for k in 0..6 {
        let a = k as f64;
        let w = glam::DVec3::new(
            mid.x + (a * 1.3).sin() * 2.0,
            mid.y + (a * 0.7).cos() * 2.0,
            (a * 0.37) % 1.5,
        );
        for (i, c) in cams.iter().enumerate() {
            if let Some(q) = c.project(w).filter(|q| c.in_frame(*q)) {
                rows += &format!(
                    "gcp{k},{},{},{},v{i:02}.jpg,{},{}\n",
                    w.x, w.y, w.z, q.x, q.y
                );
            }
        }
    }
    Ok(vec![rows.into_bytes()])
}

/// The files of a stored surface light field, in the order of an `slf` bundle (a coding's
/// files that another coding does not have are empty parts).
const SLF_FILES: [&str; 9] = [
    "header.json",
    "texels.bin",
    "normals.bin",
    "median.bin",
    "lumispheres.bin",
    "prototypes.bin",
    "coefficients.bin",
    "codebook.bin",
    "indices.bin",
];

/// A stored surface light field from a bundle of [`SLF_FILES`] beside its mesh, loaded as `igi
/// slf render` loads it and rendered through a camera above the mesh. A render with a value
/// that is not finite is a failure (a panic, so the fuzzer keeps the input).
fn run_slf(p: &Path) -> Result<(), String> {
    let dir = p.with_file_name("field");
    unbundle(&read(p)?, &dir, &SLF_FILES)?;
    let (field, mesh) = igi_lightfield::store::load(&dir).map_err(|e| format!("{e:#}"))?;
    let camera = slf_camera()?;
    let (image, alpha) = field
        .render(&mesh, &camera, &Default::default())
        .map_err(|e| e.to_string())?;
    assert_finite(&image, &alpha);
    Ok(())
}

/// A camera 2 units above the fuzz field's triangle, looking down at it at a slant.
fn slf_camera() -> Result<igi_camera::Camera, String> {
    let (eye, at) = (
        glam::DVec3::new(0.3, -0.6, 2.0),
        glam::DVec3::new(0.3, 0.3, 0.0),
    );
    igi_camera::Camera::look_at(eye, at, 16, 16, 60.0).map_err(|e| e.to_string())
}

/// Fields of three points on a 4 x 4 atlas of one triangle, one a coding, saved by
/// `igi_lightfield::store::save`; the seeds are their files as bundles.
fn setup_slf(_fx: &Path, work: &Path) -> Result<Vec<Vec<u8>>, String> {
    use igi_lightfield::{Codebook, Coding, Octahedron, Pfa, SurfaceLightField};
    let n = Octahedron::new(1).len();
    let lumispheres = |count: usize| -> Vec<Vec<glam::Vec3>> {
        (0..count)
            .map(|k| {
                (0..n)
                    .map(|i| glam::Vec3::new(0.1 * k as f32, -0.2 + 0.01 * i as f32, 0.3))
                    .collect()
            })
            .collect()
    };
    let codings = [
        Coding::MedianOnly,
        Coding::Faired(lumispheres(3)),
        Coding::Pfa(Pfa {
            prototypes: lumispheres(3),
            coefficients: vec![vec![0.2, 0.3, 0.5]; 3],
            energy_history: Vec::new(),
        }),
        Coding::Quantized(Codebook {
            codewords: lumispheres(2),
            index: vec![0, 1, 1],
        }),
    ];
    let mesh = igi_geometry::TriMesh {
        positions: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        uvs: Some(vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]),
        indices: vec![[0, 1, 2]],
        ..Default::default()
    };
    std::fs::create_dir_all(work.join("slf")).map_err(|e| e.to_string())?;
    let mut seeds = Vec::new();
    for (k, coding) in codings.into_iter().enumerate() {
        let field = SurfaceLightField::new(
            Octahedron::new(1),
            4,
            vec![0, 5, 15],
            vec![glam::Vec3::new(0.2, 0.3, 0.4); 3],
            vec![glam::Vec3::Z; 3],
            coding,
        )
        .with_gain(igi_lightfield::AngleGain {
            knots: vec![2.0, 1.5, 1.0],
        });
        let dir = work.join(format!("slf/seed{k}"));
        igi_lightfield::store::save(&dir, &field, &mesh, serde_json::Value::Null)
            .map_err(|e| e.to_string())?;
        let parts: Vec<Vec<u8>> = SLF_FILES
            .iter()
            .map(|f| std::fs::read(dir.join(f)).unwrap_or_default())
            .collect();
        seeds.push(bundle(&parts));
    }
    let mesh_ply = read(&work.join("slf/seed0/mesh.ply"))?;
    write(&work.join("slf/field/mesh.ply"), &mesh_ply)?;
    Ok(seeds)
}

/// A hull folder from a bundle of its `hull.json` and `surfels.ply` (the rig it names, with two
/// views, stays as set up), loaded as `igi hull render` loads it and rendered through the first
/// view's camera. A render with a value that is not finite is a failure (a panic).
fn run_hull(p: &Path) -> Result<(), String> {
    let dir = p.with_file_name("folder");
    unbundle(&read(p)?, &dir, &["hull.json", "surfels.ply"])?;
    let model = igi_opacity_hull::build::load_model(&dir).map_err(|e| e.to_string())?;
    let camera =
        igi_camera::Camera::load(&p.with_file_name("rig/v0.json")).map_err(|e| e.to_string())?;
    let (image, alpha) = igi_opacity_hull::render::render(&model, &camera, Default::default());
    assert_finite(&image, &alpha);
    Ok(())
}

/// A rig of two 16 x 16 views around the origin and a hull of 48 surfels on a sphere of radius
/// 0.5 seen by both; the seed is the folder's `hull.json` and `surfels.ply` as a bundle.
fn setup_hull(_fx: &Path, work: &Path) -> Result<Vec<Vec<u8>>, String> {
    let rig = work.join("hull/rig");
    std::fs::create_dir_all(&rig).map_err(|e| e.to_string())?;
    let mut toml = String::from("[object]\nbbox_min = [-1, -1, -1]\nbbox_max = [1, 1, 1]\n");
    for (v, eye) in [[0.0, -3.0, 1.0], [3.0, 0.0, 1.0]].iter().enumerate() {
        let eye = glam::DVec3::from_array(*eye);
        let cam = igi_camera::Camera::look_at(eye, glam::DVec3::ZERO, 16, 16, 40.0)
            .map_err(|e| e.to_string())?;
        cam.save(&rig.join(format!("v{v}.json")))
            .map_err(|e| e.to_string())?;
        igi_imaging::write_exr(&rig.join(format!("v{v}.exr")), &small_image(16, 16, false))
            .map_err(|e| e.to_string())?;
        toml += &format!("[[view]]\nid = \"v{v}\"\ncamera = \"v{v}.json\"\nphoto = \"v{v}.exr\"\n");
    }
    write(&rig.join("rig.toml"), toml.as_bytes())?;
    let n = 48;
    let normals: Vec<[f32; 3]> = (0..n)
        .map(|i| {
            let (z, phi) = (1.0 - (2 * i + 1) as f32 / n as f32, 2.4 * i as f32);
            let r = (1.0 - z * z).sqrt();
            [r * phi.cos(), r * phi.sin(), z]
        })
        .collect();
    let surfels = igi_opacity_hull::surfel::Surfels {
        positions: normals.iter().map(|d| d.map(|x| 0.5 * x)).collect(),
        normals: normals.clone(),
        radius: vec![0.08; n],
        area: vec![0.02; n],
        views: 2,
        visible: vec![true; 2 * n],
        opacity: (0..2 * n).map(|k| (k % 5) as f32 / 4.0).collect(),
    };
    let ply = work.join("hull/seed.ply");
    igi_geometry::write_points_ply(&ply, &surfels.to_cloud()).map_err(|e| e.to_string())?;
    // relative to the folder `run_hull` unbundles into (hull/folder), as `igi hull build`
    // writes it: the seed, and so every mutation, is the same in any work folder
    let manifest = igi_opacity_hull::build::Manifest {
        rig: PathBuf::from("../rig/rig.toml"),
        views: vec!["v0".into(), "v1".into()],
        bbox_min: [-1.0; 3],
        bbox_max: [1.0; 3],
        resolution: 256,
        surfels: n,
    };
    let json = serde_json::to_vec_pretty(&manifest).map_err(|e| e.to_string())?;
    Ok(vec![bundle(&[json, read(&ply)?])])
}

const TOKENS: [&[u8]; 29] = [
    b"0",
    b"-1",
    b"1e30",
    b"-1e30",
    b"nan",
    b"NaN",
    b"inf",
    b"-inf",
    b"4294967296",
    b"18446744073709551616",
    b"18446744073709551615",
    b"4611686018427387904",
    b"9223372036854775807",
    b"2147483647",
    b"1e-45",
    b"\"\"",
    b"[]",
    b"{}",
    b"null",
    b"999999999",
    b"0.0",
    b"\n",
    b",",
    b"#",
    b"[[",
    b"]]",
    b"=",
    "\u{feff}".as_bytes(),
    b"1e308",
];

/// The leading [`TOKENS`] that are numbers (what [`replace_number`] puts in a number's place).
const NUMBER_TOKENS: usize = 15;

const WORDS: [u32; 7] = [0, 1, 0x7fff_ffff, 0x8000_0000, 0xffff_ffff, 1 << 30, 65536];

/// One to four random edits of `data` (length capped at 1 MiB).
pub fn mutate(rng: &mut Pcg64, data: &mut Vec<u8>, corpus: &[Vec<u8>]) {
    for _ in 0..rng.gen_range(1..=4) {
        let n = data.len();
        let at = if n == 0 { 0 } else { rng.gen_range(0..n) };
        match rng.gen_range(0..10) {
            0 if n > 0 => data[at] ^= 1 << rng.gen_range(0..8),
            1 if n > 0 => data[at] = rng.gen(),
            2 => {
                let k = rng.gen_range(1..=8);
                for _ in 0..k {
                    data.insert(at, rng.gen());
                }
            }
            3 if n > 0 => {
                let end = (at + rng.gen_range(1..=16)).min(n);
                data.drain(at..end);
            }
            4 if n > 0 => {
                let end = (at + rng.gen_range(1..=64)).min(n);
                let piece = data[at..end].to_vec();
                let to = rng.gen_range(0..=data.len());
                data.splice(to..to, piece);
            }
            5 if n > 0 => data.truncate(at),
            6 if !corpus.is_empty() => {
                let other = &corpus[rng.gen_range(0..corpus.len())];
                if !other.is_empty() {
                    let from = rng.gen_range(0..other.len());
                    let end = (from + rng.gen_range(1..=256)).min(other.len());
                    data.truncate(at);
                    data.extend_from_slice(&other[from..end]);
                }
            }
            7 => replace_number(rng, data),
            8 => {
                let t = TOKENS[rng.gen_range(0..TOKENS.len())];
                data.splice(at..at, t.iter().copied());
            }
            _ if n >= 4 => {
                let w = WORDS[rng.gen_range(0..WORDS.len())].to_le_bytes();
                let at = rng.gen_range(0..=n - 4);
                data[at..at + 4].copy_from_slice(&w);
            }
            _ => data.push(rng.gen()),
        }
    }
    data.truncate(1 << 20);
}

/// Replaces one run of digits (a number in a text format) by an extreme token.
fn replace_number(rng: &mut Pcg64, data: &mut Vec<u8>) {
    let starts: Vec<usize> = (0..data.len())
        .filter(|&i| data[i].is_ascii_digit() && (i == 0 || !data[i - 1].is_ascii_digit()))
        .collect();
    if starts.is_empty() {
        return;
    }
    let s = starts[rng.gen_range(0..starts.len())];
    let mut e = s;
    while e < data.len()
        && (data[e].is_ascii_digit() || data[e] == b'.' || data[e] == b'e' || data[e] == b'-')
    {
        e += 1;
    }
    let t = TOKENS[rng.gen_range(0..NUMBER_TOKENS)];
    data.splice(s..e, t.iter().copied());
}

/// What the executions of one target came to.
#[derive(Clone, Debug, Default)]
pub struct Stats {
    pub target: String,
    pub executions: u64,
    pub accepted: u64,
    pub errors: u64,
    /// Panics (each input saved in the crash folder).
    pub crashes: u64,
    /// Executions over the time limit.
    pub hangs: u64,
    /// Executions whose peak heap exceeded the memory limit.
    pub over_memory: u64,
    pub slowest_ms: f64,
    pub peak_bytes: usize,
    pub corpus: usize,
    pub wall_s: f64,
}

/// Limits and places of a fuzz run.
pub struct Config {
    pub executions: u64,
    pub seed: u64,
    pub fixtures: PathBuf,
    pub work: PathBuf,
    pub crashes: PathBuf,
    pub time_limit_ms: f64,
    pub memory_limit: usize,
}

fn signature(msg: &str) -> String {
    let s: String = msg.chars().filter(|c| !c.is_ascii_digit()).collect();
    let s = s.rsplit(": ").take(3).collect::<Vec<_>>().join("|");
    s.chars().take(120).collect()
}

/// Fuzzes one target (see the crate overview).
pub fn fuzz(t: &Target, cfg: &Config) -> Result<Stats, FuzzError> {
    let work = cfg.work.join(t.name);
    std::fs::create_dir_all(&work).map_err(io(&work))?;
    std::fs::create_dir_all(&cfg.crashes).map_err(io(&cfg.crashes))?;
    let mut corpus = (t.setup)(&cfg.fixtures, &work).map_err(|msg| FuzzError::Setup {
        target: t.name.into(),
        msg,
    })?;
    let input = work.join(t.input);
    let mut seen = HashSet::new();
    let mut rng = Pcg64::seed_from_u64(cfg.seed);
    let mut st = Stats {
        target: t.name.to_string(),
        ..Stats::default()
    };
    let prev_hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let t0 = Instant::now();
    for i in 0..cfg.executions {
        let mut data = corpus[rng.gen_range(0..corpus.len())].clone();
        // the first executions run the seeds themselves
        if i >= corpus.len() as u64 || i > 16 {
            mutate(&mut rng, &mut data, &corpus);
        }
        let Execution {
            result: r,
            ms,
            peak,
        } = execute(t, &input, &data)?;
        st.executions += 1;
        st.slowest_ms = st.slowest_ms.max(ms);
        st.peak_bytes = st.peak_bytes.max(peak);
        if ms > cfg.time_limit_ms {
            st.hangs += 1;
            save(&cfg.crashes, t, "hang", st.hangs, &data)?;
        }
        if peak > cfg.memory_limit {
            st.over_memory += 1;
            save(&cfg.crashes, t, "memory", st.over_memory, &data)?;
        }
        let sig = match r {
            Ok(Ok(())) => {
                st.accepted += 1;
                "ok".to_string()
            }
            Ok(Err(msg)) => {
                st.errors += 1;
                signature(&msg)
            }
            Err(_) => {
                st.crashes += 1;
                save(&cfg.crashes, t, "crash", st.crashes, &data)?;
                "panic".to_string()
            }
        };
        if seen.insert(sig) && corpus.len() < 1024 {
            corpus.push(data);
        }
    }
    std::panic::set_hook(prev_hook);
    st.corpus = corpus.len();
    st.wall_s = t0.elapsed().as_secs_f64();
    Ok(st)
}

/// One run of a parser: its result (`Err` for a panic), time and peak heap above the start.
pub struct Execution {
    pub result: std::thread::Result<Result<(), String>>,
    pub ms: f64,
    pub peak: usize,
}

/// Writes `data` to the target's `input` file and runs the parser on it once.
fn execute(t: &Target, input: &Path, data: &[u8]) -> Result<Execution, FuzzError> {
    std::fs::write(input, data).map_err(io(input))?;
    PEAK.store(LIVE.load(Ordering::Relaxed), Ordering::Relaxed);
    let base = LIVE.load(Ordering::Relaxed);
    let ti = Instant::now();
    let result = std::panic::catch_unwind(AssertUnwindSafe(|| (t.run)(input)));
    Ok(Execution {
        result,
        ms: ti.elapsed().as_secs_f64() * 1e3,
        peak: PEAK.load(Ordering::Relaxed).saturating_sub(base),
    })
}

/// Runs target `t` once on the saved input `file` (a crash, hang or memory case), in a work
/// folder prepared as [`fuzz`] prepares it, so that a finding can be reproduced and debugged.
pub fn replay(t: &Target, cfg: &Config, file: &Path) -> Result<Execution, FuzzError> {
    let work = cfg.work.join(t.name);
    std::fs::create_dir_all(&work).map_err(io(&work))?;
    (t.setup)(&cfg.fixtures, &work).map_err(|msg| FuzzError::Setup {
        target: t.name.into(),
        msg,
    })?;
    let data = std::fs::read(file).map_err(io(file))?;
    execute(t, &work.join(t.input), &data)
}

fn save(dir: &Path, t: &Target, kind: &str, n: u64, data: &[u8]) -> Result<(), FuzzError> {
    if n > 20 {
        return Ok(());
    }
    let ext = t.input.rsplit('.').next().unwrap_or("bin");
    let p = dir.join(format!("{}-{kind}-{n}.{ext}", t.name));
    std::fs::write(&p, data).map_err(io(&p))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mutations_are_deterministic_per_seed_and_bounded() {
        let seed = b"ply\nformat ascii 1.0\nelement vertex 3\n0 0 0\n".to_vec();
        let run = |s: u64| {
            let mut rng = Pcg64::seed_from_u64(s);
            let mut d = seed.clone();
            for _ in 0..200 {
                mutate(&mut rng, &mut d, std::slice::from_ref(&seed));
            }
            d
        };
        assert_eq!(run(3), run(3));
        assert_ne!(run(3), run(4));
        assert!(run(5).len() < 1 << 20);
    }

    #[test]
    fn signatures_ignore_numbers() {
        assert_eq!(
            signature("x.ply: line 12: bad"),
            signature("x.ply: line 7: bad")
        );
        assert_ne!(signature("x.ply: bad header"), signature("x.ply: bad face"));
    }
}
