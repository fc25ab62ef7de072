//! Analytic checks of the skies: the CIE overcast sky's ratios and irradiance, the clear sky's
//! symmetry about the solar meridian, finite non-negative radiance over the whole sphere at the
//! model's extremes, the sun disk's irradiance, the lat-long convention and the errors.

use glam::DVec3;
use igi_imaging::latlong;
use igi_sky::hosek::{solar_irradiance_rgb, HosekWilkie};
use igi_sky::{CieOvercast, Sky, SkyError, SunPosition, SUN_ANGULAR_RADIUS_DEG};
use std::f64::consts::{FRAC_PI_2, PI};

fn dir(azimuth_deg: f64, elevation_deg: f64) -> DVec3 {
    let (a, e) = (azimuth_deg.to_radians(), elevation_deg.to_radians());
    DVec3::new(e.cos() * a.cos(), e.cos() * a.sin(), e.sin())
}

fn luminance(c: [f64; 3]) -> f64 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// A sphere of directions: a 96 x 48 grid, the horizon ring at z = 0 exactly, the poles.
fn sphere() -> Vec<DVec3> {
    let mut ds = vec![DVec3::Z, -DVec3::Z];
    for i in 0..48 {
        for j in 0..96 {
            ds.push(latlong::pixel_center_direction(i, j, 96, 48).as_dvec3());
        }
    }
    for j in 0..360 {
        let a = (j as f64).to_radians();
        ds.push(DVec3::new(a.cos(), a.sin(), 0.0));
    }
    ds
}

#[test]
fn overcast_zenith_is_three_times_the_horizon_and_gives_its_irradiance() {
    let sky = CieOvercast::from_horizontal_irradiance([7.0 * PI / 9.0, 1.0, 0.0]).unwrap();
    // L_z = 9 E_h / (7 pi)
    assert!((sky.zenith[0] - 1.0).abs() < 1e-15, "{:?}", sky.zenith);
    let z = sky.radiance_from(DVec3::Z);
    let h = sky.radiance_from(DVec3::new(1.0, -2.0, 0.0));
    let at60 = sky.radiance_from(dir(123.0, 30.0));
    for c in 0..2 {
        assert!((z[c] / h[c] - 3.0).abs() < 1e-14, "{z:?} {h:?}");
        assert!((at60[c] / z[c] - 2.0 / 3.0).abs() < 1e-14, "{at60:?}");
    }
    assert_eq!(z[2], 0.0);
    assert_eq!(sky.radiance_from(dir(10.0, -0.1)), [0.0; 3]);
    assert_eq!(sky.radiance_from(DVec3::ZERO), [0.0; 3]);
    // the map's integral of L cos(theta) dOmega is the horizontal irradiance
    let (w, h) = (256, 256);
    let map = sky.latlong(w, h).unwrap();
    let mut e = 0.0;
    for i in 0..h {
        for j in 0..w {
            let d = latlong::pixel_center_direction(i, j, w, h).as_dvec3();
            if d.z > 0.0 {
                e += map.get(j, i)[1] as f64 * d.z * latlong::pixel_solid_angle(i, w, h) as f64;
            }
        }
    }
    eprintln!("overcast: map irradiance {e:.6} for 1 ({w} x {h})");
    assert!((e - 1.0).abs() < 2e-3, "{e}");
    assert_eq!(sky.horizontal_irradiance()[1], 1.0);
}

#[test]
fn the_clear_sky_is_symmetric_about_the_solar_meridian() {
    let sun_az: f64 = 37.0;
    for (t, el) in [(1.0, 0.0), (2.5, 25.0), (7.3, 61.0), (10.0, 90.0)] {
        let sky = Sky::new(t, [0.2, 0.3, 0.4], dir(sun_az, el)).unwrap();
        let mut worst = 0.0f64;
        for k in 0..36 {
            for e in [0.0, 1.0, 10.0, 30.0, 60.0, 89.0] {
                let off = 5.0 * k as f64 + 2.5;
                let a = sky.radiance(dir(sun_az + off, e));
                let b = sky.radiance(dir(sun_az - off, e));
                for c in 0..3 {
                    let rel = (a[c] - b[c]).abs() / a[c].abs().max(b[c].abs()).max(1e-300);
                    worst = worst.max(rel);
                }
            }
        }
        assert!(worst < 1e-10, "turbidity {t}, elevation {el}: {worst}");
    }
}

#[test]
fn the_clear_sky_is_finite_and_non_negative_over_the_sphere() {
    let mut most_negative = 0.0f64;
    for t in [1.0, 10.0] {
        for el in [0.0, 90.0] {
            for albedo in [0.0, 1.0] {
                let sun = dir(200.0, el);
                let sky = Sky::new(t, [albedo; 3], sun).unwrap();
                let mut ds = sphere();
                // gamma = 0, and the horizon point below the sun (theta = 90 deg)
                ds.push(sun);
                ds.push(dir(200.0, 0.0));
                for d in ds {
                    let l = sky.radiance(d);
                    assert!(
                        l.iter().all(|v| v.is_finite() && *v >= 0.0),
                        "{t} {el} {d} {l:?}"
                    );
                    if d.z < 0.0 {
                        assert_eq!(l, [0.0; 3]);
                    }
                }
                // the raw model: finite at gamma = 0 and at theta = 90 degrees
                let m = sky.model();
                for (theta, gamma) in [(0.0, 0.0), (FRAC_PI_2, 0.0), (FRAC_PI_2, PI), (0.3, 0.0)] {
                    let l = m.radiance(theta, gamma);
                    assert!(l.iter().all(|v| v.is_finite()), "{t} {el} {l:?}");
                    most_negative = l.iter().fold(most_negative, |a, v| a.min(*v));
                }
                let map = sky.latlong(64, 32).unwrap();
                assert!(map
                    .pixels
                    .iter()
                    .flatten()
                    .all(|v| v.is_finite() && *v >= 0.0));
            }
        }
    }
    eprintln!("raw model's most negative value at the checked extremes: {most_negative:.3}");
}

#[test]
fn the_lat_long_map_follows_igis_convention() {
    let sky = Sky::new(3.0, [0.1; 3], dir(90.0, 30.0)).unwrap();
    let (w, h) = (48, 24);
    let map = sky.latlong(w, h).unwrap();
    for i in 0..h {
        for j in 0..w {
            let d = latlong::pixel_center_direction(i, j, w, h).as_dvec3();
            let want = sky.radiance(d);
            let got = map.get(j, i);
            for c in 0..3 {
                assert!((got[c] as f64 - want[c]).abs() <= 1e-5 * want[c].abs() + 1e-30);
            }
            if i >= h / 2 {
                assert_eq!(got, [0.0; 3], "row {i} is below the horizon");
            }
        }
    }
    // the brightest pixel of the upper half lies in the sun's azimuth (90: +Y, u = 0.25; at
    // this size its row is near the horizon, which brightens toward the sun)
    let (mut best, mut at) = (0.0, (0, 0));
    for i in 0..h / 2 {
        for j in 0..w {
            let y = luminance(map.get(j, i).map(|v| v as f64));
            if y > best {
                (best, at) = (y, (i, j));
            }
        }
    }
    let sun_px = latlong::direction_to_pixel(dir(90.0, 30.0).as_vec3(), w, h);
    assert!((at.1 as f32 - sun_px.0).abs() <= 1.0, "{at:?} {sun_px:?}");
    let toward = luminance(sky.radiance(dir(90.0, 30.0)));
    let away = luminance(sky.radiance(dir(270.0, 30.0)));
    assert!(toward > 3.0 * away, "{toward} {away}");
    assert!(matches!(sky.latlong(0, 4), Err(SkyError::MapSize(0, 4))));
}

#[test]
fn per_channel_albedo_is_the_scalar_model_per_channel() {
    let sky = HosekWilkie::new(4.2, [0.0, 0.35, 1.0], 0.4).unwrap();
    for (c, a) in [0.0, 0.35, 1.0].into_iter().enumerate() {
        let one = HosekWilkie::new(4.2, [a; 3], 0.4).unwrap();
        for (theta, gamma) in [(0.1, 0.5), (1.2, 2.0), (1.5, 0.05)] {
            assert_eq!(sky.radiance(theta, gamma)[c], one.radiance(theta, gamma)[c]);
        }
    }
}

#[test]
fn the_sun_disk_keeps_the_models_irradiance() {
    let sky = Sky::new(2.0, [0.2; 3], dir(150.0, 45.0)).unwrap();
    let disk = sky.sun_disk();
    assert_eq!(disk.angular_radius_deg, SUN_ANGULAR_RADIUS_DEG);
    assert!((disk.direction - dir(150.0, 45.0)).length() < 1e-15);
    let e = sky.solar_irradiance();
    let got = disk.irradiance();
    for c in 0..3 {
        assert!((got[c] / e[c] - 1.0).abs() < 1e-12, "{got:?} {e:?}");
    }
    // the wider disk is dimmer by the ratio of solid angles (0.2667 / 0.255 deg squared)
    let mean = e[1] / (2.0 * PI * (1.0 - (0.255f64.to_radians()).cos()));
    let ratio = mean / disk.radiance[1];
    assert!(
        (ratio - (0.2667f64 / 0.255).powi(2)).abs() < 1e-4,
        "{ratio}"
    );
    // as a lighting file's sun
    let s = disk.to_section();
    assert_eq!(s.angular_diameter_deg, 2.0 * SUN_ANGULAR_RADIUS_DEG);
    assert_eq!(s.radiance, disk.radiance);
    igi_formats::lighting::check_sun(
        s.direction.map(|v| v as f32),
        s.radiance.map(|v| v as f32),
        s.angular_diameter_deg as f32,
    )
    .unwrap();
    // a sun on the horizon is so red that Rec. 709 puts its blue below zero: set to zero
    let low = Sky::new(1.0, [0.2; 3], dir(0.0, 0.0)).unwrap();
    assert!(low.solar_irradiance()[2] < 0.0);
    let d = low.sun_disk();
    assert!(
        d.radiance[0] > 0.0 && d.radiance[2] == 0.0,
        "{:?}",
        d.radiance
    );
    assert!(matches!(
        sky.sun_disk_of_radius(0.0),
        Err(SkyError::SunRadius(_))
    ));
}

/// Orders of magnitude against the physical sky: the model's units times 683 lm/W are
/// photometric. A clear sun overhead gives a normal illuminance of the order of 10^5 lux, the
/// clear sky's diffuse light on the ground of the order of 10^4 lux, and the zenith is blue.
#[test]
fn the_clear_sky_has_daylights_orders_of_magnitude() {
    let sky = Sky::new(2.0, [0.2; 3], dir(0.0, 60.0)).unwrap();
    let sun_lux = 683.0 * luminance(sky.solar_irradiance());
    let (w, h) = (512, 256);
    let mut diffuse = [0.0; 3];
    for i in 0..h / 2 {
        let omega = latlong::pixel_solid_angle(i, w, h) as f64;
        for j in 0..w {
            let d = latlong::pixel_center_direction(i, j, w, h).as_dvec3();
            let l = sky.radiance(d);
            for c in 0..3 {
                diffuse[c] += l[c] * d.z * omega;
            }
        }
    }
    let sky_lux = 683.0 * luminance(diffuse);
    let zenith = sky.radiance(DVec3::Z);
    eprintln!(
        "turbidity 2, sun 60 deg up: sun {sun_lux:.0} lx normal, sky {sky_lux:.0} lx horizontal, zenith {zenith:?}"
    );
    assert!(sun_lux > 5e4 && sun_lux < 1.2e5, "{sun_lux}");
    assert!(sky_lux > 5e3 && sky_lux < 4e4, "{sky_lux}");
    assert!(zenith[2] > zenith[1] && zenith[1] > zenith[0], "{zenith:?}");
    // a hazier sky lets through less sun
    let hazy = solar_irradiance_rgb(8.0, 60f64.to_radians());
    assert!(luminance(hazy) < 0.9 * luminance(sky.solar_irradiance()));
}

#[test]
fn out_of_range_parameters_are_refused_by_name() {
    let up = dir(0.0, 30.0);
    for t in [0.5, 10.5, f64::NAN] {
        let e = Sky::new(t, [0.2; 3], up).unwrap_err().to_string();
        assert!(e.contains("turbidity") && e.contains("1 to 10"), "{e}");
    }
    for a in [[-0.1, 0.2, 0.2], [0.2, 1.5, 0.2], [0.2, 0.2, f64::NAN]] {
        let e = Sky::new(2.0, a, up).unwrap_err().to_string();
        assert!(e.contains("ground albedo"), "{e}");
    }
    let e = Sky::new(2.0, [0.2; 3], dir(0.0, -2.0))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("solar elevation -2") && e.contains("horizon"),
        "{e}"
    );
    for d in [DVec3::ZERO, DVec3::new(f64::NAN, 0.0, 1.0)] {
        let e = Sky::new(2.0, [0.2; 3], d).unwrap_err().to_string();
        assert!(e.contains("sun direction"), "{e}");
    }
    assert!(matches!(
        CieOvercast::from_horizontal_irradiance([1.0, -1.0, 1.0]),
        Err(SkyError::Irradiance(_))
    ));
    assert!(matches!(
        CieOvercast::new([1.0, f64::INFINITY, 1.0]),
        Err(SkyError::Radiance(_))
    ));
    // the sun from its position and the site's north (east = north x up)
    let p = SunPosition {
        azimuth_deg: 90.0,
        zenith_deg: 60.0,
    };
    let sky = Sky::at_position(2.0, [0.2; 3], p, [0.0, 1.0, 0.0]).unwrap();
    assert!(
        (sky.sun() - dir(0.0, 30.0)).length() < 1e-12,
        "{}",
        sky.sun()
    );
    assert!((sky.solar_elevation_rad() - 30f64.to_radians()).abs() < 1e-12);
}
