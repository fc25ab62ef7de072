//! Issue 16, item 2: the sun's direction within 0.25 degrees and its irradiance within 2% on
//! boards the size of a real board photograph (1024x768, spheres about 90 px in radius), from
//! independent Mitsuba 3 renders (`datasets/fixtures/board1024/el{14,35,60}/sunny`, written by
//! `datasets/mitsuba/board_fixtures.py --size 1024x768 --fx 766 --sun-el EL`, see
//! datasets/README.md), including a low sun (14 degrees elevation).
//!
//! Also the error against sphere radius on synthetic boards (`igi_synth::board::render_board_sensor`: lens
//! blur before pixel integration, the sun's spot rendered exactly), the cause of the old
//! synthetic boards' excess error, and the sphere centres refined from their outlines.
//!
//! `cargo test -p igi-probe --test integration sun_accuracy:: -- --nocapture` prints the errors;
//! `-- --ignored --nocapture` runs the sweeps of docs/PROBE.md.

use glam::DVec3;
use igi_camera::Camera;
use igi_imaging::read_image;
use igi_probe::{process, Board, ProbeOptions, ProbeResult};
use std::path::PathBuf;

fn dir(el: u32) -> PathBuf {
    PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../datasets/fixtures/board1024"
    ))
    .join(format!("el{el}/sunny"))
}

/// (true sun direction, true radiance) of a fixture.
fn truth(el: u32) -> (DVec3, [f64; 3]) {
    let p = dir(el).join("truth.json");
    let j: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
    let v: Vec<f64> = serde_json::from_value(j["sun"]["direction"].clone()).unwrap();
    let r: Vec<f64> = serde_json::from_value(j["sun"]["radiance"].clone()).unwrap();
    (DVec3::new(v[0], v[1], v[2]), [r[0], r[1], r[2]])
}

fn run(el: u32, refine: bool) -> ProbeResult {
    let d = dir(el);
    let cam = Camera::load(&d.join("camera.json")).unwrap();
    let board = Board::load(&d.join("board.json")).unwrap();
    let img = read_image(&d.join("board.exr")).unwrap();
    assert_eq!((img.width, img.height), (1024, 768));
    let opt = ProbeOptions {
        refine_centers: refine,
        ..ProbeOptions::default()
    };
    process(&img, &cam, &board, &opt).unwrap()
}

/// (direction error in degrees, worst relative irradiance error over the channels).
fn sun_errors(el: u32, refine: bool) -> (f64, f64) {
    let (dir_t, rad_t) = truth(el);
    let r = run(el, refine);
    for f in &r.diagnostics.outline_fits {
        eprintln!(
            "  {} centre refined: moved {:.3} px, {} of {} edge points, RMS {:.3} px",
            f.kind, f.shift_px, f.edge_points_used, f.edge_points, f.rms_px
        );
    }
    let sun = r.diagnostics.sun.as_ref().expect("sun found");
    let d = DVec3::from_array(sun.direction);
    let ang = d.dot(dir_t).clamp(-1.0, 1.0).acos().to_degrees();
    let rad = sun.radiance.expect("sun radiance");
    let rel = (0..3)
        .map(|c| (rad[c] as f64 / rad_t[c] - 1.0).abs())
        .fold(0.0, f64::max);
    let radius = r
        .diagnostics
        .sphere_radius_px
        .iter()
        .map(|x| x.1)
        .fold(0.0, f64::max);
    eprintln!(
        "sun at {el} deg: direction off {ang:.4} deg, irradiance off {:.2}% (R G B {:.4} {:.4} {:.4}), spot {:?}, radius {radius:.1} px",
        100.0 * rel,
        rad[0] as f64 / rad_t[0],
        rad[1] as f64 / rad_t[1],
        rad[2] as f64 / rad_t[2],
        sun.spot_pixel
    );
    (ang, rel)
}

#[test]
fn mitsuba_boards_sun_within_quarter_degree_and_two_percent() {
    for el in [14, 35, 60] {
        let (ang, rel) = sun_errors(el, false);
        assert!(ang <= 0.25, "sun at {el} deg: direction {ang:.3} deg off");
        assert!(
            rel <= 0.02,
            "sun at {el} deg: irradiance {:.2}% off",
            100.0 * rel
        );
    }
}

/// The Mitsuba boards with the sphere centres refined from their outlines although they are
/// exact: the refinement's own error (about 0.07 px here) keeps them within the goal.
#[test]
fn mitsuba_boards_with_outline_refinement_stay_within_quarter_degree() {
    for el in [14, 35, 60] {
        let (ang, rel) = sun_errors(el, true);
        assert!(ang <= 0.25, "sun at {el} deg: direction {ang:.3} deg off");
        assert!(
            rel <= 0.02,
            "sun at {el} deg: irradiance {:.2}% off",
            100.0 * rel
        );
    }
}

/// A smooth analytic sky (lat-long `w` x `w/2`) with a brighter horizon and circumsolar glow.
fn sky(w: usize, sun: DVec3) -> igi_imaging::HdrImage {
    igi_imaging::latlong::map_from_fn(w, w / 2, |d| {
        let d = d.as_dvec3();
        let up = d.z.max(0.0);
        let glow = 0.8 * (-d.dot(sun).clamp(-1.0, 1.0).acos() / 0.35).exp();
        let v = [
            0.9 - 0.6 * up + glow,
            0.95 - 0.5 * up + glow,
            1.05 - 0.2 * up + 0.6 * glow,
        ];
        let below = if d.z < 0.0 { 0.25 } else { 1.0 };
        v.map(|x| (x * below) as f32)
    })
}

/// How a synthetic board is rendered.
#[derive(Clone, Copy, Debug)]
enum Render {
    /// The old way: `render_board` with `ss` x `ss` box samples, then `gaussian_blur` of the
    /// pixels (the lens applied after the pixels have integrated the spot).
    BoxThenBlur { ss: usize, sigma: f64 },
    /// `render_board_sensor`: lens blur before the pixel integration, the sun's spot exact.
    Sensor { ss: usize, sigma: f64 },
}

/// One synthetic board's result.
struct SynthRun {
    /// Direction error, degrees.
    ang: f64,
    /// Worst relative irradiance error over the channels.
    rel: f64,
    /// Found spot centre minus the true reflection point of the sun's centre, pixels.
    spot_off: [f64; 2],
}

/// The camera and board of a synthetic board whose spheres (0.07 m, 0.6 m away, the layout of
/// the Mitsuba boards) are `r` pixels in radius; the image is just large enough for them.
fn synth_setup(r: f64) -> (Camera, Board) {
    use igi_probe::BoardSphere;
    let fx = r / (0.07f64 / 0.6).asin().tan();
    let side = (5.3 * r).ceil() as u32 + 8;
    let c = (side as f64 - 1.0) / 2.0;
    let mut cam = Camera::pinhole(side, side, fx, fx, c, c - fx / 60.0);
    // camera x right = world -Y, y down = world -Z, z forward = world +X
    let rot =
        glam::DMat3::from_cols_array_2d(&[[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
            .transpose();
    cam.pose = igi_camera::WorldToCamera {
        r: rot,
        t: DVec3::ZERO,
    };
    let mut board = Board::load(&dir(35).join("board.json")).unwrap();
    let sph = |x: f64, y: f64| BoardSphere {
        center_cam: DVec3::new(x, y, 0.6),
        radius: 0.07,
    };
    board.mirror = sph(-0.10, -0.08);
    board.black = Some(sph(0.10, -0.08));
    board.diffuse = Some(sph(0.0, 0.10));
    (cam, board)
}

const SUN_RADIANCE: [f32; 3] = [8.0e4, 7.6e4, 6.8e4];

/// A synthetic board of sphere radius `r` px (see [`synth_setup`]) rendered by `how`, the sun at
/// `el` degrees elevation, azimuth `az`, processed with the default options.
fn synth_errors(r: f64, el: f64, az: f64, how: Render) -> SynthRun {
    use igi_synth::board::{
        direction_from_angles, gaussian_blur, render_board, render_board_sensor, Sensor, SynthSun,
    };
    let (cam, board) = synth_setup(r);
    let s = direction_from_angles(el, az);
    let sun = SynthSun {
        direction: s,
        radiance: SUN_RADIANCE,
        diameter_deg: 0.53,
    };
    let t0 = std::time::Instant::now();
    let sky = sky(32, s);
    let img = match how {
        Render::BoxThenBlur { ss, sigma } => {
            gaussian_blur(&render_board(&cam, &board, &sky, Some(sun), ss), sigma)
        }
        Render::Sensor { ss, sigma } => render_board_sensor(
            &cam,
            &board,
            &sky,
            Some(sun),
            Sensor {
                ss,
                blur_sigma: sigma,
            },
        ),
    };
    let t1 = std::time::Instant::now();
    let res = process(&img, &cam, &board, &ProbeOptions::default()).unwrap();
    let t2 = std::time::Instant::now();
    let est = res.diagnostics.sun.as_ref().expect("sun found");
    let ang = DVec3::from_array(est.direction)
        .dot(s)
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees();
    let rad = est.radiance.expect("radiance");
    let rel = (0..3)
        .map(|c| (rad[c] as f64 / SUN_RADIANCE[c] as f64 - 1.0).abs())
        .fold(0.0, f64::max);
    let black = board.black.as_ref().unwrap();
    let bv = igi_capture::sphere::SphereView::new(&cam, igi_probe::SphereKind::Black, black);
    let truth = bv.reflection_point(s).unwrap().pixel;
    let spot_off = [est.spot_pixel[0] - truth.x, est.spot_pixel[1] - truth.y];
    let secs = ((t1 - t0).as_secs_f64(), (t2 - t1).as_secs_f64());
    let side = cam.width;
    eprintln!(
        "synthetic board r {r:.0} px ({side}x{side}, {how:?}), sun at {el} deg az {az}: direction off {ang:.4} deg, irradiance off {:.2}%, spot off ({:+.3}, {:+.3}) px, render {:.1} s, process {:.1} s",
        100.0 * rel,
        spot_off[0],
        spot_off[1],
        secs.0,
        secs.1
    );
    SynthRun { ang, rel, spot_off }
}

/// CI-sized: the smallest sphere of the sweep (40 px), the low sun, the sensor model.
#[test]
fn synthetic_40px_board_low_sun_within_quarter_degree_and_two_percent() {
    let run = synth_errors(40.0, 14.0, 200.0, Render::Sensor { ss: 3, sigma: 0.5 });
    assert!(run.ang <= 0.25, "direction {:.3} deg off", run.ang);
    assert!(run.rel <= 0.02, "irradiance {:.2}% off", 100.0 * run.rel);
    let off = run.spot_off[0].hypot(run.spot_off[1]);
    assert!(off < 0.02, "spot centre {off:.3} px off");
}

/// CI-sized: a sharper lens (blur 0.25 px) on the 40 px board, where the intensity-weighted
/// centroid of the spot was 0.21 deg off (its bias, about 0.09 px); the fit of the blurred,
/// pixel-integrated sun disk (`igi_capture::spot`) is not.
#[test]
fn synthetic_40px_board_sharp_lens_spot_fit() {
    for el in [14.0, 35.0] {
        let run = synth_errors(40.0, el, 200.0, Render::Sensor { ss: 3, sigma: 0.25 });
        assert!(
            run.ang <= 0.05,
            "sun at {el}: direction {:.3} deg off",
            run.ang
        );
        assert!(run.rel <= 0.02, "irradiance {:.2}% off", 100.0 * run.rel);
    }
}

/// The sun's spot on the black sphere of a board with a black sky: its intensity centroid in
/// the rendered pixels against the true reflection point of the sun's centre, for sub-pixel
/// positions across a pixel (the sun's azimuth stepped). Returns the worst offset in pixels.
fn spot_centroid_worst_offset(
    render: &dyn Fn(&Camera, &Board, igi_synth::board::SynthSun) -> igi_imaging::HdrImage,
) -> f64 {
    use igi_synth::board::{direction_from_angles, SynthSun};
    let (cam, board) = synth_setup(40.0);
    let black = board.black.unwrap();
    let view = igi_capture::sphere::SphereView::new(&cam, igi_probe::SphereKind::Black, &black);
    let (x0, y0, x1, y1) = view.pixel_bbox();
    let mut worst: f64 = 0.0;
    for k in 0..6 {
        let s = direction_from_angles(14.0, 200.0 + 0.25 * k as f64);
        let sun = SynthSun {
            direction: s,
            radiance: SUN_RADIANCE,
            diameter_deg: 0.53,
        };
        let img = render(&cam, &board, sun);
        let (mut sw, mut sx, mut sy) = (0.0, 0.0, 0.0);
        for y in y0..=y1 {
            for x in x0..=x1 {
                let v = igi_probe::pipeline::luminance(img.get(x, y));
                sw += v;
                sx += v * x as f64;
                sy += v * y as f64;
            }
        }
        let truth = view.reflection_point(s).unwrap().pixel;
        let off = (sx / sw - truth.x).hypot(sy / sw - truth.y);
        eprintln!(
            "sun azimuth {:.2}: spot centroid {:.3} px off",
            200.0 + 0.25 * k as f64,
            off
        );
        worst = worst.max(off);
    }
    worst
}

/// The cause of the synthetic boards' excess error (docs/PROBE.md): the old synthetic camera
/// integrated the sub-pixel spot over its pixel before blurring the pixels, which moves the
/// spot's centroid toward the pixel's centre by up to tenths of a pixel (1.3 deg per pixel on a
/// 90 px sphere); `render_board_sensor` blurs before integrating, as a lens does, and keeps it.
#[test]
fn sensor_model_keeps_the_sun_spot_centroid_where_the_old_renderer_moved_it() {
    use igi_synth::board::{gaussian_blur, render_board, render_board_sensor, Sensor};
    let dark = igi_imaging::HdrImage::new(32, 16);
    let sensor = spot_centroid_worst_offset(&|cam, board, sun| {
        render_board_sensor(
            cam,
            board,
            &dark,
            Some(sun),
            Sensor {
                ss: 2,
                blur_sigma: 0.5,
            },
        )
    });
    let old = spot_centroid_worst_offset(&|cam, board, sun| {
        gaussian_blur(&render_board(cam, board, &dark, Some(sun), 12), 0.5)
    });
    eprintln!("worst spot centroid offset: sensor model {sensor:.4} px, box then blur {old:.4} px");
    assert!(
        sensor < 0.01,
        "sensor model: spot centroid {sensor:.4} px off"
    );
    assert!(
        old > 0.05,
        "box then blur: spot centroid only {old:.4} px off"
    );
}

/// Sun direction error (degrees) of `board` processed on `img`, its centres refined from their
/// outlines when `refine`.
fn sun_error(
    img: &igi_imaging::HdrImage,
    cam: &Camera,
    board: &Board,
    s: DVec3,
    refine: bool,
) -> f64 {
    let opt = ProbeOptions {
        refine_centers: refine,
        ..ProbeOptions::default()
    };
    let res = process(img, cam, board, &opt).unwrap();
    assert_eq!(
        res.diagnostics.outline_fits.len(),
        if refine { 2 } else { 0 }
    );
    let d = DVec3::from_array(res.diagnostics.sun.as_ref().expect("sun").direction);
    d.angle_between(s).to_degrees()
}

/// Distances (mm) across the line of sight of the mirror and black spheres' centres from the truth.
fn centre_errors(b: &Board, truth: &Board) -> [f64; 2] {
    let across = |a: DVec3, t: DVec3| {
        let (los, d) = (t.normalize(), a - t);
        1e3 * (d - d.dot(los) * los).length()
    };
    [
        across(b.mirror.center_cam, truth.mirror.center_cam),
        across(b.black.unwrap().center_cam, truth.black.unwrap().center_cam),
    ]
}

/// Issue 16 / PROBE.md "Known limits": sphere centres from an imprecise pose (each off by
/// 0.3-0.4 mm, 0.3 px, across the line of sight) turn the sun by about `2 dc / r`; refined from
/// their silhouettes (`igi_probe::outline`) most of that error goes.
#[test]
fn outline_refinement_undoes_a_perturbed_sphere_placement() {
    use igi_synth::board::{direction_from_angles, render_board_sensor, Sensor, SynthSun};
    let (cam, board) = synth_setup(60.0);
    let s = direction_from_angles(14.0, 200.0);
    let sun = SynthSun {
        direction: s,
        radiance: SUN_RADIANCE,
        diameter_deg: 0.53,
    };
    let img = render_board_sensor(
        &cam,
        &board,
        &sky(32, s),
        Some(sun),
        Sensor {
            ss: 3,
            blur_sigma: 0.5,
        },
    );
    let mut off = board.clone();
    off.mirror.center_cam += DVec3::new(-0.2e-3, 0.25e-3, 0.3e-3);
    off.black.as_mut().unwrap().center_cam += DVec3::new(0.25e-3, -0.2e-3, -0.3e-3);
    let (refined, fits, warnings) = igi_probe::outline::refine_board(&img, &cam, &off, 0.5);
    assert!(warnings.is_empty(), "{warnings:?}");
    let (from_truth, _, _) = igi_probe::outline::refine_board(&img, &cam, &board, 0.5);
    let (e_true, e_off, e_ref) = (
        sun_error(&img, &cam, &board, s, false),
        sun_error(&img, &cam, &off, s, false),
        sun_error(&img, &cam, &off, s, true),
    );
    for f in &fits {
        eprintln!(
            "{}: {} edge points ({} used), shift {:.3} px, RMS {:.3} px, edge offset {:+.3} px",
            f.kind, f.edge_points, f.edge_points_used, f.shift_px, f.rms_px, f.edge_offset_px
        );
    }
    let (c_off, c_ref, c_truth) = (
        centre_errors(&off, &board),
        centre_errors(&refined, &board),
        centre_errors(&from_truth, &board),
    );
    eprintln!(
        "sun error: true centres {e_true:.3} deg, perturbed {e_off:.3} deg, refined {e_ref:.3} deg; \
         mirror and black centres across the line of sight (mm): perturbed {c_off:.3?}, refined \
         {c_ref:.3?}, refined from the true centres {c_truth:.3?}"
    );
    assert!(
        e_off > 0.5,
        "the perturbation should matter: {e_off:.3} deg"
    );
    assert!(
        e_ref < 0.35 * e_off && e_ref < 0.25,
        "refined: {e_ref:.3} deg"
    );
    assert!(c_ref.iter().all(|e| *e < 0.15), "{c_ref:?}");
    assert!(c_truth.iter().all(|e| *e < 0.15), "{c_truth:?}");
}

/// The table of docs/PROBE.md: error against sphere radius in pixels (40 to 600).
/// `cargo test -p igi-probe --test integration sun_accuracy:: -- --ignored --nocapture`
#[test]
#[ignore]
fn error_against_sphere_radius() {
    for r in [40.0, 60.0, 90.0, 150.0, 300.0, 600.0] {
        for el in [14.0, 35.0] {
            synth_errors(r, el, 200.0, Render::Sensor { ss: 3, sigma: 0.5 });
        }
    }
}

/// Where 0.25 deg is missed: smaller spheres (20, 30 px) with the same lens, and a sharper lens
/// (blur 0.25 px) from 20 to 150 px.
/// `cargo test -p igi-probe --test integration sun_accuracy::error_against_sphere_radius_small_spheres_and_sharp_lens -- --ignored --nocapture`
#[test]
#[ignore]
fn error_against_sphere_radius_small_spheres_and_sharp_lens() {
    for (sigma, radii) in [
        (0.5, &[20.0, 30.0][..]),
        (0.25, &[20.0, 30.0, 40.0, 60.0, 90.0, 150.0][..]),
    ] {
        for r in radii {
            for el in [14.0, 35.0] {
                synth_errors(*r, el, 200.0, Render::Sensor { ss: 3, sigma });
            }
        }
    }
}

/// Where the sun's spot centroid lands against the true reflection point, the old synthetic
/// camera (box samples fine enough to hit the spot, then the blur) against the sensor model, on
/// the same boards (docs/PROBE.md).
/// `cargo test -p igi-probe --test integration sun_accuracy::old_renderer -- --ignored --nocapture`
#[test]
#[ignore]
fn old_renderer_against_sensor_model() {
    for r in [60.0f64, 90.0] {
        for el in [14.0, 35.0] {
            let ss = ((3.0 / (0.0023 * r)).ceil() as usize).clamp(2, 24);
            synth_errors(r, el, 200.0, Render::BoxThenBlur { ss, sigma: 0.5 });
            synth_errors(r, el, 200.0, Render::Sensor { ss: 3, sigma: 0.5 });
        }
    }
}
