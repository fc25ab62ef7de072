//! The lighting-capture board file of FORMATS.md and the calibration of its spheres.

use crate::ProbeError;
use glam::DVec3;
use std::path::Path;

/// Default reflectance of the diffuse sphere's paint.
pub const DIFFUSE_REFLECTANCE: [f64; 3] = [0.30, 0.31, 0.32];
/// Default complex index (n, k) of the steel mirror sphere, per channel (about 52 % at normal).
pub const MIRROR_IOR: [(f64, f64); 3] = [(2.40, 2.98), (2.40, 3.02), (2.40, 3.02)];
/// Default index of the black sphere's glossy dielectric coat.
pub const BLACK_IOR: f64 = 1.5;

/// What a sphere is made of.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SphereKind {
    Mirror,
    Black,
    Diffuse,
}

impl SphereKind {
    pub fn name(self) -> &'static str {
        match self {
            SphereKind::Mirror => "mirror",
            SphereKind::Black => "black",
            SphereKind::Diffuse => "diffuse",
        }
    }
}

/// Position of one sphere in the camera frame of the board photograph (OpenCV convention).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoardSphere {
    pub center_cam: DVec3,
    pub radius: f64,
}

/// A board: the mirror sphere (required), the black and diffuse spheres (optional, e.g. a
/// lone chrome ball), and their calibration.
#[derive(Clone, Debug, PartialEq)]
pub struct Board {
    pub mirror: BoardSphere,
    pub black: Option<BoardSphere>,
    pub diffuse: Option<BoardSphere>,
    pub mirror_ior: [(f64, f64); 3],
    pub black_ior: f64,
    pub diffuse_reflectance: [f64; 3],
}

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct SphereJson {
    kind: SphereKind,
    center: [f64; 3],
    radius: f64,
    #[serde(default)]
    reflectance: Option<[f64; 3]>,
    #[serde(default)]
    ior: Option<serde_json::Value>,
}

#[derive(serde::Deserialize)]
struct BoardJson {
    spheres: Vec<SphereJson>,
}

impl Board {
    /// A board with only a mirror sphere and default calibration.
    pub fn mirror_only(center_cam: DVec3, radius: f64) -> Self {
        Board {
            mirror: BoardSphere { center_cam, radius },
            black: None,
            diffuse: None,
            mirror_ior: MIRROR_IOR,
            black_ior: BLACK_IOR,
            diffuse_reflectance: DIFFUSE_REFLECTANCE,
        }
    }

    pub fn load(path: &Path) -> Result<Board, ProbeError> {
        let text = std::fs::read_to_string(path).map_err(|e| ProbeError::Io { path: path.to_path_buf(), source: e })?;
        Board::from_json_str(&text, path)
    }

    /// Parse FORMATS.md board JSON; `path` names the file in errors.
    pub fn from_json_str(text: &str, path: &Path) -> Result<Board, ProbeError> {
        let bad = |msg: String| ProbeError::Board { path: path.to_path_buf(), msg };
        let j: BoardJson = serde_json::from_str(text).map_err(|e| bad(e.to_string()))?;
        let mut board = Board::mirror_only(DVec3::ZERO, 0.0);
        let mut seen = [false; 3];
        for (i, s) in j.spheres.iter().enumerate() {
            let slot = s.kind as usize;
            if seen[slot] {
                return Err(bad(format!("sphere {i}: a second '{}' sphere (one of each kind)", s.kind.name())));
            }
            seen[slot] = true;
            if !s.center.iter().all(|v| v.is_finite()) || !(s.radius.is_finite() && s.radius > 0.0) {
                return Err(bad(format!("sphere {i} ({}): centre must be finite and radius positive", s.kind.name())));
            }
            if s.center[2] <= s.radius {
                return Err(bad(format!(
                    "sphere {i} ({}): centre z = {} is not in front of the camera by more than the radius {} \
                     (centres are in the camera frame, z forward)",
                    s.kind.name(),
                    s.center[2],
                    s.radius
                )));
            }
            let bs = BoardSphere { center_cam: DVec3::from_array(s.center), radius: s.radius };
            match s.kind {
                SphereKind::Mirror => {
                    board.mirror = bs;
                    if let Some(v) = &s.ior {
                        let arr: [[f64; 2]; 3] = serde_json::from_value(v.clone())
                            .map_err(|_| bad(format!("sphere {i} (mirror): ior must be [[n_r, k_r], [n_g, k_g], [n_b, k_b]]")))?;
                        if arr.iter().flatten().any(|x| !(x.is_finite() && *x >= 0.0)) || arr.iter().any(|p| p[0] <= 0.0) {
                            return Err(bad(format!("sphere {i} (mirror): ior entries must be finite, n > 0, k >= 0")));
                        }
                        board.mirror_ior = [(arr[0][0], arr[0][1]), (arr[1][0], arr[1][1]), (arr[2][0], arr[2][1])];
                    }
                }
                SphereKind::Black => {
                    board.black = Some(bs);
                    if let Some(v) = &s.ior {
                        let n = v.as_f64().ok_or_else(|| bad(format!("sphere {i} (black): ior must be a number")))?;
                        if !(n.is_finite() && n > 1.0) {
                            return Err(bad(format!("sphere {i} (black): ior {n} must be > 1")));
                        }
                        board.black_ior = n;
                    }
                }
                SphereKind::Diffuse => {
                    board.diffuse = Some(bs);
                    if let Some(r) = s.reflectance {
                        if r.iter().any(|x| !(x.is_finite() && *x > 0.0 && *x <= 1.0)) {
                            return Err(bad(format!("sphere {i} (diffuse): reflectance {r:?} must be in (0, 1]")));
                        }
                        board.diffuse_reflectance = r;
                    }
                }
            }
            if s.kind != SphereKind::Diffuse && s.reflectance.is_some() {
                return Err(bad(format!("sphere {i} ({}): 'reflectance' applies to the diffuse sphere only", s.kind.name())));
            }
            if s.kind == SphereKind::Diffuse && s.ior.is_some() {
                return Err(bad(format!("sphere {i} (diffuse): 'ior' applies to mirror and black spheres only")));
            }
        }
        if !seen[SphereKind::Mirror as usize] {
            return Err(bad("no 'mirror' sphere (the sky map comes from it)".into()));
        }
        Ok(board)
    }

    /// Reflectance of the mirror sphere per channel at incidence cosine `cos_i`.
    pub fn mirror_reflectance(&self, cos_i: f64) -> [f64; 3] {
        self.mirror_ior.map(|(n, k)| crate::fresnel::conductor(cos_i, n, k))
    }

    /// Reflectance of the black sphere (grey) at incidence cosine `cos_i`.
    pub fn black_reflectance(&self, cos_i: f64) -> [f64; 3] {
        [crate::fresnel::dielectric(cos_i, self.black_ior); 3]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const P: &str = "board.json";

    #[test]
    fn parses_formats_example_and_overrides() {
        let t = r#"{ "spheres": [
            { "kind": "mirror", "center": [-0.1, 0, 0.6], "radius": 0.07, "ior": [[2.5, 3.0], [2.4, 3.1], [2.3, 3.2]] },
            { "kind": "black", "center": [0.1, 0, 0.6], "radius": 0.07, "ior": 1.6 },
            { "kind": "diffuse", "center": [0, 0.1, 0.6], "radius": 0.07, "reflectance": [0.2, 0.25, 0.3] } ] }"#;
        let b = Board::from_json_str(t, Path::new(P)).unwrap();
        assert_eq!(b.mirror.center_cam, DVec3::new(-0.1, 0.0, 0.6));
        assert_eq!(b.mirror_ior[2], (2.3, 3.2));
        assert_eq!(b.black_ior, 1.6);
        assert_eq!(b.diffuse_reflectance, [0.2, 0.25, 0.3]);
        let d = Board::from_json_str(r#"{"spheres":[{"kind":"mirror","center":[0,0,1],"radius":0.1}]}"#, Path::new(P)).unwrap();
        assert_eq!(d.mirror_ior, MIRROR_IOR);
        assert!(d.black.is_none() && d.diffuse.is_none());
        let r = d.mirror_reflectance(1.0);
        assert!(r.iter().all(|v| (0.52..0.54).contains(v)), "{r:?}");
    }

    #[test]
    fn bad_boards_name_file_and_problem() {
        let cases = [
            (r#"{"spheres":[]}"#, "no 'mirror'"),
            (r#"{"spheres":[{"kind":"mirror","center":[0,0,1],"radius":-1}]}"#, "radius positive"),
            (r#"{"spheres":[{"kind":"mirror","center":[0,0,-1],"radius":0.1}]}"#, "in front of the camera"),
            (r#"{"spheres":[{"kind":"chrome","center":[0,0,1],"radius":0.1}]}"#, "unknown variant"),
            (r#"{"spheres":[{"kind":"mirror","center":[0,0,1],"radius":0.1},{"kind":"mirror","center":[0,0,2],"radius":0.1}]}"#, "second"),
            (r#"{"spheres":[{"kind":"mirror","center":[0,0,1],"radius":0.1,"ior":1.5}]}"#, "ior must be"),
        ];
        for (t, want) in cases {
            let e = Board::from_json_str(t, Path::new(P)).unwrap_err().to_string();
            assert!(e.contains("board.json") && e.contains(want), "{e}");
        }
    }
}
