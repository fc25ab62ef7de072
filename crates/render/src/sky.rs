//! Procedural skies for synthetic scenes (the embedded default and tests): a clear sky with a
//! sun, and a CIE overcast sky, as lat-long maps in FORMATS.md's convention.
//!
//! These are simple analytic models chosen to look plausible and to stress the solver the way
//! real skies do (a sun about 10^5 times brighter than the sky, a brighter horizon, a
//! circumsolar glow), not a physical sky model. Directions below the horizon see a uniform
//! ground of radiance `ground`.

use glam::Vec3;
use igi_imaging::{latlong, HdrImage};

/// A clear sky: blue zenith, whiter horizon, a glow around the sun. `sun` is the unit
/// direction toward the sun; `zenith` the radiance at the zenith (blue channel).
pub fn clear_sky(width: usize, height: usize, sun: Vec3, zenith: f32, ground: Vec3) -> HdrImage {
    let sun = sun.normalize_or(Vec3::Z);
    sky_map(width, height, ground, |d| {
        let base = Vec3::new(0.30, 0.50, 1.0) * zenith;
        let horizon = Vec3::new(0.85, 0.90, 1.0) * zenith * 1.6;
        let t = (1.0 - d.z).powi(3);
        let gamma = d.dot(sun).clamp(-1.0, 1.0).acos();
        let glow = Vec3::new(1.0, 0.9, 0.75)
            * zenith
            * (2.5 * (-gamma / 0.15).exp() + 0.4 * (-gamma / 0.8).exp());
        base * (1.0 - t) + horizon * t + glow
    })
}

/// The CIE standard overcast sky, L(theta) = L_z (1 + 2 cos theta) / 3, grey.
pub fn overcast_sky(width: usize, height: usize, zenith: f32, ground: Vec3) -> HdrImage {
    sky_map(width, height, ground, |d| {
        Vec3::splat(zenith * (1.0 + 2.0 * d.z) / 3.0)
    })
}

/// A lat-long map of `sky(d)` for the pixel-centre directions `d` above the horizon (`d.z > 0`)
/// and `ground` below it.
fn sky_map(width: usize, height: usize, ground: Vec3, sky: impl Fn(Vec3) -> Vec3) -> HdrImage {
    latlong::map_from_fn(width, height, |d| {
        if d.z <= 0.0 { ground } else { sky(d) }.to_array()
    })
}

/// Unit direction toward the sun from its elevation and azimuth (degrees; azimuth from +X
/// toward +Y, as the lat-long phi).
pub fn sun_direction(elevation_deg: f32, azimuth_deg: f32) -> Vec3 {
    let (e, a) = (elevation_deg.to_radians(), azimuth_deg.to_radians());
    Vec3::new(e.cos() * a.cos(), e.cos() * a.sin(), e.sin())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn skies_are_finite_positive_and_brightest_toward_the_sun() {
        let sun = sun_direction(30.0, 45.0);
        let s = clear_sky(64, 32, sun, 1.0, Vec3::splat(0.1));
        assert!(s
            .pixels
            .iter()
            .all(|p| p.iter().all(|c| c.is_finite() && *c > 0.0)));
        let (u, v) = latlong::direction_to_uv(sun);
        let at_sun = s.bilinear(u * 64.0 - 0.5, v * 32.0 - 0.5).unwrap();
        let away = s.get(40, 5);
        assert!(at_sun[0] > 2.0 * away[0], "{at_sun:?} vs {away:?}");
        let o = overcast_sky(64, 32, 3.0, Vec3::splat(0.1));
        // zenith row is (1 + 2 cos theta)/3 with theta = pi * 0.5 / 32
        let expect = 3.0 * (1.0 + 2.0 * (std::f32::consts::PI * 0.5 / 32.0).cos()) / 3.0;
        assert!((o.get(0, 0)[1] - expect).abs() < 1e-5);
        assert!((sun_direction(90.0, 10.0) - Vec3::Z).length() < 1e-6);
    }
}
