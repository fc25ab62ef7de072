//! Stability and bad input: a sun of a few pixels, clipped diffuse highlights, small and
//! cut-off spheres, NaN pixels.

use glam::DVec3;
use igi_camera::Camera;
use igi_capture::SphereError;
use igi_imaging::{read_image, HdrImage};
use igi_probe::{process, Board, ProbeError, ProbeOptions};
use igi_synth::board::{direction_from_angles, render_board, SynthSun};
use std::path::PathBuf;

fn fixture(case: &str) -> PathBuf {
    PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../datasets/fixtures/board"
    ))
    .join(case)
}

fn cam_board() -> (Camera, Board) {
    let d = fixture("sunny");
    (
        Camera::load(&d.join("camera.json")).unwrap(),
        Board::load(&d.join("board.json")).unwrap(),
    )
}

/// A smooth analytic sky (lat-long 128x64).
fn sky() -> HdrImage {
    igi_imaging::latlong::map_from_fn(128, 64, |d| {
        let up = d.z.max(0.0);
        [
            0.5 + 0.4 * up + 0.1 * d.x,
            0.6 + 0.3 * up,
            0.9 - 0.2 * up + 0.05 * d.y,
        ]
    })
}

#[test]
fn sun_of_a_few_pixels() {
    // a 2.5 degree sun: a spot of about one pixel across on the black sphere, spread over
    // a few pixels by box-filtered supersampled rendering (no lens blur)
    let (cam, board) = cam_board();
    let s = direction_from_angles(40.0, 165.0);
    let sun = SynthSun {
        direction: s,
        radiance: [2.0e4, 1.9e4, 1.7e4],
        diameter_deg: 2.5,
    };
    let img = render_board(&cam, &board, &sky(), Some(sun), 8);
    let opt = ProbeOptions {
        sun_diameter_deg: 2.5,
        ..ProbeOptions::default()
    };
    let r = process(&img, &cam, &board, &opt).unwrap();
    let est = r.diagnostics.sun.as_ref().expect("sun found");
    let ang = DVec3::from_array(est.direction)
        .dot(s)
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees();
    let rad = est.radiance.unwrap();
    eprintln!(
        "few-pixel sun: {ang:.3} deg, radiance {rad:?}, check {:?}",
        r.diagnostics.check_rms_percent
    );
    assert!(ang < 0.25, "{ang}");
    for c in 0..3 {
        assert!(
            (rad[c] / sun.radiance[c] - 1.0).abs() < 0.02,
            "channel {c}: {}",
            rad[c]
        );
    }
    assert!(r.diagnostics.check_rms_percent.unwrap() < 2.0);
}

#[test]
fn clipped_diffuse_highlight_is_masked_out_of_the_solve() {
    let d = fixture("sunny");
    let (cam, board) = cam_board();
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("truth.json")).unwrap()).unwrap();
    let rad_t: Vec<f64> = serde_json::from_value(truth["sun"]["radiance"].clone()).unwrap();
    let img = read_image(&d.join("board.exr")).unwrap();
    // clip the brightest part of the diffuse sphere (rows >= 139 hold only that sphere)
    let mut vals: Vec<f32> = (139 * 256..256 * 256).map(|k| img.pixels[k][1]).collect();
    vals.sort_by(|a, b| a.total_cmp(b));
    let clip = vals[vals.len() * 85 / 100];
    let mut clipped = img.clone();
    let mut unmasked = img.clone();
    let mut n = 0;
    for k in 139 * 256..256 * 256 {
        if img.pixels[k].iter().any(|v| *v >= clip) {
            clipped.pixels[k] = [clip; 3];
            clipped.valid[k] = false;
            unmasked.pixels[k] = [clip; 3];
            n += 1;
        }
    }
    assert!(n > 100);
    let opt = ProbeOptions::default();
    let r = process(&clipped, &cam, &board, &opt).unwrap();
    let rad = r.diagnostics.sun.as_ref().unwrap().radiance.unwrap();
    // (n also counts rim and background pixels, which the solve does not use anyway)
    assert!(
        r.diagnostics.diffuse_pixels_masked >= 1000,
        "{} of {n}",
        r.diagnostics.diffuse_pixels_masked
    );
    for c in 0..3 {
        assert!(
            (rad[c] as f64 / rad_t[c] - 1.0).abs() < 0.02,
            "masked: channel {c} {}",
            rad[c]
        );
    }
    // the same clipped values used as if they were good bias the sun low
    let bad = process(&unmasked, &cam, &board, &opt).unwrap();
    let rad_bad = bad.diagnostics.sun.as_ref().unwrap().radiance.unwrap();
    eprintln!("clipped diffuse: masked {rad:?}, unmasked {rad_bad:?}, truth {rad_t:?}");
    let worst = (0..3)
        .map(|c| (rad_bad[c] as f64 / rad_t[c] - 1.0).abs())
        .fold(0.0, f64::max);
    assert!(
        worst > 0.02,
        "clipping should matter: worst unmasked error {worst}"
    );
    // and the saturation option masks them too
    let opt2 = ProbeOptions {
        saturation: Some(clip),
        ..ProbeOptions::default()
    };
    let r2 = process(&unmasked, &cam, &board, &opt2).unwrap();
    assert_eq!(
        r2.diagnostics.diffuse_pixels_masked,
        r.diagnostics.diffuse_pixels_masked
    );
}

#[test]
fn small_sphere_warns_and_cut_off_sphere_errors() {
    let (cam, mut board) = cam_board();
    // shrink the spheres to about 15 px
    for s in [
        Some(&mut board.mirror),
        board.black.as_mut(),
        board.diffuse.as_mut(),
    ]
    .into_iter()
    .flatten()
    {
        s.radius *= 15.0 / 47.0;
    }
    let img = render_board(&cam, &board, &sky(), None, 2);
    let r = process(&img, &cam, &board, &ProbeOptions::default()).unwrap();
    let w = r.diagnostics.warnings.join("\n");
    assert!(
        w.contains("mirror sphere is only") && w.contains("under 20 px"),
        "{w}"
    );
    assert!(r.sky.pixels.iter().flatten().all(|v| v.is_finite()));

    let (cam, mut board) = cam_board();
    board.diffuse.as_mut().unwrap().center_cam.y += 0.05; // pushes it past the bottom edge
    let img = render_board(&cam, &board, &sky(), None, 1);
    let e = process(&img, &cam, &board, &ProbeOptions::default()).unwrap_err();
    assert!(matches!(
        e,
        ProbeError::Sphere(SphereError::OutsideImage { .. })
    ));
    let msg = e.to_string();
    assert!(
        msg.contains("diffuse sphere is partly outside the 256x256 image"),
        "{msg}"
    );

    let wrong = HdrImage::new(100, 100);
    let e = process(&wrong, &cam, &cam_board().1, &ProbeOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("100x100") && e.contains("256x256"), "{e}");
}

#[test]
fn nan_pixels_never_reach_the_output() {
    let d = fixture("cloudy");
    let (cam, board) = cam_board();
    let mut img = read_image(&d.join("board.exr")).unwrap();
    // NaN and inf in a band across the mirror sphere
    for y in 60..64 {
        for x in 20..100 {
            img.set(x, y, [f32::NAN, f32::INFINITY, 1.0]);
        }
    }
    let r = process(&img, &cam, &board, &ProbeOptions::default()).unwrap();
    for m in [&r.sky, &r.sky_measured, &r.mirror_hemi] {
        assert!(m.pixels.iter().flatten().all(|v| v.is_finite()));
    }
    assert!(r.sky_measured.valid_fraction() < 0.86);
    assert!(r.diagnostics.check_rms_percent.unwrap().is_finite());
}
