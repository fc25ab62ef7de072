//! The multi-view capture file `rig.toml` (FORMATS.md, "Multi-view capture"), shared by the
//! opacity-hull and surface-light-field pipelines: a box around the object and the views, each
//! a camera file, a photograph and optionally a mask, matting pairs and light images. Parsed and
//! checked here with paths as written; `igi_camera::Rig` resolves them against the file's folder
//! and loads the cameras.

use crate::{FileKind, FormatsError};
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
    /// Vector from the object toward the light (world frame); `igi_camera::Rig` normalises it.
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

impl RigView {
    /// Calls `f` on every file path of the view (camera, photo, mask, backdrops, lights).
    pub fn for_each_path(&mut self, mut f: impl FnMut(&mut PathBuf)) {
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

/// A `rig.toml` as written (paths as written, light directions as written).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RigFile {
    pub object: RigObject,
    #[serde(rename = "view", default)]
    pub views: Vec<RigView>,
}

/// Why a rig file cannot be used; [`FormatsError::Rig`] names the file.
#[derive(Debug, thiserror::Error)]
pub enum RigProblem {
    /// The text is not the TOML of a rig (a missing key, a wrong type, an unknown key).
    #[error("{0}")]
    Syntax(Box<toml::de::Error>),
    #[error("[object] bbox_min {lo:?} must be below bbox_max {hi:?} on every axis")]
    Bounds { lo: [f64; 3], hi: [f64; 3] },
    #[error("view {view:?}: empty view id")]
    EmptyId { view: String },
    #[error("view {view:?}: view id used twice")]
    DuplicateId { view: String },
    #[error("view {view:?}: backdrop entry lambda = {lambda}, n = {n}: n must be 1 or -1 and lambda positive")]
    Backdrop { view: String, lambda: f64, n: i32 },
    #[error("view {view:?}: light direction {direction:?} is not a non-zero vector")]
    LightDirection { view: String, direction: [f64; 3] },
}

/// Whether `d` can give a light's direction once normalised: finite and not (near) zero.
pub fn is_light_direction(d: [f64; 3]) -> bool {
    let d = glam::DVec3::from_array(d);
    d.is_finite() && d.length() >= 1e-12
}

impl RigFile {
    /// The rig in TOML `text`, checked ([`check`](Self::check)); no path is resolved.
    pub fn parse(text: &str) -> Result<RigFile, RigProblem> {
        let rig: RigFile = toml::from_str(text).map_err(|e| RigProblem::Syntax(Box::new(e)))?;
        rig.check()?;
        Ok(rig)
    }

    /// What can be checked without reading images: a finite, non-empty bounding box, unique
    /// non-empty view ids, matting entries with `n = +-1` and a positive `lambda`, light
    /// directions that are finite and non-zero.
    pub fn check(&self) -> Result<(), RigProblem> {
        let (lo, hi) = (self.object.bbox_min, self.object.bbox_max);
        if lo.iter().chain(&hi).any(|x| !x.is_finite()) || (0..3).any(|k| !(lo[k] < hi[k])) {
            return Err(RigProblem::Bounds { lo, hi });
        }
        let mut seen = std::collections::HashSet::new();
        for v in &self.views {
            let view = || v.id.clone();
            if v.id.trim().is_empty() {
                return Err(RigProblem::EmptyId { view: view() });
            }
            if !seen.insert(v.id.as_str()) {
                return Err(RigProblem::DuplicateId { view: view() });
            }
            for b in &v.backdrops {
                if !(b.n == 1 || b.n == -1) || !(b.lambda > 0.0 && b.lambda.is_finite()) {
                    return Err(RigProblem::Backdrop {
                        view: view(),
                        lambda: b.lambda,
                        n: b.n,
                    });
                }
            }
            for l in &v.lights {
                if !is_light_direction(l.direction) {
                    return Err(RigProblem::LightDirection {
                        view: view(),
                        direction: l.direction,
                    });
                }
            }
        }
        Ok(())
    }

    /// Reads and checks the file at `path` (every error names it).
    pub fn read(path: &Path) -> Result<RigFile, FormatsError> {
        let text = std::fs::read_to_string(path).map_err(|source| FormatsError::Open {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(&text).map_err(|problem| FormatsError::Rig {
            path: path.to_path_buf(),
            problem: Box::new(problem),
        })
    }

    /// The file's text (tables in field order, paths as they are).
    pub fn to_toml(&self) -> Result<String, toml::ser::Error> {
        toml::to_string(self)
    }

    /// Writes the file atomically.
    pub fn write(&self, path: &Path) -> Result<(), FormatsError> {
        let text = self.to_toml().map_err(|source| FormatsError::Serialize {
            path: path.to_path_buf(),
            kind: FileKind::Rig,
            source: Box::new(source),
        })?;
        igi_files::write_text_atomic(path, &text).map_err(|e| FormatsError::Write(Box::new(e)))
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
lights = [ { direction = [0, 0, 2], image = "lit/L0.exr" } ]
"#;

    #[test]
    fn parse_check_and_write() {
        let rig = RigFile::parse(TEXT).unwrap();
        assert_eq!(rig.views[0].camera, Path::new("cameras/cam0.json"));
        assert_eq!(rig.views[0].lights[0].direction, [0.0, 0.0, 2.0]);
        assert_eq!(RigFile::parse(&rig.to_toml().unwrap()).unwrap(), rig);
        for (bad, says) in [
            (TEXT.replace("[1, 1, 2]", "[1, -1, 2]"), "bbox_min"),
            (TEXT.replace("\"cam0\"", "\" \""), "empty view id"),
            (
                TEXT.replace("[0, 0, 2]", "[0, 0, 0]"),
                "view \"cam0\": light direction",
            ),
            (TEXT.replace("photo = \"photos/cam0.exr\"", ""), "photo"),
        ] {
            let e = RigFile::parse(&bad).unwrap_err().to_string();
            assert!(e.contains(says), "{e}");
        }
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("rig.toml");
        assert!(RigFile::read(&p).is_err());
        rig.write(&p).unwrap();
        assert_eq!(RigFile::read(&p).unwrap(), rig);
        std::fs::write(
            &p,
            TEXT.replace("cam0\"\ncamera", "cam0\"\nid = \"x\"\ncamera"),
        )
        .unwrap();
        let e = RigFile::read(&p).unwrap_err().to_string();
        assert!(e.starts_with(&format!("{}: ", p.display())), "{e}");
    }
}
