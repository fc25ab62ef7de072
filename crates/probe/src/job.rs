//! `igi probe`'s jobs, each one call from a request of paths and options: the lighting from a
//! photograph of the board ([`probe_files`]: inputs read and checked, the board placed, the
//! photograph processed, everything written) and the mirror's complex index from
//! reflectance samples ([`calibrate_mirror_file`]).

use crate::fiducial::{place_board, BoardPose};
use crate::fresnel::{conductor, fit_mirror_ior, ReflectanceSamples};
use crate::input::{load_photograph, PhotoSource};
use crate::outputs::write_outputs;
use crate::{process, BoardSpec, Diagnostics, ProbeError, ProbeOptions};
use igi_camera::Camera;
use igi_imaging::hdr::parse_time;
use std::path::{Path, PathBuf};

/// When the sphere centres are refined from their outlines.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RefineSpheres {
    /// When the board's fiducials placed the spheres (an imprecise pose).
    Auto,
    On,
    Off,
}

/// `igi probe`: the board photograph (one image, or brackets with their exposure times as
/// written), its camera, the board file, the lighting file to write (.toml; the maps go beside
/// it) and the options of the processing.
#[derive(Clone, Debug)]
pub struct ProbeRequest {
    /// One image; `None` when `brackets` are given.
    pub image: Option<PathBuf>,
    pub brackets: Vec<PathBuf>,
    /// One exposure time per bracket (seconds, decimal or a fraction such as `1/250`).
    pub times: Vec<String>,
    pub camera: PathBuf,
    pub board: PathBuf,
    pub output: PathBuf,
    /// Decode sRGB-encoded 8-bit inputs to linear first.
    pub srgb: bool,
    /// Saturation level (default: the input's clip level).
    pub saturation: Option<f32>,
    pub map_width: usize,
    pub hemi_size: usize,
    pub camera_mask_deg: f64,
    pub max_incidence_deg: f64,
    pub sun_mask_px: f64,
    pub refine_spheres: RefineSpheres,
}

/// One step of [`probe_files`], for a progress bar and the log.
#[derive(Clone, Copy, Debug)]
pub enum ProbeStep<'a> {
    /// The board placed in the camera frame.
    Placed,
    /// The photograph processed; the fiducials' pose when they placed the board.
    Processed(Option<&'a BoardPose>),
    /// Everything written.
    Written,
}

/// The lighting (sky map + sun) from a photograph of the board, written with its maps,
/// pictures and diagnostics; returns the diagnostics.
pub fn probe_files(
    req: &ProbeRequest,
    step: &dyn Fn(ProbeStep),
) -> Result<Diagnostics, ProbeError> {
    check_request(req)?;
    let camera = Camera::load(&req.camera)?;
    let spec = BoardSpec::load(&req.board)?;
    let (image, saturation) = load_photograph(&photo_source(req)?, req.srgb, req.saturation)?;
    // spheres in the camera frame: from the fiducials' pose (opencv feature) or the file
    let placement = place_board(&spec, &image, &camera).map_err(|e| ProbeError::Placing {
        board: req.board.clone(),
        source: Box::new(e),
    })?;
    step(ProbeStep::Placed);
    let opt = probe_options(req, placement.refine_by_default(), saturation);
    let mut r =
        process(&image, &camera, &placement.board, &opt).map_err(|e| ProbeError::Processing {
            photo: photo_name(req),
            source: Box::new(e),
        })?;
    r.diagnostics.warnings.extend(placement.warnings);
    step(ProbeStep::Processed(placement.pose.as_ref()));
    r.diagnostics.board_pose = placement.pose;
    write_outputs(&req.output, &r)?;
    step(ProbeStep::Written);
    Ok(r.diagnostics)
}

/// The lighting file and its siblings, and the options: checked before any work.
fn check_request(req: &ProbeRequest) -> Result<(), ProbeError> {
    let ext = req.output.extension().and_then(|e| e.to_str());
    if ext.map(str::to_ascii_lowercase).as_deref() != Some("toml") {
        return Err(ProbeError::LightingName {
            path: req.output.clone(),
        });
    }
    igi_files::check_output_file(&req.output)?;
    // the pictures the pipeline holds at once, each f32 RGB with a validity byte (13 bytes a
    // pixel): the lat-long maps (measured, filled, convolved, written; and their supersampled
    // reads) and the hemispheres (mirror, black sphere, diffuse, written)
    let (mw, hs) = (req.map_width as u128, req.hemi_size as u128);
    igi_files::check_alloc_default(
        &format!("the lat-long maps (--map-width {})", req.map_width),
        mw * (mw / 2) * 13 * 6,
    )?;
    igi_files::check_alloc_default(
        &format!("the hemisphere pictures (--hemi-size {})", req.hemi_size),
        hs * hs * 13 * 6,
    )?;
    if !(req.sun_mask_px >= 0.0 && req.sun_mask_px.is_finite()) {
        return Err(ProbeError::Arguments(format!(
            "--sun-mask-px {} must be a finite radius in pixels, 0 or more",
            req.sun_mask_px
        )));
    }
    Ok(())
}

/// The photograph: the image, or the brackets with their parsed times.
fn photo_source(req: &ProbeRequest) -> Result<PhotoSource, ProbeError> {
    Ok(match &req.image {
        Some(image) if req.brackets.is_empty() => PhotoSource::Image(image.clone()),
        _ => PhotoSource::Brackets {
            images: req.brackets.clone(),
            times: req
                .times
                .iter()
                .map(|t| parse_time(t))
                .collect::<Result<_, _>>()?,
        },
    })
}

/// The photograph as errors name it: the image, else the first bracket.
fn photo_name(req: &ProbeRequest) -> String {
    req.image
        .as_ref()
        .or(req.brackets.first())
        .map(|p| p.display().to_string())
        .unwrap_or_default()
}

/// The options of [`process`] (`refine_auto`: the placement's default for
/// [`RefineSpheres::Auto`]; `saturation`: the input's clip level when not given).
fn probe_options(req: &ProbeRequest, refine_auto: bool, saturation: Option<f32>) -> ProbeOptions {
    let opt = ProbeOptions {
        map_width: req.map_width,
        hemi_size: req.hemi_size,
        conv_width: (req.map_width / 2).clamp(2, 128),
        camera_mask_deg: req.camera_mask_deg,
        max_incidence_deg: req.max_incidence_deg,
        saturation: req.saturation.or(saturation),
        refine_centers: match req.refine_spheres {
            RefineSpheres::On => true,
            RefineSpheres::Off => false,
            RefineSpheres::Auto => refine_auto,
        },
        sun_mask_px: req.sun_mask_px,
        ..ProbeOptions::default()
    };
    ProbeOptions {
        conv_width: if req.map_width.is_multiple_of(opt.conv_width) {
            opt.conv_width
        } else {
            req.map_width
        },
        ..opt
    }
}

/// `igi probe calibrate-mirror`: reflectance-versus-angle samples (CSV `angle_deg,r,g,b`) and
/// where to write the fit as JSON (optional).
#[derive(Clone, Debug)]
pub struct CalibrateMirrorRequest {
    pub samples: PathBuf,
    pub output: Option<PathBuf>,
}

/// The mirror's complex index per channel, as fitted.
#[derive(Clone, Debug)]
pub struct MirrorFit {
    /// `[n, k]` per channel (R, G, B): the board file's `ior` entry.
    pub ior: [[f64; 2]; 3],
    /// RMS reflectance residual per channel.
    pub rms: [f64; 3],
    pub samples: usize,
}

/// Fits the mirror sphere's complex index n + ik per channel to the samples; tells `fitted`
/// the fit, then writes it as JSON when asked.
pub fn calibrate_mirror_file(
    req: &CalibrateMirrorRequest,
    fitted: &dyn Fn(&MirrorFit),
) -> Result<MirrorFit, ProbeError> {
    let samples = ReflectanceSamples::load(&req.samples)?;
    let fits = fit_mirror_ior(&samples).map_err(|e| ProbeError::FittingIor {
        path: req.samples.clone(),
        source: Box::new(e),
    })?;
    let fit = MirrorFit {
        ior: fits.map(|f| [f.n, f.k]),
        rms: fits.map(|f| f.rms),
        samples: samples.angle_deg.len(),
    };
    fitted(&fit);
    if let Some(out) = &req.output {
        let json = serde_json::json!({
            "ior": fit.ior,
            "rms": fit.rms,
            "normal_incidence_reflectance": fits.map(|f| conductor(1.0, f.n, f.k)),
            "samples": fit.samples,
            "source": req.samples.display().to_string(),
        });
        write_json(out, &json)?;
    }
    Ok(fit)
}

fn write_json(path: &Path, json: &serde_json::Value) -> Result<(), ProbeError> {
    let text = serde_json::to_string_pretty(json).expect("JSON values serialise");
    Ok(igi_files::write_text_atomic(path, &text)?)
}
