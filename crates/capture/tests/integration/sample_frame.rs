//! `igi_capture::sample_frame` against synthetic photographs of the sample frame with known pose,
//! light and BRDFs (the renderer is `igi_synth::sample_frame`).

use igi_synth::sample_frame as synth;

use std::path::Path;

use glam::{DVec2, DVec3, Vec3};
use igi_brdf::samples::{group_by_material, parse_samples, samples_to_csv};
use igi_brdf::{fit_material, FitOptions};
use igi_camera::cv::rotation_angle_between;
use igi_camera::Camera;
use igi_capture::sample_frame::closest_approach;
use igi_capture::{measure_photo, MeasureOptions, PhotoMeasurement, PoseInput, SampleFrame};
use synth::{camera, dir, true_corners, Synth};

const TARGET: DVec3 = DVec3::new(-0.02, 0.02, 0.0);

fn light_at(theta_l: f64) -> DVec3 {
    DVec3::new(-0.04, 0.0, 0.0) + dir(theta_l, 180.0) * 0.6
}

fn view(theta_v: f64, phi_v: f64) -> Camera {
    camera(TARGET + dir(theta_v, phi_v) * 0.5)
}

fn measure(s: &Synth, cam: &Camera, name: &str) -> PhotoMeasurement {
    let img = s.render(cam);
    let corners = true_corners(cam, &s.frame);
    measure_photo(
        &s.frame,
        cam,
        &img,
        Path::new(name),
        &PoseInput::Corners(corners),
        &MeasureOptions::default(),
    )
    .unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// The paper's geometry in miniature: lights at 0, 30, 50, 75 degrees in one plane, views on
/// both sides and out of the plane.
fn views() -> Vec<(f64, f64, f64)> {
    let mut v = Vec::new();
    for tl in [0.0, 30.0, 50.0, 75.0] {
        for (tv, pv) in [
            (45.0, 180.0),
            (20.0, 0.0),
            (40.0, 0.0),
            (60.0, 0.0),
            (35.0, 90.0),
        ] {
            // keep the highlight inside 0.9 of each sphere's radius: camera and light less than
            // about 115 degrees apart, and not the same direction
            let sep = dir(tl, 180.0).angle_between(dir(tv, pv)).to_degrees();
            if (12.0..115.0).contains(&sep) {
                v.push((tv, pv, tl));
            }
        }
    }
    v
}

#[test]
fn synthetic_frame_recovers_pose_light_and_brdf_then_fits() {
    let mut all = Vec::new();
    let (mut worst_ang, mut worst_pos, mut worst_light, mut worst_val, mut worst_gap) =
        (0.0f64, 0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for (k, &(tv, pv, tl)) in views().iter().enumerate() {
        let s = Synth::new(light_at(tl));
        let cam = view(tv, pv);
        let m = measure(&s, &cam, &format!("view{k}.exr"));
        let ang = rotation_angle_between(&m.pose().r, &cam.pose.r).to_degrees();
        let pos = (DVec3::from_array(m.camera_center) - cam.center_world()).length();
        let lerr = (m.light_position() - s.light).length() / (s.light - TARGET).length();
        worst_ang = worst_ang.max(ang);
        worst_pos = worst_pos.max(pos);
        worst_light = worst_light.max(lerr);
        worst_gap = worst_gap.max(m.gap);
        eprintln!("view {k} (theta_v {tv}, phi_v {pv}, theta_l {tl}): pose {ang:.1e} deg, light {:.3}%, gap {:.1e} m", lerr * 100.0, m.gap);
        // the recovered intensity is the true one
        for c in 0..3 {
            let e = (m.intensity[c] / s.intensity[c] - 1.0).abs();
            assert!(
                e < 0.01,
                "view {k}: intensity {:?} vs {:?}",
                m.intensity,
                s.intensity
            );
        }
        worst_val = worst_val.max(check_regions(&m, &s, k, (tv, pv, tl)));
        assert!(
            ang < 0.02 && pos < 2e-4,
            "view {k}: pose off by {ang} deg, {pos} m"
        );
        assert!(
            lerr < 0.005,
            "view {k}: light {:?} vs {:?} ({:.3}% of its distance)",
            m.light,
            s.light,
            lerr * 100.0
        );
        all.extend(m.samples());
    }
    eprintln!(
        "{} views: pose <= {worst_ang:.2e} deg / {worst_pos:.2e} m, light <= {:.3}% of distance, gap <= {worst_gap:.2e} m, pi f <= {:.2}% off",
        views().len(),
        worst_light * 100.0,
        worst_val * 100.0
    );
    check_the_fit_chain(&all);
}

/// Every region's measured `pi f` of view `k` against the true BRDF at the measured
/// directions; returns the worst relative error.
fn check_regions(m: &PhotoMeasurement, s: &Synth, k: usize, (tv, pv, tl): (f64, f64, f64)) -> f64 {
    let mut worst = 0.0f64;
    for r in &m.regions {
        let mat = &s
            .materials
            .iter()
            .find(|(n, _)| *n == r.material)
            .unwrap()
            .1;
        let truth = mat
            .as_ref()
            .eval(Vec3::from_array(r.light), Vec3::from_array(r.view))
            * std::f32::consts::PI;
        let got = Vec3::from_array(r.value);
        for c in 0..3 {
            let e = ((got[c] - truth[c]) / truth[c]).abs() as f64;
            worst = worst.max(e);
            assert!(
                e < 0.02,
                "view {k} (theta_v {tv}, phi_v {pv}, theta_l {tl}) region {} at {:?}: pi f = {got} vs {truth} ({:.2}%)",
                r.material,
                r.center,
                e * 100.0
            );
        }
    }
    worst
}

/// The chain: CSV text -> parser of `igi brdf fit` -> fit, predictions close to the truth.
fn check_the_fit_chain(all: &[igi_brdf::BrdfSample]) {
    let csv = samples_to_csv(all);
    let parsed = parse_samples(&csv, Path::new("measured.csv")).unwrap();
    assert_eq!(parsed.len(), all.len());
    let truth = synth::materials();
    for (name, s) in group_by_material(&parsed) {
        let rep = fit_material(&name, &s, &FitOptions::default()).unwrap();
        let m = &truth.iter().find(|(n, _)| *n == name).unwrap().1;
        let mut worst = 0.0f32;
        for x in &s {
            let a = rep.brdf.as_ref().eval(x.light, x.view);
            let b = m.as_ref().eval(x.light, x.view);
            worst = worst.max(((a - b).abs() / b).max_element());
        }
        eprintln!(
            "fit {name}: {} samples, rms {:.4}, worst relative error at the samples {:.3}",
            s.len(),
            rep.rms,
            worst
        );
        assert!(
            rep.rms < 0.03 && worst < 0.05,
            "{name}: rms {} worst {worst}",
            rep.rms
        );
    }
}

#[test]
fn corner_noise_of_half_a_pixel_moves_the_light_a_few_percent() {
    let s = Synth::new(light_at(30.0));
    let cam = view(40.0, 0.0);
    let img = s.render(&cam);
    let noise = [
        DVec2::new(0.5, -0.3),
        DVec2::new(-0.4, 0.4),
        DVec2::new(0.3, 0.5),
        DVec2::new(-0.5, -0.2),
    ];
    let corners: Vec<DVec2> = true_corners(&cam, &s.frame)
        .iter()
        .zip(noise)
        .map(|(p, n)| *p + n)
        .collect();
    let m = measure_photo(
        &s.frame,
        &cam,
        &img,
        Path::new("noisy.exr"),
        &PoseInput::Corners(corners),
        &MeasureOptions::default(),
    )
    .unwrap();
    let ang = rotation_angle_between(&m.pose().r, &cam.pose.r).to_degrees();
    let lerr = (m.light_position() - s.light).length() / (s.light - TARGET).length();
    eprintln!(
        "0.5 px corner noise: pose {ang:.3} deg, light {:.3}% of distance, gap {:.2e} m",
        lerr * 100.0,
        m.gap
    );
    // the light's triangulation is sensitive to the pose: 0.2 degrees of pose error moves the
    // spheres by about 0.3 px relative to their highlights (measured: 3.2% of the distance)
    assert!(ang < 0.3 && lerr < 0.05, "pose {ang} deg, light {lerr}");
    for r in &m.regions {
        let mat = &s
            .materials
            .iter()
            .find(|(n, _)| *n == r.material)
            .unwrap()
            .1;
        let truth = mat
            .as_ref()
            .eval(Vec3::from_array(r.light), Vec3::from_array(r.view))
            * std::f32::consts::PI;
        let e = ((Vec3::from_array(r.value) - truth).abs() / truth).max_element();
        assert!(e < 0.15, "{}: {e}", r.material); // measured 11% (tile, N = 25, at 40 degrees)
    }
}

#[test]
fn saturated_small_highlight_is_located_by_its_saturated_pixels() {
    let mut s = Synth::new(light_at(30.0));
    s.light_radiance = 2000.0; // highlight peaks near 100
    s.saturate_above = Some(10.0); // everything else is below 2
    let cam = view(40.0, 0.0);
    let m = measure(&s, &cam, "sat.exr");
    assert!(m.highlights.iter().all(|h| h.saturated));
    let lerr = (m.light_position() - s.light).length() / (s.light - TARGET).length();
    eprintln!(
        "saturated highlights: light {:.3}% of distance",
        lerr * 100.0
    );
    assert!(lerr < 0.02, "{lerr}");
}

fn expect_err(s: &Synth, cam: &Camera, input: PoseInput, want: &[&str]) {
    let img = s.render(cam);
    let e = measure_photo(
        &s.frame,
        cam,
        &img,
        Path::new("photos/bad.exr"),
        &input,
        &MeasureOptions::default(),
    )
    .err()
    .unwrap_or_else(|| panic!("expected an error containing {want:?}"))
    .to_string();
    assert!(e.contains("photos/bad.exr"), "{e}");
    for w in want {
        assert!(e.contains(w), "{e:?} should contain {w:?}");
    }
}

#[test]
fn bad_photos_give_clear_errors_naming_the_file() {
    let cam = view(40.0, 0.0);
    let good = |s: &Synth| PoseInput::Corners(true_corners(&cam, &s.frame));
    // no highlight: the light is not reflected by the spheres
    let mut s = Synth::new(light_at(30.0));
    s.coat = 0.0;
    expect_err(&s, &cam, good(&s), &["sphere 0", "no highlight"]);
    // the highlight blown out over a large part of the sphere
    let mut s = Synth::new(light_at(30.0));
    s.saturate_above = Some(0.001);
    expect_err(&s, &cam, good(&s), &["sphere 0", "saturated"]);
    // the white standard saturated, highlights fine
    let mut s = Synth::new(light_at(30.0));
    s.light_radiance = 20.0; // highlights at 1
    s.saturate_above = Some(0.5); // the white standard is about 0.7
    expect_err(&s, &cam, good(&s), &["white standard", "saturated"]);
    let s = Synth::new(light_at(30.0));
    // a corner outside the image
    let mut c = true_corners(&cam, &s.frame);
    c[2] = DVec2::new(1500.0, 20.0);
    expect_err(&s, &cam, PoseInput::Corners(c), &["corner 2", "outside"]);
    // degenerate corners: three on a line
    let mut c = true_corners(&cam, &s.frame);
    c[2] = (c[1] + c[3]) * 0.5;
    expect_err(&s, &cam, PoseInput::Corners(c), &["collinear"]);
    // corners in the wrong order
    let mut c = true_corners(&cam, &s.frame);
    c.swap(0, 1);
    expect_err(&s, &cam, PoseInput::Corners(c), &["wrong order"]);
    // too few corners
    let c = true_corners(&cam, &s.frame)[..3].to_vec();
    expect_err(
        &s,
        &cam,
        PoseInput::Corners(c),
        &["3 corner pixels", "4 fiducials"],
    );
    // ArUco without OpenCV says so
    #[cfg(not(feature = "opencv"))]
    expect_err(&s, &cam, PoseInput::Aruco, &["opencv", "--corners"]);
}

#[test]
fn bad_frame_files_give_clear_errors_naming_the_file() {
    let p = Path::new("frames/f.json");
    let check = |text: String, want: &str| {
        let e = SampleFrame::from_json_str(&text, p)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("frames/f.json") && e.contains(want),
            "{e:?} should contain {want:?}"
        );
    };
    let base = synth::FRAME_JSON;
    check(base.replace("[-0.14,  0.10]", "[0.0, -0.10]"), "collinear");
    check(
        base.replace(
            "\"radius\": 0.025 },\n    { \"center\": [ 0.07",
            "\"radius\": -1 },\n    { \"center\": [ 0.07",
        ),
        "radius",
    );
    check(
        base.replace("[-0.07,  0.035]", "[-0.2, 0.035]"),
        "inside the ortho",
    );
    check(
        base.replace("\"reflectance\": 0.99", "\"reflectance\": 0"),
        "reflectance",
    );
    check(base.replace("\"4x4_50\"", "\"7x7\""), "aruco_dictionary");
    check(
        base.replace("\"px_per_m\"", "\"px_per_metre\""),
        "unknown field",
    );
    check(
        base.replace(
            "\"material\": \"tile\",  \"center\": [-0.01,  0.035]",
            "\"material\": \"a,b\",  \"center\": [-0.01,  0.035]",
        ),
        "comma",
    );
}

#[test]
fn closest_approach_recovers_a_known_point() {
    let l = DVec3::new(0.1, -0.2, 0.5);
    let (o1, o2) = (DVec3::new(-0.07, 0.12, 0.03), DVec3::new(0.07, 0.12, 0.03));
    let (p, gap, s, u) =
        closest_approach(o1, (l - o1).normalize(), o2, (l - o2).normalize()).unwrap();
    assert!((p - l).length() < 1e-12 && gap < 1e-12 && s > 0.0 && u > 0.0);
}
