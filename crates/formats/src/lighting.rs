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

use crate::{FileKind, TomlFile};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

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
}
