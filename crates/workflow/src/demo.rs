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
//!
//! With `estimate_light` (`igi demo --no-probes`, issue 34) step 2 has no probes: the three
//! skies are physical ([`TRUE_SKIES`]: Hosek-Wilkie sun and sky, CIE overcast) at three times
//! of 21 June 2026 in Paris, the sun placed by NOAA's algorithm ([`noaa_sun_direction`]); the
//! survey carries the site's location and each photo's `time` and no lighting file, so step 4
//! estimates each photo's light with the albedo ([`crate::lightfit`]), and `demo.json` says how
//! close it came ([`EstimatedLight`]).

use crate::solve::{AtlasRequest, SolveJob, SolveRequest};
use crate::WorkflowError;
use glam::{DVec3, Vec3};
use igi_camera::Camera;
use igi_imaging::{write_exr, write_png_tonemapped, HdrImage};
use igi_reflect::parts::build_parts;
use igi_reflect::result::SolveResult;
use igi_reflect::solver::{Progress, SolveOptions, Truth};
use igi_reflect::truth::truth_atlas;
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
    /// No probes (`igi demo --no-probes`, issue 34): the photographs carry their `time` and
    /// the survey its `[site]` location, no lighting file, so the solve estimates each photo's
    /// light ([`crate::lightfit`]); the true skies are Hosek-Wilkie and CIE overcast skies of
    /// known scales with the sun placed by NOAA's solar calculator algorithm
    /// ([`noaa_sun_direction`]), independent of the solve's SPA.
    #[serde(default)]
    pub estimate_light: bool,
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
            estimate_light: false,
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
    /// The probe captures (none with `estimate_light`).
    pub probes: Vec<ProbeSummary>,
    /// With `estimate_light`: the estimated lighting against the truth.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub estimated_light: Option<EstimatedLight>,
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
    let (lights, true_suns) = if opts.estimate_light {
        let (l, s) = true_skies()?;
        (l, Some(s))
    } else {
        (lightings(), None)
    };
    let shots = demo_shots(&lights, opts)?;
    let (recorded, probes) = if opts.estimate_light {
        // the survey names no lighting file (make_probeless); the true skies are kept
        (true_skies()?.0, Vec::new())
    } else {
        stage("recovering the lighting from probe captures");
        capture_lightings(&lights, &pictures)?
    };
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
    if opts.estimate_light {
        make_probeless(&survey_dir, &shots)?;
    }
    write_photo_pictures(&survey_dir, &shots, &pictures, opts.estimate_light)?;
    stage(if opts.estimate_light {
        "solving for the albedo and each photo's light (no probes)"
    } else {
        "solving for the albedo"
    });
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
        estimated_light: match &true_suns {
            Some(suns) => Some(estimated_light(&solved.result, &shots, suns)?),
            None => None,
        },
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

/// Tone-mapped pictures of the survey photographs (each at its own exposure with `auto`: the
/// physical skies of the probe-less demo are about 40 times brighter than the probe demo's).
fn write_photo_pictures(
    survey_dir: &Path,
    shots: &[ShotSpec],
    pictures: &Path,
    auto: bool,
) -> Result<(), WorkflowError> {
    for s in shots {
        let img =
            igi_imaging::read_image(&survey_dir.join("photos").join(format!("{}.exr", s.id)))?;
        let e = if auto {
            igi_imaging::auto_exposure(&img)
        } else {
            1.0
        };
        write_png_tonemapped(&pictures.join(format!("photo-{}.png", s.id)), &img, e)?;
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
    let recovered = solved.result.albedo_scene()?;
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
    for (p, truth) in result.parts.iter().zip(&truth.texels) {
        let r = p.resolution();
        let mut side = HdrImage::new(2 * r + 4, r);
        for (t, v) in p.part.cache.texels.iter().zip(truth) {
            let k = t.index as usize;
            side.set(k % r, k / r, v.unwrap_or(Vec3::ZERO).to_array());
        }
        for y in 0..r {
            for x in 0..r {
                side.set(x + r + 4, y, p.rho[y * r + x].to_array());
            }
        }
        write_png_tonemapped(
            &pictures.join(format!("albedo-{}-truth-vs-recovered.png", p.name())),
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

/// The site of the probe-less demo: Paris (WGS84 degrees); north is +Y (the default).
pub const SITE: (f64, f64) = (48.85, 2.35);

/// Most iterations of the probe-less demo at its default size (`igi demo --no-probes`), each
/// followed by a lighting round: the light starts from the model's clear sky over a grey
/// albedo and takes more rounds to settle than the albedo alone (docs/SKY.md, "The demo
/// without probes").
pub const NO_PROBES_ITERATIONS: u32 = 10;

/// One true sky of the probe-less demo: at `time` (21 June 2026, Paris summer time), the
/// Hosek-Wilkie sun and clear sky of `turbidity` (ground albedo
/// [`crate::lightfit::GROUND_ALBEDO`]) times `sun_scale` and `sky_scale`, plus a CIE overcast
/// sky of zenith radiance `overcast_zenith`: the model of [`crate::lightfit`], so its
/// parameters are what the fit should find.
#[derive(Clone, Debug, Serialize)]
pub struct TrueSky {
    pub name: &'static str,
    pub time: &'static str,
    pub turbidity: f64,
    pub sun_scale: f64,
    pub sky_scale: f64,
    pub overcast_zenith: f64,
}

/// The probe-less demo's three skies (lighting 0, 1, 2 of the demo's eight shots: three, two and
/// three photos). Without a reference target the solve fixes the global scale by making the
/// mean fitted sun scale over the photos with a sun 1: the true scales meet it (3 x 0.96 + 2 x
/// 1.06 = 5), so the albedo is comparable to the truth without a rescale.
pub const TRUE_SKIES: [TrueSky; 3] = [
    TrueSky {
        name: "sunny",
        time: "2026-06-21T11:00:00+02:00",
        turbidity: 3.0,
        sun_scale: 0.96,
        sky_scale: 0.95,
        overcast_zenith: 0.0,
    },
    TrueSky {
        name: "low-sun",
        time: "2026-06-21T19:45:00+02:00",
        turbidity: 4.5,
        sun_scale: 1.06,
        sky_scale: 1.1,
        overcast_zenith: 0.0,
    },
    TrueSky {
        name: "overcast",
        time: "2026-06-21T15:00:00+02:00",
        turbidity: 3.0,
        sun_scale: 0.0,
        sky_scale: 0.0,
        overcast_zenith: 2.0,
    },
];

/// The lighting of a true sky with the sun toward `sun` (world, unit).
fn true_sky_lighting(t: &TrueSky, sun: [f64; 3]) -> Result<LightingSpec, WorkflowError> {
    use igi_sky::{CieOvercast, Sky};
    let (w, h) = (crate::lightfit::MAP_WIDTH, crate::lightfit::MAP_WIDTH / 2);
    let g = crate::lightfit::GROUND_ALBEDO;
    let sky = Sky::new(t.turbidity, [g; 3], DVec3::from_array(sun))?;
    let mut map = sky.latlong(w, h)?;
    let overcast = CieOvercast::new([1.0; 3])?.latlong(w, h)?;
    for (p, o) in map.pixels.iter_mut().zip(&overcast.pixels) {
        for c in 0..3 {
            p[c] = (t.sky_scale * p[c] as f64 + t.overcast_zenith * o[c] as f64) as f32;
        }
    }
    // the model's disk irradiance, carried by a disk of the lighting files' diameter
    let half = (igi_imaging::color::SUN_ANGULAR_DIAMETER_DEG / 2.0).to_radians();
    let omega = 2.0 * std::f64::consts::PI * (1.0 - half.cos());
    let e = sky.sun_disk().irradiance();
    let dir = DVec3::from_array(sun).as_vec3();
    Ok(LightingSpec {
        name: t.name.into(),
        sky: map,
        sun: (t.sun_scale > 0.0).then(|| {
            (
                dir,
                Vec3::new(
                    (t.sun_scale * e[0] / omega) as f32,
                    (t.sun_scale * e[1] / omega) as f32,
                    (t.sun_scale * e[2] / omega) as f32,
                ),
            )
        }),
    })
}

/// The sun's world direction (x east, y north, z up) at `time` seen from (`latitude_deg`,
/// `longitude_deg`) by NOAA's solar calculator algorithm (Meeus's low-precision formulae with
/// NOAA's refraction approximation; good to about 0.01-0.02 degrees between 1900 and 2100): the
/// probe-less demo's true sun, independent of the NREL SPA the solve uses.
pub fn noaa_sun_direction(
    time: &igi_formats::PhotoTime,
    latitude_deg: f64,
    longitude_deg: f64,
) -> [f64; 3] {
    let (sin, cos) = (|d: f64| d.to_radians().sin(), |d: f64| d.to_radians().cos());
    let secs = time.unix_seconds() as f64 + time.nanos() as f64 * 1e-9;
    let jd = secs / 86400.0 + 2_440_587.5;
    let t = (jd - 2_451_545.0) / 36525.0;
    let l0 = (280.46646 + t * (36000.76983 + t * 0.0003032)).rem_euclid(360.0);
    let m = 357.52911 + t * (35999.05029 - 0.0001537 * t);
    let e = 0.016708634 - t * (0.000042037 + 0.0000001267 * t);
    let c = sin(m) * (1.914602 - t * (0.004817 + 0.000014 * t))
        + sin(2.0 * m) * (0.019993 - 0.000101 * t)
        + sin(3.0 * m) * 0.000289;
    let omega = 125.04 - 1934.136 * t;
    let lambda = l0 + c - 0.00569 - 0.00478 * sin(omega);
    let eps0 = 23.0 + (26.0 + (21.448 - t * (46.815 + t * (0.00059 - t * 0.001813))) / 60.0) / 60.0;
    let eps = eps0 + 0.00256 * cos(omega);
    let decl = (sin(eps) * sin(lambda)).asin().to_degrees();
    let y = (eps / 2.0).to_radians().tan().powi(2);
    let eq_time = 4.0
        * (y * sin(2.0 * l0) - 2.0 * e * sin(m) + 4.0 * e * y * sin(m) * cos(2.0 * l0)
            - 0.5 * y * y * sin(4.0 * l0)
            - 1.25 * e * e * sin(2.0 * m))
        .to_degrees();
    let minutes = secs.rem_euclid(86400.0) / 60.0;
    let true_solar = (minutes + eq_time + 4.0 * longitude_deg).rem_euclid(1440.0);
    let hour_angle = if true_solar / 4.0 < 0.0 {
        true_solar / 4.0 + 180.0
    } else {
        true_solar / 4.0 - 180.0
    };
    let lat = latitude_deg;
    let cos_zen = (sin(lat) * sin(decl) + cos(lat) * cos(decl) * cos(hour_angle)).clamp(-1.0, 1.0);
    let zen = cos_zen.acos().to_degrees();
    let a = (((sin(lat) * cos(zen)) - sin(decl)) / (cos(lat) * sin(zen)))
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees();
    let azimuth = if hour_angle > 0.0 {
        (a + 180.0).rem_euclid(360.0)
    } else {
        (540.0 - a).rem_euclid(360.0)
    };
    let el = 90.0 - zen;
    let te = el.to_radians().tan();
    let refraction = (if el > 85.0 {
        0.0
    } else if el > 5.0 {
        58.1 / te - 0.07 / te.powi(3) + 0.000086 / te.powi(5)
    } else if el > -0.575 {
        1735.0 + el * (-518.2 + el * (103.4 + el * (-12.79 + el * 0.711)))
    } else {
        -20.772 / te
    }) / 3600.0;
    let el = el + refraction;
    [sin(azimuth) * cos(el), cos(azimuth) * cos(el), sin(el)]
}

/// The probe-less demo's lightings (photos rendered under them) and each one's true sun.
/// The true skies and each one's sun direction (`None` overcast).
type TrueSkies = (Vec<LightingSpec>, Vec<Option<[f64; 3]>>);

fn true_skies() -> Result<TrueSkies, WorkflowError> {
    let mut lights = Vec::new();
    let mut suns = Vec::new();
    for t in &TRUE_SKIES {
        let time = igi_formats::PhotoTime::parse_rfc3339(t.time)
            .map_err(|e| WorkflowError::Options(format!("demo time {}: {e}", t.time)))?;
        let sun = noaa_sun_direction(&time, SITE.0, SITE.1);
        lights.push(true_sky_lighting(t, sun)?);
        suns.push((t.sun_scale > 0.0).then_some(sun));
    }
    Ok((lights, suns))
}

/// Turns the written survey into a probe-less one: the site's location, each photo's `time`,
/// no lighting files (the true skies stay in `lighting/`, unnamed by the survey).
fn make_probeless(survey_dir: &Path, shots: &[ShotSpec]) -> Result<(), WorkflowError> {
    use igi_formats::survey::SurveyFile;
    use igi_formats::TomlFile;
    let path = survey_dir.join("survey.toml");
    let mut f = SurveyFile::read(&path)?;
    f.site.latitude_deg = Some(SITE.0);
    f.site.longitude_deg = Some(SITE.1);
    for (p, s) in f.photo.iter_mut().zip(shots) {
        p.lighting = None;
        p.time = Some(TRUE_SKIES[s.lighting].time.to_string());
    }
    f.write(
        &path,
        &["igi demo --no-probes: no lighting files; each photo's light is estimated from its time at the site"],
    )?;
    Ok(())
}

/// How the probe-less demo's estimated lighting compares with the truth (`demo.json`).
#[derive(Clone, Debug, Serialize)]
pub struct EstimatedLight {
    /// Whether a reference target fixed the scale (the demo has none: `false`).
    pub absolute_scale: bool,
    /// The factor of the solve's last gauge step.
    pub gauge: f64,
    /// Lighting rounds done.
    pub rounds: u32,
    pub photos: Vec<EstimatedPhoto>,
}

/// One photo's estimated lighting against its true sky.
#[derive(Clone, Debug, Serialize)]
pub struct EstimatedPhoto {
    pub photo: String,
    pub time: String,
    /// Angle between the solve's sun (SPA) and the photographs' (NOAA), degrees; `None` for an
    /// overcast sky.
    pub sun_direction_error_deg: Option<f64>,
    pub fitted: crate::lightfit::SkyParams,
    pub stderr: crate::lightfit::SkyParams,
    pub truth: TrueSky,
    /// Relative RMS residual of the fit.
    pub relative_rms: f64,
}

/// The solve's lighting record against the true skies.
fn estimated_light(
    result: &SolveResult,
    shots: &[ShotSpec],
    suns: &[Option<[f64; 3]>],
) -> Result<EstimatedLight, WorkflowError> {
    let record: crate::lightfit::LightingRecord = result
        .report
        .lighting
        .clone()
        .and_then(|v| serde_json::from_value(v).ok())
        .ok_or_else(|| WorkflowError::Options("the demo's solve recorded no lighting".into()))?;
    let mut photos = Vec::new();
    for f in &record.photos {
        let Some(s) = shots.iter().find(|s| s.id == f.photo) else {
            continue;
        };
        let d = DVec3::from_array(f.sun_direction);
        photos.push(EstimatedPhoto {
            photo: f.photo.clone(),
            time: f.time.clone(),
            sun_direction_error_deg: suns[s.lighting].map(|t| {
                d.normalize()
                    .dot(DVec3::from_array(t).normalize())
                    .clamp(-1.0, 1.0)
                    .acos()
                    .to_degrees()
            }),
            fitted: f.params,
            stderr: f.stderr,
            truth: TRUE_SKIES[s.lighting].clone(),
            relative_rms: f.relative_rms,
        });
    }
    Ok(EstimatedLight {
        absolute_scale: record.absolute_scale,
        gauge: record.gauge,
        rounds: record.rounds,
        photos,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn angle(a: [f64; 3], b: [f64; 3]) -> f64 {
        DVec3::from_array(a)
            .normalize()
            .dot(DVec3::from_array(b).normalize())
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees()
    }

    #[test]
    fn noaa_sun_matches_noaas_calculator_and_spa() {
        // NOAA's solar calculator at (37.9 N, 23.7 E), 06:30 UTC on the 2026 solstice: zenith 52.059,
        // azimuth 88.14 degrees (with refraction)
        let t = igi_formats::PhotoTime::parse_rfc3339("2026-06-21T06:30:00Z").unwrap();
        let d = noaa_sun_direction(&t, 37.9, 23.7);
        let zen = d[2].acos().to_degrees();
        let az = d[0].atan2(d[1]).to_degrees();
        assert!((zen - 52.059).abs() < 0.01, "zenith {zen}");
        assert!((az - 88.14).abs() < 0.01, "azimuth {az}");
        // the demo's sunny times against the solve's SPA (igi-sky)
        for s in TRUE_SKIES.iter().filter(|s| s.sun_scale > 0.0) {
            let t = igi_formats::PhotoTime::parse_rfc3339(s.time).unwrap();
            let spa = crate::lightfit::SkyPhoto::new(
                t,
                crate::lightfit::SiteLocation {
                    latitude_deg: SITE.0,
                    longitude_deg: SITE.1,
                    north: [0.0, 1.0, 0.0],
                },
            )
            .unwrap()
            .unwrap();
            let a = angle(spa.sun, noaa_sun_direction(&t, SITE.0, SITE.1));
            assert!(a < 0.05, "{}: NOAA {a} deg from SPA", s.time);
            println!(
                "{}: elevation {:.2} deg, NOAA {a:.4} deg from SPA",
                s.time,
                spa.position.elevation_deg()
            );
        }
    }
}
