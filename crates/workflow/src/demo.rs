//! The embedded default (`igi demo`): a complete run of the pipeline on a procedural site, with
//! no downloaded data.
//!
//! 1. Build the procedural colonnade site (`igi_geometry::procedural`) and give every part a
//!    known per-texel albedo (`igi_synth::survey::albedo_pattern`).
//! 2. Make three lighting conditions (sunny, low sun, overcast skies from `igi_render::sky`),
//!    photograph the three-sphere board under each (`igi_synth::board`) and recover the
//!    lighting files from those captures with `igi_probe::process`, as `igi probe` does.
//! 3. Path-trace the survey photographs under the true skies at a high sample count and write
//!    the survey folder with the probe-recovered lighting files.
//! 4. Solve with the job `igi solve` runs ([`crate::solve::solve`]), with the ground truth attached, so the report records the albedo
//!    error per iteration, on the true textures' 128-texel atlases, or (`igi demo --atlas-auto`)
//!    on atlases sized from the photographs (`igi_reflect::atlas_size`); the error is measured at
//!    the solve's texel centres against the true scene.
//! 5. Re-render the recovered site from a held-out viewpoint under a held-out lighting and
//!    compare with a rendering of the true site (relative mean, RMSE against the two images'
//!    Monte-Carlo noise).
//! 6. Write pictures a person can look at and `demo.json`.

use crate::solve::{AtlasRequest, SolveJob, SolveRequest};
use crate::WorkflowError;
use glam::{DVec3, Vec3};
use igi_camera::Camera;
use igi_imaging::{write_exr, write_png_tonemapped, HdrImage};
use igi_reflect::parts::build_parts;
use igi_reflect::result::SolveResult;
use igi_reflect::solver::{Progress, SolveOptions, Truth};
use igi_reflect::truth::{scene_with_albedo, truth_atlas};
use igi_render::sky::{clear_sky, overcast_sky, sun_direction};
use igi_render::{compare_images, difference_image, render_image, Comparison, RenderOptions};
use igi_synth::survey::{albedo_pattern, write_survey, LightingSpec, ShotSpec};
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

/// Sizes of the demo (the defaults run in a few minutes on 2 cores).
#[derive(Clone, Debug, Serialize)]
pub struct DemoOptions {
    pub seed: u64,
    /// Texels per side of the true albedo textures (the site as photographed), and of the
    /// solve's atlases when `atlas_auto_max` is `None`.
    pub atlas: u32,
    /// Solve with `--atlas auto` (each part's atlas from the photographs' pixel footprint,
    /// large meshes cut into parts) within this many texels per side; `None` solves on the
    /// truth's atlases.
    pub atlas_auto_max: Option<u32>,
    pub photo_width: u32,
    pub photo_height: u32,
    pub photo_spp: u32,
    pub solve_spp: Vec<u32>,
    pub iterations: u32,
    pub relight_spp: u32,
    /// Rounds of footprint deblurring per solve iteration (`SolveOptions::deblur`; 4 by
    /// default: the demo's albedo has detail near the pixel size).
    pub deblur: u32,
}

impl Default for DemoOptions {
    fn default() -> Self {
        DemoOptions {
            seed: 7,
            atlas: 128,
            atlas_auto_max: None,
            photo_width: 480,
            photo_height: 320,
            photo_spp: 48,
            solve_spp: vec![16, 64, 128],
            iterations: 3,
            relight_spp: 32,
            deblur: 4,
        }
    }
}

/// The numbers `igi demo` reports (`demo.json`).
#[derive(Clone, Debug, Serialize)]
pub struct DemoReport {
    pub options: DemoOptions,
    pub parts: usize,
    pub triangles: usize,
    pub photos: usize,
    pub photo_seconds: f64,
    pub solve_seconds: f64,
    pub iterations: usize,
    /// Mean absolute rho_d error per channel over texels seen in at least two photos.
    pub albedo_mae: Option<[f32; 3]>,
    /// Mean absolute rho_d error per channel as rendered, at area-uniform points of the site's
    /// surface whose texel two photos saw (`igi_reflect::truth`).
    pub albedo_surface_mae: Option<[f32; 3]>,
    pub probes: Vec<ProbeSummary>,
    pub relight: Comparison,
    pub total_seconds: f64,
}

/// How well the probe captures recovered each lighting.
#[derive(Clone, Debug, Serialize)]
pub struct ProbeSummary {
    pub name: String,
    pub sun_found: bool,
    /// Angle between the recovered and the true sun direction, degrees.
    pub sun_direction_error_deg: Option<f64>,
    /// Relative error of the recovered sun radiance per channel.
    pub sun_radiance_error: Option<[f64; 3]>,
    /// The probe's own check: diffuse convolution of the recovered lighting against the
    /// diffuse sphere, RMS percent.
    pub check_rms_percent: Option<f64>,
}

/// The lighting-capture board of the demo (FORMATS.md board file, camera frame): three 7 cm
/// spheres 0.6 m in front of the board camera (about 88 px in radius).
const BOARD: &str = r#"{ "spheres": [
  { "kind": "mirror",  "center": [-0.15, 0.0, 0.6], "radius": 0.06 },
  { "kind": "black",   "center": [ 0.0,  0.0, 0.6], "radius": 0.06 },
  { "kind": "diffuse", "center": [ 0.15, 0.0, 0.6], "radius": 0.06 } ] }"#;

/// Photographs the board under `truth` and recovers a lighting from it, as `igi probe` does.
fn probe_capture(
    truth: &LightingSpec,
    pictures: &Path,
) -> Result<(LightingSpec, ProbeSummary), WorkflowError> {
    use igi_synth::board::{render_board, SynthSun};
    let board = igi_probe::Board::from_json_str(BOARD, Path::new("demo board"))?;
    let cam = Camera::look_at(
        DVec3::new(0.0, 0.0, 1.5),
        DVec3::new(0.0, 1.0, 1.5),
        640,
        480,
        40.0,
    )?;
    let sun = truth.sun.map(|(d, l)| SynthSun {
        direction: d.normalize().as_dvec3(),
        radiance: l.to_array(),
        diameter_deg: igi_imaging::color::SUN_ANGULAR_DIAMETER_DEG,
    });
    let image = render_board(&cam, &board, &truth.sky, sun, 4);
    write_png_tonemapped(
        &pictures.join(format!("board-{}.png", truth.name)),
        &image,
        1.0,
    )?;
    let r = igi_probe::process(&image, &cam, &board, &igi_probe::ProbeOptions::default())?;
    tracing::info!("probe {}: {}", truth.name, r.diagnostics.sun_decision);
    let est = r.diagnostics.sun.as_ref();
    let rec_sun = est.and_then(|s| {
        s.radiance.map(|l| {
            (
                glam::DVec3::from_array(s.direction).as_vec3(),
                Vec3::from_array(l),
            )
        })
    });
    let summary = ProbeSummary {
        name: truth.name.clone(),
        sun_found: r.diagnostics.sun_found,
        sun_direction_error_deg: match (rec_sun, truth.sun) {
            (Some((a, _)), Some((b, _))) => Some(
                (a.dot(b.normalize()).clamp(-1.0, 1.0) as f64)
                    .acos()
                    .to_degrees(),
            ),
            _ => None,
        },
        sun_radiance_error: match (rec_sun, truth.sun) {
            (Some((_, a)), Some((_, b))) => Some(std::array::from_fn(|k| {
                (a[k] as f64 - b[k] as f64) / b[k] as f64
            })),
            _ => None,
        },
        check_rms_percent: r.diagnostics.check_rms_percent,
    };
    Ok((
        LightingSpec {
            name: truth.name.clone(),
            sky: r.sky,
            sun: rec_sun,
        },
        summary,
    ))
}

fn lightings() -> Vec<LightingSpec> {
    let sunny = sun_direction(52.0, 35.0);
    let low = sun_direction(12.0, 250.0);
    vec![
        LightingSpec {
            name: "sunny".into(),
            sky: clear_sky(128, 64, sunny, 0.5, Vec3::new(0.06, 0.055, 0.05)),
            sun: Some((sunny, Vec3::new(5.0e4, 4.8e4, 4.5e4))),
        },
        LightingSpec {
            name: "low-sun".into(),
            sky: clear_sky(128, 64, low, 0.35, Vec3::new(0.04, 0.035, 0.03)),
            sun: Some((low, Vec3::new(3.6e4, 2.7e4, 1.8e4))),
        },
        LightingSpec {
            name: "overcast".into(),
            sky: overcast_sky(128, 64, 1.6, Vec3::new(0.12, 0.11, 0.1)),
            sun: None,
        },
    ]
}

/// Where every camera of the demo looks.
const TARGET: Vec3 = Vec3::new(0.0, 0.0, 1.8);

/// Creates folder `p` (and its parents).
fn make_folder(p: &Path) -> Result<(), WorkflowError> {
    std::fs::create_dir_all(p)
        .map_err(|e| WorkflowError::file(p, format!("cannot create folder: {e}")))
}

/// Runs the demo into `out` (created). `progress(stage)` reports the stage names.
pub fn run_demo(
    out: &Path,
    opts: &DemoOptions,
    progress: &dyn Progress,
    stage: &dyn Fn(&str),
) -> Result<DemoReport, WorkflowError> {
    let t0 = Instant::now();
    if opts.photo_spp < igi_render::adaptive::MIN_SPP {
        // the photographs are rendered with adaptive samples, whose pilot needs them
        return Err(WorkflowError::Options(format!(
            "demo photographs need at least {} samples per pixel, got {}",
            igi_render::adaptive::MIN_SPP,
            opts.photo_spp
        )));
    }
    let pictures = out.join("pictures");
    make_folder(&pictures)?;
    stage("building the procedural site");
    let site = igi_geometry::procedural::colonnade_site(opts.seed, 1);
    let triangles = site.iter().map(|(_, m)| m.indices.len()).sum();
    let parts = build_parts(site, opts.atlas)?;
    let truth: Vec<Vec<Vec3>> = parts
        .iter()
        .map(|p| truth_atlas(p, albedo_pattern))
        .collect();
    let lights = lightings();
    let shots = demo_shots(&lights, opts)?;
    stage("recovering the lighting from probe captures");
    let (recorded, probes) = capture_lightings(&lights, &pictures)?;
    stage("rendering the survey photographs");
    let survey_dir = out.join("survey");
    let tp = Instant::now();
    progress.begin("photographs", shots.len() as u64);
    write_survey(
        &survey_dir,
        &parts,
        &truth,
        &lights,
        &recorded,
        &shots,
        // the simulation's Monte-Carlo noise is not a camera's: as little of it as the samples
        // allow
        &RenderOptions {
            spp: opts.photo_spp,
            seed: opts.seed,
            stratified: true,
            adaptive: true,
            ..RenderOptions::default()
        },
        &|_, _| progress.advance(1),
    )?;
    progress.finish();
    let photo_seconds = tp.elapsed().as_secs_f64();
    write_photo_pictures(&survey_dir, &shots, &pictures)?;
    stage("solving for the albedo");
    let solved = solve_demo(out, opts, progress)?;
    stage("re-lighting from a held-out view");
    let relight = relight_held_out(out, &solved, opts)?;
    write_albedo_pictures(&pictures, &solved.result, &solved.truth)?;
    copy_file(
        &out.join("result").join("convergence.png"),
        &pictures.join("convergence.png"),
    )?;
    let report = DemoReport {
        options: opts.clone(),
        parts: solved.result.parts.len(),
        triangles,
        photos: solved.photos,
        photo_seconds,
        solve_seconds: solved.seconds,
        iterations: solved.result.report.iterations.len(),
        albedo_mae: solved
            .result
            .report
            .iterations
            .last()
            .and_then(|r| r.truth_mae),
        albedo_surface_mae: solved
            .result
            .report
            .iterations
            .last()
            .and_then(|r| r.truth_surface_mae),
        probes,
        relight,
        total_seconds: t0.elapsed().as_secs_f64(),
    };
    igi_files::write_text_atomic(
        &out.join("demo.json"),
        &serde_json::to_string_pretty(&report).expect("report serialises"),
    )?;
    Ok(report)
}

/// The demo's eight survey photographs: (azimuth, distance, height, lighting) around the
/// colonnade.
fn demo_shots(lights: &[LightingSpec], opts: &DemoOptions) -> Result<Vec<ShotSpec>, WorkflowError> {
    let views: [(f32, f32, f32, usize); 8] = [
        (-30.0, 16.0, 4.0, 0),
        (20.0, 15.0, 5.0, 0),
        (75.0, 15.0, 3.5, 0),
        (150.0, 16.0, 4.5, 1),
        (210.0, 15.0, 4.0, 1),
        (260.0, 14.0, 6.0, 2),
        (-80.0, 15.0, 3.0, 2),
        (110.0, 17.0, 5.5, 2),
    ];
    let (w, h) = (opts.photo_width, opts.photo_height);
    views
        .iter()
        .enumerate()
        .map(|(k, &(az, dist, z, l))| {
            let a = az.to_radians();
            let eye = Vec3::new(dist * a.cos(), dist * a.sin(), z);
            Ok(ShotSpec {
                id: format!("view{k}-{}", lights[l].name),
                camera: Camera::look_at(eye.as_dvec3(), TARGET.as_dvec3(), w, h, 65.0)?,
                lighting: l,
            })
        })
        .collect()
}

/// Each lighting as the probe pipeline recovers it from a photographed board, with how well.
fn capture_lightings(
    lights: &[LightingSpec],
    pictures: &Path,
) -> Result<(Vec<LightingSpec>, Vec<ProbeSummary>), WorkflowError> {
    let mut recorded = Vec::new();
    let mut probes = Vec::new();
    for l in lights {
        let (rec, summary) = probe_capture(l, pictures)?;
        recorded.push(rec);
        probes.push(summary);
    }
    Ok((recorded, probes))
}

/// Tone-mapped pictures of the survey photographs.
fn write_photo_pictures(
    survey_dir: &Path,
    shots: &[ShotSpec],
    pictures: &Path,
) -> Result<(), WorkflowError> {
    for s in shots {
        let img =
            igi_imaging::read_image(&survey_dir.join("photos").join(format!("{}.exr", s.id)))?;
        write_png_tonemapped(&pictures.join(format!("photo-{}.png", s.id)), &img, 1.0)?;
    }
    Ok(())
}

/// The demo's solve: its result, the true albedo at its texels, the true scene, the number of
/// photographs and the solve's wall time.
struct DemoSolve {
    result: SolveResult,
    truth: Truth,
    truth_scene: igi_render::Scene,
    photos: usize,
    seconds: f64,
}

/// Solves the survey in `out/survey` into `out/result` with the job `igi solve` runs (the
/// truth scene attached, the folder started afresh), on the truth's atlases or (with
/// `atlas_auto_max`) on atlases sized from the photographs.
fn solve_demo(
    out: &Path,
    opts: &DemoOptions,
    progress: &dyn Progress,
) -> Result<DemoSolve, WorkflowError> {
    let survey_dir = out.join("survey");
    let truth_file = survey_dir.join("truth").join("scene.toml");
    let request = SolveRequest {
        survey: survey_dir,
        output: out.join("result"),
        atlas: match opts.atlas_auto_max {
            None => AtlasRequest::Fixed(opts.atlas),
            Some(max) => AtlasRequest::Auto { max },
        },
        options: SolveOptions {
            max_iterations: opts.iterations,
            spp: opts.solve_spp.clone(),
            seed: opts.seed,
            deblur: opts.deblur,
            ..SolveOptions::default()
        },
        truth: Some(truth_file.clone()),
        restart: true,
    };
    let started = SolveJob::check(&request)?.start(progress)?;
    let photos = started.photos.len();
    let truth = started.truth.clone().expect("the request names the truth");
    let ts = Instant::now();
    let result = started.iterate(progress)?;
    let (truth_scene, _) = igi_render::Scene::load(&truth_file)?;
    Ok(DemoSolve {
        result,
        truth,
        truth_scene,
        photos,
        seconds: ts.elapsed().as_secs_f64(),
    })
}

/// Renders the recovered and the true site from a held-out viewpoint under a held-out
/// lighting (both written into the survey, so `igi render` can repeat it), writes the images
/// and their pictures, and compares them.
fn relight_held_out(
    out: &Path,
    solved: &DemoSolve,
    opts: &DemoOptions,
) -> Result<Comparison, WorkflowError> {
    let pictures = out.join("pictures");
    let new_sun = sun_direction(30.0, 160.0);
    let held_out = LightingSpec {
        name: "held-out".into(),
        sky: clear_sky(128, 64, new_sun, 0.45, Vec3::new(0.05, 0.05, 0.045)),
        sun: Some((new_sun, Vec3::new(4.5e4, 4.0e4, 3.4e4))),
    };
    held_out.write(&out.join("survey").join("lighting"))?;
    let lighting = held_out.lighting()?;
    let a = 125.0f32.to_radians();
    let eye = Vec3::new(19.0 * a.cos(), 19.0 * a.sin(), 7.0);
    let (w, h) = (opts.photo_width, opts.photo_height);
    let cam = Camera::look_at(eye.as_dvec3(), TARGET.as_dvec3(), w, h, 65.0)?;
    cam.save(&out.join("survey").join("cameras").join("held-out.json"))?;
    let ropts = RenderOptions {
        spp: opts.relight_spp,
        seed: opts.seed ^ 0xABCD,
        indirect: 2,
        russian_roulette: false,
        stratified: false,
        adaptive: false,
    };
    let recovered = scene_with_albedo(&solved.result.parts, &solved.result.rho)?;
    let relit = render_image(&recovered, &lighting, &cam, &ropts, &|_| {})?;
    let reference_opts = RenderOptions {
        seed: opts.seed ^ 0x1234,
        ..ropts
    };
    let reference = render_image(
        &solved.truth_scene,
        &lighting,
        &cam,
        &reference_opts,
        &|_| {},
    )?;
    let cmp = compare_images(
        &relit.mean,
        &reference.mean,
        Some(&relit.stderr),
        Some(&reference.stderr),
    )?;
    write_exr(&out.join("relit.exr"), &relit.mean)?;
    write_exr(&out.join("relit-reference.exr"), &reference.mean)?;
    write_png_tonemapped(&pictures.join("relit.png"), &relit.mean, 1.0)?;
    write_png_tonemapped(&pictures.join("relit-reference.png"), &reference.mean, 1.0)?;
    let diff = difference_image(&relit.mean, &reference.mean, None)?;
    write_png_tonemapped(&pictures.join("relit-difference.png"), &diff, 1.0)?;
    Ok(cmp)
}

/// True and recovered albedo atlases side by side, per part.
fn write_albedo_pictures(
    pictures: &Path,
    result: &SolveResult,
    truth: &Truth,
) -> Result<(), WorkflowError> {
    for (i, p) in result.parts.iter().enumerate() {
        let r = p.resolution();
        let mut side = HdrImage::new(2 * r + 4, r);
        for (t, v) in p.cache.texels.iter().zip(&truth.texels[i]) {
            let k = t.index as usize;
            side.set(k % r, k / r, v.unwrap_or(Vec3::ZERO).to_array());
        }
        for y in 0..r {
            for x in 0..r {
                side.set(x + r + 4, y, result.rho[i][y * r + x].to_array());
            }
        }
        write_png_tonemapped(
            &pictures.join(format!("albedo-{}-truth-vs-recovered.png", p.name)),
            &side,
            1.0,
        )?;
    }
    Ok(())
}

/// Copies `from` to `to`.
fn copy_file(from: &Path, to: &Path) -> Result<(), WorkflowError> {
    std::fs::copy(from, to)
        .map(|_| ())
        .map_err(|e| WorkflowError::file(from, format!("cannot copy: {e}")))
}
