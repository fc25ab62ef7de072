//! `igi sky`: the lighting file of a place and time read back through igi-formats' reader,
//! its sun against igi-sky's SPA direction, its map's horizontal irradiance against the
//! model's, and clear refusals (nothing written) for bad input.

use igi_formats::lighting::LightingRadiance;
use igi_sky::{sun_direction, sun_position, Refraction, Sky};
use std::path::Path;
use std::process::Command;

fn igi(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_igi"))
        .args(args)
        .arg("--quiet")
        .output()
        .unwrap()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

const TIME: &str = "2026-06-21T17:30:00+02:00";

/// Horizontal irradiance of the model's dome by a fine quadrature in (theta, phi), per channel.
fn model_horizontal_irradiance(sky: &Sky) -> [f64; 3] {
    let (nt, np) = (400, 800);
    let mut e = [0.0; 3];
    for i in 0..nt {
        let th = (i as f64 + 0.5) / nt as f64 * std::f64::consts::FRAC_PI_2;
        for j in 0..np {
            let ph = (j as f64 + 0.5) / np as f64 * 2.0 * std::f64::consts::PI;
            let d = glam::DVec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos());
            let l = sky.radiance(d);
            let w = th.cos()
                * th.sin()
                * (std::f64::consts::FRAC_PI_2 / nt as f64)
                * (2.0 * std::f64::consts::PI / np as f64);
            for c in 0..3 {
                e[c] += l[c] * w;
            }
        }
    }
    e
}

#[test]
fn sky_from_a_survey_reads_back_with_the_spa_sun_and_the_models_irradiance() {
    let dir = tempfile::tempdir().unwrap();
    // a survey whose north is +X (so the sun direction is rotated from the default)
    std::fs::write(
        dir.path().join("survey.toml"),
        "[site]\nmesh = \"site.ply\"\nlatitude_deg = 48.85\nlongitude_deg = 2.35\nnorth = [1.0, 0.0, 0.0]\n",
    )
    .unwrap();
    let out = dir.path().join("evening.toml");
    let o = igi(&[
        "sky",
        "--survey",
        s(dir.path()),
        "--time",
        TIME,
        "--width",
        "256",
        "-o",
        s(&out),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let light = LightingRadiance::load(&out).unwrap();
    let sun = light.sun.as_ref().expect("a [sun]");
    let time = igi_formats::time::PhotoTime::parse_rfc3339(TIME).unwrap();
    let pos = sun_position(&time, 48.85, 2.35, 0.0, Refraction::STANDARD).unwrap();
    let want = sun_direction(pos, [1.0, 0.0, 0.0]).unwrap();
    let got = glam::DVec3::from(sun.direction.map(f64::from)).normalize();
    let angle = got.angle_between(want).to_degrees();
    assert!(angle < 1e-4, "sun {got} vs SPA {want}: {angle} deg");
    assert!((pos.elevation_deg() - 40.64).abs() < 0.05, "{pos:?}");
    // the disk gives the model's solar irradiance
    let sky = Sky::new(3.0, [0.2; 3], want).unwrap();
    let e_sun = sky.solar_irradiance();
    for c in 0..3 {
        let e = sun.radiance[c] as f64 * sun.solid_angle;
        assert!(
            (e / e_sun[c] - 1.0).abs() < 1e-5,
            "sun channel {c}: {e} vs {}",
            e_sun[c]
        );
    }
    // the map's horizontal irradiance against the model's
    let (w, h, px) = light.environment.as_ref().expect("an [environment]");
    assert_eq!((*w, *h), (256, 128));
    let img = igi_imaging::HdrImage {
        width: *w,
        height: *h,
        pixels: px.clone(),
        valid: vec![true; px.len()],
    };
    let e_map = igi_sky::job::map_horizontal_irradiance(&img);
    let e_model = model_horizontal_irradiance(&sky);
    for c in 0..3 {
        let r = e_map[c] / e_model[c];
        assert!(
            (r - 1.0).abs() < 2e-3,
            "channel {c}: map {} model {}",
            e_map[c],
            e_model[c]
        );
    }
    eprintln!("horizontal irradiance: map {e_map:?}, model {e_model:?}");
}

#[test]
fn overcast_sky_at_night_gives_the_cie_irradiance() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("night.toml");
    let o = igi(&[
        "sky",
        "--site",
        "48.85,2.35",
        "--time",
        "2026-06-21T23:30:00+02:00",
        "--overcast",
        "--zenith-radiance",
        "9",
        "--width",
        "256",
        "-o",
        s(&out),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let light = LightingRadiance::load(&out).unwrap();
    assert!(light.sun.is_none());
    let (w, h, px) = light.environment.unwrap();
    let img = igi_imaging::HdrImage {
        width: w,
        height: h,
        pixels: px.clone(),
        valid: vec![true; px.len()],
    };
    let e = igi_sky::job::map_horizontal_irradiance(&img);
    let want = 7.0 * std::f64::consts::PI * 9.0 / 9.0;
    for v in e {
        assert!((v / want - 1.0).abs() < 0.01, "{v} vs {want}");
    }
}

#[test]
fn bad_input_is_refused_naming_the_option_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let bare = dir.path().join("bare");
    std::fs::create_dir(&bare).unwrap();
    std::fs::write(bare.join("survey.toml"), "[site]\nmesh = \"site.ply\"\n").unwrap();
    let out = dir.path().join("l.toml");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            vec!["--site", "48.85,2.35", "--time", "2026-06-21T17:30:00"],
            "--time",
        ),
        (vec!["--site", "91,2.35", "--time", TIME], "--site latitude"),
        (vec!["--survey", s(&bare), "--time", TIME], "survey.toml"),
        (
            vec![
                "--site",
                "48.85,2.35",
                "--time",
                "2026-06-21T23:30:00+02:00",
            ],
            "below the horizon",
        ),
        (
            vec!["--site", "48.85,2.35", "--time", TIME, "--turbidity", "12"],
            "--turbidity",
        ),
    ];
    for (args, needle) in cases {
        let mut a = vec!["sky"];
        a.extend(args.iter().copied());
        a.extend(["-o", s(&out)]);
        let o = igi(&a);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?} succeeded");
        assert!(err.contains(needle), "{args:?}: {err}");
        let left: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .filter(|n| n != "bare")
            .collect();
        assert!(left.is_empty(), "{args:?} left {left:?}");
    }
}

#[test]
fn igi_render_relights_a_result_with_the_written_sky() {
    let dir = tempfile::tempdir().unwrap();
    let light = dir.path().join("evening.toml");
    let o = igi(&[
        "sky",
        "--site",
        "48.85,2.35",
        "--time",
        TIME,
        "--width",
        "64",
        "-o",
        s(&light),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let fx = Path::new(env!("CARGO_MANIFEST_DIR")).join("datasets/fixtures");
    let out = dir.path().join("render.exr");
    let o = igi(&[
        "render",
        s(&fx.join("export/result")),
        "--lighting",
        s(&light),
        "--camera",
        s(&fx.join("outdoor/camera.json")),
        "--spp",
        "2",
        "-o",
        s(&out),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let img = igi_imaging::read_image(&out).unwrap();
    let mean: f64 = img.pixels.iter().map(|p| p[1] as f64).sum::<f64>() / img.pixels.len() as f64;
    assert!(mean.is_finite() && mean > 0.0, "mean green {mean}");
}
