//! The multi-view capture file `rig.toml` (FORMATS.md, "Multi-view capture"), shared by the
//! opacity-hull and surface-light-field pipelines.
//!
//! [`Rig::load`] reads the file through `igi_formats::rig::RigFile` (which checks what can be
//! checked without reading images: a finite, non-empty bounding box, unique non-empty view ids,
//! matting entries with `n = +-1` and a positive `lambda`, light directions that are finite and
//! non-zero), resolves every path relative to the folder of the rig file and normalises the
//! light directions. Every error names the rig file and, where it concerns one view, the view's
//! id. [`Rig::load_cameras`] loads and checks
//! each view's camera; [`Rig::save`] writes the file back with paths relative to its folder
//! where they lie below it.

use crate::{Camera, CameraError};
use igi_formats::rig::RigFile;
use igi_formats::FormatsError;
use std::path::{Path, PathBuf};

pub use igi_formats::rig::{BackdropPair, LightImage, RigObject, RigView};

/// A multi-view capture. After [`Rig::load`] every path is resolved (joined to the rig file's
/// folder when relative), every light direction is a unit vector, and `path` is the rig file
/// itself.
#[derive(Clone, Debug, PartialEq)]
pub struct Rig {
    pub object: RigObject,
    pub views: Vec<RigView>,
    /// The file this rig was read from.
    pub path: PathBuf,
}

impl Rig {
    /// Read, check and resolve a rig file (read and checked by `igi_formats::rig`).
    pub fn load(path: &Path) -> Result<Rig, CameraError> {
        Ok(Self::from_file(RigFile::read(path)?, path))
    }

    /// Parse rig TOML text as if read from `path` (relative paths resolve against its folder).
    pub fn from_toml_str(text: &str, path: &Path) -> Result<Rig, CameraError> {
        let file = RigFile::parse(text).map_err(|problem| FormatsError::Rig {
            path: path.to_path_buf(),
            problem: Box::new(problem),
        })?;
        Ok(Self::from_file(file, path))
    }

    /// The rig a (checked) rig file read from `path` describes: paths joined to the file's
    /// folder when relative, light directions normalised.
    pub fn from_file(file: RigFile, path: &Path) -> Rig {
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        let mut views = file.views;
        for v in &mut views {
            v.for_each_path(|p| {
                if p.is_relative() {
                    *p = base.join(&*p);
                }
            });
            for l in &mut v.lights {
                l.direction = glam::DVec3::from_array(l.direction).normalize().to_array();
            }
        }
        Rig {
            object: file.object,
            views,
            path: path.to_path_buf(),
        }
    }

    /// The rig file of this rig, every path written relative to `dir` where it lies below it.
    pub fn to_file(&self, dir: &Path) -> RigFile {
        let mut views = self.views.clone();
        for v in &mut views {
            v.for_each_path(|p| {
                if let Ok(r) = p.strip_prefix(dir) {
                    *p = r.to_path_buf();
                }
            });
        }
        RigFile {
            object: self.object.clone(),
            views,
        }
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
        self.to_file(dir).to_toml().expect("rig serialises")
    }

    /// Write the rig to `path` atomically (paths relative to its folder where possible).
    pub fn save(&self, path: &Path) -> Result<(), CameraError> {
        let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        Ok(self.to_file(&dir).write(path)?)
    }
}

fn rig_error(path: &Path, msg: String) -> CameraError {
    CameraError::Rig {
        path: path.to_path_buf(),
        msg,
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
