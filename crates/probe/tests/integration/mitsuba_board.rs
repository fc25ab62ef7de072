//! Ground truth from an independent renderer: the Mitsuba 3 board fixtures of
//! `datasets/mitsuba/board_fixtures.py` (sunny and cloudy), as HDR images and as clipped
//! 16-bit linear brackets.

use glam::{DVec3, Vec3};
use igi_camera::Camera;
use igi_imaging::hdr::{merge_linear, LinearParams};
use igi_imaging::{latlong, read_image, HdrImage};
use igi_probe::envmap::latlong_lookup;
use igi_probe::{process, Board, ProbeOptions, ProbeResult};
use std::path::PathBuf;

fn dir(case: &str) -> PathBuf {
    PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../datasets/fixtures/board"
    ))
    .join(case)
}

struct Truth {
    sky: HdrImage,
    sun: Option<(DVec3, [f64; 3])>,
}

fn truth(case: &str) -> Truth {
    let d = dir(case);
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("truth.json")).unwrap()).unwrap();
    let sun = j.get("sun").map(|s| {
        let v: Vec<f64> = serde_json::from_value(s["direction"].clone()).unwrap();
        let r: Vec<f64> = serde_json::from_value(s["radiance"].clone()).unwrap();
        (DVec3::new(v[0], v[1], v[2]), [r[0], r[1], r[2]])
    });
    Truth {
        sky: read_image(&d.join("sky_truth.exr")).unwrap(),
        sun,
    }
}

fn run(case: &str, brackets: bool) -> ProbeResult {
    let d = dir(case);
    let cam = Camera::load(&d.join("camera.json")).unwrap();
    let board = Board::load(&d.join("board.json")).unwrap();
    let img = if brackets {
        let imgs: Vec<HdrImage> = (0..3)
            .map(|i| read_image(&d.join(format!("bracket_{i}.png"))).unwrap())
            .collect();
        merge_linear(
            &imgs,
            &[0.25, 1.0 / 32.0, 1.0 / 256.0],
            LinearParams::default(),
        )
        .unwrap()
        .0
    } else {
        read_image(&d.join("board.exr")).unwrap()
    };
    process(&img, &cam, &board, &ProbeOptions::default()).unwrap()
}

/// Relative RMS (sqrt(sum |r - t|^2 / sum |t|^2)) of the recovered sky over the truth map's
/// pixel centres where the recovered map is valid; also the fraction of the sphere covered.
fn sky_error(r: &ProbeResult, t: &HdrImage) -> (f64, f64) {
    let (mut se, mut st, mut n, mut total) = (0.0, 0.0, 0, 0.0);
    for i in 0..t.height {
        let sa = latlong::pixel_solid_angle(i, t.width, t.height) as f64;
        for j in 0..t.width {
            let dir: Vec3 = latlong::pixel_center_direction(i, j, t.width, t.height);
            total += sa;
            if let Some(v) = latlong_lookup(&r.sky_measured, dir) {
                let g = t.get(j, i);
                for c in 0..3 {
                    se += sa * (v[c] - g[c]).powi(2) as f64;
                    st += sa * (g[c] as f64).powi(2);
                }
                n += 1;
                let _ = n;
            }
        }
    }
    let covered: f64 = (0..t.height)
        .map(|i| {
            let sa = latlong::pixel_solid_angle(i, t.width, t.height) as f64;
            (0..t.width)
                .filter(|&j| {
                    latlong_lookup(
                        &r.sky_measured,
                        latlong::pixel_center_direction(i, j, t.width, t.height),
                    )
                    .is_some()
                })
                .count() as f64
                * sa
        })
        .sum();
    ((se / st).sqrt(), covered / total)
}

fn check_sunny(brackets: bool) {
    let t = truth("sunny");
    let r = run("sunny", brackets);
    let d = &r.diagnostics;
    let (sun_t, rad_t) = t.sun.unwrap();
    let sun = d.sun.as_ref().expect("sun found");
    let dirv = DVec3::from_array(sun.direction);
    let ang = dirv.dot(sun_t).clamp(-1.0, 1.0).acos().to_degrees();
    let rad = sun.radiance.unwrap();
    let rel: Vec<f64> = (0..3).map(|c| rad[c] as f64 / rad_t[c] - 1.0).collect();
    let (sky_rms, cov) = sky_error(&r, &t.sky);
    eprintln!(
        "sunny brackets={brackets}: sun error {ang:.4} deg, radiance rel {rel:?}, residual {:?}, check {:?}, sky rel RMS {:.4} over {:.1}% of the sphere; {}",
        sun.residual_rms_percent, d.check_rms_percent, sky_rms, 100.0 * cov, d.sun_decision
    );
    assert!(d.sun_found);
    assert!(ang < 0.25, "sun direction off by {ang} deg");
    for c in 0..3 {
        assert!(
            rel[c].abs() < 0.02,
            "sun radiance channel {c} off by {:.2}%",
            100.0 * rel[c]
        );
    }
    assert!(sky_rms < 0.03, "sky relative RMS {sky_rms}");
    assert!(cov > 0.6, "valid directions cover only {cov}");
    assert!(
        d.check_rms_percent.unwrap() < 2.0,
        "check RMS {:?}",
        d.check_rms_percent
    );
    for p in r.sky.pixels.iter() {
        assert!(p.iter().all(|v| v.is_finite() && *v >= 0.0));
    }
}

#[test]
fn sunny_hdr() {
    check_sunny(false);
}

#[test]
fn sunny_brackets() {
    check_sunny(true);
}

fn check_cloudy(brackets: bool) {
    let t = truth("cloudy");
    let r = run("cloudy", brackets);
    let d = &r.diagnostics;
    let (sky_rms, cov) = sky_error(&r, &t.sky);
    eprintln!(
        "cloudy brackets={brackets}: sky rel RMS {sky_rms:.4} over {:.1}%, check {:?}; {}",
        100.0 * cov,
        d.check_rms_percent,
        d.sun_decision
    );
    assert!(!d.sun_found, "{}", d.sun_decision);
    assert!(d.sun.is_none());
    assert!(sky_rms < 0.03, "sky relative RMS {sky_rms}");
    assert!(cov > 0.6);
    assert!(
        d.check_rms_percent.unwrap() < 2.0,
        "check RMS {:?}",
        d.check_rms_percent
    );
}

#[test]
fn cloudy_hdr() {
    check_cloudy(false);
}

#[test]
fn cloudy_brackets() {
    check_cloudy(true);
}

/// Sphere calibration from the image itself: reflectance-versus-angle samples of the Mitsuba
/// mirror sphere under the known cloudy sky, fitted by Levenberg-Marquardt, give back the
/// conductor's complex index.
#[test]
fn mirror_index_fitted_from_the_rendered_sphere() {
    use igi_capture::sphere::SphereView;
    let d = dir("cloudy");
    let cam = Camera::load(&d.join("camera.json")).unwrap();
    let board = Board::load(&d.join("board.json")).unwrap();
    let img = read_image(&d.join("board.exr")).unwrap();
    let sky = truth("cloudy").sky;
    let view = SphereView::new(&cam, igi_probe::SphereKind::Mirror, &board.mirror);
    let (x0, y0, x1, y1) = view.pixel_bbox();
    let mut samples: Vec<Vec<(f64, f64)>> = vec![Vec::new(); 3];
    for y in y0..=y1 {
        for x in x0..=x1 {
            let Some((_, n, dv)) = view.hit_pixel(x as f64, y as f64) else {
                continue;
            };
            let cos_i = n.dot(-dv);
            if cos_i < 0.35 {
                continue;
            }
            let l = latlong_lookup(&sky, dv.reflect(n).as_vec3()).unwrap();
            let p = img.get(x, y);
            for c in 0..3 {
                samples[c].push((cos_i.acos(), (p[c] / l[c]) as f64));
            }
        }
    }
    let want = [(2.40, 2.98), (2.40, 3.02), (2.40, 3.02)];
    for c in 0..3 {
        let fit = igi_probe::fresnel::fit_complex_ior(&samples[c], (1.5, 2.0)).unwrap();
        eprintln!(
            "channel {c}: n {:.3} k {:.3} (rms {:.4}, {} samples)",
            fit.n,
            fit.k,
            fit.rms,
            samples[c].len()
        );
        assert!(
            (fit.n - want[c].0).abs() < 0.05 && (fit.k - want[c].1).abs() < 0.05,
            "{fit:?}"
        );
        let r0 = igi_probe::fresnel::conductor(1.0, fit.n, fit.k);
        let r0_want = igi_probe::fresnel::conductor(1.0, want[c].0, want[c].1);
        assert!((r0 - r0_want).abs() < 0.005, "{r0} vs {r0_want}");
    }
}
