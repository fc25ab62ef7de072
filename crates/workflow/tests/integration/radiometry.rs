//! Radiometric calibration in the pipeline: the photographs of a synthetic survey are taken
//! through a lens with known vignetting and a sensor with known colour crosstalk. The camera
//! radiometry is fitted from synthetic flat fields and a colour-checker photograph taken with the
//! same camera, and the survey's `[radiometry]` key applies it to every photo on load. The
//! solver's albedo error with the calibration matches the error on the clean photographs; without
//! it the error is several times larger.

use glam::{DVec2, DVec3, Vec3};
use igi_camera::radiometry::{
    apply_color_matrix, fit_radiometry, render_checker, CameraRadiometry, Falloff, RadiometryInputs,
};
use igi_camera::Camera;
use igi_imaging::HdrImage;
use igi_reflect::parts::build_parts;
use igi_reflect::solver::truth_from_scene;
use igi_reflect::truth::truth_atlas;
use igi_reflect::{SolveOptions, SolveResult};
use igi_render::sky::{clear_sky, overcast_sky, sun_direction};
use igi_render::RenderOptions;
use igi_synth::survey::{ground_and_block, write_survey, LightingSpec, ShotSpec};
use igi_workflow::Survey;
use rand::{Rng, SeedableRng};
use std::path::Path;

const FALLOFF: Falloff = Falloff {
    a2: -0.45,
    a4: 0.1,
    a6: -0.05,
};
const CROSSTALK: [[f64; 3]; 3] = [[0.78, 0.17, 0.05], [0.12, 0.72, 0.16], [0.04, 0.22, 0.74]];

/// What the synthetic camera does to the radiance reaching it.
fn through_camera(img: &mut HdrImage) {
    FALLOFF.vignette(img);
    apply_color_matrix(img, &CROSSTALK);
}

fn noisy(img: &mut HdrImage, rel: f64, seed: u64) {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    for p in &mut img.pixels {
        *p = p.map(|c| (c as f64 * (1.0 + rng.gen_range(-rel..rel))) as f32);
    }
}

/// The calibration fitted from two flat fields and a checker photo of the synthetic camera.
fn calibrate(w: usize, h: usize) -> CameraRadiometry {
    let flats: Vec<HdrImage> = [0.5f32, 1.5]
        .iter()
        .enumerate()
        .map(|(k, v)| {
            let mut f = HdrImage::new(w, h);
            f.pixels.iter_mut().for_each(|p| *p = [*v; 3]);
            through_camera(&mut f);
            noisy(&mut f, 0.005, k as u64);
            f
        })
        .collect();
    let corners = [
        DVec2::new(8.0, 20.0),
        DVec2::new(88.0, 16.0),
        DVec2::new(90.0, 72.0),
        DVec2::new(6.0, 76.0),
    ];
    let white = 1.7;
    let mut checker = render_checker(w, h, &corners, white, 0.2).unwrap();
    through_camera(&mut checker);
    noisy(&mut checker, 0.005, 7);
    fit_radiometry(&RadiometryInputs {
        flats: &flats,
        checker: Some((&checker, corners)),
        white: Some(white),
    })
    .unwrap()
}

/// Final per-channel albedo MAE of a short solve of the survey file `survey`.
fn solve_mae(survey: &Path, res: u32) -> [f32; 3] {
    let survey = Survey::load(survey).unwrap();
    let photos: Vec<_> = survey.photos.iter().map(|p| p.load().unwrap()).collect();
    let meshes: Vec<_> = survey
        .meshes
        .iter()
        .map(|m| {
            (
                m.file_stem().unwrap().to_string_lossy().into_owned(),
                igi_geometry::read_mesh(m).unwrap(),
            )
        })
        .collect();
    let parts = build_parts(meshes, res).unwrap();
    let (truth_scene, _) = igi_render::Scene::load(&survey.root.join("truth/scene.toml")).unwrap();
    let truth = truth_from_scene(&parts, &truth_scene);
    let opts = SolveOptions {
        atlas_resolution: res,
        max_iterations: 2,
        min_iterations: 2,
        spp: vec![32, 64],
        ..SolveOptions::default()
    };
    let ids: Vec<String> = photos.iter().map(|p| p.id.clone()).collect();
    let done = igi_reflect::solve_in_memory(
        SolveResult::fresh(parts, ids, &opts),
        &photos,
        None,
        Some(&truth),
        &opts,
    )
    .unwrap();
    done.report.iterations.last().unwrap().truth_mae.unwrap()
}

#[test]
fn calibrated_photos_solve_as_well_as_clean_ones_and_uncalibrated_ones_do_not() {
    let dir = tempfile::tempdir().unwrap();
    let res = 32;
    let (w, h) = (96usize, 96usize);
    let shots = write_clean_survey(dir.path(), res, (w, h));
    let (cal, calibrated) = write_raw_surveys(dir.path(), &shots, (w, h));
    let mean = |m: [f32; 3]| m.iter().sum::<f32>() / 3.0;
    let mae_clean = solve_mae(&dir.path().join("survey.toml"), res);
    let mae_cal = solve_mae(&dir.path().join("calibrated.toml"), res);
    let mae_raw = solve_mae(&dir.path().join("raw.toml"), res);
    eprintln!("albedo MAE: clean {mae_clean:?} (mean {:.4}), calibrated {mae_cal:?} (mean {:.4}), uncalibrated {mae_raw:?} (mean {:.4})", mean(mae_clean), mean(mae_cal), mean(mae_raw));
    let ratio = mean(mae_cal) / mean(mae_clean);
    assert!(
        (ratio - 1.0).abs() <= 0.10,
        "calibrated / clean albedo MAE = {ratio:.3} (goal within 10 %)"
    );
    assert!(
        mean(mae_raw) > 2.0 * mean(mae_clean),
        "uncalibrated MAE {mae_raw:?} is not measurably worse than clean {mae_clean:?}"
    );

    refuses_bad_radiometry(dir.path(), &cal, &calibrated);
}

/// The ground and block survey (six clean photos: three views under a sunny and an overcast
/// sky) at an atlas of `res`; returns its shots.
fn write_clean_survey(dir: &Path, res: u32, (w, h): (usize, usize)) -> Vec<ShotSpec> {
    let parts = build_parts(ground_and_block(), res).unwrap();
    let truth: Vec<Vec<Vec3>> = parts
        .iter()
        .map(|p| {
            truth_atlas(p, |x| {
                Vec3::new(0.3 + 0.2 * (0.5 * x.x).sin(), 0.4, 0.25 + 0.1 * x.z)
            })
        })
        .collect();
    let sun = sun_direction(40.0, 30.0);
    let lightings = vec![
        LightingSpec {
            name: "sunny".into(),
            sky: clear_sky(64, 32, sun, 0.6, Vec3::splat(0.08)),
            sun: Some((sun, Vec3::new(6.0e4, 5.7e4, 5.2e4))),
        },
        LightingSpec {
            name: "overcast".into(),
            sky: overcast_sky(64, 32, 2.0, Vec3::splat(0.15)),
            sun: None,
        },
    ];
    let mut shots = Vec::new();
    for (k, az) in [20.0f32, 140.0, 260.0].iter().enumerate() {
        let a = az.to_radians();
        let eye = Vec3::new(6.5 * a.cos(), 6.5 * a.sin(), 3.5);
        for (li, l) in lightings.iter().enumerate() {
            let target = DVec3::new(0.0, 0.0, 0.5);
            let camera = Camera::look_at(eye.as_dvec3(), target, w as u32, h as u32, 70.0).unwrap();
            shots.push(ShotSpec {
                id: format!("cam{k}-{}", l.name),
                camera,
                lighting: li,
            });
        }
    }
    write_survey(
        dir,
        &parts,
        &truth,
        &lightings,
        &lightings,
        &shots,
        &RenderOptions {
            spp: 128,
            seed: 11,
            ..RenderOptions::default()
        },
        &|_, _| {},
    )
    .unwrap();

    shots
}

/// The same photographs through the synthetic camera, in photos_raw/, its fitted radiometry
/// (radiometry.json), and the surveys raw.toml (uncalibrated) and calibrated.toml; returns the
/// radiometry and calibrated.toml's text.
fn write_raw_surveys(
    dir: &Path,
    shots: &[ShotSpec],
    (w, h): (usize, usize),
) -> (CameraRadiometry, String) {
    let raw = dir.join("photos_raw");
    std::fs::create_dir_all(&raw).unwrap();
    for s in shots {
        let mut img = igi_imaging::read_image(&dir.join(format!("photos/{}.exr", s.id))).unwrap();
        through_camera(&mut img);
        igi_imaging::write_exr(&raw.join(format!("{}.exr", s.id)), &img).unwrap();
    }
    let cal = calibrate(w, h);
    eprintln!("fitted radiometry: {cal:?}");
    cal.save(&dir.join("radiometry.json")).unwrap();
    let clean = std::fs::read_to_string(dir.join("survey.toml")).unwrap();
    let uncalibrated = clean.replace("\"photos/", "\"photos_raw/");
    assert_ne!(uncalibrated, clean);
    let calibrated = format!("[radiometry]\ncamera = \"radiometry.json\"\n\n{uncalibrated}");
    std::fs::write(dir.join("raw.toml"), &uncalibrated).unwrap();
    std::fs::write(dir.join("calibrated.toml"), &calibrated).unwrap();

    (cal, calibrated)
}

/// A photo whose shape does not match the calibration is refused when the survey is read,
/// naming the radiometry file and the photo; a broken radiometry file fails when the survey is
/// read, before any work.
fn refuses_bad_radiometry(dir: &Path, cal: &CameraRadiometry, calibrated: &str) {
    let bad = CameraRadiometry {
        width: 40,
        height: 30,
        ..cal.clone()
    };
    bad.save(&dir.join("wide.json")).unwrap();
    std::fs::write(
        dir.join("wide.toml"),
        calibrated.replace("radiometry.json", "wide.json"),
    )
    .unwrap();
    let e = match Survey::load(&dir.join("wide.toml")) {
        Ok(_) => panic!("a radiometry file of another aspect ratio was accepted"),
        Err(e) => e.to_string(),
    };
    assert!(
        e.contains("wide.json") && e.contains("cam0-sunny") && e.contains("96x96"),
        "{e}"
    );
    // a broken radiometry file fails when the survey is read, before any work
    std::fs::write(dir.join("broken.json"), "{}").unwrap();
    std::fs::write(
        dir.join("broken.toml"),
        calibrated.replace("radiometry.json", "broken.json"),
    )
    .unwrap();
    let e = Survey::load(&dir.join("broken.toml"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("broken.json"), "{e}");
}
