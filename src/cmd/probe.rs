//! `igi probe`: lighting (sky map + sun) from a photograph of the three-sphere board.
use crate::report::Ctx;
use anyhow::{bail, Context};
use igi_camera::Camera;
use igi_files::write_text_atomic;
use igi_imaging::hdr::parse_time;
use igi_imaging::HdrImage;
use igi_probe::fiducial::place_board;
use igi_probe::fresnel::{fit_mirror_ior, ReflectanceSamples};
use igi_probe::input::{load_photograph, PhotoSource};
use igi_probe::outputs::write_outputs;
use igi_probe::{process, BoardSpec, ProbeOptions};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct ProbeArgs {
    #[command(subcommand)]
    pub action: Option<ProbeAction>,
    /// Board photograph: linear HDR (.exr, .hdr) or a single LDR image (clipped values masked).
    #[arg(required_unless_present = "brackets")]
    pub image: Option<PathBuf>,
    /// Exposure brackets of the board (linear sensor values; see --srgb), merged before use.
    #[arg(long, num_args = 1.., conflicts_with = "image", requires = "times")]
    pub brackets: Vec<PathBuf>,
    /// Exposure time of each bracket in seconds (e.g. 0.25 or 1/250).
    #[arg(long, num_args = 1..)]
    pub times: Vec<String>,
    /// Camera file (JSON, OpenCV model) of the board photograph.
    #[arg(long, required = true)]
    pub camera: Option<PathBuf>,
    /// Board file (JSON, FORMATS.md): sphere kinds, centres and radii in the camera frame, or
    /// (with the opencv feature) fiducials and centres in the board frame (docs/PROBE.md).
    #[arg(long, required = true)]
    pub board: Option<PathBuf>,
    /// Output lighting file (TOML). The sky map, diagnostics and pictures go beside it.
    #[arg(short, long, required = true)]
    pub output: Option<PathBuf>,
    /// Decode sRGB-encoded 8-bit inputs (JPEG photographs) to linear before merging.
    #[arg(long)]
    pub srgb: bool,
    /// Pixel value (after --srgb decoding) at or above which a pixel counts as saturated.
    /// Default: 0.98 for LDR inputs, none for HDR inputs.
    #[arg(long)]
    pub saturation: Option<f32>,
    /// Width of the lat-long sky map (height is half).
    #[arg(long, default_value_t = 256)]
    pub map_width: usize,
    /// Side of the upper-hemisphere pictures.
    #[arg(long, default_value_t = 512)]
    pub hemi_size: usize,
    /// Masked cone around the camera's own reflection, degrees.
    #[arg(long, default_value_t = 4.0)]
    pub camera_mask_deg: f64,
    /// Largest incidence angle used on the mirror and black spheres, degrees.
    #[arg(long, default_value_t = 72.0)]
    pub max_incidence_deg: f64,
    /// Radius (pixels) masked around the sun's reflection in the mirror sphere, so the sun's light
    /// stays out of the sky map. On spheres under about 30 px in radius, 3 keeps more of the sky
    /// around the sun (docs/PROBE.md).
    #[arg(long, default_value_t = 4.0)]
    pub sun_mask_px: f64,
    /// Refine the mirror and black spheres' centres from their outlines in the image: auto (when
    /// the board's fiducials placed them; an imprecise pose), on (also `--refine-spheres` alone)
    /// or off (docs/PROBE.md).
    #[arg(long, value_enum, default_value_t = RefineSpheres::Auto, num_args = 0..=1, default_missing_value = "on")]
    pub refine_spheres: RefineSpheres,
}

/// When `igi probe` refines the sphere centres from their outlines.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum RefineSpheres {
    Auto,
    On,
    Off,
}

#[derive(clap::Subcommand, Debug)]
pub enum ProbeAction {
    /// Fit the mirror sphere's complex index n + ik per channel (Levenberg-Marquardt) to
    /// reflectance-versus-angle samples; prints the board file's "ior" entry.
    CalibrateMirror(CalibrateMirrorArgs),
}

#[derive(clap::Args, Debug)]
pub struct CalibrateMirrorArgs {
    /// Samples (CSV with the header angle_deg,r,g,b): incidence angle in degrees and the
    /// measured reflectance (0-1) per channel.
    pub samples: PathBuf,
    /// Also write the fit as JSON: {"ior": [[n_r, k_r], [n_g, k_g], [n_b, k_b]], "rms": [...], ...}.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
}

fn calibrate_mirror(a: CalibrateMirrorArgs) -> anyhow::Result<()> {
    let samples = ReflectanceSamples::load(&a.samples)?;
    let fits = fit_mirror_ior(&samples)
        .with_context(|| format!("fitting the complex index to {}", a.samples.display()))?;
    let ior = fits.map(|f| [f.n, f.k]);
    let json = serde_json::json!({
        "ior": ior,
        "rms": fits.map(|f| f.rms),
        "normal_incidence_reflectance": fits.map(|f| igi_probe::fresnel::conductor(1.0, f.n, f.k)),
        "samples": samples.angle_deg.len(),
        "source": a.samples.display().to_string(),
    });
    println!(
        "\"ior\": [{}]",
        ior.iter()
            .map(|[n, k]| format!("[{n:.4}, {k:.4}]"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    eprintln!(
        "calibrate-mirror: {} samples, RMS residual {:.2e} {:.2e} {:.2e} (R, G, B)",
        samples.angle_deg.len(),
        fits[0].rms,
        fits[1].rms,
        fits[2].rms
    );
    if let Some(out) = &a.output {
        write_text_atomic(out, &serde_json::to_string_pretty(&json)?)?;
    }
    Ok(())
}

fn load_input(a: &ProbeArgs) -> anyhow::Result<(HdrImage, Option<f32>)> {
    let source = if a.brackets.is_empty() {
        PhotoSource::Image(a.image.clone().expect("clap requires IMAGE or --brackets"))
    } else {
        PhotoSource::Brackets {
            images: a.brackets.clone(),
            times: a
                .times
                .iter()
                .map(|t| parse_time(t))
                .collect::<Result<_, _>>()?,
        }
    };
    Ok(load_photograph(&source, a.srgb, a.saturation)?)
}

pub fn run(a: ProbeArgs, ctx: &Ctx) -> anyhow::Result<()> {
    if let Some(ProbeAction::CalibrateMirror(c)) = a.action {
        return calibrate_mirror(c);
    }
    let (Some(camera_path), Some(board_path), Some(output)) = (&a.camera, &a.board, &a.output)
    else {
        bail!("igi probe needs --camera, --board and -o (or a subcommand)");
    };
    check_arguments(&a, output)?;
    let pb = ctx.progress(4, "probe");
    let camera = Camera::load(camera_path)?;
    let spec = BoardSpec::load(board_path)?;
    let (image, saturation) = load_input(&a)?;
    // spheres in the camera frame: from the fiducials' pose (opencv feature) or the file
    let placement = place_board(&spec, &image, &camera).with_context(|| {
        format!(
            "placing the board {} in the camera frame",
            board_path.display()
        )
    })?;
    let refine_auto = placement.refine_by_default();
    let board = placement.board;
    pb.inc(1);
    let opt = probe_options(&a, refine_auto, saturation);
    let src = a
        .image
        .as_ref()
        .or(a.brackets.first())
        .map(|p| p.display().to_string())
        .unwrap_or_default();
    let mut r = process(&image, &camera, &board, &opt)
        .with_context(|| format!("processing the board photograph {src}"))?;
    r.diagnostics.warnings.extend(placement.warnings);
    if let Some(p) = &placement.pose {
        eprintln!(
            "probe: board pose from fiducials {:?} ({} of {} corners, RMS {:.3} px)",
            p.markers_found, p.corners_inliers, p.corners_matched, p.rms_px
        );
    }
    r.diagnostics.board_pose = placement.pose;
    pb.inc(1);
    write_outputs(output, &r)?;
    pb.inc(2);
    pb.finish_and_clear();
    print_summary(&r.diagnostics, output);
    Ok(())
}

/// The lighting file and its siblings, and the options: checked before any work.
fn check_arguments(a: &ProbeArgs, output: &std::path::Path) -> anyhow::Result<()> {
    if output
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .as_deref()
        != Some("toml")
    {
        bail!(
            "{}: -o names the lighting file written (.toml); its maps are written beside it",
            output.display()
        );
    }
    igi_files::check_output_file(output)?;
    if !(a.sun_mask_px >= 0.0 && a.sun_mask_px.is_finite()) {
        bail!(
            "--sun-mask-px {} must be a finite radius in pixels, 0 or more",
            a.sun_mask_px
        );
    }
    Ok(())
}

/// The options of [`process`] from the command line (`refine_auto`: the placement's default
/// for `--refine-spheres auto`; `saturation`: the input's clip level when not given).
fn probe_options(a: &ProbeArgs, refine_auto: bool, saturation: Option<f32>) -> ProbeOptions {
    let opt = ProbeOptions {
        map_width: a.map_width,
        hemi_size: a.hemi_size,
        conv_width: (a.map_width / 2).clamp(2, 128),
        camera_mask_deg: a.camera_mask_deg,
        max_incidence_deg: a.max_incidence_deg,
        saturation: a.saturation.or(saturation),
        refine_centers: match a.refine_spheres {
            RefineSpheres::On => true,
            RefineSpheres::Off => false,
            RefineSpheres::Auto => refine_auto,
        },
        sun_mask_px: a.sun_mask_px,
        ..ProbeOptions::default()
    };
    ProbeOptions {
        conv_width: if a.map_width.is_multiple_of(opt.conv_width) {
            opt.conv_width
        } else {
            a.map_width
        },
        ..opt
    }
}

/// One line on the sun and the check, then the warnings.
fn print_summary(d: &igi_probe::pipeline::Diagnostics, output: &std::path::Path) {
    eprintln!(
        "probe: sun {}{}; check RMS {}; wrote {}",
        if d.sun_found {
            "found"
        } else {
            "not found (sun solve skipped)"
        },
        d.sun
            .as_ref()
            .map(|s| format!(
                " at elevation {:.2} deg, azimuth {:.2} deg, radiance {}",
                s.elevation_deg,
                s.azimuth_deg,
                s.radiance
                    .map(|r| format!("{:.4e} {:.4e} {:.4e}", r[0], r[1], r[2]))
                    .unwrap_or_else(|| "unknown".into())
            ))
            .unwrap_or_default(),
        d.check_rms_percent
            .map(|c| format!("{c:.2}%"))
            .unwrap_or_else(|| "n/a (no diffuse sphere)".into()),
        output.display()
    );
    for w in &d.warnings {
        eprintln!("warning: {w}");
    }
}
