//! OpenCV pinhole camera: intrinsics, (k1, k2, p1, p2, k3) distortion, typed poses, JSON I/O.
//!
//! Convention (FORMATS.md): camera x right, y down, z forward; `x_cam = R x_world + t`;
//! pixel centres at integer coordinates, the top-left pixel centre at (0, 0).

pub use crate::error::{CameraFileError, RotationError};
use crate::CameraError;
use glam::{DMat3, DVec2, DVec3, Vec2, Vec3};
pub use igi_formats::CameraFile;
use igi_imaging::HdrImage;
use rayon::prelude::*;
use std::path::Path;

/// OpenCV radial/tangential distortion coefficients.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Distortion {
    pub k1: f64,
    pub k2: f64,
    pub p1: f64,
    pub p2: f64,
    pub k3: f64,
}

impl Distortion {
    pub fn is_zero(&self) -> bool {
        self.k1 == 0.0 && self.k2 == 0.0 && self.p1 == 0.0 && self.p2 == 0.0 && self.k3 == 0.0
    }

    pub fn to_array(&self) -> [f64; 5] {
        [self.k1, self.k2, self.p1, self.p2, self.k3]
    }

    pub fn from_array(a: [f64; 5]) -> Self {
        Distortion {
            k1: a[0],
            k2: a[1],
            p1: a[2],
            p2: a[3],
            k3: a[4],
        }
    }

    /// Distort a normalised image point (x/z, y/z) with the OpenCV model.
    pub fn distort(&self, p: DVec2) -> DVec2 {
        let (x, y) = (p.x, p.y);
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        DVec2::new(
            x * radial + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x),
            y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y,
        )
    }

    /// Jacobian of [`Self::distort`] as (d/dx, d/dy) columns.
    fn jacobian(&self, p: DVec2) -> (DVec2, DVec2) {
        let (x, y) = (p.x, p.y);
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        let dr = 2.0 * self.k1 + r2 * (4.0 * self.k2 + 6.0 * self.k3 * r2);
        let a = radial + dr * x * x + 2.0 * self.p1 * y + 6.0 * self.p2 * x;
        let b = dr * x * y + 2.0 * self.p1 * x + 2.0 * self.p2 * y;
        let d = radial + dr * y * y + 6.0 * self.p1 * y + 2.0 * self.p2 * x;
        (DVec2::new(a, b), DVec2::new(b, d))
    }

    /// Invert [`Self::distort`]: the undistorted normalised point whose distortion is `pd`.
    /// Damped Newton iteration from `pd`, to a residual below 1e-10 (or `None` if it does
    /// not converge, e.g. outside the region where the model is invertible).
    pub fn undistort(&self, pd: DVec2) -> Option<DVec2> {
        if self.is_zero() {
            return Some(pd);
        }
        if !pd.is_finite() {
            return None;
        }
        let mut p = pd;
        let mut res = self.distort(p) - pd;
        for _ in 0..200 {
            let err = res.length();
            if err < 1e-10 {
                return Some(p);
            }
            let (c0, c1) = self.jacobian(p);
            let det = c0.x * c1.y - c1.x * c0.y;
            if !det.is_finite() || det.abs() < 1e-300 {
                return None;
            }
            // solve J dp = -res
            let dp = DVec2::new(
                c1.y * -res.x - c1.x * -res.y,
                -c0.y * -res.x + c0.x * -res.y,
            ) / det;
            let mut step = 1.0;
            loop {
                let q = p + dp * step;
                let r = self.distort(q) - pd;
                if r.length() < err || step < 1e-6 {
                    p = q;
                    res = r;
                    break;
                }
                step *= 0.5;
            }
        }
        (res.length() < 1e-10).then_some(p)
    }
}

/// Pinhole intrinsics (no skew) and distortion.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Intrinsics {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    pub dist: Distortion,
}

impl Intrinsics {
    /// Normalised (undistorted) point -> pixel (a lens without distortion skips the
    /// polynomial, whose value would be `xn` itself).
    #[inline]
    pub fn to_pixel(&self, xn: DVec2) -> DVec2 {
        let d = if self.dist.is_zero() {
            xn
        } else {
            self.dist.distort(xn)
        };
        DVec2::new(self.fx * d.x + self.cx, self.fy * d.y + self.cy)
    }

    /// Pixel -> undistorted normalised point (None if undistortion fails).
    pub fn to_normalized(&self, px: DVec2) -> Option<DVec2> {
        self.dist.undistort(DVec2::new(
            (px.x - self.cx) / self.fx,
            (px.y - self.cy) / self.fy,
        ))
    }

    pub fn k_matrix(&self) -> [[f64; 3]; 3] {
        [
            [self.fx, 0.0, self.cx],
            [0.0, self.fy, self.cy],
            [0.0, 0.0, 1.0],
        ]
    }

    /// Checks that the distortion can be a lens over a `width x height` image: at points along
    /// the lines from the principal point to the corners and edge midpoints (the pixel grid's
    /// outer points included), some direction distorts to the pixel and it lies within
    /// [`LENS_STRETCH`] times the pixel's distance from the axis, either way (k1 = 1e6 puts
    /// a pixel a quarter of the way to a corner of a 128-pixel image 30 times nearer the axis;
    /// k1 = -1e6 folds the image, its pixels seeing directions across the axis).
    pub fn check_lens(&self, width: u32, height: u32) -> Result<(), CameraFileError> {
        if self.dist.is_zero() {
            return Ok(());
        }
        let (w, h) = (width as f64 - 0.5, height as f64 - 0.5);
        let outer = [
            (-0.5, -0.5),
            (w, -0.5),
            (-0.5, h),
            (w, h),
            (w / 2.0, -0.5),
            (w / 2.0, h),
            (-0.5, h / 2.0),
            (w, h / 2.0),
        ];
        let centre = DVec2::new(self.cx, self.cy);
        for (u, v) in outer {
            for t in [0.25, 0.5, 0.75, 1.0] {
                let px = centre + (DVec2::new(u, v) - centre) * t;
                let pd = DVec2::new((px.x - self.cx) / self.fx, (px.y - self.cy) / self.fy);
                if pd.length() < 1e-9 {
                    continue;
                }
                let bad = |why: String| CameraFileError::Lens {
                    dist: self.dist.to_array(),
                    pixel: [px.x, px.y],
                    why,
                };
                let Some(p) = self.dist.undistort(pd) else {
                    return Err(bad("no direction distorts to it (the model folds back \
                                    before it)"
                        .into()));
                };
                let stretch = p.length() / pd.length();
                if !(1.0 / LENS_STRETCH..=LENS_STRETCH).contains(&stretch) {
                    return Err(bad(format!(
                        "sees the direction at {stretch:.3e} times its distance from the axis \
                         (a lens stays within {LENS_STRETCH}x either way)"
                    )));
                }
            }
        }
        Ok(())
    }
}

/// How far a lens may move a pixel's direction from where the pinhole would put it: its
/// distance from the optical axis at most this many times larger or smaller
/// ([`Intrinsics::check_lens`]).
pub const LENS_STRETCH: f64 = 10.0;

/// World-to-camera rigid transform: `x_cam = r * x_world + t`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WorldToCamera {
    pub r: DMat3,
    pub t: DVec3,
}

/// Camera-to-world rigid transform: `x_world = r * x_cam + t`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraToWorld {
    pub r: DMat3,
    pub t: DVec3,
}

impl WorldToCamera {
    pub fn identity() -> Self {
        WorldToCamera {
            r: DMat3::IDENTITY,
            t: DVec3::ZERO,
        }
    }
    pub fn apply(&self, p_world: DVec3) -> DVec3 {
        self.r * p_world + self.t
    }
    pub fn inverse(&self) -> CameraToWorld {
        let (r, t) = invert_rigid(self.r, self.t);
        CameraToWorld { r, t }
    }
}

impl CameraToWorld {
    pub fn apply(&self, p_cam: DVec3) -> DVec3 {
        self.r * p_cam + self.t
    }
    pub fn inverse(&self) -> WorldToCamera {
        let (r, t) = invert_rigid(self.r, self.t);
        WorldToCamera { r, t }
    }
}

/// The inverse of the rigid transform `x -> r x + t`: `x -> r^T x - r^T t`.
fn invert_rigid(r: DMat3, t: DVec3) -> (DMat3, DVec3) {
    let rt = r.transpose();
    (rt, -(rt * t))
}

/// RMS pixel distance between where two cameras project the same world points (the points in
/// front of both); `None` when no point is. The reprojection error of an estimated pose
/// against the true one.
pub fn reprojection_rms(a: &Camera, b: &Camera, points: &[DVec3]) -> Option<f64> {
    let d2: Vec<f64> = points
        .iter()
        .filter_map(|p| Some(a.project(*p)?.distance_squared(b.project(*p)?)))
        .collect();
    (!d2.is_empty()).then(|| (d2.iter().sum::<f64>() / d2.len() as f64).sqrt())
}

/// The points that `cam` projects into its image (pixel centres at integers, so the frame is
/// [-0.5, width - 0.5) x [-0.5, height - 0.5)): where a photograph's reprojection error is
/// measured, since points outside the frame constrain nothing the photo shows.
pub fn points_in_frame(cam: &Camera, points: &[DVec3]) -> Vec<DVec3> {
    points
        .iter()
        .copied()
        .filter(|p| cam.project(*p).is_some_and(|q| cam.in_frame(q)))
        .collect()
}

/// A calibrated camera with its pose.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    pub width: u32,
    pub height: u32,
    pub intrinsics: Intrinsics,
    pub pose: WorldToCamera,
}

fn json_numbers(v: &serde_json::Value, what: &'static str) -> Result<Vec<f64>, CameraFileError> {
    let arr = v.as_array().ok_or(CameraFileError::NotNumbers { what })?;
    arr.iter()
        .map(|x| {
            x.as_f64().ok_or_else(|| CameraFileError::NonNumber {
                what,
                value: x.clone(),
            })
        })
        .collect()
}

/// The finite numbers of JSON array `v` (`what` names it in errors).
fn json_finite(v: &serde_json::Value, what: &'static str) -> Result<Vec<f64>, CameraFileError> {
    let d = json_numbers(v, what)?;
    if d.iter().any(|x| !x.is_finite()) {
        return Err(CameraFileError::NonFinite { what });
    }
    Ok(d)
}

fn json_matrix3(v: &serde_json::Value, what: &'static str) -> Result<DMat3, CameraFileError> {
    let rows = v.as_array().ok_or(CameraFileError::NotMatrix { what })?;
    if rows.len() != 3 {
        return Err(CameraFileError::Rows {
            what,
            rows: rows.len(),
        });
    }
    let mut m = [[0.0; 3]; 3];
    for (i, r) in rows.iter().enumerate() {
        let r = json_numbers(r, what)?;
        if r.len() != 3 {
            return Err(CameraFileError::RowLength {
                what,
                row: i,
                entries: r.len(),
            });
        }
        m[i] = [r[0], r[1], r[2]];
    }
    if m.iter().flatten().any(|x| !x.is_finite()) {
        return Err(CameraFileError::NonFinite { what });
    }
    Ok(DMat3::from_cols_array_2d(&m).transpose())
}

fn rows_of(m: &DMat3) -> [[f64; 3]; 3] {
    m.transpose().to_cols_array_2d()
}

/// Check that `r` is a rotation: |R^T R - I| <= 1e-6 elementwise and det within 1e-6 of +1.
pub fn check_rotation(r: &DMat3) -> Result<(), RotationError> {
    if !r.is_finite() {
        return Err(RotationError::NonFinite);
    }
    let e = r.transpose() * *r - DMat3::IDENTITY;
    let max = e.to_cols_array().iter().fold(0.0f64, |a, x| a.max(x.abs()));
    if max > 1e-6 {
        return Err(RotationError::NotOrthonormal { max });
    }
    let det = r.determinant();
    if (det - 1.0).abs() > 1e-6 {
        return Err(RotationError::NotRotation { det });
    }
    Ok(())
}

/// Image size of a camera file: positive integers, at most [`MAX_CAMERA_PIXELS`] pixels.
fn camera_size(j: &CameraFile) -> Result<(u32, u32), CameraFileError> {
    let dim = |v: &serde_json::Value, what: &'static str| -> Result<u32, CameraFileError> {
        v.as_u64()
            .filter(|&x| x > 0 && x <= u32::MAX as u64)
            .map(|x| x as u32)
            .ok_or_else(|| CameraFileError::Dimension {
                what,
                found: v.clone(),
            })
    };
    let width = dim(&j.width, "width")?;
    let height = dim(&j.height, "height")?;
    if width as u64 * height as u64 > MAX_CAMERA_PIXELS {
        return Err(CameraFileError::TooLarge {
            width,
            height,
            limit: MAX_CAMERA_PIXELS,
        });
    }
    Ok((width, height))
}

/// Intrinsics of a camera file: K without skew and with positive focal lengths, and the
/// distortion (none when absent or null).
fn camera_intrinsics(j: &CameraFile) -> Result<Intrinsics, CameraFileError> {
    let k = json_matrix3(&j.K, "K")?;
    let kr = rows_of(&k);
    if kr[0][1] != 0.0 || kr[1][0] != 0.0 || kr[2] != [0.0, 0.0, 1.0] {
        return Err(CameraFileError::Skew(kr));
    }
    let (fx, fy, cx, cy) = (kr[0][0], kr[1][1], kr[0][2], kr[1][2]);
    if !(fx > 0.0 && fy > 0.0) {
        return Err(CameraFileError::Focal { fx, fy });
    }
    let dist = match &j.dist {
        None | Some(serde_json::Value::Null) => Distortion::default(),
        Some(v) => {
            let d = json_numbers(v, "dist")?;
            if !(d.len() == 4 || d.len() == 5) {
                return Err(CameraFileError::DistLength(d.len()));
            }
            let d = json_finite(v, "dist")?;
            Distortion {
                k1: d[0],
                k2: d[1],
                p1: d[2],
                p2: d[3],
                k3: d.get(4).copied().unwrap_or(0.0),
            }
        }
    };
    Ok(Intrinsics {
        fx,
        fy,
        cx,
        cy,
        dist,
    })
}

/// Pose of a camera file: R a rotation, t three finite numbers.
fn camera_pose(j: &CameraFile) -> Result<WorldToCamera, CameraFileError> {
    let r = json_matrix3(&j.R, "R")?;
    check_rotation(&r)?;
    let t = json_numbers(&j.t, "t")?;
    if t.len() != 3 {
        return Err(CameraFileError::TranslationLength(t.len()));
    }
    let t = json_finite(&j.t, "t")?;
    Ok(WorldToCamera {
        r,
        t: DVec3::new(t[0], t[1], t[2]),
    })
}

/// The most pixels a camera file may have: the image limit, [`igi_imaging::io::MAX_IMAGE_PIXELS`]
/// (2^29, 536 Mpixel); an HDR image that size needs 6.5 GiB. Larger sizes are refused when the
/// camera is read, before any allocation.
pub const MAX_CAMERA_PIXELS: u64 = igi_imaging::io::MAX_IMAGE_PIXELS;

impl Camera {
    /// Camera without distortion and identity pose.
    pub fn pinhole(width: u32, height: u32, fx: f64, fy: f64, cx: f64, cy: f64) -> Self {
        Camera {
            width,
            height,
            intrinsics: Intrinsics {
                fx,
                fy,
                cx,
                cy,
                dist: Distortion::default(),
            },
            pose: WorldToCamera::identity(),
        }
    }

    /// A pinhole camera (no distortion, principal point at the image centre) at `eye` looking at
    /// `target`, world Z up in the image ([`WorldToCamera::look_at`]), with a horizontal field
    /// of view of `hfov_deg` degrees. An error when the view direction is degenerate (`eye` at
    /// `target`) or vertical.
    pub fn look_at(
        eye: DVec3,
        target: DVec3,
        width: u32,
        height: u32,
        hfov_deg: f64,
    ) -> Result<Camera, CameraError> {
        let pose = WorldToCamera::look_at(eye, target, DVec3::Z).ok_or_else(|| {
            CameraError::InvalidInput(format!("camera at {eye} looking at {target} is degenerate"))
        })?;
        let f = 0.5 * width as f64 / (0.5 * hfov_deg.to_radians()).tan();
        let mut cam = Camera::pinhole(
            width,
            height,
            f,
            f,
            width as f64 / 2.0 - 0.5,
            height as f64 / 2.0 - 0.5,
        );
        cam.pose = pose;
        Ok(cam)
    }

    /// Parse and validate a camera from FORMATS.md JSON text; `path` is used in errors.
    pub fn from_json_str(text: &str, path: &Path) -> Result<Camera, CameraError> {
        let j = CameraFile::parse(text)
            .map_err(|e| CameraError::camera(path, CameraFileError::Json(e)))?;
        Self::from_file(&j, path)
    }

    /// Checks a parsed camera file and builds the camera; `path` is used in errors.
    pub fn from_file(j: &CameraFile, path: &Path) -> Result<Camera, CameraError> {
        let err = |problem| CameraError::camera(path, problem);
        let (width, height) = camera_size(j).map_err(err)?;
        let intrinsics = camera_intrinsics(j).map_err(err)?;
        intrinsics.check_lens(width, height).map_err(err)?;
        let pose = camera_pose(j).map_err(err)?;
        Ok(Camera {
            width,
            height,
            intrinsics,
            pose,
        })
    }

    /// Load and validate a camera JSON file (FORMATS.md).
    pub fn load(path: &Path) -> Result<Camera, CameraError> {
        let text = std::fs::read_to_string(path).map_err(|e| CameraError::io(path, e))?;
        Self::from_json_str(&text, path)
    }

    /// JSON text in the FORMATS.md layout (`dist` omitted when zero).
    pub fn to_json_string(&self) -> String {
        self.to_file().to_json()
    }

    /// The camera file of this camera (`dist` omitted when zero).
    pub fn to_file(&self) -> CameraFile {
        let i = &self.intrinsics;
        CameraFile {
            width: self.width.into(),
            height: self.height.into(),
            K: serde_json::json!(i.k_matrix()),
            dist: (!i.dist.is_zero()).then(|| serde_json::json!(i.dist.to_array())),
            R: serde_json::json!(rows_of(&self.pose.r)),
            t: serde_json::json!(self.pose.t.to_array()),
        }
    }

    /// Save as JSON, atomically.
    pub fn save(&self, path: &Path) -> Result<(), CameraError> {
        Ok(self.to_file().write(path)?)
    }

    /// Pixel coordinates of a world point (distortion applied); `None` behind the camera.
    #[inline]
    pub fn project(&self, p_world: DVec3) -> Option<DVec2> {
        let pc = self.pose.apply(p_world);
        if !(pc.z > 0.0) {
            return None;
        }
        Some(
            self.intrinsics
                .to_pixel(DVec2::new(pc.x / pc.z, pc.y / pc.z)),
        )
    }

    /// Whether pixel coordinates `q` lie in the frame (pixel centres at integers, so the frame
    /// is [-0.5, width - 0.5) x [-0.5, height - 0.5)).
    pub fn in_frame(&self, q: DVec2) -> bool {
        let (w, h) = (self.width as f64 - 0.5, self.height as f64 - 0.5);
        q.x >= -0.5 && q.y >= -0.5 && q.x < w && q.y < h
    }

    /// World-space ray (origin = camera centre, unit direction) through pixel (u, v).
    /// If undistortion fails to converge (far outside the valid lens field) the
    /// distorted normalised point is used.
    pub fn pixel_ray(&self, u: f64, v: f64) -> (DVec3, DVec3) {
        let i = &self.intrinsics;
        let pd = DVec2::new((u - i.cx) / i.fx, (v - i.cy) / i.fy);
        let xn = i.dist.undistort(pd).unwrap_or(pd);
        let dir_cam = DVec3::new(xn.x, xn.y, 1.0).normalize();
        let c2w = self.pose.inverse();
        (c2w.t, (c2w.r * dir_cam).normalize())
    }

    /// Camera centre in world coordinates (`-R^T t`).
    pub fn center_world(&self) -> DVec3 {
        self.pose.inverse().t
    }

    /// The same camera without lens distortion.
    pub fn without_distortion(&self) -> Camera {
        let mut c = self.clone();
        c.intrinsics.dist = Distortion::default();
        c
    }
}

/// [`Camera::pixel_ray`] in f32 for a renderer's inner loop: the camera-to-world rotation,
/// the centre and the intrinsics are converted once, and a ray costs a few multiplies and one
/// normalisation. A camera with lens distortion goes through the f64 undistortion (Newton
/// steps) of [`Camera::pixel_ray`], whose cost dwarfs the conversion.
#[derive(Clone, Copy, Debug)]
pub struct PixelRays<'a> {
    camera: &'a Camera,
    distorted: bool,
    origin: Vec3,
    /// Columns of the camera-to-world rotation.
    r: [Vec3; 3],
    inv_f: Vec2,
    c: Vec2,
}

impl<'a> PixelRays<'a> {
    pub fn new(camera: &'a Camera) -> Self {
        let i = &camera.intrinsics;
        let c2w = camera.pose.inverse();
        PixelRays {
            camera,
            distorted: !i.dist.is_zero(),
            origin: c2w.t.as_vec3(),
            r: [
                c2w.r.x_axis.as_vec3(),
                c2w.r.y_axis.as_vec3(),
                c2w.r.z_axis.as_vec3(),
            ],
            inv_f: Vec2::new((1.0 / i.fx) as f32, (1.0 / i.fy) as f32),
            c: Vec2::new(i.cx as f32, i.cy as f32),
        }
    }

    /// Image width of the camera, in pixels.
    pub fn width(&self) -> u32 {
        self.camera.width
    }

    /// World-space ray (origin = camera centre, unit direction) through pixel (u, v), as
    /// [`Camera::pixel_ray`] gives it, rounded to f32.
    #[inline]
    pub fn ray(&self, u: f32, v: f32) -> (Vec3, Vec3) {
        if self.distorted {
            let (o, d) = self.camera.pixel_ray(u as f64, v as f64);
            return (o.as_vec3(), d.as_vec3());
        }
        let xn = (Vec2::new(u, v) - self.c) * self.inv_f;
        let d = self.r[0] * xn.x + self.r[1] * xn.y + self.r[2];
        (self.origin, d.normalize())
    }
}

/// Remove lens distortion from `img` taken with `cam`: the output has the same size and
/// K and no distortion. Each output pixel is the bilinear sample of the input at the
/// distorted position; pixels that map outside the input (or onto invalid pixels) are
/// black and marked invalid. Returns the image and the output camera.
pub fn undistort_image(img: &HdrImage, cam: &Camera) -> Result<(HdrImage, Camera), CameraError> {
    if img.width != cam.width as usize || img.height != cam.height as usize {
        return Err(CameraError::InvalidInput(format!(
            "image is {}x{} but the camera is {}x{}",
            img.width, img.height, cam.width, cam.height
        )));
    }
    let i = cam.intrinsics;
    let mut out = HdrImage::new(img.width, img.height);
    let w = img.width;
    out.pixels
        .par_chunks_mut(w)
        .zip(out.valid.par_chunks_mut(w))
        .enumerate()
        .for_each(|(y, (prow, vrow))| {
            for x in 0..w {
                let xn = DVec2::new((x as f64 - i.cx) / i.fx, (y as f64 - i.cy) / i.fy);
                let src = i.to_pixel(xn);
                match img.bilinear(src.x as f32, src.y as f32) {
                    Some(v) => prow[x] = v,
                    None => {
                        prow[x] = [0.0; 3];
                        vrow[x] = false;
                    }
                }
            }
        });
    Ok((out, cam.without_distortion()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn test_camera() -> Camera {
        let r = DMat3::from_rotation_z(0.3)
            * DMat3::from_rotation_x(-1.2)
            * DMat3::from_rotation_y(0.1);
        Camera {
            width: 640,
            height: 480,
            intrinsics: Intrinsics {
                fx: 500.0,
                fy: 510.0,
                cx: 320.5,
                cy: 239.0,
                dist: Distortion {
                    k1: -0.2,
                    k2: 0.05,
                    p1: 0.001,
                    p2: -0.0005,
                    k3: 0.0,
                },
            },
            pose: WorldToCamera {
                r,
                t: DVec3::new(0.1, -0.2, 3.0),
            },
        }
    }

    /// Points are kept exactly when they project inside the frame: on the pixel grid's edge,
    /// just outside it, behind the camera.
    #[test]
    fn points_in_frame_keeps_what_the_image_shows() {
        let cam = test_camera();
        let c2w = cam.pose.inverse();
        let at = |u: f64, v: f64, depth: f64| {
            let (o, d) = cam.pixel_ray(u, v);
            let z = cam.pose.apply(o + d).z - cam.pose.apply(o).z; // depth per unit along d
            o + d * (depth / z)
        };
        let inside = [
            at(-0.49, 0.0, 3.0),
            at(639.49, 479.49, 10.0),
            at(320.0, 240.0, 1.0),
        ];
        let outside = [
            at(-0.51, 100.0, 3.0),
            at(100.0, 479.51, 3.0),
            at(700.0, 240.0, 2.0),
        ];
        let behind = c2w.apply(DVec3::new(0.0, 0.0, -2.0));
        let all: Vec<DVec3> = inside
            .iter()
            .chain(&outside)
            .copied()
            .chain([behind])
            .collect();
        let kept = points_in_frame(&cam, &all);
        assert_eq!(kept.len(), 3, "{kept:?}");
        for (k, p) in inside.iter().enumerate() {
            assert!(kept[k].distance(*p) < 1e-12);
        }
    }

    #[test]
    fn distort_matches_opencv_formula_by_hand() {
        let d = Distortion {
            k1: 0.1,
            k2: 0.01,
            p1: 0.001,
            p2: 0.002,
            k3: 0.001,
        };
        let p = d.distort(DVec2::new(0.5, -0.25));
        // r2 = 0.3125; radial = 1 + 0.03125 + 0.0009765625 + 0.000030517578125
        let radial = 1.032_257_080_078_125;
        let xd = 0.5 * radial + 2.0 * 0.001 * 0.5 * -0.25 + 0.002 * (0.3125 + 0.5);
        let yd = -0.25 * radial + 0.001 * (0.3125 + 0.125) + 2.0 * 0.002 * 0.5 * -0.25;
        assert!((p.x - xd).abs() < 1e-15 && (p.y - yd).abs() < 1e-15);
    }

    #[test]
    fn undistort_round_trip_moderate_and_strong() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        let cases = [
            Distortion {
                k1: -0.2,
                k2: 0.05,
                p1: 0.001,
                p2: -0.0005,
                k3: 0.0,
            },
            // strong barrel (fisheye-like) distortion
            Distortion {
                k1: -0.45,
                k2: 0.25,
                p1: 0.004,
                p2: -0.003,
                k3: -0.06,
            },
            // strong pincushion
            Distortion {
                k1: 0.6,
                k2: 0.4,
                p1: -0.01,
                p2: 0.01,
                k3: 0.2,
            },
        ];
        let f = 800.0;
        for d in cases {
            let mut worst = 0.0f64;
            for _ in 0..2000 {
                let p = DVec2::new(rng.gen_range(-0.7..0.7), rng.gen_range(-0.5..0.5));
                let pd = d.distort(p);
                let back = d.undistort(pd).expect("converges");
                worst = worst.max((back - p).length() * f);
                // residual in the distorted domain is below 1e-10
                assert!((d.distort(back) - pd).length() < 1e-10);
            }
            assert!(worst < 1e-4, "{d:?}: worst round trip {worst} px");
        }
    }

    #[test]
    fn f32_pixel_rays_match_the_f64_ones() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
        for cam in [test_camera(), test_camera().without_distortion()] {
            let rays = PixelRays::new(&cam);
            assert_eq!(rays.width(), 640);
            for _ in 0..500 {
                let (u, v) = (rng.gen_range(-0.5f32..639.5), rng.gen_range(-0.5f32..479.5));
                let (o, d) = cam.pixel_ray(u as f64, v as f64);
                let (o32, d32) = rays.ray(u, v);
                assert!((o32.as_dvec3() - o).length() < 1e-6 * (1.0 + o.length()));
                assert!(
                    (d32.as_dvec3() - d).length() < 5e-7,
                    "{u} {v}: {d32} vs {d}"
                );
            }
        }
    }

    #[test]
    fn project_pixel_ray_round_trip() {
        let cam = test_camera();
        let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
        for _ in 0..500 {
            let (u, v) = (rng.gen_range(0.0..639.0), rng.gen_range(0.0..479.0));
            let (o, d) = cam.pixel_ray(u, v);
            assert!((d.length() - 1.0).abs() < 1e-12);
            let p = o + d * rng.gen_range(0.5..20.0);
            let px = cam.project(p).unwrap();
            assert!((px - DVec2::new(u, v)).length() < 1e-6, "{u} {v} -> {px}");
        }
        // behind the camera
        let c = cam.center_world();
        let fwd = cam.pose.inverse().r * DVec3::Z;
        assert!(cam.project(c - fwd).is_none());
        // principal point maps to the optical axis
        let mut nd = cam.without_distortion();
        nd.intrinsics.cx = 320.0;
        let (o, d) = nd.pixel_ray(320.0, 239.0);
        assert!((o - c).length() < 1e-12 && (d - fwd).length() < 1e-12);
    }

    #[test]
    fn pose_inverse_round_trip() {
        let cam = test_camera();
        let p = DVec3::new(1.0, 2.0, -0.5);
        let c2w = cam.pose.inverse();
        assert!((c2w.apply(cam.pose.apply(p)) - p).length() < 1e-12);
        let back = c2w.inverse();
        assert!((back.t - cam.pose.t).length() < 1e-12);
        assert!(back.r.abs_diff_eq(cam.pose.r, 1e-12));
    }

    #[test]
    fn json_round_trip_and_optional_dist() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("cam.json");
        let cam = test_camera();
        cam.save(&p).unwrap();
        let back = Camera::load(&p).unwrap();
        // serde_json parses floats to within 1 ulp
        assert!(
            back.pose.r.abs_diff_eq(cam.pose.r, 1e-15)
                && back.pose.t.abs_diff_eq(cam.pose.t, 1e-15)
        );
        assert_eq!(back.intrinsics, cam.intrinsics);
        assert_eq!((back.width, back.height), (640, 480));
        let text = r#"{"width": 4, "height": 3, "K": [[2,0,1.5],[0,2,1],[0,0,1]],
                       "R": [[1,0,0],[0,1,0],[0,0,1]], "t": [0,0,0]}"#;
        let c = Camera::from_json_str(text, &p).unwrap();
        assert!(c.intrinsics.dist.is_zero());
        assert_eq!(
            c.project(DVec3::new(0.0, 0.0, 1.0)),
            Some(DVec2::new(1.5, 1.0))
        );
    }

    #[test]
    fn json_rejects_bad_rotation_shapes_and_values() {
        let p = Path::new("/some/cam.json");
        let base = |r: &str, extra: &str| {
            format!(
                r#"{{"width": 4, "height": 3, "K": [[2,0,1.5],[0,2,1],[0,0,1]], "R": {r}, "t": [0,0,0]{extra}}}"#
            )
        };
        let check = |text: String, needle: &str| {
            let e = Camera::from_json_str(&text, p).unwrap_err().to_string();
            assert!(
                e.contains("/some/cam.json") && e.contains(needle),
                "{e} (wanted {needle})"
            );
        };
        check(base("[[1,0,0],[0,1,0],[0,0,1.001]]", ""), "not orthonormal");
        check(base("[[1,0,0],[0,1,0],[0,0,-1]]", ""), "det(R)");
        check(base("[[1,0,0],[0,1,0]]", ""), "3 rows");
        check(base("[[1,0,0],[0,1],[0,0,1]]", ""), "row 1");
        check(base("[[1,0,0],[0,1,0],[0,0,null]]", ""), "non-number");
        check(
            base("[[1,0,0],[0,1,0],[0,0,1]]", r#", "dist": [0.1, 0.2]"#),
            "dist",
        );
        check(
            base("[[1,0,0],[0,1,0],[0,0,1]]", "").replace("\"t\": [0,0,0]", "\"t\": [0,0]"),
            "t must have 3",
        );
        check(
            base("[[1,0,0],[0,1,0],[0,0,1]]", "").replace("\"width\": 4", "\"width\": -4"),
            "width",
        );
        check("{ not json".into(), "invalid camera file");
        // 1e-7 perturbation is accepted (within tolerance)
        assert!(Camera::from_json_str(&base("[[1,0,0],[0,1,0],[0,0,1.0000001]]", ""), p).is_ok());
    }

    #[test]
    fn undistort_image_straightens_synthetic_distorted_image() {
        // Render a smooth pattern seen through a distorted camera; undistorting it must give
        // the pattern as seen by the distortion-free camera.
        let mut cam = Camera::pinhole(160, 120, 120.0, 120.0, 79.5, 59.5);
        cam.intrinsics.dist = Distortion {
            k1: 0.2,
            k2: 0.02,
            p1: 0.002,
            p2: -0.001,
            k3: 0.0,
        };
        let pattern = |xn: DVec2| -> [f32; 3] {
            [
                (1.0 + (3.0 * xn.x).sin() * (2.0 * xn.y).cos()) as f32,
                (xn.x + 2.0) as f32,
                (xn.y * xn.y) as f32,
            ]
        };
        let mut distorted = HdrImage::new(160, 120);
        for y in 0..120 {
            for x in 0..160 {
                let xn = cam
                    .intrinsics
                    .to_normalized(DVec2::new(x as f64, y as f64))
                    .unwrap();
                distorted.set(x, y, pattern(xn));
            }
        }
        let (und, ocam) = undistort_image(&distorted, &cam).unwrap();
        assert!(ocam.intrinsics.dist.is_zero());
        assert_eq!(ocam.intrinsics.fx, 120.0);
        let mut max_err = 0.0f32;
        let mut n = 0;
        for y in 0..120 {
            for x in 0..160 {
                if !und.is_valid(x, y) {
                    continue;
                }
                n += 1;
                let xn = DVec2::new((x as f64 - 79.5) / 120.0, (y as f64 - 59.5) / 120.0);
                let t = pattern(xn);
                let g = und.get(x, y);
                for c in 0..3 {
                    max_err = max_err.max((t[c] - g[c]).abs());
                }
            }
        }
        assert!(n > 120 * 160 / 2, "{n}");
        // bilinear interpolation error of a smooth pattern with ~0.03 /px gradient
        assert!(max_err < 5e-3, "max err {max_err}");
        // pincushion distortion: corners of the undistorted image fall outside the input
        assert!(!und.is_valid(0, 0));
    }
}

impl WorldToCamera {
    /// The pose of a camera at `eye` looking at `target`, with world `up` (Z in igi's frame)
    /// pointing up in the image (OpenCV axes: x right, y down, z forward). `None` when the view
    /// direction is degenerate or parallel to `up`.
    pub fn look_at(eye: DVec3, target: DVec3, up: DVec3) -> Option<WorldToCamera> {
        let z = (target - eye).try_normalize()?;
        let x = z.cross(up).try_normalize()?;
        let y = z.cross(x);
        let r = DMat3::from_cols(x, y, z).transpose();
        Some(WorldToCamera { r, t: -(r * eye) })
    }
}

#[cfg(test)]
mod look_at_tests {
    use super::*;

    #[test]
    fn look_at_puts_the_target_at_the_principal_point_and_up_at_the_top() {
        let pose = WorldToCamera::look_at(
            DVec3::new(1.0, -5.0, 2.0),
            DVec3::new(0.0, 0.0, 1.0),
            DVec3::Z,
        )
        .unwrap();
        let mut cam = Camera::pinhole(100, 80, 90.0, 90.0, 49.5, 39.5);
        cam.pose = pose;
        let c = cam.project(DVec3::new(0.0, 0.0, 1.0)).unwrap();
        assert!(
            (c.x - 49.5).abs() < 1e-9 && (c.y - 39.5).abs() < 1e-9,
            "{c}"
        );
        let above = cam.project(DVec3::new(0.0, 0.0, 1.5)).unwrap();
        assert!(
            above.y < c.y,
            "a point above the target is higher in the image"
        );
        assert!(check_rotation(&cam.pose.r).is_ok());
        assert!((cam.center_world() - DVec3::new(1.0, -5.0, 2.0)).length() < 1e-12);
    }

    #[test]
    fn camera_look_at_spans_its_field_of_view_and_refuses_a_vertical_view() {
        let (eye, target) = (DVec3::new(4.0, 0.0, 1.0), DVec3::new(0.0, 0.0, 1.0));
        let cam = Camera::look_at(eye, target, 64, 48, 90.0).unwrap();
        let c = cam.project(target).unwrap();
        assert!(
            (c.x - 31.5).abs() < 1e-9 && (c.y - 23.5).abs() < 1e-9,
            "{c}"
        );
        // 45 degrees off the axis lands on the frame's edge (x = -0.5 or width - 0.5)
        let edge = cam.project(DVec3::new(0.0, 4.0, 1.0)).unwrap();
        assert!((edge.x - 63.5).abs() < 1e-9, "{edge}");
        assert!(Camera::look_at(eye, eye + DVec3::Z, 64, 48, 90.0).is_err());
        assert!(Camera::look_at(eye, eye, 64, 48, 90.0).is_err());
    }
}
