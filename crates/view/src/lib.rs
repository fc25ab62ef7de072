//! # igi-view
//!
//! `igi view DIR`: a local web viewer of a solve result, opacity-hull or surface-light-field
//! folder. A small HTTP server
//! (`tiny_http`) on 127.0.0.1 serves
//! * `/`: the page (embedded: `assets/index.html`), which orbits the site, lights it with a sun
//!   whose direction the user sets, and shows the albedo lit or alone; its title becomes
//!   `igi: ready` once the first frame is drawn, `igi: error: ...` if anything fails;
//! * `/three/...`: three.js r170, vendored and embedded (`assets/three`, MIT licence kept);
//! * `/igi/scene.json` (what is shown) and `/igi/scene.glb` (the folder as glTF, made once at
//!   start in memory by `igi_export::folder_glb`, the bytes `igi export --format gltf`
//!   writes); `/igi/stderr/K.png` (part K's standard-error picture);
//! * `/igi/sky?time=RFC3339`: the sun and sky of the site (`--survey` or `--site`) at that
//!   time, as `igi sky` writes them (igi-sky), in the page's terms ([`light::PageLight`]);
//! * `/files/PATH`: the served folder's own files, and nothing outside it (`..`, absolute
//!   paths and links that leave the folder are refused);
//! * `/igi/event?...`: what the page tells the server (its title as it changes, its frame
//!   time), handed to the caller ([`ViewEvent::Page`]; `igi view` prints `page: ...` on
//!   standard error), so scripts and tests learn when the page is ready.
//!
//! Only GET and HEAD are answered (405 otherwise). Everything is checked before the server
//! starts: the folder must be a result, hull or light-field folder, and the port free.

mod error;
pub mod light;
mod route;

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
    /// The site whose sun and sky at a date and time the page may ask for (`/igi/sky`):
    /// a survey's `[site]` or a place given directly, as for `igi sky`.
    pub sky_place: Option<igi_sky::job::Place>,
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
        let site = route::Site::open(&req.dir, &lights, req.sky_place.clone())?;
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
            let header = |k: &str, v: &str| {
                tiny_http::Header::from_bytes(k.as_bytes(), v.as_bytes()).expect("ASCII header")
            };
            let len = reply.body.len();
            let body = if head { Vec::new() } else { reply.body };
            let response = tiny_http::Response::new(
                tiny_http::StatusCode(reply.status),
                vec![
                    header("Content-Type", reply.content_type),
                    header("Cache-Control", "no-store"),
                ],
                std::io::Cursor::new(body),
                Some(len),
                None,
            );
            let url = request.url().to_string();
            // a client that went away is not the server's problem
            match request.respond(response) {
                Ok(()) => tracing::debug!("answered {url}: {} ({len} bytes)", reply.status),
                Err(e) => tracing::debug!("answering {url}: {e}"),
            }
        }
    }
}
