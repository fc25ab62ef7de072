//! The camera file (FORMATS.md, JSON): one camera's image size, intrinsics, distortion and
//! world-to-camera pose. Parsed here; checked and built into a camera by `igi-camera`.

use crate::FormatsError;
use std::path::Path;

/// A camera file (FORMATS.md, JSON) as written: the keys of the format, each value kept as
/// JSON so that every problem gets its own message ("width must be a positive integer", "K row
/// 1 must have 3 entries"). `igi_camera::Camera::from_file` checks and builds a
/// camera; `Camera::to_file` is its inverse. `Camera::load` reads and `Camera::save` writes
/// (through [`CameraFile::parse`] and [`CameraFile::write`]).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[allow(non_snake_case)]
pub struct CameraFile {
    pub width: serde_json::Value,
    pub height: serde_json::Value,
    /// `[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`.
    pub K: serde_json::Value,
    /// `[k1, k2, p1, p2, k3]` (or 4 entries, or absent / null for none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dist: Option<serde_json::Value>,
    /// World-to-camera rotation, rows.
    pub R: serde_json::Value,
    /// World-to-camera translation.
    pub t: serde_json::Value,
}

impl CameraFile {
    /// The camera file in JSON `text` (values unchecked: `igi-camera` checks each).
    pub fn parse(text: &str) -> Result<CameraFile, serde_json::Error> {
        serde_json::from_str(text)
    }

    /// The file's text (pretty JSON, keys in the contract's order).
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a camera file serialises")
    }

    /// Writes the file atomically.
    pub fn write(&self, path: &Path) -> Result<(), FormatsError> {
        igi_files::write_text_atomic(path, &self.to_json())
            .map_err(|e| FormatsError::Write(Box::new(e)))
    }
}
