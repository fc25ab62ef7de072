//! A COLMAP sparse model as read (cameras, images, 3D points) and its cameras converted to the
//! contract camera (`igi_camera::Camera`).
//!
//! COLMAP's conventions: camera axes as OpenCV's (x right, y down, z forward); an image's pose
//! is world to camera, `x_cam = R(q) x_world + t` with `q` a Hamilton quaternion (w, x, y, z);
//! the centre of the top-left pixel at (0.5, 0.5), so the contract's principal point is
//! COLMAP's minus 0.5 in each axis. Distortion models convert exactly to OpenCV's
//! (k1, k2, p1, p2, k3) or are refused by name.

use glam::{DMat3, DVec3};
use igi_camera::{Camera, Distortion, Intrinsics, WorldToCamera};

/// COLMAP's camera models, with the ids of its binary files and the names of its text files.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CameraModel {
    SimplePinhole,
    Pinhole,
    SimpleRadial,
    Radial,
    OpenCv,
    OpenCvFisheye,
    FullOpenCv,
    Fov,
    SimpleRadialFisheye,
    RadialFisheye,
    ThinPrismFisheye,
    RadTanThinPrismFisheye,
}

/// (model, id, name, number of parameters), in COLMAP's order.
const MODELS: [(CameraModel, i32, &str, usize); 12] = [
    (CameraModel::SimplePinhole, 0, "SIMPLE_PINHOLE", 3),
    (CameraModel::Pinhole, 1, "PINHOLE", 4),
    (CameraModel::SimpleRadial, 2, "SIMPLE_RADIAL", 4),
    (CameraModel::Radial, 3, "RADIAL", 5),
    (CameraModel::OpenCv, 4, "OPENCV", 8),
    (CameraModel::OpenCvFisheye, 5, "OPENCV_FISHEYE", 8),
    (CameraModel::FullOpenCv, 6, "FULL_OPENCV", 12),
    (CameraModel::Fov, 7, "FOV", 5),
    (
        CameraModel::SimpleRadialFisheye,
        8,
        "SIMPLE_RADIAL_FISHEYE",
        4,
    ),
    (CameraModel::RadialFisheye, 9, "RADIAL_FISHEYE", 5),
    (CameraModel::ThinPrismFisheye, 10, "THIN_PRISM_FISHEYE", 12),
    (
        CameraModel::RadTanThinPrismFisheye,
        11,
        "RAD_TAN_THIN_PRISM_FISHEYE",
        16,
    ),
];

impl CameraModel {
    fn row(self) -> (CameraModel, i32, &'static str, usize) {
        MODELS
            .into_iter()
            .find(|m| m.0 == self)
            .unwrap_or(MODELS[0])
    }
    /// The model of a binary file's `model_id`.
    pub fn from_id(id: i32) -> Option<Self> {
        MODELS.into_iter().find(|m| m.1 == id).map(|m| m.0)
    }
    /// The model of a text file's name (as COLMAP writes it, upper case).
    pub fn from_name(name: &str) -> Option<Self> {
        MODELS.into_iter().find(|m| m.2 == name).map(|m| m.0)
    }
    pub fn id(self) -> i32 {
        self.row().1
    }
    pub fn name(self) -> &'static str {
        self.row().2
    }
    /// How many parameters the model has.
    pub fn num_params(self) -> usize {
        self.row().3
    }
}

/// One COLMAP camera (intrinsics shared by images).
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapCamera {
    pub id: u32,
    pub model: CameraModel,
    pub width: u64,
    pub height: u64,
    pub params: Vec<f64>,
}

/// One registered image: its pose (world to camera) and its 2D points.
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapImage {
    pub id: u32,
    /// Hamilton quaternion (w, x, y, z) of the world-to-camera rotation.
    pub q: [f64; 4],
    pub t: [f64; 3],
    pub camera_id: u32,
    pub name: String,
    /// (x, y) in COLMAP's pixel convention and the 3D point id (-1: none).
    pub points2d: Vec<([f64; 2], i64)>,
}

/// One 3D point and its track of (image id, 2D point index).
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapPoint {
    pub id: u64,
    pub xyz: [f64; 3],
    pub rgb: [u8; 3],
    pub error: f64,
    pub track: Vec<(u32, u32)>,
}

/// A sparse model: what `cameras`, `images` and `points3D` hold, in file order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ColmapModel {
    pub cameras: Vec<ColmapCamera>,
    pub images: Vec<ColmapImage>,
    pub points: Vec<ColmapPoint>,
}

/// The rotation matrix of a Hamilton quaternion (w, x, y, z), normalised first; `None` for a
/// quaternion of zero or non-finite length.
pub fn quat_to_matrix(q: [f64; 4]) -> Option<DMat3> {
    let n = q.iter().map(|x| x * x).sum::<f64>().sqrt();
    if !(n > 0.0) || !n.is_finite() {
        return None;
    }
    let [w, x, y, z] = q.map(|c| c / n);
    let rows = [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ];
    Some(DMat3::from_cols_array_2d(&rows).transpose())
}

/// A Hamilton quaternion (w, x, y, z), w >= 0, of a rotation matrix (Shepperd's method).
pub fn matrix_to_quat(r: DMat3) -> [f64; 4] {
    let m = |i: usize, j: usize| r.col(j)[i];
    let tr = m(0, 0) + m(1, 1) + m(2, 2);
    let q = if tr > 0.0 {
        let s = (tr + 1.0).sqrt() * 2.0;
        [
            s / 4.0,
            (m(2, 1) - m(1, 2)) / s,
            (m(0, 2) - m(2, 0)) / s,
            (m(1, 0) - m(0, 1)) / s,
        ]
    } else if m(0, 0) > m(1, 1) && m(0, 0) > m(2, 2) {
        let s = (1.0 + m(0, 0) - m(1, 1) - m(2, 2)).sqrt() * 2.0;
        [
            (m(2, 1) - m(1, 2)) / s,
            s / 4.0,
            (m(0, 1) + m(1, 0)) / s,
            (m(0, 2) + m(2, 0)) / s,
        ]
    } else if m(1, 1) > m(2, 2) {
        let s = (1.0 + m(1, 1) - m(0, 0) - m(2, 2)).sqrt() * 2.0;
        [
            (m(0, 2) - m(2, 0)) / s,
            (m(0, 1) + m(1, 0)) / s,
            s / 4.0,
            (m(1, 2) + m(2, 1)) / s,
        ]
    } else {
        let s = (1.0 + m(2, 2) - m(0, 0) - m(1, 1)).sqrt() * 2.0;
        [
            (m(1, 0) - m(0, 1)) / s,
            (m(0, 2) + m(2, 0)) / s,
            (m(1, 2) + m(2, 1)) / s,
            s / 4.0,
        ]
    };
    if q[0] < 0.0 {
        q.map(|c| -c)
    } else {
        q
    }
}

/// COLMAP's (fx, fy, cx, cy, [k1, k2, p1, p2, k3]) of a camera the contract can hold exactly,
/// or why it cannot.
fn opencv_params(cam: &ColmapCamera) -> Result<([f64; 4], [f64; 5]), String> {
    let p = &cam.params;
    let n = cam.model.num_params();
    if p.len() != n {
        return Err(format!(
            "{} takes {n} parameters, not {}",
            cam.model.name(),
            p.len()
        ));
    }
    Ok(match cam.model {
        CameraModel::SimplePinhole => ([p[0], p[0], p[1], p[2]], [0.0; 5]),
        CameraModel::Pinhole => ([p[0], p[1], p[2], p[3]], [0.0; 5]),
        CameraModel::SimpleRadial => ([p[0], p[0], p[1], p[2]], [p[3], 0.0, 0.0, 0.0, 0.0]),
        CameraModel::Radial => ([p[0], p[0], p[1], p[2]], [p[3], p[4], 0.0, 0.0, 0.0]),
        CameraModel::OpenCv => ([p[0], p[1], p[2], p[3]], [p[4], p[5], p[6], p[7], 0.0]),
        CameraModel::FullOpenCv => {
            if p[9..12].iter().any(|&k| k != 0.0) {
                return Err(format!(
                    "FULL_OPENCV with k4, k5, k6 = {:?}: the contract camera has no rational \
                     distortion (only k1, k2, p1, p2, k3); recalibrate with OPENCV or \
                     FULL_OPENCV with k4 = k5 = k6 = 0",
                    &p[9..12]
                ));
            }
            ([p[0], p[1], p[2], p[3]], [p[4], p[5], p[6], p[7], p[8]])
        }
        other => {
            return Err(format!(
                "camera model {} is not supported: the contract camera is OpenCV's pinhole \
                 with (k1, k2, p1, p2, k3) distortion; supported: SIMPLE_PINHOLE, PINHOLE, \
                 SIMPLE_RADIAL, RADIAL, OPENCV, FULL_OPENCV (k4 = k5 = k6 = 0)",
                other.name()
            ))
        }
    })
}

/// The contract intrinsics of a COLMAP camera (principal point moved by -0.5 px), with its
/// size, or why it cannot be one.
pub fn contract_intrinsics(cam: &ColmapCamera) -> Result<(u32, u32, Intrinsics), String> {
    let ([fx, fy, cx, cy], d) = opencv_params(cam)?;
    let size = |v: u64, what: &str| {
        u32::try_from(v)
            .ok()
            .filter(|&v| v > 0)
            .ok_or_else(|| format!("{what} {v} is not a size in pixels"))
    };
    let (w, h) = (size(cam.width, "width")?, size(cam.height, "height")?);
    if !(fx > 0.0 && fy > 0.0) || cam.params.iter().any(|p| !p.is_finite()) {
        return Err(format!(
            "parameters {:?} are not a camera (focal length > 0, finite)",
            cam.params
        ));
    }
    Ok((
        w,
        h,
        from_pixel_corner_origin(fx, fy, cx, cy, Distortion::from_array(d)),
    ))
}

/// The contract's intrinsics from a principal point measured with the centre of the top-left
/// pixel at (0.5, 0.5), as COLMAP, Metashape and nerfstudio do (the contract puts it at
/// (0, 0): the point moves by -0.5 px).
pub fn from_pixel_corner_origin(
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
    dist: Distortion,
) -> Intrinsics {
    Intrinsics {
        fx,
        fy,
        cx: cx - 0.5,
        cy: cy - 0.5,
        dist,
    }
}

/// The world-to-camera pose of an image, or why it has none.
pub fn image_pose(img: &ColmapImage) -> Result<WorldToCamera, String> {
    let r = quat_to_matrix(img.q).ok_or_else(|| {
        format!(
            "image `{}`: quaternion {:?} is not a rotation",
            img.name, img.q
        )
    })?;
    let t = DVec3::from_array(img.t);
    if !t.is_finite() {
        return Err(format!(
            "image `{}`: translation {:?} is not finite",
            img.name, img.t
        ));
    }
    Ok(WorldToCamera { r, t })
}

/// The contract camera of an image (in the model's frame), or why it cannot be one.
pub fn contract_camera(model: &ColmapModel, img: &ColmapImage) -> Result<Camera, String> {
    let cam = model
        .cameras
        .iter()
        .find(|c| c.id == img.camera_id)
        .ok_or_else(|| {
            format!(
                "image `{}` names camera {}, which the model lacks",
                img.name, img.camera_id
            )
        })?;
    let (width, height, intrinsics) = contract_intrinsics(cam)
        .map_err(|e| format!("camera {} (image `{}`): {e}", cam.id, img.name))?;
    Ok(Camera {
        width,
        height,
        intrinsics,
        pose: image_pose(img)?,
    })
}
