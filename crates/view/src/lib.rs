//! # igi-view
//!
//! `igi view DIR`: a local web viewer of a solve result, opacity-hull or surface-light-field
//! folder. A small HTTP server
//! (`tiny_http`) on 127.0.0.1 serves
//! * `/`: the page (embedded: `assets/index.html`), which orbits or flies through the site,
//!   looks through capture cameras, refines a tileset's levels, lights it with a sun
//!   whose direction the user sets, and shows the albedo lit or alone; its title becomes
//!   `igi: ready` once the first frame is drawn, `igi: error: ...` if anything fails;
//! * `/three/...`: three.js r170, vendored and embedded (`assets/three`, MIT licence kept);
//! * `/igi/scene.json` (what is shown) and `/igi/scene.glb` (the folder as glTF, made once at
//!   start in memory by `igi_export::folder_glb`, the bytes `igi export --format gltf`
//!   writes); `/igi/stderr/K.png` (part K's standard-error picture);
//! * `/igi/sky?time=RFC3339`: the sun and sky of the site (`--survey` or `--site`) at that
//!   time, as `igi sky` writes them (igi-sky), in the page's terms ([`light::PageLight`]);
//! * `/igi/photo/K.png`: photo K of the survey (`--survey`), as the page overlays it from its
//!   capture camera ([`photo`]); cameras to look through come in `scene.json`;
//! * `/igi/slf.bin`: a light field's tables for the page's shader of its view-dependent
//!   colour ([`slf`]);
//! * `/files/PATH`: the served folder's own files, and nothing outside it (`..`, absolute
//!   paths and links that leave the folder are refused);
//! * `/igi/event?...`: what the page tells the server (its title as it changes, its frame
//!   time), handed to the caller ([`ViewEvent::Page`]; `igi view` prints `page: ...` on
//!   standard error), so scripts and tests learn when the page is ready.
//!
//! Every answer closes its connection (`Connection: close`: see `answer` for why). Only GET
//! and HEAD are answered (405 otherwise). Everything is checked before the server
//! starts: the folder must be a result, hull or light-field folder, and the port free.

mod error;
pub mod light;
pub mod photo;
mod route;
pub mod slf;

pub use error::ViewError;
pub use route::{respond, sky_light, Reply};

use std::path::{Path, PathBuf};

/// What `igi view` serves.
#[derive(Clone, Debug)]
pub struct ViewRequest {
    pub dir: PathBuf,
    /// Lighting files the page offers (the survey's, or any contract lighting file).
    pub lightings: Vec<PathBuf>,
    /// The port on 127.0.0.1: `None` tries [`DEFAULT_PORT`], then any free port; a port asked
    /// for that is in use is an error (0: any free port).
    pub port: Option<u16>,
    /// A place given directly (as `igi sky --site`) whose sun and sky at a date and time the
    /// page may ask for (`/igi/sky`).
    pub sky_place: Option<igi_sky::job::Place>,
    /// A survey folder (or its `survey.toml`): its photographs are overlaid from their capture
    /// cameras, and its `[site]`, when it has a location, places the sun and sky of a date and
    /// time (unless `sky_place` is given).
    pub survey: Option<PathBuf>,
    /// Camera files the page may look through (as it looks through a photograph's camera,
    /// without a picture).
    pub cameras: Vec<PathBuf>,
}

/// The port tried first when none is asked for.
pub const DEFAULT_PORT: u16 = 8765;

/// What a running viewer tells its caller.
pub enum ViewEvent<'a> {
    /// The server listens: the page's address.
    Ready(&'a str),
    /// The page said something (`title=igi: ready`, `frame_ms=...`).
    Page(&'a str),
}

/// Check the folder, make its scene, bind the port, tell `on_event` the page's address, then
/// answer requests (telling `on_event` what the page says) until the process ends.
pub fn serve(req: &ViewRequest, on_event: &mut dyn FnMut(ViewEvent)) -> Result<(), ViewError> {
    let viewer = Viewer::bind(req)?;
    on_event(ViewEvent::Ready(&viewer.url()));
    viewer.serve(on_event);
    Ok(())
}

/// A viewer ready to serve: the folder checked, its scene made, the port bound.
pub struct Viewer {
    server: tiny_http::Server,
    site: route::Site,
}

impl Viewer {
    /// Check the folder, make its scene and bind the port.
    pub fn bind(req: &ViewRequest) -> Result<Viewer, ViewError> {
        let lights = req
            .lightings
            .iter()
            .map(|p| light::page_light(p))
            .collect::<Result<Vec<_>, _>>()?;
        let photos = match &req.survey {
            Some(s) => Some(photo::PagePhotos::open(s)?),
            None => None,
        };
        let sky_place = req.sky_place.clone().or_else(|| {
            let survey = req.survey.as_ref()?;
            let has_location = photos.as_ref()?.has_location();
            has_location.then(|| igi_sky::job::Place::Survey {
                path: survey.clone(),
            })
        });
        let extras = route::Extras {
            lights,
            sky_place,
            photos,
            cameras: photo::cameras_json(&req.cameras)?,
        };
        let site = route::Site::open(&req.dir, extras)?;
        let bind = |port: u16| {
            tiny_http::Server::http(("127.0.0.1", port)).map_err(|e| ViewError::Bind {
                port,
                reason: e.to_string(),
            })
        };
        let server = match req.port {
            Some(port) => bind(port)?,
            None => bind(DEFAULT_PORT).or_else(|_| bind(0))?,
        };
        Ok(Viewer { server, site })
    }

    /// The page's address, `http://127.0.0.1:PORT/`.
    pub fn url(&self) -> String {
        let port = self.server.server_addr().to_ip().map_or(0, |a| a.port());
        format!("http://127.0.0.1:{port}/")
    }

    /// The folder served.
    pub fn dir(&self) -> &Path {
        &self.site.root
    }

    /// Answer requests until the process ends; `on_event` hears what the page says.
    pub fn serve(self, on_event: &mut dyn FnMut(ViewEvent)) {
        for request in self.server.incoming_requests() {
            tracing::debug!("{} {}", request.method(), request.url());
            let reply = respond(&self.site, request.method().as_str(), request.url());
            if let Some(text) = &reply.event {
                on_event(ViewEvent::Page(text));
            }
            let head = request.method() == &tiny_http::Method::Head;
            let url = request.url().to_string();
            // a client that went away is not the server's problem
            match answer(request, &reply, head) {
                Ok(()) => tracing::debug!(
                    "answered {url}: {} ({} bytes)",
                    reply.status,
                    reply.body.len()
                ),
                Err(e) => tracing::debug!("answering {url}: {e}"),
            }
        }
    }
}

/// Writes `reply` to `request`'s connection and asks the client to close it
/// (`Connection: close`, which tiny_http's `Response` cannot send).
///
/// tiny_http gives each connection a pool thread for the connection's whole life, and its pool
/// can count a thread it has already woken as idle: a connection accepted in that moment waits
/// in the pool's queue, unread, until another connection ends. A browser keeps its
/// connections open for minutes, so under load a page stalled with a request unread in the
/// socket (docs/VIEW.md). Closing after every answer frees the thread at once.
fn answer(request: tiny_http::Request, reply: &Reply, head: bool) -> std::io::Result<()> {
    use std::io::Write;
    let code = tiny_http::StatusCode(reply.status);
    let mut w = request.into_writer();
    write!(
        w,
        "HTTP/1.1 {} {}\r\nContent-Type: {}\r\nContent-Length: {}\r\nCache-Control: no-store\r\nConnection: close\r\n\r\n",
        reply.status,
        code.default_reason_phrase(),
        reply.content_type,
        reply.body.len()
    )?;
    if !head {
        w.write_all(&reply.body)?;
    }
    w.flush()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::{BufRead, BufReader, Read, Write};
    use std::net::TcpStream;
    use std::time::Duration;

    /// One answer read as a browser reads it: the status, whether the server asked to close
    /// the connection, and the body (by its length).
    fn read_answer(stream: &mut BufReader<TcpStream>) -> (u16, bool, Vec<u8>) {
        let mut line = String::new();
        stream.read_line(&mut line).unwrap();
        let status = line.split(' ').nth(1).unwrap().parse().unwrap();
        let (mut len, mut close) = (0, false);
        loop {
            let mut h = String::new();
            stream.read_line(&mut h).unwrap();
            let h = h.trim_end().to_ascii_lowercase();
            if h.is_empty() {
                break;
            }
            if let Some(v) = h.strip_prefix("content-length:") {
                len = v.trim().parse().unwrap();
            }
            close |= h == "connection: close";
        }
        let mut body = vec![0; len];
        stream.read_exact(&mut body).unwrap();
        (status, close, body)
    }

    /// A browser opens several keep-alive connections at once (chromium: six per host) and
    /// keeps each open until the server says otherwise: every one is answered, and every
    /// answer asks the client to close, so that no connection holds one of tiny_http's pool
    /// threads while another waits unread ([`answer`]).
    #[test]
    fn many_connections_opened_at_once_are_all_answered() {
        let dir = tempfile::tempdir().unwrap();
        let viewer = Viewer {
            server: tiny_http::Server::http("127.0.0.1:0").unwrap(),
            site: route::tests::site(dir.path()),
        };
        let addr = viewer
            .url()
            .trim_start_matches("http://")
            .trim_end_matches('/')
            .to_string();
        std::thread::spawn(move || viewer.serve(&mut |_| {}));
        for round in 0..20 {
            let mut open: Vec<BufReader<TcpStream>> = (0..12)
                .map(|_| {
                    let s = TcpStream::connect(&addr).unwrap();
                    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
                    BufReader::new(s)
                })
                .collect();
            for s in &mut open {
                s.get_mut()
                    .write_all(b"GET /igi/scene.json HTTP/1.1\r\nHost: x\r\n\r\n")
                    .unwrap();
            }
            let mut kept = Vec::new();
            for (k, mut s) in open.into_iter().enumerate() {
                let (status, close, body) = read_answer(&mut s);
                assert_eq!(
                    (status, close, body.as_slice()),
                    (200, true, &b"{}"[..]),
                    "round {round}, connection {k}"
                );
                if !close {
                    kept.push(s); // as a browser does: the connection stays open for reuse
                }
            }
            drop(kept);
        }
    }
}
