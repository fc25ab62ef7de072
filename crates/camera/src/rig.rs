//! The multi-view capture file `rig.toml` (FORMATS.md, "Multi-view capture"), shared by the
//! opacity-hull and surface-light-field pipelines.
//!
//! [`Rig::load`] parses the file, resolves every path relative to the folder of the rig file,
//! and validates what can be checked without reading images: a finite, non-empty bounding box,
//! unique non-empty view ids, matting entries with `n = +-1` and a positive `lambda`, light
//! directions that are finite and non-zero (normalised on load). Every error names the rig
//! file and, where it concerns one view, the view's id. [`Rig::load_cameras`] loads and checks
//! each view's camera; [`Rig::save`] writes the file back with paths relative to its folder
//! where they lie below it.

use crate::{Camera, CameraError};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// `[object]`: a box that surely contains the object (world frame, metres).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RigObject {
    pub bbox_min: [f64; 3],
    pub bbox_max: [f64; 3],
}

/// One matting capture of a view: the backdrop pattern alone and the object in front of it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BackdropPair {
    /// Pattern wavelength in pixels (Eq. 1 of Matusik et al. 2002).
    pub lambda: f64,
    /// Pattern sign, +1 or -1.
    pub n: i32,
    pub backdrop: PathBuf,
    pub object: PathBuf,
}

/// One reflectance-field capture: the object lit by one distant light of unit irradiance.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LightImage {
    /// Unit vector from the object toward the light (world frame); normalised on load.
    pub direction: [f64; 3],
    pub image: PathBuf,
}

/// One `[[view]]`: a camera pose and the images taken from it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RigView {
    pub id: String,
    pub camera: PathBuf,
    pub photo: PathBuf,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mask: Option<PathBuf>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub backdrops: Vec<BackdropPair>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub lights: Vec<LightImage>,
}

/// A multi-view capture. After [`Rig::load`] every path is resolved (joined to the rig file's
/// folder when relative) and `path` is the rig file itself.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Rig {
    pub object: RigObject,
    #[serde(rename = "view", default)]
    pub views: Vec<RigView>,
    /// The file this rig was read from (not part of the TOML).
    #[serde(skip)]
    pub path: PathBuf,
}

impl Rig {
    /// Read, resolve and validate a rig file.
    pub fn load(path: &Path) -> Result<Rig, CameraError> {
        let text = std::fs::read_to_string(path).map_err(|e| CameraError::io(path, e))?;
        Self::from_toml_str(&text, path)
    }

    /// Parse rig TOML text as if read from `path` (relative paths resolve against its folder).
    pub fn from_toml_str(text: &str, path: &Path) -> Result<Rig, CameraError> {
        let mut rig: Rig = toml::from_str(text).map_err(|source| CameraError::RigSyntax {
            path: path.to_path_buf(),
            source: Box::new(source),
        })?;
        rig.path = path.to_path_buf();
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        for v in &mut rig.views {
            resolve_view(v, &base);
        }
        rig.validate()?;
        Ok(rig)
    }

    fn validate(&mut self) -> Result<(), CameraError> {
        let (lo, hi) = (self.object.bbox_min, self.object.bbox_max);
        if lo.iter().chain(&hi).any(|x| !x.is_finite()) || (0..3).any(|k| !(lo[k] < hi[k])) {
            return Err(rig_error(
                &self.path,
                format!("[object] bbox_min {lo:?} must be below bbox_max {hi:?} on every axis"),
            ));
        }
        let mut seen = std::collections::HashSet::new();
        for v in &mut self.views {
            let err = |msg: String| CameraError::RigView {
                path: self.path.clone(),
                view: v.id.clone(),
                msg,
            };
            if v.id.trim().is_empty() {
                return Err(err("empty view id".into()));
            }
            if !seen.insert(v.id.clone()) {
                return Err(err("view id used twice".into()));
            }
            for b in &v.backdrops {
                if !(b.n == 1 || b.n == -1) || !(b.lambda > 0.0 && b.lambda.is_finite()) {
                    return Err(err(format!(
                        "backdrop entry lambda = {}, n = {}: n must be 1 or -1 and lambda positive",
                        b.lambda, b.n
                    )));
                }
            }
            for l in &mut v.lights {
                let d = glam::DVec3::from_array(l.direction);
                if !d.is_finite() || d.length() < 1e-12 {
                    return Err(err(format!(
                        "light direction {:?} is not a non-zero vector",
                        l.direction
                    )));
                }
                l.direction = d.normalize().to_array();
            }
        }
        Ok(())
    }

    /// Fail unless the rig has at least `n` views.
    pub fn require_views(&self, n: usize) -> Result<(), CameraError> {
        if self.views.len() < n {
            return Err(rig_error(
                &self.path,
                format!("{} view(s); at least {n} are needed", self.views.len()),
            ));
        }
        Ok(())
    }

    /// The view with this id.
    pub fn view(&self, id: &str) -> Option<&RigView> {
        self.views.iter().find(|v| v.id == id)
    }

    /// Load and validate every view's camera (in view order). Errors name the rig and the view.
    pub fn load_cameras(&self) -> Result<Vec<Camera>, CameraError> {
        self.views.iter().map(|v| self.load_camera(v)).collect()
    }

    /// Load one view's camera; an error names the rig file and the view.
    pub fn load_camera(&self, view: &RigView) -> Result<Camera, CameraError> {
        Camera::load(&view.camera).map_err(|e| self.view_error(view, e))
    }

    /// Wrap an error about one of `view`'s files so that it names the rig file and the view.
    pub fn view_error(&self, view: &RigView, source: impl Into<CameraError>) -> CameraError {
        CameraError::RigViewFile {
            path: self.path.clone(),
            view: view.id.clone(),
            source: Box::new(source.into()),
        }
    }

    /// An error about `view` that is not about one file (sizes that disagree, ...).
    pub fn view_message(&self, view: &RigView, msg: impl Into<String>) -> CameraError {
        CameraError::RigView {
            path: self.path.clone(),
            view: view.id.clone(),
            msg: msg.into(),
        }
    }

    /// TOML text with every path written relative to `dir` where it lies below it.
    pub fn to_toml_string(&self, dir: &Path) -> String {
        let mut out = self.clone();
        for v in &mut out.views {
            v.for_each_path(|p| {
                if let Ok(r) = p.strip_prefix(dir) {
                    *p = r.to_path_buf();
                }
            });
        }
        toml::to_string(&out).expect("rig serialises")
    }

    /// Write the rig to `path` atomically (paths relative to its folder where possible).
    pub fn save(&self, path: &Path) -> Result<(), CameraError> {
        let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        Ok(igi_files::write_text_atomic(
            path,
            &self.to_toml_string(&dir),
        )?)
    }
}

fn rig_error(path: &Path, msg: String) -> CameraError {
    CameraError::Rig {
        path: path.to_path_buf(),
        msg,
    }
}

fn resolve_view(v: &mut RigView, base: &Path) {
    v.for_each_path(|p| {
        if p.is_relative() {
            *p = base.join(&*p);
        }
    });
}

impl RigView {
    /// Calls `f` on every file path of the view (camera, photo, mask, backdrops, lights).
    fn for_each_path(&mut self, mut f: impl FnMut(&mut PathBuf)) {
        f(&mut self.camera);
        f(&mut self.photo);
        if let Some(m) = &mut self.mask {
            f(m);
        }
        for b in &mut self.backdrops {
            f(&mut b.backdrop);
            f(&mut b.object);
        }
        for l in &mut self.lights {
            f(&mut l.image);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TEXT: &str = r#"
[object]
bbox_min = [-1, -1, 0]
bbox_max = [1, 1, 2]

[[view]]
id = "cam0"
camera = "cameras/cam0.json"
photo = "photos/cam0.exr"
mask = "/abs/mask0.png"
backdrops = [ { lambda = 27, n = 1, backdrop = "bg/27p.exr", object = "obj/27p.exr" } ]
lights = [ { direction = [0, 0, 2], image = "lit/L0.exr" } ]

[[view]]
id = "cam1"
camera = "cameras/cam1.json"
photo = "photos/cam1.png"
"#;

    #[test]
    fn paths_resolve_against_the_rig_folder_and_round_trip() {
        let rig = Rig::from_toml_str(TEXT, Path::new("/data/cap/rig.toml")).unwrap();
        assert_eq!(rig.views.len(), 2);
        let v = &rig.views[0];
        assert_eq!(v.camera, Path::new("/data/cap/cameras/cam0.json"));
        assert_eq!(v.mask.as_deref(), Some(Path::new("/abs/mask0.png")));
        assert_eq!(v.backdrops[0].object, Path::new("/data/cap/obj/27p.exr"));
        assert_eq!(v.lights[0].direction, [0.0, 0.0, 1.0]);
        assert!(rig.views[1].backdrops.is_empty() && rig.views[1].mask.is_none());
        let text = rig.to_toml_string(Path::new("/data/cap"));
        assert!(
            text.contains("\"cameras/cam0.json\"") && text.contains("/abs/mask0.png"),
            "{text}"
        );
        let again = Rig::from_toml_str(&text, Path::new("/data/cap/rig.toml")).unwrap();
        assert_eq!(again, rig);
    }

    #[test]
    fn errors_name_the_file_and_the_view() {
        let p = Path::new("/x/rig.toml");
        let e = Rig::from_toml_str(&TEXT.replace("n = 1", "n = 2"), p)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("/x/rig.toml") && e.contains("cam0") && e.contains("n must be 1 or -1"),
            "{e}"
        );
        let e = Rig::from_toml_str(&TEXT.replace("id = \"cam1\"", "id = \"cam0\""), p)
            .unwrap_err()
            .to_string();
        assert!(e.contains("cam0") && e.contains("used twice"), "{e}");
        let e = Rig::from_toml_str(&TEXT.replace("[1, 1, 2]", "[1, -1, 2]"), p)
            .unwrap_err()
            .to_string();
        assert!(e.contains("/x/rig.toml") && e.contains("bbox_min"), "{e}");
        let e = Rig::from_toml_str(&TEXT.replace("photo = \"photos/cam1.png\"", ""), p)
            .unwrap_err()
            .to_string();
        assert!(e.contains("/x/rig.toml") && e.contains("photo"), "{e}");
        let rig = Rig::from_toml_str(TEXT, p).unwrap();
        let e = rig.require_views(3).unwrap_err().to_string();
        assert!(e.contains("2 view(s)") && e.contains("at least 3"), "{e}");
        let e = rig.load_cameras().unwrap_err().to_string();
        assert!(
            e.contains("/x/rig.toml") && e.contains("cam0") && e.contains("/x/cameras/cam0.json"),
            "{e}"
        );
    }
}
