//! The lighting-capture board file of FORMATS.md and the calibration of its spheres.

use crate::ProbeError;
use glam::DVec3;
use igi_camera::cv::ArucoDict;
use igi_camera::WorldToCamera;
pub use igi_capture::fiducial::FiducialMarker;
pub use igi_capture::sphere::{BoardSphere, SphereKind};
use igi_formats::board::{BoardFile, FiducialsSection, SphereEntry};
use std::path::{Path, PathBuf};

/// Default reflectance of the diffuse sphere's paint.
pub const DIFFUSE_REFLECTANCE: [f64; 3] = [0.30, 0.31, 0.32];
pub use crate::fresnel::MIRROR_IOR;
/// Default index of the black sphere's glossy dielectric coat.
pub const BLACK_IOR: f64 = 1.5;

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

/// The board's fiducials (docs/PROBE.md, "Board file: fiducials").
#[derive(Clone, Debug, PartialEq)]
pub struct Fiducials {
    pub dictionary: ArucoDict,
    pub markers: Vec<FiducialMarker>,
}

/// One sphere as the board file gives it: its centre in the camera frame, in the board frame,
/// or both.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SphereSpec {
    pub center_cam: Option<DVec3>,
    pub center_board: Option<DVec3>,
    pub radius: f64,
}

/// A parsed board file (FORMATS.md, plus the optional fiducials and board-frame centres of
/// docs/PROBE.md). [`BoardSpec::in_camera_frame`] gives the [`Board`] from the camera-frame
/// centres; [`BoardSpec::with_pose`] from the board-frame centres and a board pose (which
/// [`crate::fiducial::place_board`] estimates from the fiducials).
#[derive(Clone, Debug, PartialEq)]
pub struct BoardSpec {
    /// The file, for error messages.
    pub path: PathBuf,
    /// Mirror, black, diffuse (indexed by `SphereKind as usize`).
    pub spheres: [Option<SphereSpec>; 3],
    pub fiducials: Option<Fiducials>,
    pub mirror_ior: [(f64, f64); 3],
    pub black_ior: f64,
    pub diffuse_reflectance: [f64; 3],
}

impl BoardSpec {
    pub fn load(path: &Path) -> Result<BoardSpec, ProbeError> {
        BoardSpec::from_file(&BoardFile::read(path)?, path)
    }

    fn bad(&self, msg: String) -> ProbeError {
        ProbeError::Board {
            path: self.path.clone(),
            msg,
        }
    }

    /// Parse board JSON; `path` names the file in errors.
    pub fn from_json_str(text: &str, path: &Path) -> Result<BoardSpec, ProbeError> {
        BoardSpec::from_file(&BoardFile::from_json_str(text, path)?, path)
    }

    /// The board a parsed file describes, every value checked; `path` names the file in errors.
    pub fn from_file(j: &BoardFile, path: &Path) -> Result<BoardSpec, ProbeError> {
        let bad = |msg: String| ProbeError::Board {
            path: path.to_path_buf(),
            msg,
        };
        let mut spec = BoardSpec {
            path: path.to_path_buf(),
            spheres: [None; 3],
            fiducials: None,
            mirror_ior: MIRROR_IOR,
            black_ior: BLACK_IOR,
            diffuse_reflectance: DIFFUSE_REFLECTANCE,
        };
        for (i, s) in j.spheres.iter().enumerate() {
            let slot = s.kind as usize;
            if spec.spheres[slot].is_some() {
                return Err(bad(format!(
                    "sphere {i}: a second '{}' sphere (one of each kind)",
                    s.kind.name()
                )));
            }
            spec.spheres[slot] = Some(check_sphere(i, s, &j.spheres[..i]).map_err(bad)?);
            spec.calibrate(i, s).map_err(bad)?;
        }
        if spec.spheres[SphereKind::Mirror as usize].is_none() {
            return Err(bad("no 'mirror' sphere (the sky map comes from it)".into()));
        }
        match &j.fiducials {
            Some(f) => spec.fiducials = Some(fiducials_from(f).map_err(bad)?),
            None => spec.check_placeable().map_err(bad)?,
        }
        Ok(spec)
    }

    /// Sphere `i`'s calibration keys (`ior`, `reflectance`), each for its kind only.
    fn calibrate(&mut self, i: usize, s: &SphereEntry) -> Result<(), String> {
        let name = s.kind.name();
        match (s.kind, &s.ior, s.reflectance) {
            (SphereKind::Diffuse, Some(_), _) => {
                return Err(format!(
                    "sphere {i} (diffuse): 'ior' applies to mirror and black spheres only"
                ))
            }
            (SphereKind::Mirror | SphereKind::Black, _, Some(_)) => {
                return Err(format!(
                    "sphere {i} ({name}): 'reflectance' applies to the diffuse sphere only"
                ))
            }
            (SphereKind::Mirror, Some(v), _) => self.mirror_ior = mirror_ior(i, v)?,
            (SphereKind::Black, Some(v), _) => {
                let n = v
                    .as_f64()
                    .ok_or_else(|| format!("sphere {i} (black): ior must be a number"))?;
                if !(n.is_finite() && n > 1.0) {
                    return Err(format!("sphere {i} (black): ior {n} must be > 1"));
                }
                self.black_ior = n;
            }
            (SphereKind::Diffuse, None, Some(r)) => {
                if r.iter().any(|x| !(x.is_finite() && *x > 0.0 && *x <= 1.0)) {
                    return Err(format!(
                        "sphere {i} (diffuse): reflectance {r:?} must be in (0, 1]"
                    ));
                }
                self.diffuse_reflectance = r;
            }
            _ => {}
        }
        Ok(())
    }

    /// Without fiducials every sphere needs its camera-frame centre.
    fn check_placeable(&self) -> Result<(), String> {
        match self
            .spheres
            .iter()
            .position(|s| s.is_some_and(|s| s.center_cam.is_none()))
        {
            Some(i) => Err(format!(
                "the {} sphere has only 'center_board': board-frame centres need 'fiducials' to place them",
                SphereKind::from_index(i).name()
            )),
            None => Ok(()),
        }
    }

    fn board_with(
        &self,
        center: impl Fn(SphereKind, &SphereSpec) -> Result<DVec3, ProbeError>,
    ) -> Result<Board, ProbeError> {
        let get = |k: SphereKind| -> Result<Option<BoardSphere>, ProbeError> {
            match &self.spheres[k as usize] {
                None => Ok(None),
                Some(s) => Ok(Some(BoardSphere {
                    center_cam: center(k, s)?,
                    radius: s.radius,
                })),
            }
        };
        let board = Board {
            mirror: get(SphereKind::Mirror)?.expect("parsing requires a mirror sphere"),
            black: get(SphereKind::Black)?,
            diffuse: get(SphereKind::Diffuse)?,
            mirror_ior: self.mirror_ior,
            black_ior: self.black_ior,
            diffuse_reflectance: self.diffuse_reflectance,
        };
        for s in std::iter::once(&board.mirror)
            .chain(board.black.iter())
            .chain(board.diffuse.iter())
        {
            if s.center_cam.z <= s.radius {
                return Err(self.bad(format!(
                    "a sphere placed at {:?} (camera frame) is not in front of the camera by more than its radius",
                    s.center_cam.to_array()
                )));
            }
        }
        Ok(board)
    }

    /// The board from the spheres' camera-frame centres (FORMATS.md). A sphere given only in
    /// the board frame is an error that says the fiducials (and the opencv feature) are needed.
    pub fn in_camera_frame(&self) -> Result<Board, ProbeError> {
        self.board_with(|k, s| {
            s.center_cam.ok_or_else(|| {
                self.bad(format!(
                    "the {} sphere has no camera-frame 'center', only 'center_board': placing it needs the camera pose \
                     from the board's fiducials, which needs igi built with the opencv feature \
                     (cargo build --features opencv); or give every sphere's camera-frame 'center'",
                    k.name()
                ))
            })
        })
    }

    /// The board from the spheres' board-frame centres and the board's pose in the camera
    /// (`x_cam = R x_board + t`).
    pub fn with_pose(&self, board_to_camera: &WorldToCamera) -> Result<Board, ProbeError> {
        self.board_with(|k, s| {
            s.center_board
                .map(|c| board_to_camera.apply(c))
                .ok_or_else(|| {
                    self.bad(format!(
                        "the {} sphere has no 'center_board' to place with the fiducials' pose",
                        k.name()
                    ))
                })
        })
    }

    /// Whether every sphere has a board-frame centre (so the fiducials' pose can place them).
    pub fn has_board_centres(&self) -> bool {
        self.spheres
            .iter()
            .flatten()
            .all(|s| s.center_board.is_some())
    }

    /// Whether every sphere has a camera-frame centre.
    pub fn has_camera_centres(&self) -> bool {
        self.spheres
            .iter()
            .flatten()
            .all(|s| s.center_cam.is_some())
    }
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

    /// Load a board file whose spheres have camera-frame centres ([`BoardSpec::in_camera_frame`]).
    pub fn load(path: &Path) -> Result<Board, ProbeError> {
        BoardSpec::load(path)?.in_camera_frame()
    }

    /// Parse FORMATS.md board JSON; `path` names the file in errors.
    pub fn from_json_str(text: &str, path: &Path) -> Result<Board, ProbeError> {
        BoardSpec::from_json_str(text, path)?.in_camera_frame()
    }

    /// Reflectance of the mirror sphere per channel at incidence cosine `cos_i`.
    pub fn mirror_reflectance(&self, cos_i: f64) -> [f64; 3] {
        self.mirror_ior
            .map(|(n, k)| crate::fresnel::conductor(cos_i, n, k))
    }

    /// Reflectance of the black sphere (grey) at incidence cosine `cos_i`.
    pub fn black_reflectance(&self, cos_i: f64) -> [f64; 3] {
        [crate::fresnel::dielectric(cos_i, self.black_ior); 3]
    }
}

/// Sphere `i` of the file checked against itself and the spheres before it (`earlier`).
fn check_sphere(i: usize, s: &SphereEntry, earlier: &[SphereEntry]) -> Result<SphereSpec, String> {
    let name = s.kind.name();
    let finite = |c: &Option<[f64; 3]>| c.is_none_or(|c| c.iter().all(|v| v.is_finite()));
    if !finite(&s.center) || !finite(&s.center_board) || !s.radius.is_finite() || s.radius <= 0.0 {
        return Err(format!(
            "sphere {i} ({name}): centre must be finite and radius positive"
        ));
    }
    if s.center.is_none() && s.center_board.is_none() {
        return Err(format!(
            "sphere {i} ({name}): no 'center' (camera frame) or 'center_board' (board frame)"
        ));
    }
    if let Some(c) = s.center.filter(|c| c[2] <= s.radius) {
        return Err(format!(
            "sphere {i} ({name}): centre z = {} is not in front of the camera by more than the radius {} \
             (centres are in the camera frame, z forward)",
            c[2], s.radius
        ));
    }
    // two real spheres cannot interpenetrate: overlapping ones are a typo in the file
    for (k, o) in earlier.iter().enumerate() {
        for (a, b) in [(s.center, o.center), (s.center_board, o.center_board)] {
            if let (Some(a), Some(b)) = (a, b) {
                let d = DVec3::from_array(a).distance(DVec3::from_array(b));
                if d < s.radius + o.radius {
                    return Err(format!(
                        "spheres {k} ({}) and {i} ({name}) overlap: centres {d:.4} apart, radii {} + {}",
                        o.kind.name(),
                        o.radius,
                        s.radius
                    ));
                }
            }
        }
    }
    Ok(SphereSpec {
        center_cam: s.center.map(DVec3::from_array),
        center_board: s.center_board.map(DVec3::from_array),
        radius: s.radius,
    })
}

/// The mirror's complex index per channel from `[[n_r, k_r], [n_g, k_g], [n_b, k_b]]`.
fn mirror_ior(i: usize, v: &serde_json::Value) -> Result<[(f64, f64); 3], String> {
    let arr: [[f64; 2]; 3] = serde_json::from_value(v.clone()).map_err(|_| {
        format!("sphere {i} (mirror): ior must be [[n_r, k_r], [n_g, k_g], [n_b, k_b]]")
    })?;
    if arr.iter().flatten().any(|x| !(x.is_finite() && *x >= 0.0))
        || arr.iter().any(|p| p[0] <= 0.0)
    {
        return Err(format!(
            "sphere {i} (mirror): ior entries must be finite, n > 0, k >= 0"
        ));
    }
    Ok(arr.map(|p| (p[0], p[1])))
}

/// The fiducials section checked: a known dictionary, at least 2 markers, distinct ids, finite
/// distinct corners.
fn fiducials_from(f: &FiducialsSection) -> Result<Fiducials, String> {
    let dictionary = ArucoDict::from_name(&f.dictionary).ok_or_else(|| {
        format!(
            "fiducials: unknown ArUco dictionary '{}' (DICT_4X4_50, DICT_5X5_100, DICT_6X6_250 or DICT_ARUCO_ORIGINAL)",
            f.dictionary
        )
    })?;
    if f.markers.len() < 2 {
        return Err(format!(
            "fiducials: {} marker(s); the pose needs at least 2 (8 corners)",
            f.markers.len()
        ));
    }
    let mut markers = Vec::new();
    for (i, m) in f.markers.iter().enumerate() {
        if f.markers[..i].iter().any(|o| o.id == m.id) {
            return Err(format!("fiducials: marker id {} appears twice", m.id));
        }
        let c = m.corners.map(DVec3::from_array);
        let degenerate = (0..4).any(|k| c[k].distance(c[(k + 1) % 4]) <= 0.0);
        if m.corners.iter().flatten().any(|v| !v.is_finite()) || degenerate {
            return Err(format!(
                "fiducials: marker {} corners must be finite and distinct",
                m.id
            ));
        }
        markers.push(FiducialMarker {
            id: m.id,
            corners: c,
        });
    }
    Ok(Fiducials {
        dictionary,
        markers,
    })
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
        let d = Board::from_json_str(
            r#"{"spheres":[{"kind":"mirror","center":[0,0,1],"radius":0.1}]}"#,
            Path::new(P),
        )
        .unwrap();
        assert_eq!(d.mirror_ior, MIRROR_IOR);
        assert!(d.black.is_none() && d.diffuse.is_none());
        let r = d.mirror_reflectance(1.0);
        assert!(r.iter().all(|v| (0.52..0.54).contains(v)), "{r:?}");
    }

    #[test]
    fn bad_boards_name_file_and_problem() {
        let cases = [
            (r#"{"spheres":[]}"#, "no 'mirror'"),
            (
                r#"{"spheres":[{"kind":"mirror","center":[0,0,1],"radius":-1}]}"#,
                "radius positive",
            ),
            (
                r#"{"spheres":[{"kind":"mirror","center":[0,0,-1],"radius":0.1}]}"#,
                "in front of the camera",
            ),
            (
                r#"{"spheres":[{"kind":"chrome","center":[0,0,1],"radius":0.1}]}"#,
                "unknown variant",
            ),
            (
                r#"{"spheres":[{"kind":"mirror","center":[0,0,1],"radius":0.1},{"kind":"mirror","center":[0,0,2],"radius":0.1}]}"#,
                "second",
            ),
            (
                r#"{"spheres":[{"kind":"mirror","center":[0,0,1],"radius":0.1,"ior":1.5}]}"#,
                "ior must be",
            ),
            (
                r#"{"spheres":[{"kind":"mirror","center":[0,0,1],"radius":0.1,"ior":[[1,0],[0,1],[1,1]]}]}"#,
                "n > 0",
            ),
            (
                r#"{"spheres":[{"kind":"mirror","center":[0,0,1],"radius":0.1},{"kind":"black","center":[0,0,1],"radius":0.1,"ior":0.9}]}"#,
                "overlap",
            ),
            (
                r#"{"spheres":[{"kind":"mirror","center":[0,0,1],"radius":0.1},{"kind":"black","center":[1,0,1],"radius":0.1,"ior":0.9}]}"#,
                "ior 0.9 must be > 1",
            ),
            (
                r#"{"spheres":[{"kind":"mirror","center":[0,0,1],"radius":0.1,"reflectance":[0.5,0.5,0.5]}]}"#,
                "applies to the diffuse sphere only",
            ),
            (
                r#"{"spheres":[{"kind":"mirror","center":[0,0,1],"radius":0.1},{"kind":"diffuse","center":[1,0,1],"radius":0.1,"ior":1.5}]}"#,
                "applies to mirror and black spheres only",
            ),
            (
                r#"{"spheres":[{"kind":"mirror","center":[0,0,1],"radius":0.1},{"kind":"diffuse","center":[1,0,1],"radius":0.1,"reflectance":[0.5,1.5,0.5]}]}"#,
                "must be in (0, 1]",
            ),
            (
                r#"{"spheres":[{"kind":"mirror","center_board":[0,0,0],"radius":0.1}]}"#,
                "need 'fiducials'",
            ),
            (
                r#"{"spheres":[{"kind":"mirror","radius":0.1}]}"#,
                "no 'center'",
            ),
            (
                r#"{"spheres":[{"kind":"mirror","center_board":[0,0,0],"radius":0.1}],"fiducials":{"dictionary":"DICT_9X9","markers":[]}}"#,
                "unknown ArUco dictionary",
            ),
            (
                r#"{"spheres":[{"kind":"mirror","center_board":[0,0,0],"radius":0.1}],"fiducials":{"dictionary":"DICT_4X4_50","markers":[{"id":1,"corners":[[0,0,0],[1,0,0],[1,1,0],[0,1,0]]}]}}"#,
                "at least 2",
            ),
            (
                r#"{"spheres":[{"kind":"mirror","center_board":[0,0,0],"radius":0.1}],"fiducials":{"dictionary":"DICT_4X4_50","markers":[{"id":1,"corners":[[0,0,0],[1,0,0],[1,1,0],[0,1,0]]},{"id":1,"corners":[[0,0,0],[1,0,0],[1,1,0],[0,1,0]]}]}}"#,
                "appears twice",
            ),
            (
                r#"{"spheres":[{"kind":"mirror","center_board":[0,0,0],"radius":0.1}],"fiducials":{"dictionary":"DICT_4X4_50","markers":[{"id":1,"corners":[[0,0,0],[0,0,0],[1,1,0],[0,1,0]]},{"id":2,"corners":[[0,0,0],[1,0,0],[1,1,0],[0,1,0]]}]}}"#,
                "finite and distinct",
            ),
        ];
        for (t, want) in cases {
            let e = Board::from_json_str(t, Path::new(P))
                .unwrap_err()
                .to_string();
            assert!(e.contains("board.json") && e.contains(want), "{e}");
        }
    }
}
