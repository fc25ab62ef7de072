//! `igi demo --no-probes` (issue 34): the embedded demo with no probe captures. The survey
//! carries the site's location and each photo's time and no lighting file; the solve estimates
//! each photo's light with the albedo. Checked against the demo's true skies: the sun's
//! direction (the solve's SPA against the NOAA algorithm the photographs were lit by), the
//! overcast photos fitted without a sun, the albedo error, and each estimated photo's picture
//! and re-rendering in `result/lighting/` (the re-rendering's residual against the photograph
//! is the one the fit reports).

use igi_testkit::run_ok;
use std::path::Path;

fn igi() -> std::process::Command {
    igi_testkit::Cli::new(env!("CARGO_BIN_EXE_igi")).command()
}

/// The relative RMS residual of `render` against `photo` over the pixels whose centre ray hits
/// `scene`, weighted as the fit weighs them (each residual over the pixel's value, floored at
/// 5 % of the mean).
fn relative_rms(
    photo: &igi_imaging::HdrImage,
    render: &igi_imaging::HdrImage,
    scene: &igi_render::Scene,
    camera: &igi_camera::Camera,
) -> f64 {
    let pixels: Vec<usize> = (0..photo.pixels.len())
        .filter(|&i| {
            let (x, y) = ((i % photo.width) as f64, (i / photo.width) as f64);
            let (o, d) = camera.pixel_ray(x, y);
            photo.valid[i] && scene.intersect(o.as_vec3(), d.as_vec3()).is_some()
        })
        .collect();
    let mean = pixels
        .iter()
        .map(|&i| photo.pixels[i].iter().map(|&c| c as f64).sum::<f64>())
        .sum::<f64>()
        / (3 * pixels.len()) as f64;
    let floor = 0.05 * mean;
    let sse: f64 = pixels
        .iter()
        .flat_map(|&i| (0..3).map(move |c| (i, c)))
        .map(|(i, c)| {
            let b = photo.pixels[i][c] as f64;
            ((render.pixels[i][c] as f64 - b) / b.max(floor)).powi(2)
        })
        .sum();
    (sse / (3 * pixels.len()) as f64).sqrt()
}

#[test]
fn demo_without_probes_estimates_each_photos_light() {
    let tmp = tempfile::tempdir().unwrap();
    let demo = tmp.path().join("demo");
    let out = run_ok(
        igi()
            .args(["demo", "--quick", "--no-probes", "--quiet", "--json", "-o"])
            .arg(&demo),
    );
    let d: serde_json::Value = serde_json::from_str(&out).expect("demo.json on stdout");
    assert_eq!(d["photos"], 8);
    assert_eq!(
        d["probes"].as_array().map(Vec::len),
        Some(0),
        "no probe captures"
    );
    // the survey names no lighting file: every photo has a time and the site a location
    let survey = std::fs::read_to_string(demo.join("survey/survey.toml")).unwrap();
    assert!(survey.contains("latitude_deg = 48.85"), "{survey}");
    assert_eq!(
        survey.matches("time = \"2026-06-21T").count(),
        8,
        "{survey}"
    );
    assert!(!survey.contains("lighting ="), "{survey}");

    let l = &d["estimated_light"];
    assert_eq!(
        l["absolute_scale"], false,
        "the demo has no reference target"
    );
    let photos = l["photos"].as_array().expect("the estimated photos");
    assert_eq!(photos.len(), 8);
    let scene = igi_render::Scene::load(&demo.join("survey/truth/scene.toml"))
        .unwrap()
        .0;
    for p in photos {
        let id = p["photo"].as_str().unwrap();
        let truth = &p["truth"];
        let fitted = &p["fitted"];
        if truth["sun_scale"].as_f64().unwrap() > 0.0 {
            // SPA against NOAA's algorithm: 0.0013 and 0.0025 degrees measured
            let e = p["sun_direction_error_deg"].as_f64().unwrap();
            assert!(e < 0.01, "{id}: sun {e} deg from the truth");
            assert!(fitted["sun_scale"].as_f64().unwrap() > 0.0, "{id}: {p}");
        } else {
            // an overcast photo is fitted as one: no sun
            assert_eq!(fitted["sun_scale"].as_f64(), Some(0.0), "{id}: {p}");
            assert!(
                fitted["overcast_scale"].as_f64().unwrap() > 0.0,
                "{id}: {p}"
            );
        }
        // the contract lighting file, the re-rendering and the picture (60 x 40 photographs:
        // photograph | re-rendering | an 80 x 40 sky, 4-pixel gaps)
        let dir = demo.join("result/lighting");
        igi_render::Lighting::load(&dir.join(format!("{id}.toml"))).unwrap();
        let pic = image::open(dir.join(format!("{id}.png"))).unwrap();
        assert_eq!((pic.width(), pic.height()), (2 * 60 + 80 + 8, 40), "{id}");
        let photo = igi_imaging::read_image(&demo.join(format!("survey/photos/{id}.exr"))).unwrap();
        let render = igi_imaging::read_image(&dir.join(format!("{id}_render.exr"))).unwrap();
        let camera =
            igi_camera::Camera::load(&demo.join(format!("survey/cameras/{id}.json"))).unwrap();
        let rms = relative_rms(&photo, &render, &scene, &camera);
        let reported = p["relative_rms"].as_f64().unwrap();
        assert!(
            (rms - reported).abs() <= 0.01 * reported,
            "{id}: the re-rendering's residual {rms} against the fit's {reported}"
        );
    }
    // photos taken at one time share their sky (three at 11:00, two at 19:45, three
    // overcast at 15:00), each with its own residual
    let mut times: Vec<&str> = photos.iter().map(|p| p["time"].as_str().unwrap()).collect();
    times.dedup();
    assert_eq!(times.len(), 3, "{times:?}");
    for t in times {
        let same: Vec<&serde_json::Value> = photos.iter().filter(|p| p["time"] == t).collect();
        assert!(same.len() >= 2, "{t}");
        for p in &same[1..] {
            assert_eq!(p["fitted"], same[0]["fitted"], "{t}");
            assert_eq!(p["stderr"], same[0]["stderr"], "{t}");
        }
    }
    // the albedo, its scale fixed without a target by a mean sun scale of 1
    let mae = d["albedo_mae"].as_array().expect("the albedo error");
    println!("albedo MAE {mae:?}");
    assert!(
        mae.iter().all(|m| m.as_f64().unwrap() < BOUND_MAE),
        "albedo MAE {mae:?}"
    );
    assert!(Path::new(&demo.join("demo.json")).is_file());
}

/// The quick demo's albedo MAE bound, as the probe demo's quick test: 2 rounds on 60 x 40
/// photographs are far from converged (measured (0.112, 0.116, 0.084), the last gauge step
/// still 1.33; the default size reaches docs/SKY.md's numbers).
const BOUND_MAE: f64 = 0.15;
