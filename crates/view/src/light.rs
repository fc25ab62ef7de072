//! A lighting file as the page shows it: the sun's direction and irradiance, and the sky's
//! irradiance on surfaces facing up and down (the page's hemisphere light).

use crate::ViewError;
use glam::Vec3;
use igi_formats::lighting::LightingRadiance;
use igi_imaging::latlong::{pixel_center_direction, pixel_solid_angle};
use std::path::Path;

/// What the page needs of one lighting file, in igi's world frame (Z up) and W m^-2.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct PageLight {
    pub name: String,
    /// Unit direction toward the sun; `None` without a sun.
    pub sun_direction: Option<[f32; 3]>,
    /// The sun's irradiance on a surface facing it (radiance x solid angle), per channel.
    pub sun_irradiance: [f32; 3],
    /// The sky's irradiance on a horizontal surface facing up, and facing down.
    pub sky_up: [f32; 3],
    pub sky_down: [f32; 3],
}

/// Read a lighting file (map, scale and sun checked by igi-formats) for the page.
pub fn page_light(path: &Path) -> Result<PageLight, ViewError> {
    let l = LightingRadiance::load(path)?;
    let (mut up, mut down) = (Vec3::ZERO, Vec3::ZERO);
    if let Some((w, h, px)) = &l.environment {
        for i in 0..*h {
            let dw = pixel_solid_angle(i, *w, *h);
            for j in 0..*w {
                let d = pixel_center_direction(i, j, *w, *h);
                let e = Vec3::from(px[i * w + j]) * dw;
                up += e * d.z.max(0.0);
                down += e * (-d.z).max(0.0);
            }
        }
    }
    let (sun_direction, sun_irradiance) = match &l.sun {
        Some(s) => (
            Some(Vec3::from(s.direction).normalize().to_array()),
            (Vec3::from(s.radiance) * s.solid_angle as f32).to_array(),
        ),
        None => (None, [0.0; 3]),
    };
    let name = path
        .file_stem()
        .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
    Ok(PageLight {
        name,
        sun_direction,
        sun_irradiance,
        sky_up: up.to_array(),
        sky_down: down.to_array(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A uniform sky of radiance L gives pi L on a surface facing up and as much facing down;
    /// the sun's irradiance is its radiance times its disk's solid angle.
    #[test]
    fn a_uniform_sky_and_a_sun_give_their_analytic_irradiance() {
        let dir = tempfile::tempdir().unwrap();
        let mut sky = igi_imaging::HdrImage::new(64, 32);
        for p in &mut sky.pixels {
            *p = [0.5, 1.0, 2.0];
        }
        igi_imaging::write_exr(&dir.path().join("sky.exr"), &sky).unwrap();
        let toml = "[environment]\nmap = \"sky.exr\"\nscale = 2.0\n\n[sun]\ndirection = [0.0, 3.0, 4.0]\nradiance = [1000.0, 900.0, 800.0]\nangular_diameter_deg = 0.53\n";
        let path = dir.path().join("noon.toml");
        std::fs::write(&path, toml).unwrap();
        let l = page_light(&path).unwrap();
        assert_eq!(l.name, "noon");
        let pi = std::f32::consts::PI;
        for (c, want) in [1.0f32, 2.0, 4.0].iter().enumerate() {
            let (up, down) = (l.sky_up[c] / (pi * want), l.sky_down[c] / (pi * want));
            assert!(
                (up - 1.0).abs() < 2e-3 && (down - 1.0).abs() < 2e-3,
                "{up} {down}"
            );
        }
        assert_eq!(l.sun_direction, Some([0.0, 0.6, 0.8]));
        let omega = 2.0 * std::f64::consts::PI * igi_formats::lighting::disk_one_minus_cos(0.53);
        let ratio = f64::from(l.sun_irradiance[0]) / (1000.0 * omega);
        assert!((ratio - 1.0).abs() < 1e-5, "{:?}", l.sun_irradiance);
    }
}
