//! What every photogrammetry format becomes before the survey is written: a list of posed
//! images (each a contract camera in the tool's own frame, named as the tool names its photo),
//! whatever the format ([`ModelFormat`]: COLMAP, Metashape's camera XML, nerfstudio's
//! `transforms.json`).

use std::path::PathBuf;

use glam::{DMat3, DVec3};
use igi_camera::{Camera, WorldToCamera};

use crate::error::ImportError;
use crate::model::{contract_camera, ColmapModel};

/// The photogrammetry tool whose cameras are imported.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ModelFormat {
    /// A COLMAP sparse folder (`cameras`, `images`, `points3D`, `.bin` or `.txt`).
    #[default]
    Colmap,
    /// Metashape's camera XML (File > Export > Export Cameras, "Agisoft XML").
    Metashape,
    /// nerfstudio's `transforms.json` (the file, or the folder holding it).
    Nerfstudio,
}

impl ModelFormat {
    pub fn name(self) -> &'static str {
        match self {
            ModelFormat::Colmap => "colmap",
            ModelFormat::Metashape => "metashape",
            ModelFormat::Nerfstudio => "nerfstudio",
        }
    }
}

/// One image of a model: the name the tool gives its photograph and its contract camera (in
/// the tool's frame).
#[derive(Clone, Debug, PartialEq)]
pub struct PosedImage {
    pub name: String,
    pub camera: Camera,
}

/// The cameras of a model, whatever its format.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CameraSet {
    /// The files read, in order.
    pub read: Vec<PathBuf>,
    /// The file naming the images (errors about an image point at it).
    pub images_file: PathBuf,
    /// Distinct intrinsics (COLMAP cameras, Metashape sensors, nerfstudio intrinsics).
    pub cameras: usize,
    pub images: Vec<PosedImage>,
    /// The model's 3D points (COLMAP only; 0 otherwise).
    pub points3d: usize,
    /// The model's 3D points in its own frame (COLMAP only; `igi import colmap --icp` aligns
    /// them to the mesh).
    pub points: Vec<glam::DVec3>,
    /// Images the model lists without a pose (Metashape's unaligned cameras), left out.
    pub unposed: Vec<String>,
}

/// The cameras of a COLMAP model (its images' contract cameras), or the first image that
/// cannot be one.
pub fn colmap_cameras(model: &ColmapModel, read: Vec<PathBuf>) -> Result<CameraSet, ImportError> {
    let images_file = read.get(1).cloned().unwrap_or_default();
    let images = model
        .images
        .iter()
        .map(|img| {
            let camera = contract_camera(model, img).map_err(|problem| ImportError::Model {
                path: images_file.clone(),
                problem,
            })?;
            Ok(PosedImage {
                name: img.name.clone(),
                camera,
            })
        })
        .collect::<Result<Vec<_>, ImportError>>()?;
    Ok(CameraSet {
        read,
        images_file,
        cameras: model.cameras.len(),
        images,
        points3d: model.points.len(),
        points: model
            .points
            .iter()
            .map(|p| glam::DVec3::from_array(p.xyz))
            .collect(),
        unposed: Vec::new(),
    })
}

/// The world-to-camera pose of a camera-to-world transform `x_world = A x_cam + c` whose
/// camera axes are OpenCV's, where `A` is a rotation times a uniform positive scale (the scale
/// of a chunk or of a dataparser; a pinhole camera's image does not depend on it). `None` when
/// `A` is not such a matrix (within 1e-6) or anything is not finite.
pub fn pose_from_camera_to_world(a: DMat3, c: DVec3) -> Option<WorldToCamera> {
    if !(a.is_finite() && c.is_finite()) {
        return None;
    }
    let det = a.determinant();
    if !(det > 0.0) {
        return None;
    }
    let r = a * (1.0 / det.cbrt());
    if !is_rotation(r) {
        return None;
    }
    let rt = r.transpose();
    Some(WorldToCamera {
        r: rt,
        t: -(rt * c),
    })
}

/// Whether `r` is a rotation within 1e-6 (orthonormal, determinant +1).
pub fn is_rotation(r: DMat3) -> bool {
    let e = r.transpose() * r - DMat3::IDENTITY;
    let off = e.to_cols_array().iter().fold(0.0f64, |m, x| m.max(x.abs()));
    off < 1e-6 && (r.determinant() - 1.0).abs() < 1e-6
}

/// A similarity `x -> s R x + t` as a (3x3 matrix `s R`, translation) pair, from its parts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Affine {
    pub m: DMat3,
    pub t: DVec3,
}

impl Affine {
    pub const IDENTITY: Affine = Affine {
        m: DMat3::IDENTITY,
        t: DVec3::ZERO,
    };

    /// `self` after `inner`: `x -> self(inner(x))`.
    pub fn then_inner(self, inner: Affine) -> Affine {
        Affine {
            m: self.m * inner.m,
            t: self.m * inner.t + self.t,
        }
    }

    /// The inverse map, `None` when `m` is singular.
    pub fn inverse(self) -> Option<Affine> {
        let det = self.m.determinant();
        if !(det.abs() > 0.0) || !det.is_finite() {
            return None;
        }
        let mi = self.m.inverse();
        Some(Affine {
            m: mi,
            t: -(mi * self.t),
        })
    }
}
