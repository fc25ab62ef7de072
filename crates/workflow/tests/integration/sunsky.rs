//! Lighting without probes (issue 34) against independent data: the Mitsuba 3 `sunsky` survey
//! (`datasets/fixtures/sunsky_survey`, written by `datasets/mitsuba/sunsky_survey.py`): six
//! photographs at six times of 21 June 2026 in Paris, five under Mitsuba's Hosek-Wilkie sun and
//! sky with their own sun and sky scales, one under a CIE overcast sky, with a grey card
//! (`[[reference]]`, albedo 0.5) on the ground. No photo has a lighting file: each gets the SPA
//! sun of its time and a sky whose turbidity and scales are fitted with the albedo.
//!
//! Pass criteria (issue 34): albedo MAE per channel <= 0.02 over texels seen twice; without the
//! card, MAE <= 0.02 after one global scale, the result saying that its scale is not absolute;
//! the sun within 0.1 degrees of Mitsuba's; the overcast photo's sky within 2 % and no sun;
//! the albedo within 1.5x of the same survey solved with its true lighting, per channel
//! (1.15x, 1.13x, 1.23x measured with the sun's colour tied to the model's; docs/SKY.md,
//! "Lighting estimated with the albedo").

use igi_formats::lighting::LightingFile;
use igi_formats::TomlFile;
use igi_reflect::solver::truth_from_scene;
use igi_reflect::{SolveOptions, SolveResult};
use igi_workflow::lightfit::{LightingRecord, SkyParams};
use igi_workflow::{AtlasRequest, LightingSource, SolveRequest, Survey};
use std::path::{Path, PathBuf};

const ATLAS: u32 = 64;
const ITERATIONS: u32 = 7;

fn fixture() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../datasets/fixtures/sunsky_survey")
}

fn truth_json() -> serde_json::Value {
    let p = fixture().join("truth.json");
    serde_json::from_str(&std::fs::read_to_string(&p).expect("fixture truth.json")).unwrap()
}

fn options() -> SolveOptions {
    SolveOptions {
        max_iterations: ITERATIONS,
        min_iterations: ITERATIONS,
        spp: vec![16, 64],
        ..SolveOptions::default()
    }
}

fn solve(survey: &Path, out: &Path) -> SolveResult {
    let request = SolveRequest {
        survey: survey.to_path_buf(),
        output: out.to_path_buf(),
        atlas: AtlasRequest::Fixed(ATLAS),
        options: options(),
        truth: None,
        restart: true,
    };
    igi_workflow::solve(&request, &igi_reflect::solver::NoProgress).unwrap()
}

/// Per texel seen at least twice: (solved, true) albedo.
fn pairs(state: &SolveResult) -> Vec<([f32; 3], [f32; 3])> {
    let scene = igi_render::Scene::load(&fixture().join("truth/scene.toml"))
        .unwrap()
        .0;
    let truth = truth_from_scene(&state.parts, &scene);
    let mut out = Vec::new();
    for (part, truth) in state.parts.iter().zip(&truth.texels) {
        for (k, t) in part.part.cache.texels.iter().enumerate() {
            let i = t.index as usize;
            if part.observations[i] < 2 {
                continue;
            }
            if let Some(rho) = truth[k] {
                out.push((part.rho[i].to_array(), rho.to_array()));
            }
        }
    }
    out
}

/// Mean absolute error per channel after multiplying the solved albedo by `g`.
fn mae(p: &[([f32; 3], [f32; 3])], g: f64) -> [f64; 3] {
    std::array::from_fn(|c| {
        p.iter()
            .map(|(a, b)| (g * a[c] as f64 - b[c] as f64).abs())
            .sum::<f64>()
            / p.len() as f64
    })
}

/// The one global scale that best maps the solved albedo onto the truth (least squares).
fn best_scale(p: &[([f32; 3], [f32; 3])]) -> f64 {
    let (mut ab, mut aa) = (0.0, 0.0);
    for (a, b) in p {
        for c in 0..3 {
            ab += a[c] as f64 * b[c] as f64;
            aa += a[c] as f64 * a[c] as f64;
        }
    }
    ab / aa
}

fn record(state: &SolveResult) -> LightingRecord {
    serde_json::from_value(state.report.lighting.clone().expect("a lighting record")).unwrap()
}

fn angle_deg(a: [f64; 3], b: [f64; 3]) -> f64 {
    let d: f64 = (0..3).map(|k| a[k] * b[k]).sum();
    let na: f64 = a.iter().map(|x| x * x).sum::<f64>().sqrt();
    let nb: f64 = b.iter().map(|x| x * x).sum::<f64>().sqrt();
    (d / (na * nb)).clamp(-1.0, 1.0).acos().to_degrees()
}

/// The survey with each photo given its true lighting, written into `dir`: igi-sky's
/// Hosek-Wilkie sky at the true turbidity and sky scale (the same RGB sky as Mitsuba's, to f32,
/// docs/SKY.md) with the sun's disk carrying the irradiance Mitsuba's sun delivers, and the CIE
/// overcast sky of the overcast photo.
fn true_lighting_survey(dir: &Path) -> PathBuf {
    let survey = Survey::load(&fixture().join("survey_nocard.toml")).unwrap();
    let truth = truth_json();
    let mut text = String::from("[site]\nmeshes = [");
    text += &survey
        .meshes
        .iter()
        .map(|m| format!("{:?}", m.display().to_string()))
        .collect::<Vec<_>>()
        .join(", ");
    text += "]\n";
    for (p, t) in survey
        .photos
        .iter()
        .zip(truth["photos"].as_array().unwrap())
    {
        let LightingSource::Estimated(sky) = &p.lighting else {
            panic!("photo {} should have its light estimated", p.id)
        };
        let params = SkyParams {
            turbidity: truth["turbidity"].as_f64().unwrap(),
            sun_scale: t["sun_scale"].as_f64().unwrap(),
            sun_colour: [1.0; 3],
            sky_scale: t["sky_scale"].as_f64().unwrap(),
            overcast_scale: t["overcast_zenith"].as_f64().unwrap(),
        };
        sky.write_lighting(dir, &p.id, &params).unwrap();
        // the sun's disk with the irradiance Mitsuba's sun delivers (its own limb darkening
        // and spectral integration), not igi-sky's
        if params.sun_scale > 0.0 {
            let path = dir.join(format!("{}.toml", p.id));
            let mut file = LightingFile::read(&path).unwrap();
            let sun = file.sun.as_mut().unwrap();
            let half = (sun.angular_diameter_deg / 2.0).to_radians();
            let omega = 2.0 * std::f64::consts::PI * (1.0 - half.cos());
            let e = &t["sun_irradiance_at_scale_1"];
            sun.radiance = std::array::from_fn(|c| {
                (params.sun_scale * e[c].as_f64().unwrap() / omega).max(0.0)
            });
            file.write(&path, &["true lighting of the test"]).unwrap();
        }
        text += &format!(
            "\n[[photo]]\nid = {:?}\nimage = {:?}\ncamera = {:?}\nlighting = \"{}.toml\"\n",
            p.id,
            p.image.display().to_string(),
            p.camera.display().to_string(),
            p.id
        );
    }
    let file = dir.join("survey.toml");
    std::fs::write(&file, text).unwrap();
    file
}

#[test]
fn the_sun_of_each_photo_is_mitsubas_within_a_tenth_of_a_degree() {
    let survey = Survey::load(&fixture().join("survey.toml")).unwrap();
    let truth = truth_json();
    for (p, t) in survey
        .photos
        .iter()
        .zip(truth["photos"].as_array().unwrap())
    {
        let LightingSource::Estimated(sky) = &p.lighting else {
            panic!("photo {} should have its light estimated", p.id)
        };
        let m: Vec<f64> = t["mitsuba_sun_direction"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        let a = angle_deg(sky.sun, [m[0], m[1], m[2]]);
        println!("{}: sun {:.4} deg from Mitsuba's", p.id, a);
        assert!(a < 0.1, "photo {}: sun {a} deg from Mitsuba's", p.id);
    }
}

#[test]
fn albedo_and_light_from_photographs_without_probes() {
    let tmp = tempfile::tempdir().unwrap();
    let truth = truth_json();

    let t0 = std::time::Instant::now();
    let card = solve(&fixture().join("survey.toml"), &tmp.path().join("card"));
    let card_s = t0.elapsed().as_secs_f64();
    let p = pairs(&card);
    let card_mae = mae(&p, 1.0);
    let rec = record(&card);
    println!(
        "card: {} texels seen twice, MAE {card_mae:.4?}, {card_s:.1} s, gauge {:.4}, reference ratio {:?}",
        p.len(),
        rec.gauge,
        rec.reference_ratio
    );
    for (f, t) in rec.photos.iter().zip(truth["photos"].as_array().unwrap()) {
        println!(
            "  {}: T {} +- {:.2}, sun {:.4} +- {:.4} (true {}) colour {:.3?}, sky {:.4} +- {:.4} (true {}), overcast {:.4} +- {:.4} (true {}), rel rms {:.3}",
            f.photo,
            f.params.turbidity,
            f.stderr.turbidity,
            f.params.sun_scale,
            f.stderr.sun_scale,
            t["sun_scale"],
            f.params.sun_colour,
            f.params.sky_scale,
            f.stderr.sky_scale,
            t["sky_scale"],
            f.params.overcast_scale,
            f.stderr.overcast_scale,
            t["overcast_zenith"],
            f.relative_rms
        );
    }
    assert!(rec.absolute_scale);
    // every photo's estimated lighting is a contract lighting file in the result
    for f in &rec.photos {
        let l = tmp
            .path()
            .join("card/lighting")
            .join(format!("{}.toml", f.photo));
        igi_render::Lighting::load(&l).unwrap();
    }
    check_pictures(&tmp.path().join("card"), &rec);

    let t1 = std::time::Instant::now();
    let nocard = solve(
        &fixture().join("survey_nocard.toml"),
        &tmp.path().join("nocard"),
    );
    let nocard_s = t1.elapsed().as_secs_f64();
    let pn = pairs(&nocard);
    let g = best_scale(&pn);
    let nocard_mae = mae(&pn, g);
    let recn = record(&nocard);
    println!(
        "no card: MAE {:.4?} as solved, {nocard_mae:.4?} after the global scale {g:.4}; reported gauge {:.4} (absolute {}), {nocard_s:.1} s",
        mae(&pn, 1.0),
        recn.gauge,
        recn.absolute_scale
    );
    assert!(!recn.absolute_scale);

    let lt = tmp.path().join("true_lighting");
    std::fs::create_dir_all(&lt).unwrap();
    let t2 = std::time::Instant::now();
    let known = solve(&true_lighting_survey(&lt), &tmp.path().join("known"));
    let known_s = t2.elapsed().as_secs_f64();
    let known_mae = mae(&pairs(&known), 1.0);
    println!("true lighting: MAE {known_mae:.4?}, {known_s:.1} s");

    let ratio: Vec<f64> = (0..3).map(|c| card_mae[c] / known_mae[c]).collect();
    println!("MAE over the true-lighting solve's: {ratio:.2?} (issue 34 asks for 1.5)");
    for c in 0..3 {
        assert!(
            ratio[c] <= 1.5,
            "MAE {card_mae:?} over the true lighting's {known_mae:?}"
        );
        assert!(card_mae[c] <= 0.02, "MAE {card_mae:?}");
        assert!(nocard_mae[c] <= 0.02, "MAE without the card {nocard_mae:?}");
    }
    // the overcast photo: no sun, the CIE overcast sky's zenith radiance within 2 %
    let t = &truth["photos"][3];
    let f = &rec.photos[3];
    assert_eq!(f.photo, t["id"].as_str().unwrap());
    let z = t["overcast_zenith"].as_f64().unwrap();
    assert!(f.params.sun_scale == 0.0, "{:?}", f.params);
    assert!(
        (f.params.overcast_scale - z).abs() <= 0.02 * z,
        "overcast zenith {} against {z}",
        f.params.overcast_scale
    );
}

/// Each estimated photo's picture `RESULT/lighting/ID.png` (photograph | re-rendering | sky)
/// is written, and its re-rendering `ID_render.exr` has the fit's residual against the
/// photograph (relative RMS over the pixels that see the site, weighted as the fit weighs
/// them).
fn check_pictures(result: &Path, rec: &LightingRecord) {
    let survey = Survey::load(&fixture().join("survey.toml")).unwrap();
    let scene = igi_render::Scene::load(&fixture().join("truth/scene.toml"))
        .unwrap()
        .0;
    for f in &rec.photos {
        let dir = result.join("lighting");
        let p = survey.photos.iter().find(|p| p.id == f.photo).unwrap();
        let pic = igi_imaging::read_image(&dir.join(format!("{}.png", f.photo))).unwrap();
        let photo = igi_imaging::read_image(&p.image).unwrap();
        assert_eq!(
            (pic.width, pic.height),
            (2 * photo.width + 2 * photo.height + 8, photo.height)
        );
        let render = igi_imaging::read_image(&dir.join(format!("{}_render.exr", f.photo))).unwrap();
        let camera = igi_camera::Camera::load(&p.camera).unwrap();
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
        let sse: f64 = pixels
            .iter()
            .flat_map(|&i| (0..3).map(move |c| (i, c)))
            .map(|(i, c)| {
                let b = photo.pixels[i][c] as f64;
                ((render.pixels[i][c] as f64 - b) / b.max(0.05 * mean)).powi(2)
            })
            .sum();
        let rms = (sse / (3 * pixels.len()) as f64).sqrt();
        println!(
            "  {}: re-rendering's relative RMS {rms:.4} (fit {:.4})",
            f.photo, f.relative_rms
        );
        assert!(
            (rms - f.relative_rms).abs() <= 0.01 * f.relative_rms,
            "{}: re-rendering {rms} against the fit's {}",
            f.photo,
            f.relative_rms
        );
    }
}

/// The fixture's survey text with `edit` applied, written into `dir` with absolute paths.
fn edited_survey(dir: &Path, edit: impl Fn(String) -> String) -> PathBuf {
    let root = fixture().canonicalize().unwrap();
    let text = std::fs::read_to_string(root.join("survey.toml")).unwrap();
    let text = text
        .replace("\"geometry/", &format!("\"{}/geometry/", root.display()))
        .replace("\"photos/", &format!("\"{}/photos/", root.display()))
        .replace("\"cameras/", &format!("\"{}/cameras/", root.display()));
    let file = dir.join("survey.toml");
    std::fs::write(&file, edit(text)).unwrap();
    file
}

fn refusal(dir: &Path, edit: impl Fn(String) -> String) -> String {
    let file = edited_survey(dir, edit);
    let e = Survey::load(&file)
        .expect_err("the survey is refused")
        .to_string();
    assert!(
        e.contains(&file.display().to_string()),
        "the error names the survey file: {e}"
    );
    e
}

#[test]
fn bad_input_for_estimated_light_is_refused_naming_the_file_and_key() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    // the unedited copy loads
    Survey::load(&edited_survey(d, |t| t)).unwrap();
    let e = refusal(d, |t| {
        t.replacen("time = \"2026-06-21T08:30:00+02:00\"\n", "", 1)
    });
    assert!(
        e.contains("photo `t0830`") && e.contains("no `time`"),
        "{e}"
    );
    let e = refusal(d, |t| {
        t.replace("latitude_deg = 48.85\nlongitude_deg = 2.35\n", "")
    });
    assert!(e.contains("latitude_deg") && e.contains("[site]"), "{e}");
    let e = refusal(d, |t| {
        t.replace("latitude_deg = 48.85", "latitude_deg = 91.0")
    });
    assert!(e.contains("latitude_deg"), "{e}");
    let e = refusal(d, |t| {
        t.replace("2026-06-21T08:30:00+02:00", "2026-06-21T08:30:00")
    });
    assert!(e.contains("t0830") && e.contains("offset"), "{e}");
    let e = refusal(d, |t| {
        t.replace("center = [2.6, -2.6, 0.0]", "center = [60.0, 60.0, 0.0]")
    });
    assert!(
        e.contains("[[reference]] 1") && e.contains("no photo sees it"),
        "{e}"
    );
    let e = refusal(d, |t| {
        t.replace("2026-06-21T18:30:00+02:00", "2026-06-21T23:30:00+02:00")
    });
    assert!(
        e.contains("t1830") && e.contains("below the horizon"),
        "{e}"
    );
}

/// A photo without `time` takes the one its image's EXIF holds (FORMATS.md: DateTimeOriginal
/// with OffsetTimeOriginal, or the GPS time); a local EXIF time without its offset is refused,
/// naming the image (real JPEGs of ../shared/data: a Sony ILCE-6400 that writes the offset, an
/// iPhone 7 that does not).
#[test]
fn a_photo_without_time_takes_the_time_of_its_exif() {
    let sony = igi_testkit::shared_data("mirror_ball_ldr/olapietka_sony_a6400").join("raw1.jpg");
    let iphone =
        igi_testkit::shared_data("mirror_ball_ldr/uiuc_cs445_kagrawal_iphone7").join("ball_10.JPG");
    let tmp = tempfile::tempdir().unwrap();
    let with_image = |image: &Path| {
        let image = image.display().to_string();
        move |t: String| {
            let root = fixture().canonicalize().unwrap();
            t.replacen("time = \"2026-06-21T08:30:00+02:00\"\n", "", 1)
                .replace(
                    &format!("\"{}/photos/t0830.exr\"", root.display()),
                    &format!("{image:?}"),
                )
        }
    };
    let survey = Survey::load(&edited_survey(tmp.path(), with_image(&sony))).unwrap();
    let exif = igi_imaging::exif::read_exif(&sony).unwrap();
    let want = igi_formats::PhotoTime::from_photo_exif(&exif).unwrap();
    let sky = survey.estimated_photos()[0].clone().expect("estimated");
    assert_eq!(sky.time, want);
    assert_eq!(survey.photos[0].time, Some(want));
    println!(
        "t0830 with the Sony's raw1.jpg: time {} from its EXIF ({:?} {:?}), sun elevation {:.2} deg",
        want.to_rfc3339(),
        exif.date_time_original,
        exif.offset_time_original,
        sky.position.elevation_deg()
    );
    let e = Survey::load(&edited_survey(tmp.path(), with_image(&iphone)))
        .expect_err("no offset: refused")
        .to_string();
    assert!(
        e.contains(&iphone.display().to_string()) && e.contains("offset") && e.contains("t0830"),
        "{e}"
    );
}

/// A second camera body: t1030 photographed again from the same place at the same time by
/// a body whose calibration gives 1.3 times the values (its pixels times 1.3, `body = "B"`).
/// The fitted exposure factor of body B is 1.3 (the first body's is 1), and the albedo is as
/// good as the survey's own; the same photo given no body (one calibration assumed) pulls the
/// shared sky of 10:30 and the albedo away.
#[test]
fn a_second_camera_body_gets_its_exposure_factor() {
    let tmp = tempfile::tempdir().unwrap();
    let mut image = igi_imaging::read_image(&fixture().join("photos/t1030.exr")).unwrap();
    image
        .pixels
        .iter_mut()
        .for_each(|p| p.iter_mut().for_each(|c| *c *= 1.3));
    let b_image = tmp.path().join("t1030-b.exr");
    igi_imaging::write_exr(&b_image, &image).unwrap();
    let root = fixture().canonicalize().unwrap();
    let with_b = |body: &str| {
        let entry = format!(
            "\n[[photo]]\nid = \"t1030-b\"\nimage = {:?}\ncamera = \"{}/cameras/t1030.json\"\ntime = \"2026-06-21T10:30:00+02:00\"\n{body}",
            b_image.display().to_string(),
            root.display()
        );
        move |t: String| {
            let at = t.find("[[reference]]").unwrap_or(t.len());
            format!("{}{entry}\n{}", &t[..at], &t[at..])
        }
    };
    let run = |name: &str, body: &str| {
        let dir = tmp.path().join(name);
        std::fs::create_dir_all(&dir).unwrap();
        let survey = edited_survey(&dir, with_b(body));
        let state = solve(&survey, &dir.join("result"));
        let rec = record(&state);
        let factor = |id: &str| {
            let f = rec.photos.iter().find(|f| f.photo == id).unwrap();
            f.body_exposure
        };
        let m = mae(&pairs(&state), 1.0);
        (factor("t1030-b"), factor("t0830"), m, rec)
    };
    let (k, k0, m, rec) = run("bodies", "body = \"B\"\n");
    let (k1, _, m1, _) = run("one", "");
    println!(
        "second body: exposure factor {k:.4} (true 1.3; first body {k0}), albedo MAE {m:.4?}; as one body: factor {k1}, MAE {m1:.4?}"
    );
    assert!((k / 1.3 - 1.0).abs() < 0.01, "{k}");
    assert_eq!(k0, 1.0);
    assert_eq!(k1, 1.0);
    let f = |id: &str| rec.photos.iter().find(|f| f.photo == id).unwrap().clone();
    assert_eq!(f("t1030").params, f("t1030-b").params, "one sky at 10:30");
    assert!(m.iter().all(|&e| e < 0.02), "{m:?}");
    assert!(
        m.iter().zip(&m1).all(|(a, b)| a < b),
        "{m:?} against {m1:?}"
    );
}
