//! The answer to one request, without sockets: what the server sends for a method and a URL.

use crate::ViewError;
use std::path::{Component, Path, PathBuf};

/// An HTTP answer.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Reply {
    pub status: u16,
    pub content_type: &'static str,
    pub body: Vec<u8>,
    /// What the page told the server (`/igi/event?...`: its title as it changes, its frame
    /// time), decoded, for the command to print.
    pub event: Option<String>,
}

impl Reply {
    fn ok(content_type: &'static str, body: Vec<u8>) -> Reply {
        Reply {
            status: 200,
            content_type,
            body,
            event: None,
        }
    }

    fn error(status: u16, text: &str) -> Reply {
        Reply {
            status,
            content_type: "text/plain; charset=utf-8",
            body: format!("{status}: {text}\n").into_bytes(),
            event: None,
        }
    }
}

/// What the page is offered besides the folder.
#[derive(Default)]
pub struct Extras {
    /// Lighting files (`--lighting`), as the page lights with them.
    pub lights: Vec<crate::light::PageLight>,
    /// Where the sun and sky of a date and time are computed (`/igi/sky?time=...`).
    pub sky_place: Option<igi_sky::job::Place>,
    /// The survey's photographs, overlaid from their capture cameras (`/igi/photo/K.png`).
    pub photos: Option<crate::photo::PagePhotos>,
    /// Cameras to look through (`--camera`), as [`crate::photo::cameras_json`] gives them.
    pub cameras: serde_json::Value,
}

impl Extras {
    /// The fields of `scene.json` that say what the extras offer.
    fn add_to(&self, scene: &mut serde_json::Value) {
        scene["lightings"] = serde_json::to_value(&self.lights).expect("JSON");
        scene["sky"] = self.sky_place.is_some().into();
        scene["photos"] = self
            .photos
            .as_ref()
            .map_or_else(|| serde_json::json!([]), |p| p.json());
        scene["cameras"] = match &self.cameras {
            serde_json::Value::Null => serde_json::json!([]),
            c => c.clone(),
        };
    }
}

/// The served folder and what the page loads from it.
pub struct Site {
    /// The folder, canonical.
    pub root: PathBuf,
    scene_json: Vec<u8>,
    scene_glb: Vec<u8>,
    /// Per part of a result, its standard-error picture (PNG; `/igi/stderr/K.png`).
    stderr_png: Vec<Vec<u8>>,
    /// A prepared site's 3D Tiles, made in memory (`/igi/tiles/NAME`: `tileset.json` and the
    /// GLBs it names); empty otherwise.
    tiles: Vec<(String, Vec<u8>)>,
    /// A light field's tables for its view-dependent colour (`/igi/slf.bin`, `slf`); empty
    /// otherwise.
    slf_bin: Vec<u8>,
    extras: Extras,
}

impl Site {
    /// Check that `dir` is a result, hull or light-field folder and make its glTF scene.
    pub fn open(dir: &Path, extras: Extras) -> Result<Site, ViewError> {
        let root = dir.canonicalize().map_err(|source| ViewError::Folder {
            dir: dir.to_path_buf(),
            source,
        })?;
        let name = root
            .file_name()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
        if let Some(site) = Site::tiled(&root, &name, &extras)? {
            return Ok(Site { extras, ..site });
        }
        let glb = igi_export::folder_glb(&root).map_err(|e| match e {
            igi_export::ExportError::NotExportable { .. } => ViewError::NotViewable {
                dir: dir.to_path_buf(),
            },
            e => ViewError::Export(e),
        })?;
        let (parts, stderr_png) = match &glb.result {
            Some(r) => (parts_json(&r.materials), r.stderr_png.clone()),
            None => (Vec::new(), Vec::new()),
        };
        let mut scene_json = serde_json::json!({
            "kind": glb.kind.name(),
            "name": name,
            "scene": "/igi/scene.glb",
            "summary": glb.summary,
            "parts": parts,
            "stderr_white": igi_export::STDERR_PICTURE_MAX,
        });
        extras.add_to(&mut scene_json);
        let mut slf_bin = Vec::new();
        if let Some((field, scale)) = &glb.light_field {
            let page = crate::slf::page_field(field, *scale);
            scene_json["slf"] = page.json;
            scene_json["slf"]["url"] = "/igi/slf.bin".into();
            slf_bin = page.bin;
        }
        Ok(Site {
            root,
            scene_json: serde_json::to_vec_pretty(&scene_json).expect("JSON"),
            scene_glb: glb.bytes,
            stderr_png,
            tiles: Vec::new(),
            slf_bin,
            extras,
        })
    }

    /// A folder shown as 3D Tiles: an export of `igi export --format gltf` holding
    /// `tileset.json` (its files served under `/files/`), or a result of a prepared site (its
    /// tiles made in memory as `igi export` writes them, served under `/igi/tiles/`).
    fn tiled(root: &Path, name: &str, extras: &Extras) -> Result<Option<Site>, ViewError> {
        let scene = |tileset: &str, summary: Vec<String>, parts: Vec<serde_json::Value>| {
            let mut v = serde_json::json!({
                "kind": "tiles",
                "name": name,
                "tileset": tileset,
                "summary": summary,
                "parts": parts,
                "stderr_white": igi_export::STDERR_PICTURE_MAX,
            });
            extras.add_to(&mut v);
            serde_json::to_vec_pretty(&v).expect("JSON")
        };
        let site = |scene_json, stderr_png, tiles| Site {
            root: root.to_path_buf(),
            scene_json,
            scene_glb: Vec::new(),
            stderr_png,
            tiles,
            slf_bin: Vec::new(),
            extras: Extras::default(),
        };
        if root.join(igi_export::tiles::TILESET).is_file() {
            let summary = vec!["3D Tiles export".to_string()];
            let json = scene("/files/tileset.json", summary, Vec::new());
            return Ok(Some(site(json, Vec::new(), Vec::new())));
        }
        if igi_export::folder_kind(root).ok() != Some(igi_export::FolderKind::Result)
            || !igi_export::tiles::result_needs_tiles(root)?
        {
            return Ok(None);
        }
        let (set, mut files) = igi_export::result_tiles(root)?;
        let parts = parts_json(&set.materials);
        let summary = vec![format!(
            "{} parts, {} tiles",
            set.materials.len(),
            set.tiles
        )];
        files.push((
            igi_export::tiles::TILESET.to_string(),
            serde_json::to_vec_pretty(&set.tileset).expect("JSON"),
        ));
        let json = scene("/igi/tiles/tileset.json", summary, parts);
        Ok(Some(site(json, set.stderr_png, files)))
    }
}

/// The page's light at an RFC 3339 time: `igi sky`'s lighting file for the site (written into
/// a temporary folder by `igi_sky::job::write_sky`, with a 64 x 32 map, turbidity 3, ground
/// albedo 0.2) read as `--lighting` reads it, with the sun's azimuth and elevation.
pub fn sky_light(place: &igi_sky::job::Place, time: &str) -> Result<serde_json::Value, String> {
    use std::sync::atomic::{AtomicUsize, Ordering};
    static N: AtomicUsize = AtomicUsize::new(0);
    let tmp = std::env::temp_dir().join(format!(
        "igi-view-sky-{}-{}",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    ));
    std::fs::create_dir_all(&tmp).map_err(|e| format!("{}: {e}", tmp.display()))?;
    let req = igi_sky::job::SkyRequest {
        place: place.clone(),
        time: time.to_string(),
        turbidity: SKY_TURBIDITY,
        albedo: SKY_GROUND_ALBEDO,
        width: SKY_MAP_WIDTH,
        overcast: false,
        zenith_radiance: None,
        output: tmp.join("sky.toml"),
    };
    let got = igi_sky::job::write_sky(&req)
        .map_err(|e| e.to_string())
        .and_then(|report| {
            let mut l = crate::light::page_light(&req.output).map_err(|e| e.to_string())?;
            l.name = format!("sky at {}", report.time_utc);
            let mut v = serde_json::to_value(&l).map_err(|e| e.to_string())?;
            v["sun_azimuth_deg"] = report.sun_azimuth_deg.into();
            v["sun_elevation_deg"] = report.sun_elevation_deg.into();
            v["time_utc"] = report.time_utc.into();
            Ok(v)
        });
    let _ = std::fs::remove_dir_all(&tmp);
    got
}

/// The sky of `/igi/sky`: its map's width (as `igi sky --width`), turbidity and ground albedo.
pub const SKY_MAP_WIDTH: usize = 64;
pub const SKY_TURBIDITY: f64 = 3.0;
pub const SKY_GROUND_ALBEDO: f64 = 0.2;

const PAGE: &str = include_str!("../assets/index.html");
const THREE: &[(&str, &str)] = &[
    (
        "/three/three.module.min.js",
        include_str!("../assets/three/three.module.min.js"),
    ),
    (
        "/three/addons/controls/OrbitControls.js",
        include_str!("../assets/three/addons/controls/OrbitControls.js"),
    ),
    (
        "/three/addons/controls/FlyControls.js",
        include_str!("../assets/three/addons/controls/FlyControls.js"),
    ),
    (
        "/three/addons/loaders/GLTFLoader.js",
        include_str!("../assets/three/addons/loaders/GLTFLoader.js"),
    ),
    (
        "/three/addons/utils/BufferGeometryUtils.js",
        include_str!("../assets/three/addons/utils/BufferGeometryUtils.js"),
    ),
    ("/three/LICENSE", include_str!("../assets/three/LICENSE")),
];

/// The answer to `method url` (GET and HEAD; HEAD gets GET's headers, the server drops the body).
pub fn respond(site: &Site, method: &str, url: &str) -> Reply {
    if method != "GET" && method != "HEAD" {
        return Reply::error(405, "only GET and HEAD");
    }
    let path = url.split(['?', '#']).next().unwrap_or("/");
    if path == "/igi/event" {
        let query = url.split_once('?').map_or("", |(_, q)| q);
        let text = percent_decode(&query.replace('+', " ")).unwrap_or_default();
        let text: String = text.chars().filter(|c| !c.is_control()).take(500).collect();
        return Reply {
            event: Some(text),
            ..Reply::ok("text/plain; charset=utf-8", Vec::new())
        };
    }
    if path == "/igi/sky" {
        let Some(place) = &site.extras.sky_place else {
            return Reply::error(
                404,
                "no site: start igi view with --survey or --site for the sky of a date and time",
            );
        };
        let query = url.split_once('?').map_or("", |(_, q)| q);
        let time = query
            .split('&')
            .find_map(|kv| kv.strip_prefix("time="))
            .and_then(percent_decode)
            .unwrap_or_default();
        return match sky_light(place, &time) {
            Ok(v) => Reply::ok("application/json", serde_json::to_vec(&v).expect("JSON")),
            Err(e) => Reply::error(400, &e),
        };
    }
    if let Some(k) = path
        .strip_prefix("/igi/photo/")
        .and_then(|f| f.strip_suffix(".png"))
    {
        let photos = site.extras.photos.as_ref();
        return match k.parse::<usize>().ok().and_then(|k| photos?.png(k)) {
            Some(Ok(png)) => Reply::ok("image/png", png),
            Some(Err(e)) => Reply::error(500, &e),
            None => Reply::error(404, "not found (igi view --survey offers the photographs)"),
        };
    }
    if let Some(k) = path
        .strip_prefix("/igi/stderr/")
        .and_then(|f| f.strip_suffix(".png"))
    {
        return match k.parse::<usize>().ok().and_then(|k| site.stderr_png.get(k)) {
            Some(png) => Reply::ok("image/png", png.clone()),
            None => Reply::error(404, "not found"),
        };
    }
    if let Some(f) = path.strip_prefix("/igi/tiles/") {
        return match site.tiles.iter().find(|(n, _)| n == f) {
            Some((n, bytes)) => Reply::ok(content_type(Path::new(n)), bytes.clone()),
            None => Reply::error(404, "not found"),
        };
    }
    match path {
        "/" | "/index.html" => Reply::ok("text/html; charset=utf-8", PAGE.as_bytes().to_vec()),
        "/igi/scene.json" => Reply::ok("application/json", site.scene_json.clone()),
        "/igi/scene.glb" => Reply::ok("model/gltf-binary", site.scene_glb.clone()),
        "/igi/slf.bin" if !site.slf_bin.is_empty() => {
            Reply::ok("application/octet-stream", site.slf_bin.clone())
        }
        _ => {
            if let Some((_, js)) = THREE.iter().find(|(p, _)| *p == path) {
                let kind = if path.ends_with(".js") {
                    "text/javascript; charset=utf-8"
                } else {
                    "text/plain; charset=utf-8"
                };
                return Reply::ok(kind, js.as_bytes().to_vec());
            }
            match path.strip_prefix("/files/") {
                Some(rel) => folder_file(&site.root, rel),
                None => Reply::error(404, "not found"),
            }
        }
    }
}

/// A file under `root` named by the URL path `rel` (percent-decoded), never outside it.
fn folder_file(root: &Path, rel: &str) -> Reply {
    let Some(rel) = percent_decode(rel) else {
        return Reply::error(400, "bad percent-encoding");
    };
    let rel = Path::new(&rel);
    if rel.components().any(|c| !matches!(c, Component::Normal(_))) {
        return Reply::error(403, "outside the served folder");
    }
    let Ok(full) = root.join(rel).canonicalize() else {
        return Reply::error(404, "not found");
    };
    if !full.starts_with(root) {
        return Reply::error(403, "outside the served folder");
    }
    match std::fs::read(&full) {
        Ok(body) => Reply::ok(content_type(&full), body),
        Err(_) => Reply::error(404, "not found"),
    }
}

fn content_type(path: &Path) -> &'static str {
    match path.extension().and_then(|e| e.to_str()) {
        Some("json") => "application/json",
        Some("png") => "image/png",
        Some("jpg") | Some("jpeg") => "image/jpeg",
        Some("exr") => "image/x-exr",
        Some("glb") => "model/gltf-binary",
        Some("toml") | Some("txt") | Some("csv") => "text/plain; charset=utf-8",
        _ => "application/octet-stream",
    }
}

/// `%XX` escapes decoded (UTF-8), or `None` when malformed.
fn percent_decode(s: &str) -> Option<String> {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' {
            let hex = std::str::from_utf8(b.get(i + 1..i + 3)?).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

/// The page's description of each part's material: its glTF fit of the lobes and the route of
/// its standard-error picture.
fn parts_json(materials: &[(String, usize, igi_export::GltfFit)]) -> Vec<serde_json::Value> {
    materials
        .iter()
        .enumerate()
        .map(|(k, (name, lobes, fit))| {
            serde_json::json!({
                "name": name,
                "lobes": lobes,
                "roughness": fit.roughness,
                "specular": fit.specular,
                "specular_color": fit.specular_color,
                "fit_rel_rms": fit.rel_rms,
                "stderr": format!("/igi/stderr/{k}.png"),
            })
        })
        .collect()
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    pub(crate) fn site(root: &Path) -> Site {
        Site {
            root: root.canonicalize().unwrap(),
            scene_json: b"{}".to_vec(),
            scene_glb: b"glTF".to_vec(),
            stderr_png: vec![b"png".to_vec()],
            tiles: vec![("a_level0.glb".into(), b"glTF".to_vec())],
            slf_bin: Vec::new(),
            extras: Extras::default(),
        }
    }

    #[test]
    fn only_the_served_folder_is_reachable() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().join("result");
        std::fs::create_dir_all(root.join("parts")).unwrap();
        std::fs::write(root.join("parts/a.json"), b"{\"a\":1}").unwrap();
        std::fs::write(dir.path().join("secret.txt"), b"secret").unwrap();
        #[cfg(unix)]
        std::os::unix::fs::symlink(dir.path().join("secret.txt"), root.join("link.txt")).unwrap();
        let s = site(&root);
        let got = respond(&s, "GET", "/files/parts/a.json");
        assert_eq!((got.status, got.body.as_slice()), (200, &b"{\"a\":1}"[..]));
        assert_eq!(respond(&s, "GET", "/files/parts%2Fa.json").status, 200);
        for bad in [
            "/files/../secret.txt",
            "/files/parts/../../secret.txt",
            "/files/%2e%2e/secret.txt",
            "/files//etc/passwd",
        ] {
            let r = respond(&s, "GET", bad);
            assert_eq!(r.status, 403, "{bad}: {}", String::from_utf8_lossy(&r.body));
        }
        #[cfg(unix)]
        assert_eq!(respond(&s, "GET", "/files/link.txt").status, 403);
        assert_eq!(respond(&s, "GET", "/files/nope.json").status, 404);
        assert_eq!(respond(&s, "GET", "/files/%zz").status, 400);
    }

    #[test]
    fn only_get_and_head_are_answered() {
        let dir = tempfile::tempdir().unwrap();
        let s = site(dir.path());
        for m in ["POST", "PUT", "DELETE", "OPTIONS"] {
            assert_eq!(respond(&s, m, "/").status, 405, "{m}");
        }
        assert_eq!(respond(&s, "HEAD", "/").status, 200);
        let page = respond(&s, "GET", "/?x=1");
        assert!(String::from_utf8_lossy(&page.body).contains("igi: ready"));
        let three = respond(&s, "GET", "/three/three.module.min.js");
        assert_eq!(three.content_type, "text/javascript; charset=utf-8");
        assert!(String::from_utf8_lossy(&three.body).contains("const t=\"170\""));
        assert_eq!(respond(&s, "GET", "/igi/scene.glb").body, b"glTF");
        assert_eq!(respond(&s, "GET", "/igi/stderr/0.png").body, b"png");
        assert_eq!(respond(&s, "GET", "/igi/stderr/1.png").status, 404);
        let tile = respond(&s, "GET", "/igi/tiles/a_level0.glb");
        assert_eq!((tile.status, tile.content_type), (200, "model/gltf-binary"));
        assert_eq!(respond(&s, "GET", "/igi/tiles/b_level0.glb").status, 404);
        assert_eq!(respond(&s, "GET", "/igi/sky?time=x").status, 404);
        assert_eq!(respond(&s, "GET", "/igi/photo/0.png").status, 404);
        assert_eq!(respond(&s, "GET", "/igi/slf.bin").status, 404);
        let told = respond(&s, "GET", "/igi/event?title=igi%3A%20ready");
        assert_eq!(told.event.as_deref(), Some("title=igi: ready"));
    }
}
