//! The capture jobs the command line runs, each one call from a request of paths and options:
//! `igi camera refine` (a camera's pose refined against a model, [`refine_file`]) and
//! `igi brdf measure` (BRDF samples from photographs of the sample frame, [`measure_files`]).

use crate::refine::{refine_pose, RefineOptions, RefineReport};
use crate::sample_frame::{
    measure_photo, orthographic_view, MeasureOptions, PhotoMeasurement, PoseInput, SampleFrame,
};
use crate::CaptureError;
use glam::DVec2;
use igi_camera::Camera;
use igi_imaging::read_image;
use std::path::{Path, PathBuf};

/// `igi camera refine`: a photograph, its camera (the starting pose), the model's meshes, the
/// initial search range in pixels, whether creases are matched, the camera file to write.
#[derive(Clone, Debug)]
pub struct RefineRequest {
    pub photo: PathBuf,
    pub camera: PathBuf,
    pub meshes: Vec<PathBuf>,
    pub search_px: f64,
    pub creases: bool,
    pub output: PathBuf,
}

/// What [`refine_file`] did.
#[derive(Clone, Debug)]
pub struct RefineOutcome {
    pub report: RefineReport,
    /// The refined camera's centre, world coordinates.
    pub center_world: [f64; 3],
}

/// Refines the camera's pose by matching the model's edges and silhouette to the
/// photograph's, and writes the camera (input intrinsics, refined pose).
pub fn refine_file(req: &RefineRequest) -> Result<RefineOutcome, CaptureError> {
    igi_files::check_output_extension(&req.output, &["json"])?;
    if !(req.search_px > 0.0 && req.search_px.is_finite()) {
        return Err(CaptureError::Arguments(format!(
            "--search {}: must be a positive number of pixels",
            req.search_px
        )));
    }
    let cam = Camera::load(&req.camera)?;
    let photo = read_image(&req.photo)?;
    if photo.width != cam.width as usize || photo.height != cam.height as usize {
        return Err(CaptureError::PhotoCameraSize {
            photo: req.photo.clone(),
            size: (photo.width, photo.height),
            camera: req.camera.clone(),
            camera_size: (cam.width, cam.height),
        });
    }
    let meshes = req
        .meshes
        .iter()
        .map(|m| igi_geometry::read_mesh(m))
        .collect::<Result<Vec<_>, _>>()?;
    let rt = igi_raycast::rt_scene_of(&meshes)?;
    let opts = RefineOptions {
        search_px: req.search_px,
        creases: req.creases,
        ..RefineOptions::default()
    };
    let (out, report) =
        refine_pose(&photo, &cam, &rt, &opts).map_err(|e| CaptureError::Refining {
            photo: req.photo.clone(),
            source: Box::new(e),
        })?;
    out.save(&req.output)?;
    Ok(RefineOutcome {
        report,
        center_world: out.center_world().to_array(),
    })
}

/// `igi brdf measure`: the sample-frame file, its photographs, the camera (intrinsics; its
/// pose is ignored), the fiducials' pixels per photo as written (`u,v` pairs; none: ArUco),
/// the samples CSV to write and a folder for the orthographic views.
#[derive(Clone, Debug)]
pub struct MeasureRequest {
    pub frame: PathBuf,
    pub photos: Vec<PathBuf>,
    pub camera: PathBuf,
    pub corners: Vec<String>,
    pub output: PathBuf,
    pub ortho_dir: Option<PathBuf>,
}

/// What [`measure_files`] measured: each photograph's report and the samples written.
#[derive(Clone, Debug)]
pub struct MeasureOutcome {
    pub photos: Vec<PhotoMeasurement>,
    pub samples: usize,
}

/// Measures every photograph of the frame and writes the samples CSV (and, when asked, each
/// photo's orthographic view of the sample as `ORTHO_DIR/STEM_ortho.exr`).
pub fn measure_files(req: &MeasureRequest) -> Result<MeasureOutcome, CaptureError> {
    let frame = SampleFrame::load(&req.frame)?;
    let camera = Camera::load(&req.camera)?;
    if !req.corners.is_empty() && req.corners.len() != req.photos.len() {
        return Err(CaptureError::Arguments(format!(
            "{} --photo but {} --corners: give one --corners per photo, or none (ArUco)",
            req.photos.len(),
            req.corners.len()
        )));
    }
    let opts = MeasureOptions::default();
    let (mut photos, mut samples) = (Vec::new(), Vec::new());
    for (k, photo) in req.photos.iter().enumerate() {
        let input = match req.corners.get(k) {
            Some(c) => PoseInput::Corners(parse_corners(c)?),
            None => PoseInput::Aruco,
        };
        let img = read_image(photo)?;
        let m = measure_photo(&frame, &camera, &img, photo, &input, &opts)?;
        if let Some(dir) = &req.ortho_dir {
            write_ortho(dir, photo, k, &frame, &camera, &m, &img)?;
        }
        samples.extend(m.samples());
        photos.push(m);
    }
    igi_formats::brdf_samples::write_samples(&req.output, &samples)?;
    Ok(MeasureOutcome {
        photos,
        samples: samples.len(),
    })
}

/// The fiducials' pixels `u,v,u,v,...` (at least four pairs).
fn parse_corners(s: &str) -> Result<Vec<DVec2>, CaptureError> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .ok()
        .filter(|v: &Vec<f64>| v.len() >= 8 && v.len().is_multiple_of(2) && v.iter().all(|x| x.is_finite()))
        .ok_or_else(|| CaptureError::Arguments(format!("--corners {s:?}: expected u,v pairs for the four fiducials, e.g. 101.5,88,912,90.2,905,700,98,702")))?;
    Ok(v.chunks(2).map(|c| DVec2::new(c[0], c[1])).collect())
}

/// The orthographic view of photo `k` as `dir/STEM_ortho.exr`.
fn write_ortho(
    dir: &Path,
    photo: &Path,
    k: usize,
    frame: &SampleFrame,
    camera: &Camera,
    m: &PhotoMeasurement,
    img: &igi_imaging::HdrImage,
) -> Result<(), CaptureError> {
    std::fs::create_dir_all(dir).map_err(|e| CaptureError::CreateDir {
        path: dir.to_path_buf(),
        source: e,
    })?;
    let stem = photo
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| format!("photo{k}"));
    let cam = Camera {
        pose: m.pose(),
        ..camera.clone()
    };
    let out = dir.join(format!("{stem}_ortho.exr"));
    Ok(igi_imaging::write_exr(
        &out,
        &orthographic_view(frame, &cam, img),
    )?)
}
