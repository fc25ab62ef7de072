//! igi-sky against Mitsuba 3.9.1's `sunsky` emitter (datasets/mitsuba/sunsky_reference.py,
//! datasets/fixtures/sky/mitsuba_sunsky.csv): the sun's direction from the same time and place,
//! and the sky's radiance in 100+ directions per time, up to one scale factor per channel.

use glam::DVec3;
use igi_formats::time::PhotoTime;
use igi_sky::{sun_direction, sun_position, Refraction, Sky};
use std::collections::BTreeMap;

struct Row {
    time: String,
    sun: DVec3,
    dir: DVec3,
    rgb: [f64; 3],
}

fn rows() -> Vec<Row> {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../datasets/fixtures/sky/mitsuba_sunsky.csv"
    );
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{path}: {e}"));
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with("local_time"))
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let v: Vec<f64> = f[1..].iter().map(|x| x.parse().unwrap()).collect();
            Row {
                time: f[0].to_string(),
                sun: DVec3::new(v[0], v[1], v[2]),
                dir: DVec3::new(v[3], v[4], v[5]),
                rgb: [v[6], v[7], v[8]],
            }
        })
        .collect()
}

/// Mitsuba 3.9.1's `sunsky` RGB sky radiance over igi-sky's (the Hosek-Wilkie reference's RGB
/// data in its own units), the same in R, G and B (docs/SKY.md, "Against Mitsuba 3").
const MITSUBA_RGB_SCALE: f64 = 0.0093677;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

#[test]
fn the_sun_stands_where_mitsubas_sunsky_puts_it() {
    let mut suns = BTreeMap::new();
    for r in rows() {
        suns.insert(r.time.clone(), r.sun);
    }
    assert!(suns.len() >= 3);
    for (t, m) in &suns {
        let time = PhotoTime::parse_rfc3339(&format!("2026-06-21T{t}:00+02:00")).unwrap();
        let p = sun_position(&time, 48.85, 2.35, 0.0, Refraction::STANDARD).unwrap();
        let d = sun_direction(p, [0.0, 1.0, 0.0]).unwrap();
        let angle = d.angle_between(m.normalize()).to_degrees();
        eprintln!("{t}: SPA {d:.5} Mitsuba {m:.5}: {angle:.4} deg");
        assert!(angle < 0.1, "{t}: {angle} deg");
    }
}

#[test]
fn the_sky_has_mitsubas_shape_up_to_one_scale_per_channel() {
    let rows = rows();
    // the sky with Mitsuba's own sun direction, so that only the sky model is compared
    let ratios: Vec<[f64; 3]> = rows
        .iter()
        .map(|r| {
            let sky = Sky::new(3.0, [0.2; 3], r.sun).unwrap();
            let l = sky.radiance(r.dir);
            [0, 1, 2].map(|c| r.rgb[c] / l[c])
        })
        .collect();
    let scale = [0, 1, 2].map(|c| median(ratios.iter().map(|r| r[c]).collect()));
    let mut worst = [0.0f64; 3];
    let mut devs: [Vec<f64>; 3] = Default::default();
    for r in &ratios {
        for c in 0..3 {
            let dev = (r[c] / scale[c] - 1.0).abs();
            worst[c] = worst[c].max(dev);
            devs[c].push(dev);
        }
    }
    let med = devs.clone().map(median);
    let p95 = devs.map(|mut v| {
        v.sort_by(f64::total_cmp);
        v[v.len() * 95 / 100]
    });
    eprintln!(
        "{} directions: Mitsuba / igi scale {scale:?}; |ratio/scale - 1| median {med:?}, 95th percentile {p95:?}, worst {worst:?}",
        ratios.len()
    );
    for c in 0..3 {
        assert!(
            (scale[c] / MITSUBA_RGB_SCALE - 1.0).abs() < 1e-4,
            "channel {c}: scale {}",
            scale[c]
        );
        // the same function: equal up to Mitsuba's f32 arithmetic
        assert!(worst[c] < 1e-4, "channel {c}: worst {}", worst[c]);
    }
}
