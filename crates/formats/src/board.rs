//! The lighting-capture board file (JSON; docs/FORMATS.md, "Board file"): the spheres of the
//! board, each with its kind, centre (camera frame, or board frame with fiducials) and radius,
//! optional calibration (`ior`, `reflectance`), and the optional ArUco fiducials that place a
//! board-frame board in the photograph (docs/PROBE.md).
//!
//! ```json
//! { "spheres": [
//!     { "kind": "mirror",  "center": [-0.1, 0.0, 0.6], "radius": 0.07 },
//!     { "kind": "black",   "center": [ 0.1, 0.0, 0.6], "radius": 0.07, "ior": 1.5 },
//!     { "kind": "diffuse", "center": [ 0.0, 0.1, 0.6], "radius": 0.07,
//!       "reflectance": [0.30, 0.31, 0.32] } ] }
//! ```
//! Unknown keys are refused. The values are checked where the board is built (`igi-probe`).

use crate::{FileKind, FormatsError};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// What a sphere is made of.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SphereKind {
    Mirror,
    Black,
    Diffuse,
}

impl SphereKind {
    /// The kind stored at index `i` (`SphereKind as usize`: mirror 0, black 1, diffuse 2).
    pub fn from_index(i: usize) -> SphereKind {
        [SphereKind::Mirror, SphereKind::Black, SphereKind::Diffuse][i]
    }

    /// The name the file uses.
    pub fn name(self) -> &'static str {
        match self {
            SphereKind::Mirror => "mirror",
            SphereKind::Black => "black",
            SphereKind::Diffuse => "diffuse",
        }
    }
}

/// One entry of `spheres`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SphereEntry {
    pub kind: SphereKind,
    /// Centre in the photograph's camera frame (metres, OpenCV: z forward).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub center: Option<[f64; 3]>,
    /// Centre in the board frame (placed by the fiducials).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub center_board: Option<[f64; 3]>,
    pub radius: f64,
    /// The diffuse sphere's paint reflectance per channel.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reflectance: Option<[f64; 3]>,
    /// The mirror's complex index `[[n, k]; 3]` or the black coat's real index: kept as JSON so
    /// that each shape gets its own message where it is checked.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ior: Option<serde_json::Value>,
}

/// One ArUco marker: its id and its four corners in the board frame (the dictionary's order).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MarkerEntry {
    pub id: i32,
    pub corners: [[f64; 3]; 4],
}

/// `fiducials`: an ArUco dictionary name and the markers.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FiducialsSection {
    pub dictionary: String,
    pub markers: Vec<MarkerEntry>,
}

/// A board file as written.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoardFile {
    pub spheres: Vec<SphereEntry>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fiducials: Option<FiducialsSection>,
}

impl BoardFile {
    /// Reads and parses the board file at `path`.
    pub fn read(path: &Path) -> Result<BoardFile, FormatsError> {
        let text = std::fs::read_to_string(path).map_err(|source| FormatsError::Read {
            path: path.to_path_buf(),
            kind: FileKind::Board,
            source,
        })?;
        BoardFile::from_json_str(&text, path)
    }

    /// Parses board JSON; `path` names the file in errors.
    pub fn from_json_str(text: &str, path: &Path) -> Result<BoardFile, FormatsError> {
        serde_json::from_str(text).map_err(|source| FormatsError::ParseJson {
            path: path.to_path_buf(),
            kind: FileKind::Board,
            source: Box::new(source),
        })
    }

    /// The file's text (pretty JSON).
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a board serialises")
    }

    /// Writes the file atomically.
    pub fn write(&self, path: &Path) -> Result<(), FormatsError> {
        igi_files::write_text_atomic(path, &self.to_json())
            .map_err(|e| FormatsError::Write(Box::new(e)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_the_documented_example_and_writes_it_back() {
        let text = r#"{ "spheres": [
            { "kind": "mirror", "center": [-0.1, 0.0, 0.6], "radius": 0.07, "ior": [[2.5, 3.0], [2.4, 3.1], [2.3, 3.2]] },
            { "kind": "black", "center_board": [0.1, 0.0, 0.0], "radius": 0.07, "ior": 1.5 },
            { "kind": "diffuse", "center": [0.0, 0.1, 0.6], "radius": 0.07, "reflectance": [0.3, 0.31, 0.32] } ],
          "fiducials": { "dictionary": "DICT_4X4_50", "markers": [
            { "id": 3, "corners": [[0, 0, 0], [0.05, 0, 0], [0.05, 0.05, 0], [0, 0.05, 0]] } ] } }"#;
        let b = BoardFile::from_json_str(text, Path::new("b.json")).unwrap();
        assert_eq!(b.spheres[1].kind, SphereKind::Black);
        assert_eq!(b.spheres[1].center_board, Some([0.1, 0.0, 0.0]));
        assert_eq!(b.spheres[2].reflectance, Some([0.3, 0.31, 0.32]));
        assert_eq!(b.fiducials.as_ref().unwrap().markers[0].id, 3);
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("board.json");
        b.write(&p).unwrap();
        assert_eq!(BoardFile::read(&p).unwrap(), b);
    }

    #[test]
    fn refuses_unknown_keys_and_kinds_naming_the_file() {
        for (text, want) in [
            (
                r#"{"spheres":[{"kind":"chrome","radius":1}]}"#,
                "unknown variant",
            ),
            (
                r#"{"spheres":[{"kind":"mirror","radius":1,"colour":1}]}"#,
                "unknown field",
            ),
            (r#"{"sphere":[]}"#, "unknown field"),
        ] {
            let e = BoardFile::from_json_str(text, Path::new("b.json"))
                .unwrap_err()
                .to_string();
            assert!(
                e.contains("b.json") && e.contains("board file") && e.contains(want),
                "{e}"
            );
        }
    }
}
