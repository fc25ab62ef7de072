//! `igi probe`: lighting (sky map + sun) from a photograph of the three-sphere board.
use crate::report::Ctx;
use anyhow::bail;
use igi_probe::job::{
    calibrate_mirror_file, probe_files, CalibrateMirrorRequest, ProbeRequest, ProbeStep,
};
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
    #[arg(allow_negative_numbers = true, value_parser = crate::cmd::values::positive_f32, long)]
    pub saturation: Option<f32>,
    /// Width of the lat-long sky map (height is half).
    #[arg(long, default_value_t = 256)]
    pub map_width: usize,
    /// Side of the upper-hemisphere pictures.
    #[arg(long, default_value_t = 512)]
    pub hemi_size: usize,
    /// Masked cone around the camera's own reflection, degrees.
    #[arg(allow_negative_numbers = true, value_parser = crate::cmd::values::cone_deg, long, default_value_t = 4.0)]
    pub camera_mask_deg: f64,
    /// Largest incidence angle used on the mirror and black spheres, degrees.
    #[arg(allow_negative_numbers = true, value_parser = crate::cmd::values::incidence_deg, long, default_value_t = 72.0)]
    pub max_incidence_deg: f64,
    /// Radius (pixels) masked around the sun's reflection in the mirror sphere, so the sun's light
    /// stays out of the sky map. On spheres under about 30 px in radius, 3 keeps more of the sky
    /// around the sun (docs/PROBE.md).
    #[arg(allow_negative_numbers = true, value_parser = crate::cmd::values::non_negative, long, default_value_t = 4.0)]
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
    let req = CalibrateMirrorRequest {
        samples: a.samples,
        output: a.output,
    };
    calibrate_mirror_file(&req, &|fit| {
        println!(
            "\"ior\": [{}]",
            fit.ior
                .iter()
                .map(|[n, k]| format!("[{n:.4}, {k:.4}]"))
                .collect::<Vec<_>>()
                .join(", ")
        );
        eprintln!(
            "calibrate-mirror: {} samples, RMS residual {:.2e} {:.2e} {:.2e} (R, G, B)",
            fit.samples, fit.rms[0], fit.rms[1], fit.rms[2]
        );
    })?;
    Ok(())
}

pub fn run(mut a: ProbeArgs, ctx: &Ctx) -> anyhow::Result<()> {
    match a.action.take() {
        Some(ProbeAction::CalibrateMirror(c)) => calibrate_mirror(c),
        None => probe(a, ctx),
    }
}

impl ProbeArgs {
    /// The job `igi probe` asks for.
    fn request(self) -> anyhow::Result<ProbeRequest> {
        let (Some(camera), Some(board), Some(output)) = (self.camera, self.board, self.output)
        else {
            bail!("igi probe needs --camera, --board and -o (or a subcommand)");
        };
        Ok(ProbeRequest {
            image: self.image,
            brackets: self.brackets,
            times: self.times,
            camera,
            board,
            output,
            srgb: self.srgb,
            saturation: self.saturation,
            map_width: self.map_width,
            hemi_size: self.hemi_size,
            camera_mask_deg: self.camera_mask_deg,
            max_incidence_deg: self.max_incidence_deg,
            sun_mask_px: self.sun_mask_px,
            refine_spheres: match self.refine_spheres {
                RefineSpheres::Auto => igi_probe::job::RefineSpheres::Auto,
                RefineSpheres::On => igi_probe::job::RefineSpheres::On,
                RefineSpheres::Off => igi_probe::job::RefineSpheres::Off,
            },
        })
    }
}

fn probe(a: ProbeArgs, ctx: &Ctx) -> anyhow::Result<()> {
    let req = a.request()?;
    let pb = ctx.progress(4, "probe");
    let d = probe_files(&req, &|s| match s {
        ProbeStep::Placed => pb.inc(1),
        ProbeStep::Processed(pose) => {
            if let Some(p) = pose {
                eprintln!(
                    "probe: board pose from fiducials {:?} ({} of {} corners, RMS {:.3} px)",
                    p.markers_found, p.corners_inliers, p.corners_matched, p.rms_px
                );
            }
            pb.inc(1);
        }
        ProbeStep::Written => pb.inc(2),
    })?;
    pb.finish_and_clear();
    print_summary(&d, &req.output);
    Ok(())
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
