//! The lighting file (`docs/FORMATS.md`, "Lighting file"): an optional lat-long environment map
//! and an optional sun disk.
//!
//! ```toml
//! [environment]
//! map = "sky.exr"
//! scale = 1.0
//!
//! [sun]
//! direction = [0.0, 0.0, 1.0]
//! radiance = [60000.0, 57000.0, 52000.0]
//! angular_diameter_deg = 0.53
//! ```
//! Unknown keys inside a section are refused; unknown top-level keys are ignored (as they have
//! always been).

use crate::{FileKind, FormatsError, TomlFile};
use igi_imaging::HdrImage;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A lighting file as written. Neither section is required by the format; a renderer that
/// needs light refuses a file with neither.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct LightingFile {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub environment: Option<EnvironmentSection>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sun: Option<SunSection>,
}

/// `[environment]`: a lat-long map of linear RGB radiance, times `scale`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EnvironmentSection {
    /// The map, relative to the lighting file's folder.
    pub map: PathBuf,
    #[serde(default = "one")]
    pub scale: f64,
}

/// `[sun]`: a disk of uniform radiance.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SunSection {
    /// Toward the sun, world frame (need not be unit as written).
    pub direction: [f64; 3],
    /// Radiance of the disk, in the units of the map.
    pub radiance: [f64; 3],
    #[serde(default = "sun_diameter")]
    pub angular_diameter_deg: f64,
}

fn one() -> f64 {
    1.0
}

fn sun_diameter() -> f64 {
    igi_imaging::color::SUN_ANGULAR_DIAMETER_DEG
}

impl TomlFile for LightingFile {
    const KIND: FileKind = FileKind::Lighting;
}

/// The largest radiance a light may have: products of radiance, solid angles, albedos and
/// path weights stay inside `f32` (3.4e38) with a wide margin.
pub const MAX_RADIANCE: f32 = 1e15;

/// A lighting value that cannot light anything (from a file or built in code).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum LightingValueError {
    #[error("environment map is empty")]
    EmptyMap,
    #[error("environment scale {0} is not a finite non-negative number")]
    Scale(f32),
    #[error("environment map pixel (row {row}, column {col}) is {value:?} (times scale {scale}): radiance must be finite, >= 0 and at most {MAX_RADIANCE:e}")]
    MapPixel {
        row: usize,
        col: usize,
        value: [f32; 3],
        scale: f32,
    },
    #[error("sun direction {0:?} is not a non-zero finite vector")]
    SunDirection([f32; 3]),
    #[error("sun radiance {0:?} must be finite, >= 0 and at most {MAX_RADIANCE:e} (larger values overflow f32 in the estimates)")]
    SunRadiance([f32; 3]),
    #[error("sun angular_diameter_deg = {0}: must be in (0, 180)")]
    SunDiameter(f32),
}

/// The radiance of a lat-long map times `scale`, row-major with row 0 at the zenith (the
/// FORMATS.md mapping, unchanged: `igi_imaging::latlong` gives each pixel's direction).
/// Non-finite, negative or huge values (> [`MAX_RADIANCE`]) are refused with the pixel.
pub fn scaled_radiance(img: &HdrImage, scale: f32) -> Result<Vec<[f32; 3]>, LightingValueError> {
    if img.width == 0 || img.height == 0 {
        return Err(LightingValueError::EmptyMap);
    }
    if !(scale.is_finite() && scale >= 0.0) {
        return Err(LightingValueError::Scale(scale));
    }
    img.pixels
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let v = p.map(|c| c * scale);
            let bad = v
                .iter()
                .any(|c| !(c.is_finite() && *c >= 0.0 && *c <= MAX_RADIANCE));
            if bad {
                return Err(LightingValueError::MapPixel {
                    row: i / img.width,
                    col: i % img.width,
                    value: *p,
                    scale,
                });
            }
            Ok(v)
        })
        .collect()
}

/// Checks a sun's values: a non-zero finite direction, radiance finite in [0, MAX_RADIANCE],
/// an angular diameter in (0, 180) degrees.
pub fn check_sun(
    direction: [f32; 3],
    radiance: [f32; 3],
    angular_diameter_deg: f32,
) -> Result<(), LightingValueError> {
    let len = direction.iter().map(|c| c * c).sum::<f32>().sqrt();
    if !(len.is_finite() && len > 0.0) {
        return Err(LightingValueError::SunDirection(direction));
    }
    if radiance
        .iter()
        .any(|c| !(c.is_finite() && *c >= 0.0 && *c <= MAX_RADIANCE))
    {
        return Err(LightingValueError::SunRadiance(radiance));
    }
    if !(angular_diameter_deg > 0.0 && angular_diameter_deg < 180.0) {
        return Err(LightingValueError::SunDiameter(angular_diameter_deg));
    }
    Ok(())
}

/// `1 - cos(half angle)` of a disk of this angular diameter, without cancellation (a 0.53
/// degree sun keeps full precision); the disk's solid angle is `2 pi` times it.
pub fn disk_one_minus_cos(angular_diameter_deg: f64) -> f64 {
    let half = angular_diameter_deg.to_radians() / 2.0;
    2.0 * (half / 2.0).sin().powi(2)
}

/// The sun of a lighting file, checked: unit direction, radiance, disk solid angle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SunRadiance {
    /// Toward the sun, as written (cast to f32; not normalised, so that a renderer that
    /// normalises it gets the same bits as from the file): see [`SunRadiance::unit_direction`].
    pub direction: [f32; 3],
    pub radiance: [f32; 3],
    pub angular_diameter_deg: f32,
    /// Solid angle of the disk (sr).
    pub solid_angle: f64,
}

/// What a lighting file lights with, read and checked: the environment's radiance (the map
/// times `scale`, FORMATS.md lat-long, row 0 at the zenith) and the sun. The one reading of a
/// lighting file's light that the renderers share (`igi-render` builds its sampled lighting on
/// it, `igi-opacity-hull` integrates it over the Voronoi cells of its light directions).
#[derive(Clone, Debug, PartialEq)]
pub struct LightingRadiance {
    /// `(width, height, texels)` of the scaled map.
    pub environment: Option<(usize, usize, Vec<[f32; 3]>)>,
    pub sun: Option<SunRadiance>,
}

/// Errors of [`LightingRadiance::load`]; each names the lighting file (and the map).
#[derive(Debug, thiserror::Error)]
pub enum LightingLoadError {
    #[error(transparent)]
    Format(#[from] FormatsError),
    /// The map cannot be read.
    #[error("{}: environment map {}: {source}", path.display(), map.display())]
    MapFile {
        path: PathBuf,
        map: PathBuf,
        #[source]
        source: Box<igi_imaging::ImagingError>,
    },
    /// The map (or the scale) holds a value that cannot light anything.
    #[error("{}: environment map {}: {source}", path.display(), map.display())]
    MapValue {
        path: PathBuf,
        map: PathBuf,
        #[source]
        source: LightingValueError,
    },
    #[error("{}: [sun]: {source}", path.display())]
    Sun {
        path: PathBuf,
        #[source]
        source: LightingValueError,
    },
    #[error("{}: names neither [environment] nor [sun]: nothing would light the scene", path.display())]
    Nothing { path: PathBuf },
}

impl LightingRadiance {
    /// Reads the lighting file at `path` and what it names (the map relative to its folder).
    pub fn load(path: &Path) -> Result<Self, LightingLoadError> {
        Self::from_file(&LightingFile::read(path)?, path)
    }

    /// The light of a parsed lighting file read from `path` (errors name it).
    pub fn from_file(f: &LightingFile, path: &Path) -> Result<Self, LightingLoadError> {
        let environment = match &f.environment {
            None => None,
            Some(e) => {
                let map = path.parent().unwrap_or(Path::new(".")).join(&e.map);
                let img =
                    igi_imaging::read_image(&map).map_err(|s| LightingLoadError::MapFile {
                        path: path.to_path_buf(),
                        map: map.clone(),
                        source: Box::new(s),
                    })?;
                let texels = scaled_radiance(&img, e.scale as f32).map_err(|source| {
                    LightingLoadError::MapValue {
                        path: path.to_path_buf(),
                        map,
                        source,
                    }
                })?;
                Some((img.width, img.height, texels))
            }
        };
        let sun = match &f.sun {
            None => None,
            Some(s) => Some(sun_radiance(s).map_err(|source| LightingLoadError::Sun {
                path: path.to_path_buf(),
                source,
            })?),
        };
        if environment.is_none() && sun.is_none() {
            return Err(LightingLoadError::Nothing {
                path: path.to_path_buf(),
            });
        }
        Ok(LightingRadiance { environment, sun })
    }
}

impl SunRadiance {
    /// The unit vector toward the sun.
    pub fn unit_direction(&self) -> [f32; 3] {
        let len = self.direction.iter().map(|c| c * c).sum::<f32>().sqrt();
        self.direction.map(|c| c / len)
    }
}

fn sun_radiance(s: &SunSection) -> Result<SunRadiance, LightingValueError> {
    let direction = s.direction.map(|c| c as f32);
    let radiance = s.radiance.map(|c| c as f32);
    let diameter = s.angular_diameter_deg as f32;
    check_sun(direction, radiance, diameter)?;
    Ok(SunRadiance {
        direction,
        radiance,
        angular_diameter_deg: diameter,
        solid_angle: 2.0 * std::f64::consts::PI * disk_one_minus_cos(diameter as f64),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_the_documented_layout_and_reads_it_back() {
        let f = LightingFile {
            environment: Some(EnvironmentSection {
                map: "noon_sky.exr".into(),
                scale: 1.0,
            }),
            sun: Some(SunSection {
                direction: crate::f32_decimals([0.0, 0.6, 0.8]),
                radiance: [60000.0, 57000.5, 0.1],
                angular_diameter_deg: 0.53,
            }),
        };
        let text = f.to_toml(&[]).unwrap();
        assert_eq!(
            text,
            "[environment]\nmap = \"noon_sky.exr\"\nscale = 1.0\n\n[sun]\ndirection = [0.0, 0.6, 0.8]\nradiance = [60000.0, 57000.5, 0.1]\nangular_diameter_deg = 0.53\n"
        );
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("noon.toml");
        f.write(&p, &["written by a test"]).unwrap();
        let back = LightingFile::read(&p).unwrap();
        assert_eq!(back, f);
        assert!(std::fs::read_to_string(&p)
            .unwrap()
            .starts_with("# written by a test\n\n[environment]\n"));
    }

    #[test]
    fn defaults_integers_and_errors_that_name_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("sun.toml");
        std::fs::write(&p, "[sun]\ndirection = [0, 0, 1]\nradiance = [1, 2, 3]\n").unwrap();
        let f = LightingFile::read(&p).unwrap();
        let s = f.sun.unwrap();
        assert_eq!(s.direction, [0.0, 0.0, 1.0]);
        assert_eq!(s.angular_diameter_deg, 0.53);
        assert!(f.environment.is_none());
        std::fs::write(&p, "[environment]\nmap = \"m.exr\"\nscal = 2\n").unwrap();
        let e = LightingFile::read(&p).unwrap_err();
        let msg = e.to_string();
        assert!(
            msg.contains("sun.toml")
                && msg.contains("not a valid lighting file")
                && msg.contains("scal"),
            "{msg}"
        );
        assert!(
            std::error::Error::source(&e).is_some(),
            "the TOML error is kept"
        );
        let e = LightingFile::read(&dir.path().join("none.toml"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("none.toml") && e.contains("cannot read lighting file"),
            "{e}"
        );
    }

    #[test]
    fn the_light_of_a_file_is_read_scaled_and_checked() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("maps")).unwrap();
        let mut map = HdrImage::new(4, 2);
        map.set(3, 1, [1.0, 2.0, 4.0]);
        igi_imaging::write_exr(&dir.path().join("maps/sky.exr"), &map).unwrap();
        let p = dir.path().join("l.toml");
        std::fs::write(
            &p,
            "[environment]\nmap = \"maps/sky.exr\"\nscale = 0.5\n[sun]\ndirection = [0, 0, 2]\nradiance = [10, 20, 30]\n",
        )
        .unwrap();
        let r = LightingRadiance::load(&p).unwrap();
        let (w, h, texels) = r.environment.unwrap();
        assert_eq!((w, h), (4, 2));
        assert_eq!(texels[7], [0.5, 1.0, 2.0]);
        let sun = r.sun.unwrap();
        assert_eq!(sun.unit_direction(), [0.0, 0.0, 1.0]);
        let half = 0.53f64.to_radians() / 2.0;
        let omega = 2.0 * std::f64::consts::PI * (1.0 - half.cos());
        assert!(
            (sun.solid_angle - omega).abs() < 1e-6 * omega,
            "the diameter passes through f32"
        );
        // errors name the file and what is wrong
        std::fs::write(&p, "[sun]\ndirection = [0, 0, 0]\nradiance = [1, 1, 1]\n").unwrap();
        let e = LightingRadiance::load(&p).unwrap_err().to_string();
        assert!(e.contains("l.toml: [sun]: sun direction"), "{e}");
        std::fs::write(&p, "[environment]\nmap = \"maps/sky.exr\"\nscale = -1\n").unwrap();
        let e = LightingRadiance::load(&p).unwrap_err().to_string();
        assert!(
            e.contains("l.toml") && e.contains("sky.exr") && e.contains("scale -1"),
            "{e}"
        );
        std::fs::write(&p, "").unwrap();
        let e = LightingRadiance::load(&p).unwrap_err().to_string();
        assert!(e.contains("names neither"), "{e}");
        assert_eq!(
            scaled_radiance(&map, 2.0).unwrap()[7],
            [2.0, 4.0, 8.0],
            "scale multiplies"
        );
        let mut bad = map.clone();
        bad.set(1, 0, [f32::INFINITY, 0.0, 0.0]);
        assert!(matches!(
            scaled_radiance(&bad, 1.0),
            Err(LightingValueError::MapPixel { row: 0, col: 1, .. })
        ));
    }
}
