//! nerfstudio's `transforms.json` as contract cameras.
//!
//! The file: intrinsics `fl_x`, `fl_y`, `cx`, `cy`, `w`, `h`, distortion `k1`, `k2`, `k3`,
//! `k4`, `p1`, `p2` and `camera_model` (`OPENCV` when absent), each at the top level or per
//! frame (a frame's own value wins); `frames[]` with `file_path` and `transform_matrix` (4x4,
//! or its top 3 rows), camera to world in OpenGL's camera axes (x right, y up, z back); and
//! optionally `applied_transform` (3x4 or 4x4), the transform nerfstudio's converters applied
//! to the original tool's world (`ns-process-data` from COLMAP swaps y and z and flips the new
//! z) so that `x_file = applied_transform x_original`.
//!
//! Conventions. OpenGL's camera axes become OpenCV's by flipping y and z:
//! `R_cv = R_gl diag(1, -1, -1)`. nerfstudio puts the centre of pixel (i, j) at (i + 0.5,
//! j + 0.5): its rays are cast through `pixel index + pixel_offset` with `pixel_offset = 0.5`
//! (`Cameras.get_image_coords` in `nerfstudio/cameras/cameras.py`), and its COLMAP converter
//! (`colmap_to_json` in `nerfstudio/process_data/colmap_utils.py`) copies COLMAP's principal
//! point unchanged, COLMAP's convention being the same. So the contract principal point is
//! `(cx - 0.5, cy - 0.5)`. `k1, k2, k3, p1, p2` are OpenCV's (nerfstudio's perspective
//! distortion is OpenCV's with an extra `k4 r^8` term, refused when nonzero); `PINHOLE` and
//! `OPENCV` are both nerfstudio's perspective camera. `OPENCV_FISHEYE`, `EQUIRECTANGULAR` and
//! any other model are refused by name.
//!
//! `applied_transform` is undone: the cameras come back in the frame of the tool that made
//! the poses (COLMAP's, say), the frame its sparse points and dense mesh are in, so that a
//! mesh from that tool fits them without `--control`. It must be a rotation times a uniform
//! scale, plus a translation.

use std::path::{Path, PathBuf};

use glam::{DMat3, DVec3};
use igi_camera::{Camera, Distortion, Intrinsics};
use serde_json::{Map, Value};

use crate::error::ImportError;
use crate::model::from_pixel_corner_origin;
use crate::source::{pose_from_camera_to_world, Affine, CameraSet, PosedImage};

/// `transforms.json` itself, or the file of that name in a folder.
pub fn transforms_path(p: &Path) -> PathBuf {
    if p.is_dir() {
        p.join("transforms.json")
    } else {
        p.to_path_buf()
    }
}

fn err(path: &Path, problem: impl Into<String>) -> ImportError {
    ImportError::Model {
        path: path.to_path_buf(),
        problem: problem.into(),
    }
}

/// A number of a frame, else of the top level; `None` when neither has it.
fn number(
    path: &Path,
    top: &Map<String, Value>,
    frame: &Map<String, Value>,
    at: &str,
    key: &str,
) -> Result<Option<f64>, ImportError> {
    let (v, where_) = match frame.get(key) {
        Some(v) => (v, at.to_string()),
        None => match top.get(key) {
            Some(v) => (v, String::new()),
            None => return Ok(None),
        },
    };
    v.as_f64()
        .filter(|x| x.is_finite())
        .map(Some)
        .ok_or_else(|| err(path, format!("{where_}`{key}` = {v} is not a number")))
}

/// The rows of a 3x4 or 4x4 matrix (last row 0 0 0 1) as an affine map.
fn matrix(path: &Path, v: &Value, what: &str) -> Result<Affine, ImportError> {
    let bad = || {
        err(
            path,
            format!("{what} is not a 4x4 (or 3x4) matrix of numbers"),
        )
    };
    let rows = v.as_array().ok_or_else(bad)?;
    if !(rows.len() == 3 || rows.len() == 4) {
        return Err(bad());
    }
    let mut m = [[0.0f64; 4]; 4];
    for (i, r) in rows.iter().enumerate() {
        let r = r.as_array().filter(|r| r.len() == 4).ok_or_else(bad)?;
        for (j, x) in r.iter().enumerate() {
            m[i][j] = x.as_f64().filter(|x| x.is_finite()).ok_or_else(bad)?;
        }
    }
    if rows.len() == 4 {
        let l = m[3];
        if l[0].abs() + l[1].abs() + l[2].abs() + (l[3] - 1.0).abs() > 1e-9 {
            return Err(err(
                path,
                format!("{what}: last row {l:?} is not [0, 0, 0, 1]"),
            ));
        }
    }
    Ok(Affine {
        m: DMat3::from_cols_array_2d(&[
            [m[0][0], m[1][0], m[2][0]],
            [m[0][1], m[1][1], m[2][1]],
            [m[0][2], m[1][2], m[2][2]],
        ]),
        t: DVec3::new(m[0][3], m[1][3], m[2][3]),
    })
}

/// The intrinsics and size of a frame (its own keys over the top level's).
fn intrinsics(
    path: &Path,
    top: &Map<String, Value>,
    frame: &Map<String, Value>,
    at: &str,
) -> Result<(u32, u32, Intrinsics), ImportError> {
    let model = frame
        .get("camera_model")
        .or_else(|| top.get("camera_model"))
        .map_or(Some("OPENCV"), Value::as_str)
        .ok_or_else(|| err(path, format!("{at}`camera_model` is not a string")))?;
    if !matches!(model, "OPENCV" | "PINHOLE") {
        return Err(err(
            path,
            format!(
                "{at}camera model {model} is not supported: the contract camera is OpenCV's \
                 pinhole with (k1, k2, p1, p2, k3) distortion; supported: OPENCV, PINHOLE"
            ),
        ));
    }
    let num = |k: &str| number(path, top, frame, at, k);
    let need = |k: &str| -> Result<f64, ImportError> {
        num(k)?.ok_or_else(|| {
            err(
                path,
                format!("{at}no `{k}` (neither the frame's nor the file's)"),
            )
        })
    };
    let size = |k: &str| -> Result<u32, ImportError> {
        let v = need(k)?;
        (v >= 1.0 && v.fract() == 0.0 && v <= f64::from(u32::MAX))
            .then_some(v as u32)
            .ok_or_else(|| err(path, format!("{at}`{k}` = {v} is not a size in pixels")))
    };
    let (w, h) = (size("w")?, size("h")?);
    let (fx, fy) = (need("fl_x")?, need("fl_y")?);
    if !(fx > 0.0 && fy > 0.0) {
        return Err(err(
            path,
            format!("{at}focal lengths fl_x = {fx}, fl_y = {fy} are not positive"),
        ));
    }
    let (cx, cy) = (need("cx")?, need("cy")?);
    let d = |k: &str| -> Result<f64, ImportError> { Ok(num(k)?.unwrap_or(0.0)) };
    if d("k4")? != 0.0 {
        return Err(err(
            path,
            format!(
                "{at}k4 = {} is an 8th-order radial term the contract camera lacks (it has \
                 k1, k2, k3)",
                d("k4")?
            ),
        ));
    }
    let dist = Distortion::from_array([d("k1")?, d("k2")?, d("p1")?, d("p2")?, d("k3")?]);
    Ok((w, h, from_pixel_corner_origin(fx, fy, cx, cy, dist)))
}

/// The cameras of a nerfstudio `transforms.json` (or the folder holding one), in the frame of
/// the tool that made the poses (`applied_transform` undone).
pub fn read_nerfstudio(p: &Path) -> Result<CameraSet, ImportError> {
    let path = transforms_path(p);
    let path = path.as_path();
    let text = std::fs::read_to_string(path).map_err(|source| ImportError::Read {
        path: path.to_path_buf(),
        what: "nerfstudio's transforms.json",
        source,
    })?;
    let v: Value = serde_json::from_str(&text)
        .map_err(|e| ImportError::text(path, e.line(), format!("not JSON: {e}")))?;
    let top = v
        .as_object()
        .ok_or_else(|| err(path, "not a JSON object (nerfstudio's transforms.json)"))?;
    let frames = top
        .get("frames")
        .and_then(Value::as_array)
        .ok_or_else(|| err(path, "no `frames` list"))?;
    let undo = match top.get("applied_transform") {
        None => Affine::IDENTITY,
        Some(a) => {
            let a = matrix(path, a, "`applied_transform`")?;
            if pose_from_camera_to_world(a.m, a.t).is_none() {
                return Err(err(
                    path,
                    "`applied_transform` is not a rotation times a uniform scale",
                ));
            }
            a.inverse()
                .ok_or_else(|| err(path, "`applied_transform` is singular"))?
        }
    };
    let gl_to_cv = DMat3::from_diagonal(DVec3::new(1.0, -1.0, -1.0));
    let mut set = CameraSet {
        read: vec![path.to_path_buf()],
        images_file: path.to_path_buf(),
        ..CameraSet::default()
    };
    let mut distinct: Vec<(u32, u32, Intrinsics)> = Vec::new();
    for (i, f) in frames.iter().enumerate() {
        let at = format!("frames[{i}]: ");
        let frame = f
            .as_object()
            .ok_or_else(|| err(path, format!("{at}not an object")))?;
        let name = frame
            .get("file_path")
            .and_then(Value::as_str)
            .ok_or_else(|| err(path, format!("{at}no `file_path`")))?;
        let name = name.strip_prefix("./").unwrap_or(name).to_string();
        let (w, h, k) = intrinsics(path, top, frame, &at)?;
        if !distinct.contains(&(w, h, k)) {
            distinct.push((w, h, k));
        }
        let c2w = matrix(
            path,
            frame
                .get("transform_matrix")
                .ok_or_else(|| err(path, format!("{at}no `transform_matrix`")))?,
            &format!("{at}`transform_matrix`"),
        )?;
        let c2w = undo.then_inner(c2w);
        let pose = pose_from_camera_to_world(c2w.m * gl_to_cv, c2w.t).ok_or_else(|| {
            err(
                path,
                format!(
                    "{at}`transform_matrix` (`{name}`) is not a rotation times a uniform scale"
                ),
            )
        })?;
        set.images.push(PosedImage {
            name,
            camera: Camera {
                width: w,
                height: h,
                intrinsics: k,
                pose,
            },
        });
    }
    set.cameras = distinct.len();
    Ok(set)
}
