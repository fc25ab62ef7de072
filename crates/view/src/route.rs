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

/// The served folder and what the page loads from it.
pub struct Site {
    /// The folder, canonical.
    pub root: PathBuf,
    scene_json: Vec<u8>,
    scene_glb: Vec<u8>,
}

impl Site {
    /// Check that `dir` is a result folder and make its glTF scene.
    pub fn open(dir: &Path, lights: &[crate::light::PageLight]) -> Result<Site, ViewError> {
        let root = dir.canonicalize().map_err(|source| ViewError::Folder {
            dir: dir.to_path_buf(),
            source,
        })?;
        if !(root.join("report.json").is_file() && root.join("parts").is_dir()) {
            return Err(ViewError::NotViewable {
                dir: dir.to_path_buf(),
            });
        }
        let scene_glb = result_glb(&root)?;
        let name = root
            .file_name()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
        let scene_json = serde_json::json!({
            "kind": "result",
            "name": name,
            "scene": "/igi/scene.glb",
            "lightings": lights,
        });
        Ok(Site {
            root,
            scene_json: serde_json::to_vec_pretty(&scene_json).expect("JSON"),
            scene_glb,
        })
    }
}

/// The result as `igi export --format gltf` writes it (exported into a temporary folder, read,
/// removed).
fn result_glb(root: &Path) -> Result<Vec<u8>, ViewError> {
    let tmp = std::env::temp_dir().join(format!("igi-view-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    let glb = tmp.join("scene.glb");
    let bytes = igi_export::export(root, igi_export::ExportFormat::Gltf, &tmp)
        .map_err(ViewError::from)
        .and_then(|_| {
            std::fs::read(&glb).map_err(|source| ViewError::Folder {
                dir: glb.clone(),
                source,
            })
        });
    let _ = std::fs::remove_dir_all(&tmp);
    bytes
}

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
    match path {
        "/" | "/index.html" => Reply::ok("text/html; charset=utf-8", PAGE.as_bytes().to_vec()),
        "/igi/scene.json" => Reply::ok("application/json", site.scene_json.clone()),
        "/igi/scene.glb" => Reply::ok("model/gltf-binary", site.scene_glb.clone()),
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

#[cfg(test)]
mod tests {
    use super::*;

    fn site(root: &Path) -> Site {
        Site {
            root: root.canonicalize().unwrap(),
            scene_json: b"{}".to_vec(),
            scene_glb: b"glTF".to_vec(),
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
        let told = respond(&s, "GET", "/igi/event?title=igi%3A%20ready");
        assert_eq!(told.event.as_deref(), Some("title=igi: ready"));
    }
}
