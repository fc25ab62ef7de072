//! Hand-held BRDF measurement with the sample frame of Debevec et al. 2004 (3.2.1): from one
//! photograph of the frame, recover
//!
//! - the camera pose from the four fiducials ([`crate::fiducial`]: user-supplied fiducial pixels
//!   and the pure-Rust [`igi_camera::planar::pose_from_plane`], or ArUco detection and PnP from
//!   [`igi_camera::cv`] with the `opencv` feature),
//! - the light position from the highlights in the two glossy black spheres
//!   ([`crate::highlight::find_highlight`]: the camera rays through the highlights' sub-pixel
//!   centres, reflected off the spheres; the light is the midpoint of the two reflected rays'
//!   closest approach),
//! - the light's intensity from the white reflectance standard,
//! - an orthographic (fronto-parallel) view of the sample plane (a homography, plus the lens
//!   distortion), and the mean `pi f` over chosen regions of it,
//!
//! and turn them into [`BrdfSample`]s of the samples CSV (FORMATS.md).
//!
//! Geometry and normalisation. Everything is in the frame's own coordinates (metres, z up out
//! of the sample plane z = 0; these are the "world" of the recovered pose). The light is a
//! point source of intensity `I` (per channel) at `L`. A surface point `p` of the plane with
//! BRDF `f` then shows radiance `f I cos(theta_l) / d^2`, with `d = |L - p|` and
//! `cos(theta_l) = (L - p).z / d`; the white standard (Lambertian reflectance `rho_w`) shows
//! `rho_w / pi I cos(theta_l) / d^2`. So
//!
//! - `I = mean over the white standard of pi Lw d^2 / (rho_w cos(theta_l))`, and
//! - per orthographic pixel of a region, `pi f = pi L d^2 / (I cos(theta_l))` with that pixel's own
//!   `d` and `theta_l`; the sample's value is the mean over the region's pixels, and its
//!   directions are those from the region's centre to the light and to the camera centre.
//!
//! This divides out the differing light direction and distance between the standard and each
//! region. It assumes the light is isotropic over the small solid angle the frame subtends from
//! it, and ignores the light's size (its distance is many times its size).

// `!(x > 0.0)` on purpose: it is also true for NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord, clippy::nonminimal_bool)]

use std::path::{Path, PathBuf};

use glam::{DMat3, DVec2, DVec3, Vec3};
use igi_camera::{cv, Camera, WorldToCamera};
use igi_imaging::HdrImage;
use serde::{Deserialize, Serialize};

use igi_brdf::BrdfSample;

use crate::fiducial::{match_markers, pose_from_marked_points, FiducialMarker};
use crate::highlight::{find_highlight, Highlight, HighlightLimits};
use crate::sphere::{SphereKind, SphereView};
use crate::CaptureError;

/// One fiducial of the frame: its centre on the frame plane (the point a user marks for
/// `--corners`) and, for ArUco detection, the marker id and side length.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Fiducial {
    pub center: [f64; 2],
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub aruco_id: Option<i32>,
    /// Marker side length, metres (ArUco only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub size: Option<f64>,
}

/// A glossy black sphere (frame coordinates).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrameSphere {
    pub center: [f64; 3],
    pub radius: f64,
}

/// A reflectance: one number (grey) or per channel.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(
    untagged,
    expecting = "a reflectance: one number (grey) or three [r, g, b]"
)]
pub enum Reflectance {
    Grey(f64),
    Rgb([f64; 3]),
}

impl Reflectance {
    pub fn rgb(&self) -> DVec3 {
        match *self {
            Reflectance::Grey(x) => DVec3::splat(x),
            Reflectance::Rgb(c) => DVec3::from_array(c),
        }
    }
}

fn default_white() -> Reflectance {
    Reflectance::Grey(0.99)
}

/// The white reflectance standard: an axis-aligned rectangle at height `z` (default 0).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WhiteStandard {
    pub min: [f64; 2],
    pub max: [f64; 2],
    #[serde(default)]
    pub z: f64,
    /// Lambertian reflectance (default 0.99).
    #[serde(default = "default_white")]
    pub reflectance: Reflectance,
}

/// The orthographic view: the rectangle `min..max` of the sample plane at `px_per_m` pixels per
/// metre; row 0 at `max[1]` (the view from above, x to the right, y up).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Ortho {
    pub min: [f64; 2],
    pub max: [f64; 2],
    pub px_per_m: f64,
}

fn default_region_px() -> usize {
    30
}

/// A measured region: `size_px` x `size_px` orthographic pixels (default 30) centred on `center`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Region {
    pub material: String,
    pub center: [f64; 2],
    #[serde(default = "default_region_px")]
    pub size_px: usize,
}

fn default_dict() -> String {
    "4x4_50".into()
}

/// The sample-frame description file (JSON; docs/BRDF.md "Measuring samples").
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SampleFrame {
    /// Four (or more) fiducials on the plane z = 0, in the order `--corners` lists them.
    pub fiducials: Vec<Fiducial>,
    /// ArUco dictionary: `4x4_50` (default), `5x5_100`, `6x6_250` or `original`.
    #[serde(default = "default_dict")]
    pub aruco_dictionary: String,
    /// The two glossy black spheres.
    pub spheres: Vec<FrameSphere>,
    pub white: WhiteStandard,
    pub ortho: Ortho,
    pub regions: Vec<Region>,
}

fn v2(a: [f64; 2]) -> DVec2 {
    DVec2::from_array(a)
}

impl SampleFrame {
    /// Read and validate a frame file; errors name it.
    pub fn load(path: &Path) -> Result<SampleFrame, CaptureError> {
        let text = std::fs::read_to_string(path).map_err(|source| CaptureError::Io {
            path: path.into(),
            source,
        })?;
        Self::from_json_str(&text, path)
    }

    /// Parse and validate frame JSON text; `path` names it in errors.
    pub fn from_json_str(text: &str, path: &Path) -> Result<SampleFrame, CaptureError> {
        let err = |msg: String| CaptureError::File {
            path: path.into(),
            msg: format!("sample frame: {msg}"),
        };
        let f: SampleFrame = serde_json::from_str(text).map_err(|e| err(e.to_string()))?;
        f.validate().map_err(err)?;
        Ok(f)
    }

    fn validate(&self) -> Result<(), String> {
        self.validate_fiducials()?;
        self.validate_spheres()?;
        self.validate_white_and_ortho()?;
        self.validate_regions()
    }

    /// At least four finite fiducials, no three (nearly) collinear; a known dictionary.
    fn validate_fiducials(&self) -> Result<(), String> {
        let finite = |xs: &[f64]| xs.iter().all(|x| x.is_finite());
        if self.fiducials.len() < 4 {
            return Err(format!(
                "needs four fiducials, found {}",
                self.fiducials.len()
            ));
        }
        for (i, fd) in self.fiducials.iter().enumerate() {
            if !finite(&fd.center) || fd.size.is_some_and(|s| !(s > 0.0 && s.is_finite())) {
                return Err(format!(
                    "fiducial {i}: centre must be finite and size positive"
                ));
            }
            if fd.aruco_id.is_some() != fd.size.is_some() {
                return Err(format!("fiducial {i}: `aruco_id` and `size` go together"));
            }
        }
        let c: Vec<DVec2> = self.fiducials.iter().map(|f| v2(f.center)).collect();
        let spread = c.iter().map(|p| (*p - c[0]).length()).fold(0.0, f64::max);
        let mut min_area = f64::INFINITY;
        for i in 0..c.len() {
            for j in i + 1..c.len() {
                for k in j + 1..c.len() {
                    min_area = min_area.min((c[j] - c[i]).perp_dot(c[k] - c[i]).abs() * 0.5);
                }
            }
        }
        if !(min_area > 1e-3 * spread * spread) {
            return Err(
                "three fiducials are (nearly) collinear: the pose would be degenerate".into(),
            );
        }
        aruco_dict(&self.aruco_dictionary)?;
        Ok(())
    }

    /// Exactly two finite, positive, disjoint spheres.
    fn validate_spheres(&self) -> Result<(), String> {
        let finite = |xs: &[f64]| xs.iter().all(|x| x.is_finite());
        if self.spheres.len() != 2 {
            return Err(format!(
                "needs exactly two spheres, found {}",
                self.spheres.len()
            ));
        }
        for (i, s) in self.spheres.iter().enumerate() {
            if !finite(&s.center) || !(s.radius > 0.0 && s.radius.is_finite()) {
                return Err(format!(
                    "sphere {i}: centre must be finite and radius positive"
                ));
            }
        }
        if (DVec3::from_array(self.spheres[0].center) - DVec3::from_array(self.spheres[1].center))
            .length()
            < self.spheres[0].radius + self.spheres[1].radius
        {
            return Err("the two spheres overlap".into());
        }
        Ok(())
    }

    /// The white standard and the orthographic rectangle: ordered, finite, sensible sizes.
    fn validate_white_and_ortho(&self) -> Result<(), String> {
        let finite = |xs: &[f64]| xs.iter().all(|x| x.is_finite());
        let w = &self.white;
        if !finite(&w.min)
            || !finite(&w.max)
            || !w.z.is_finite()
            || !(w.max[0] > w.min[0] && w.max[1] > w.min[1])
        {
            return Err("white: `min` must be below `max` in x and y (finite metres)".into());
        }
        let rho = w.reflectance.rgb();
        if !(rho.min_element() > 0.0 && rho.max_element() <= 1.5 && rho.is_finite()) {
            return Err(format!(
                "white: reflectance must be in (0, 1.5], found {:?}",
                rho.to_array()
            ));
        }
        let o = &self.ortho;
        if !finite(&o.min) || !finite(&o.max) || !(o.max[0] > o.min[0] && o.max[1] > o.min[1]) {
            return Err("ortho: `min` must be below `max` in x and y (finite metres)".into());
        }
        if !(o.px_per_m > 0.0 && o.px_per_m.is_finite()) {
            return Err(format!(
                "ortho: px_per_m must be positive, found {}",
                o.px_per_m
            ));
        }
        let (ow, oh) = self.ortho_size();
        if ow == 0 || oh == 0 || ow > 20000 || oh > 20000 {
            return Err(format!(
                "ortho: the view would be {ow}x{oh} pixels (1 to 20000 each)"
            ));
        }
        Ok(())
    }

    /// At least one region, each named plainly and inside the orthographic rectangle.
    fn validate_regions(&self) -> Result<(), String> {
        let o = &self.ortho;
        let finite = |xs: &[f64]| xs.iter().all(|x| x.is_finite());
        if self.regions.is_empty() {
            return Err("needs at least one region".into());
        }
        for (i, r) in self.regions.iter().enumerate() {
            if r.material.trim().is_empty() || r.material.contains([',', '"', '\n', '\r']) {
                return Err(format!(
                    "region {i}: material name {:?} must be non-empty, without commas or quotes",
                    r.material
                ));
            }
            if r.size_px == 0 {
                return Err(format!(
                    "region {i} ({}): size_px must be at least 1",
                    r.material
                ));
            }
            let h = r.size_px as f64 / o.px_per_m * 0.5;
            let (cx, cy) = (r.center[0], r.center[1]);
            if !finite(&r.center)
                || cx - h < o.min[0]
                || cx + h > o.max[0]
                || cy - h < o.min[1]
                || cy + h > o.max[1]
            {
                return Err(format!(
                    "region {i} ({}): its {} px square must lie inside the ortho rectangle",
                    r.material, r.size_px
                ));
            }
        }
        Ok(())
    }

    /// Width and height of the orthographic view, pixels.
    pub fn ortho_size(&self) -> (usize, usize) {
        let o = &self.ortho;
        (
            ((o.max[0] - o.min[0]) * o.px_per_m).round() as usize,
            ((o.max[1] - o.min[1]) * o.px_per_m).round() as usize,
        )
    }

    /// The affine map from orthographic pixel (column, row) to the frame plane point (x, y, 1).
    pub fn ortho_to_plane(&self) -> DMat3 {
        let o = &self.ortho;
        let s = 1.0 / o.px_per_m;
        DMat3::from_cols(
            DVec3::new(s, 0.0, 0.0),
            DVec3::new(0.0, -s, 0.0),
            DVec3::new(o.min[0] + 0.5 * s, o.max[1] - 0.5 * s, 1.0),
        )
    }

    /// The four corners of an ArUco fiducial in OpenCV's order (clockwise from the marker's
    /// top-left), for a marker printed with its image x along frame +x and its image "up" along
    /// frame +y. `None` for a fiducial without an id.
    pub fn aruco_corners(&self, i: usize) -> Option<[DVec3; 4]> {
        let f = &self.fiducials[i];
        let (c, h) = (v2(f.center), f.size? * 0.5);
        Some(
            [(-h, h), (h, h), (h, -h), (-h, -h)]
                .map(|(dx, dy)| DVec3::new(c.x + dx, c.y + dy, 0.0)),
        )
    }

    /// The fiducials that are ArUco markers, with their corners ([`Self::aruco_corners`]).
    pub fn aruco_markers(&self) -> Vec<FiducialMarker> {
        (0..self.fiducials.len())
            .filter_map(|i| {
                Some(FiducialMarker {
                    id: self.fiducials[i].aruco_id?,
                    corners: self.aruco_corners(i)?,
                })
            })
            .collect()
    }
}

fn aruco_dict(name: &str) -> Result<cv::ArucoDict, String> {
    match name.to_ascii_lowercase().as_str() {
        "4x4_50" => Ok(cv::ArucoDict::Dict4x4_50),
        "5x5_100" => Ok(cv::ArucoDict::Dict5x5_100),
        "6x6_250" => Ok(cv::ArucoDict::Dict6x6_250),
        "original" => Ok(cv::ArucoDict::Original),
        other => Err(format!(
            "unknown aruco_dictionary {other:?} (4x4_50, 5x5_100, 6x6_250, original)"
        )),
    }
}

/// How the pose of a photograph is found.
#[derive(Clone, Debug, PartialEq)]
pub enum PoseInput {
    /// Pixels of the fiducials' centres, in the frame file's order.
    Corners(Vec<DVec2>),
    /// ArUco detection and PnP (needs the `opencv` feature of igi-imaging).
    Aruco,
}

/// Thresholds of [`measure_photo`].
#[derive(Clone, Debug)]
pub struct MeasureOptions {
    /// A highlight's brightest pixel must be at least this many times the median of the
    /// sphere's pixels 6 to 10 px away from it.
    pub highlight_min_ratio: f64,
    /// Largest fraction of a sphere's pixels that may be saturated (their centroid is the
    /// highlight then); above it the highlight cannot be located.
    pub max_saturated_fraction: f64,
    /// Largest closest-approach gap of the reflected rays, as a fraction of the light's distance.
    pub max_gap_ratio: f64,
    /// Largest RMS reprojection error of the fiducials, pixels.
    pub max_pose_rms_px: f64,
}

impl Default for MeasureOptions {
    fn default() -> Self {
        MeasureOptions {
            highlight_min_ratio: 4.0,
            max_saturated_fraction: 0.05,
            max_gap_ratio: 0.05,
            max_pose_rms_px: 3.0,
        }
    }
}

/// One region's measured value.
#[derive(Clone, Debug, Serialize)]
pub struct RegionValue {
    pub material: String,
    pub center: [f64; 2],
    /// Unit directions toward the light and the camera, in the sample's local frame.
    pub light: [f32; 3],
    pub view: [f32; 3],
    /// pi f (r, g, b): mean over the region's orthographic pixels.
    pub value: [f32; 3],
    /// Relative standard deviation of the luminance of pi f over the region's pixels.
    pub rel_std: f64,
    pub pixels: usize,
}

/// Everything recovered from one photograph.
#[derive(Clone, Debug, Serialize)]
pub struct PhotoMeasurement {
    pub photo: PathBuf,
    /// `corners` or `aruco ids [..]`.
    pub pose_source: String,
    /// World (frame) to camera: rows of R, and t.
    pub r: [[f64; 3]; 3],
    pub t: [f64; 3],
    pub pose_rms_px: f64,
    pub camera_center: [f64; 3],
    /// Light position (frame coordinates) and the closest-approach gap of the two reflected rays.
    pub light: [f64; 3],
    pub gap: f64,
    pub highlights: Vec<Highlight>,
    /// Light intensity I per channel (image radiance units times m^2) from the white standard.
    pub intensity: [f64; 3],
    /// Homography from orthographic pixel (column, row, 1) to the undistorted photograph pixel
    /// (rows); the lens distortion is applied on top when sampling.
    pub homography: [[f64; 3]; 3],
    pub regions: Vec<RegionValue>,
}

impl PhotoMeasurement {
    pub fn pose(&self) -> WorldToCamera {
        WorldToCamera {
            r: DMat3::from_cols_array_2d(&self.r).transpose(),
            t: DVec3::from_array(self.t),
        }
    }

    pub fn light_position(&self) -> DVec3 {
        DVec3::from_array(self.light)
    }

    /// The regions as samples-CSV rows.
    pub fn samples(&self) -> Vec<BrdfSample> {
        self.regions
            .iter()
            .map(|r| BrdfSample {
                material: r.material.clone(),
                light: Vec3::from_array(r.light),
                view: Vec3::from_array(r.view),
                value: Vec3::from_array(r.value),
            })
            .collect()
    }
}

fn rows(m: &DMat3) -> [[f64; 3]; 3] {
    m.transpose().to_cols_array_2d()
}

/// Camera pose of a photograph from the frame's fiducials. Returns the pose, the RMS
/// reprojection error and a description of the source. Errors are messages (the caller names
/// the photo).
fn frame_pose(
    frame: &SampleFrame,
    camera: &Camera,
    img: &HdrImage,
    input: &PoseInput,
) -> Result<(WorldToCamera, f64, String), String> {
    match input {
        PoseInput::Corners(px) => {
            let plane: Vec<DVec2> = frame.fiducials.iter().map(|f| v2(f.center)).collect();
            let p =
                pose_from_marked_points(&camera.intrinsics, &plane, px, (img.width, img.height))?;
            Ok((p.pose, p.rms_px, "corners".into()))
        }
        PoseInput::Aruco => {
            let dict = aruco_dict(&frame.aruco_dictionary)?;
            let found = cv::detect_aruco(img, dict).map_err(|e| {
                format!("ArUco detection: {e} (or give the fiducial pixels with --corners)")
            })?;
            let m = match_markers(&frame.aruco_markers(), &found);
            if m.found.len() < 2 {
                let want: Vec<i32> = frame.fiducials.iter().filter_map(|f| f.aruco_id).collect();
                let seen: Vec<i32> = found.iter().map(|m| m.id).collect();
                return Err(format!("found ArUco markers {seen:?}, the frame's are {want:?}: at least two are needed for the pose"));
            }
            let mut ids = m.found.clone();
            ids.sort();
            // the markers lie in one plane: the RANSAC solver of `cv::solve_pnp` is unreliable
            // there; the matched solver (SQPnP + refinement, outlier rejection) is not
            let r = cv::solve_pnp_matched(&camera.intrinsics, &m.target, &m.pixels, 3.0)
                .map_err(|e| format!("PnP: {e}"))?;
            Ok((r.pose, r.rms_px, format!("aruco ids {ids:?}")))
        }
    }
}

/// The point of closest approach of two rays `o + s d` (unit `d`): the midpoint of the
/// closest points, the gap between them and the two ray parameters. `None` for (nearly)
/// parallel rays.
pub fn closest_approach(
    o1: DVec3,
    d1: DVec3,
    o2: DVec3,
    d2: DVec3,
) -> Option<(DVec3, f64, f64, f64)> {
    let w = o1 - o2;
    let b = d1.dot(d2);
    let den = 1.0 - b * b;
    if den < 1e-10 {
        return None;
    }
    let (dd, e) = (d1.dot(w), d2.dot(w));
    let s = (b * e - dd) / den;
    let u = (e - b * dd) / den;
    let (p1, p2) = (o1 + d1 * s, o2 + d2 * u);
    Some(((p1 + p2) * 0.5, (p1 - p2).length(), s, u))
}

/// Photograph pixel of a frame point (`None` behind the camera).
fn sample_at(cam: &Camera, img: &HdrImage, p: DVec3) -> Option<DVec3> {
    let q = cam.project(p)?;
    let v = img.bilinear(q.x as f32, q.y as f32)?;
    Some(DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64))
}

/// The orthographic view of the sample plane (`frame.ortho`): each pixel is the photograph's
/// bilinear sample at the projection (with distortion) of its plane point; invalid where that
/// falls outside the photo or on an invalid pixel.
pub fn orthographic_view(frame: &SampleFrame, cam: &Camera, img: &HdrImage) -> HdrImage {
    let (w, h) = frame.ortho_size();
    let a = frame.ortho_to_plane();
    let mut out = HdrImage::new(w, h);
    for row in 0..h {
        for col in 0..w {
            let p = a * DVec3::new(col as f64, row as f64, 1.0);
            let i = out.index(col, row);
            match sample_at(cam, img, DVec3::new(p.x, p.y, 0.0)) {
                Some(v) => out.pixels[i] = [v.x as f32, v.y as f32, v.z as f32],
                None => out.valid[i] = false,
            }
        }
    }
    out
}

/// Measure one photograph of the frame. `camera` supplies the intrinsics (its pose is ignored)
/// and must have the photo's size; `photo` names the file in errors.
pub fn measure_photo(
    frame: &SampleFrame,
    camera: &Camera,
    img: &HdrImage,
    photo: &Path,
    input: &PoseInput,
    opts: &MeasureOptions,
) -> Result<PhotoMeasurement, CaptureError> {
    let err = |msg: String| CaptureError::File {
        path: photo.into(),
        msg,
    };
    let (cam, pose_rms_px, pose_source) =
        posed_camera(frame, camera, img, input, opts).map_err(err)?;
    let (light, gap, highlights) = light_from_highlights(frame, &cam, img, opts).map_err(err)?;
    let intensity = white_intensity(frame, &cam, img, light).map_err(err)?;
    let lit = LitPhoto {
        cam: &cam,
        img,
        light,
        intensity,
        step: 1.0 / frame.ortho.px_per_m,
    };
    let regions = (frame.regions.iter().enumerate())
        .map(|(k, r)| measure_region(&lit, k, r))
        .collect::<Result<Vec<_>, String>>()
        .map_err(err)?;
    Ok(PhotoMeasurement {
        photo: photo.into(),
        pose_source,
        r: rows(&cam.pose.r),
        t: cam.pose.t.to_array(),
        pose_rms_px,
        camera_center: cam.center_world().to_array(),
        light: light.to_array(),
        gap,
        highlights,
        intensity: intensity.to_array(),
        homography: rows(&ortho_homography(frame, &cam)),
        regions,
    })
}

/// The camera with the photograph's pose from the fiducials, the pose's RMS reprojection error
/// and its source; checked against `opts.max_pose_rms_px` and for a centre above the frame.
fn posed_camera(
    frame: &SampleFrame,
    camera: &Camera,
    img: &HdrImage,
    input: &PoseInput,
    opts: &MeasureOptions,
) -> Result<(Camera, f64, String), String> {
    if (img.width, img.height) != (camera.width as usize, camera.height as usize) {
        return Err(format!(
            "the photo is {}x{} but the camera is {}x{}",
            img.width, img.height, camera.width, camera.height
        ));
    }
    let (pose, pose_rms_px, pose_source) = frame_pose(frame, camera, img, input)?;
    if !(pose_rms_px <= opts.max_pose_rms_px) {
        return Err(format!(
            "the fiducials reproject with RMS {pose_rms_px:.2} px (at most {} px): wrong order or wrong frame file?",
            opts.max_pose_rms_px
        ));
    }
    let cam = Camera {
        pose,
        ..camera.clone()
    };
    let eye = cam.center_world();
    if !(eye.z > 0.0) {
        return Err(format!(
            "the recovered camera centre {:?} is not above the frame plane",
            eye.to_array()
        ));
    }
    Ok((cam, pose_rms_px, pose_source))
}

/// The light position: the closest approach of the camera rays through the two spheres'
/// highlights, reflected. Returns it, the rays' gap there and the highlights.
fn light_from_highlights(
    frame: &SampleFrame,
    cam: &Camera,
    img: &HdrImage,
    opts: &MeasureOptions,
) -> Result<(DVec3, f64, Vec<Highlight>), String> {
    let limits = HighlightLimits {
        min_ratio: opts.highlight_min_ratio,
        max_saturated_fraction: opts.max_saturated_fraction,
    };
    let mut hl = Vec::new();
    for (k, s) in frame.spheres.iter().enumerate() {
        let view = SphereView::in_world(
            cam,
            SphereKind::Black,
            DVec3::from_array(s.center),
            s.radius,
        );
        hl.push(find_highlight(&view, img, &limits).map_err(|e| format!("sphere {k}: {e}"))?);
    }
    let ray = |h: &Highlight| (DVec3::from_array(h.point), DVec3::from_array(h.reflected));
    let ((o1, d1), (o2, d2)) = (ray(&hl[0]), ray(&hl[1]));
    let (light, gap, s1, s2) = closest_approach(o1, d1, o2, d2).ok_or_else(|| {
        "the rays reflected off the two spheres are parallel: no light position".to_string()
    })?;
    if !(s1 > 0.0 && s2 > 0.0) {
        return Err(format!(
            "the rays reflected off the spheres meet behind them (parameters {s1:.3}, {s2:.3} m): highlights misidentified?"
        ));
    }
    let dist = 0.5 * (s1 + s2);
    if gap > opts.max_gap_ratio * dist {
        return Err(format!(
            "the reflected rays pass {gap:.4} m apart at {dist:.3} m (more than {:.0}%): highlights or pose inconsistent",
            opts.max_gap_ratio * 100.0
        ));
    }
    if !(light.z > frame.white.z.max(0.0)) {
        return Err(format!(
            "the recovered light {:?} is not above the frame plane",
            light.to_array()
        ));
    }
    Ok((light, gap, hl))
}

/// The light's intensity per channel: the mean of `pi Lw d^2 / (rho_w cos(theta_l))` over the
/// white standard's inner 80 % (sampled at the orthographic view's pitch).
fn white_intensity(
    frame: &SampleFrame,
    cam: &Camera,
    img: &HdrImage,
    light: DVec3,
) -> Result<DVec3, String> {
    let w = &frame.white;
    let rho = w.reflectance.rgb();
    let step = 1.0 / frame.ortho.px_per_m;
    let (mn, mx) = (v2(w.min), v2(w.max));
    let inset = (mx - mn) * 0.1;
    let (a, b) = (mn + inset, mx - inset);
    let nx = (((b.x - a.x) / step).round() as usize).max(1);
    let ny = (((b.y - a.y) / step).round() as usize).max(1);
    let (mut sum, mut bad) = (DVec3::ZERO, 0usize);
    for j in 0..ny {
        for i in 0..nx {
            let q = DVec3::new(
                a.x + (i as f64 + 0.5) * (b.x - a.x) / nx as f64,
                a.y + (j as f64 + 0.5) * (b.y - a.y) / ny as f64,
                w.z,
            );
            let tl = light - q;
            let d2 = tl.length_squared();
            let cos = tl.z / d2.sqrt();
            match sample_at(cam, img, q) {
                Some(l) if cos > 0.0 => sum += l * std::f64::consts::PI * d2 / (rho * cos),
                _ => bad += 1,
            }
        }
    }
    if bad > 0 {
        return Err(format!(
            "white standard: {bad} of {} samples are saturated, unusable or outside the photo",
            nx * ny
        ));
    }
    let intensity = sum / (nx * ny) as f64;
    if !(intensity.min_element() > 0.0 && intensity.is_finite()) {
        return Err(format!(
            "white standard: the light intensity {:?} is not positive in every channel",
            intensity.to_array()
        ));
    }
    Ok(intensity)
}

/// A posed photograph with its recovered light, for [`measure_region`].
struct LitPhoto<'a> {
    cam: &'a Camera,
    img: &'a HdrImage,
    light: DVec3,
    intensity: DVec3,
    /// Orthographic pixel pitch, metres.
    step: f64,
}

/// Region `k`: the mean `pi f = pi L d^2 / (I cos(theta_l))` over its orthographic pixels, and
/// the directions from its centre to the light and the camera.
fn measure_region(lit: &LitPhoto, k: usize, r: &Region) -> Result<RegionValue, String> {
    let (light, step) = (lit.light, lit.step);
    let c = v2(r.center);
    let pc = DVec3::new(c.x, c.y, 0.0);
    let (l, v) = (
        (light - pc).normalize(),
        (lit.cam.center_world() - pc).normalize(),
    );
    if !(l.z > 0.0 && v.z > 0.0) {
        return Err(format!(
            "region {k} ({}): the light or the camera is below the sample plane",
            r.material
        ));
    }
    let n = r.size_px;
    let (mut acc, mut lum, mut bad) = (DVec3::ZERO, Vec::with_capacity(n * n), 0usize);
    for j in 0..n {
        for i in 0..n {
            let p = DVec3::new(
                c.x + (i as f64 - (n - 1) as f64 * 0.5) * step,
                c.y + (j as f64 - (n - 1) as f64 * 0.5) * step,
                0.0,
            );
            let tl = light - p;
            let d2 = tl.length_squared();
            let cos = tl.z / d2.sqrt();
            match sample_at(lit.cam, lit.img, p) {
                Some(val) if cos > 0.0 => {
                    let f = val * std::f64::consts::PI * d2 / (lit.intensity * cos);
                    acc += f;
                    lum.push(f.element_sum() / 3.0);
                }
                _ => bad += 1,
            }
        }
    }
    if bad > 0 {
        return Err(format!(
            "region {k} ({}): {bad} of {} pixels are saturated, unusable or outside the photo",
            r.material,
            n * n
        ));
    }
    let m = acc / (n * n) as f64;
    let ml = lum.iter().sum::<f64>() / lum.len() as f64;
    let sd = (lum.iter().map(|x| (x - ml).powi(2)).sum::<f64>() / lum.len() as f64).sqrt();
    Ok(RegionValue {
        material: r.material.clone(),
        center: r.center,
        light: l.as_vec3().to_array(),
        view: v.as_vec3().to_array(),
        value: m.as_vec3().to_array(),
        rel_std: if ml > 0.0 { sd / ml } else { 0.0 },
        pixels: n * n,
    })
}

/// The homography from orthographic pixel to undistorted photo pixel, `K [r1 r2 t] A`,
/// normalised to a unit bottom-right entry.
fn ortho_homography(frame: &SampleFrame, cam: &Camera) -> DMat3 {
    let i = &cam.intrinsics;
    let k = DMat3::from_cols(
        DVec3::new(i.fx, 0.0, 0.0),
        DVec3::new(0.0, i.fy, 0.0),
        DVec3::new(i.cx, i.cy, 1.0),
    );
    let pose = &cam.pose;
    let h = k * DMat3::from_cols(pose.r.x_axis, pose.r.y_axis, pose.t) * frame.ortho_to_plane();
    h * (1.0 / h.z_axis.z)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closest_approach_of_skew_rays() {
        let (p, gap, s, u) = closest_approach(
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::X,
            DVec3::new(1.0, -1.0, 0.2),
            DVec3::Y,
        )
        .unwrap();
        assert!((p - DVec3::new(1.0, 0.0, 0.1)).length() < 1e-12 && (gap - 0.2).abs() < 1e-12);
        assert!((s - 1.0).abs() < 1e-12 && (u - 1.0).abs() < 1e-12);
        assert!(closest_approach(DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::X).is_none());
    }

    #[test]
    fn ortho_map_puts_row_zero_at_the_top() {
        let f = SampleFrame {
            fiducials: vec![],
            aruco_dictionary: default_dict(),
            spheres: vec![],
            white: WhiteStandard {
                min: [0.0; 2],
                max: [1.0; 2],
                z: 0.0,
                reflectance: default_white(),
            },
            ortho: Ortho {
                min: [-0.1, -0.05],
                max: [0.1, 0.05],
                px_per_m: 1000.0,
            },
            regions: vec![],
        };
        assert_eq!(f.ortho_size(), (200, 100));
        let a = f.ortho_to_plane();
        let p = a * DVec3::new(0.0, 0.0, 1.0);
        assert!(
            (p.x + 0.0995).abs() < 1e-12 && (p.y - 0.0495).abs() < 1e-12,
            "{p}"
        );
        let q = a * DVec3::new(199.0, 99.0, 1.0);
        assert!(
            (q.x - 0.0995).abs() < 1e-12 && (q.y + 0.0495).abs() < 1e-12,
            "{q}"
        );
    }
}
