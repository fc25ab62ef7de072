//! A figure like Fig. 4 of Debevec et al. 2004: measured samples and the fitted BRDF in the plane
//! of incidence, one panel per material (rows) and colour channel (columns), one curve per light
//! elevation. x: signed view angle in degrees (positive on the mirror side, away from the light),
//! y: pi times the BRDF. Samples more than 10 degrees of azimuth out of the plane are not drawn.

use std::path::Path;

use glam::Vec3;
use igi_plot::{write_chart_grid, Axis, Chart, Series, PALETTE};

use crate::{BrdfError, BrdfSample, Lafortune};

fn azimuth(v: Vec3) -> f32 {
    v.y.atan2(v.x)
}

fn wrap(a: f32) -> f32 {
    let mut a = a;
    while a > std::f32::consts::PI {
        a -= std::f32::consts::TAU;
    }
    while a < -std::f32::consts::PI {
        a += std::f32::consts::TAU;
    }
    a
}

/// (light elevation group in degrees, azimuth of the light, [(signed view angle, value)])
type Group = (i32, f32, Vec<(f32, Vec3)>);

fn in_plane_groups(samples: &[BrdfSample]) -> Vec<Group> {
    let mut groups: Vec<Group> = Vec::new();
    for s in samples {
        let lt = s.light.z.clamp(-1.0, 1.0).acos().to_degrees();
        let key = (lt / 5.0).round() as i32 * 5;
        let phi_l = azimuth(s.light);
        let vt = s.view.z.clamp(-1.0, 1.0).acos().to_degrees();
        let dphi = wrap(azimuth(s.view) - phi_l).abs().to_degrees();
        // same side as the light: negative angle; mirror side: positive
        let signed = if vt < 1.0 {
            0.0
        } else if dphi <= 10.0 {
            -vt
        } else if dphi >= 170.0 {
            vt
        } else {
            continue;
        };
        match groups.iter_mut().find(|g| g.0 == key) {
            Some(g) => g.2.push((signed, s.value)),
            None => groups.push((
                key,
                if lt < 1.0 { 0.0 } else { phi_l },
                vec![(signed, s.value)],
            )),
        }
    }
    groups.sort_by_key(|g| g.0);
    groups
}

/// Draw the figure for `materials` = (name, samples, fitted BRDF) into a PNG (atomic write).
pub fn plot_fits(
    path: &Path,
    materials: &[(String, Vec<BrdfSample>, Lafortune)],
) -> Result<(), BrdfError> {
    let rows = materials.len().max(1);
    let (w, h) = (1500u32, 380 * rows as u32);
    let mut panels = Vec::with_capacity(3 * materials.len());
    for (name, samples, brdf) in materials {
        let groups = in_plane_groups(samples);
        panels.extend((0..3).map(|c| panel(name, c, &groups, brdf)));
    }
    write_chart_grid(path, (w, h), (rows, 3), &panels).map_err(|e| BrdfError::File {
        path: path.into(),
        msg: format!("cannot draw the plot: {e}"),
    })
}

/// One panel: material `name`, channel `c`, the samples of every light group (one colour per
/// group, cycled) and the fitted curve in the plane of that light.
fn panel(name: &str, c: usize, groups: &[Group], brdf: &Lafortune) -> Chart {
    let ymax = groups
        .iter()
        .flat_map(|g| g.2.iter().map(|p| p.1[c]))
        .fold(0.0f32, f32::max)
        .max(1e-6)
        * 1.15;
    let mut series = Vec::new();
    for (gi, (lt, phi_l, pts)) in groups.iter().enumerate() {
        let colour = PALETTE[gi % PALETTE.len()];
        let curve = fitted_curve(brdf, *lt, *phi_l, c, ymax);
        series.push(Series {
            legend: Some(format!("light {lt} deg")),
            ..Series::line(
                curve.map(|(a, v)| (a as f64, v as f64)).collect(),
                colour,
                2,
            )
        });
        let dots = pts.iter().map(|(a, v)| (*a as f64, v[c].min(ymax) as f64));
        series.push(Series::dots(dots.collect(), colour, 3));
    }
    Chart {
        title: format!("{name} - {}", ["red", "green", "blue"][c]),
        x: Axis::linear("view angle (deg, + = mirror side)", -90.0..90.0),
        y: Axis::linear("pi f", 0.0..ymax as f64),
        series,
    }
}

/// Channel `c` of pi times `brdf` in the plane of a light at elevation `lt` degrees and azimuth
/// `phi_l`, over signed view angles from -89.5 to 89.5 degrees, capped at `ymax`.
fn fitted_curve(
    brdf: &Lafortune,
    lt: i32,
    phi_l: f32,
    c: usize,
    ymax: f32,
) -> impl Iterator<Item = (f32, f32)> + '_ {
    let light = Vec3::new(
        (lt as f32).to_radians().sin() * phi_l.cos(),
        (lt as f32).to_radians().sin() * phi_l.sin(),
        (lt as f32).to_radians().cos(),
    );
    (0..=360).map(move |k| {
        let a = -89.5 + 179.0 * k as f32 / 360.0;
        let phi = if a < 0.0 {
            phi_l
        } else {
            phi_l + std::f32::consts::PI
        };
        let t = a.abs().to_radians();
        let v = Vec3::new(t.sin() * phi.cos(), t.sin() * phi.sin(), t.cos());
        (
            a,
            (brdf.as_ref().eval(light, v)[c] * std::f32::consts::PI).min(ymax),
        )
    })
}

/// Write text to `path` atomically (temp file in the same folder, then rename).
pub fn write_text_atomic(path: &Path, text: &str) -> Result<(), BrdfError> {
    igi_files::write_text_atomic(path, text).map_err(|e| BrdfError::File {
        path: path.into(),
        msg: format!("cannot write: {e}"),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::tests::{paper_pairs, synth};
    use crate::Lobe;

    #[test]
    fn groups_samples_in_the_plane_and_draws_a_png() {
        let m = Lafortune {
            rho_d: Vec3::splat(0.3),
            lobes: vec![Lobe {
                rho: Vec3::splat(2.0),
                cxy: -1.0,
                cz: 1.0,
                n: 30.0,
            }],
        };
        let s = synth(&m, "m", &paper_pairs(), 0.0, 0);
        let g = in_plane_groups(&s);
        assert_eq!(g.iter().map(|x| x.0).collect::<Vec<_>>(), [0, 30, 50, 75]);
        // 21 in-plane views per light; the 3 out-of-plane views (60 deg azimuth) are dropped
        assert!(
            g.iter().all(|x| x.2.len() == 21),
            "{:?}",
            g.iter().map(|x| x.2.len()).collect::<Vec<_>>()
        );
        // light at 30 deg: the mirror view (+30) carries the peak
        let peak = g[1]
            .2
            .iter()
            .max_by(|a, b| a.1.x.total_cmp(&b.1.x))
            .unwrap();
        assert!((peak.0 - 32.0).abs() <= 4.0, "{peak:?}");
        let dir = tempfile_dir();
        let p = dir.join("fig.png");
        plot_fits(&p, &[("m".into(), s, m)]).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        assert_eq!(&bytes[1..4], b"PNG");
        let _ = std::fs::remove_dir_all(&dir);
    }

    fn tempfile_dir() -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("igi-brdf-plot-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d
    }
}
