//! The survey file `survey.toml` (`docs/FORMATS.md`, "Survey folder"): the site, the
//! photographs with their cameras and lighting, optional BRDF samples, and igi's extensions
//! (a prepared site, probe captures in place of lighting files, camera radiometry).
//!
//! ```toml
//! [site]
//! meshes = ["geometry/ground.ply", "geometry/block.ply"]   # or mesh = "...", or prepared = "site.igi"
//!
//! [[photo]]
//! id = "east-0930"
//! image = "photos/east-0930.exr"
//! camera = "cameras/east-0930.json"
//! lighting = "lighting/east-0930.toml"   # or a [photo.probe] capture
//! ```
//! Every key of every section is checked: unknown keys are refused.

use crate::{FileKind, TomlFile};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// A survey file as written (paths relative to its folder).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SurveyFile {
    pub site: SiteSection,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub brdf: Option<BrdfSection>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radiometry: Option<RadiometrySection>,
    #[serde(default)]
    pub photo: Vec<PhotoEntry>,
}

/// `[site]`: meshes (`mesh` and/or `meshes`) or a prepared site (`igi prepare` output).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SiteSection {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mesh: Option<PathBuf>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub prepared: Option<PathBuf>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub meshes: Vec<PathBuf>,
}

/// `[[photo]]`: one photograph, its camera and its lighting (a file or a probe capture).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PhotoEntry {
    pub id: String,
    pub image: PathBuf,
    pub camera: PathBuf,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lighting: Option<PathBuf>,
    /// The camera radiometry applied to this photo (overrides `[radiometry]`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radiometry: Option<PathBuf>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub probe: Option<ProbeEntry>,
}

/// `[photo.probe]`: a lighting-board capture in place of a lighting file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProbeEntry {
    pub image: PathBuf,
    pub camera: PathBuf,
    pub board: PathBuf,
}

/// `[brdf]`: hand-held BRDF samples (CSV).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BrdfSection {
    pub samples: PathBuf,
}

/// `[radiometry]`: the camera radiometry file applied to every photograph on load.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RadiometrySection {
    pub camera: PathBuf,
}

impl TomlFile for SurveyFile {
    const KIND: FileKind = FileKind::Survey;
}

#[cfg(test)]
mod tests {
    use super::*;

    fn photo(id: &str, lighting: &str) -> PhotoEntry {
        PhotoEntry {
            id: id.into(),
            image: format!("photos/{id}.exr").into(),
            camera: format!("cameras/{id}.json").into(),
            lighting: Some(format!("lighting/{lighting}.toml").into()),
            radiometry: None,
            probe: None,
        }
    }

    #[test]
    fn writes_the_synthetic_survey_layout() {
        let f = SurveyFile {
            site: SiteSection {
                meshes: vec!["geometry/ground.ply".into(), "geometry/block.ply".into()],
                ..SiteSection::default()
            },
            brdf: None,
            radiometry: None,
            photo: vec![photo("a", "sunny"), photo("b", "overcast")],
        };
        let text = f.to_toml(&[]).unwrap();
        assert_eq!(
            text,
            "[site]\nmeshes = [\"geometry/ground.ply\", \"geometry/block.ply\"]\n\n[[photo]]\nid = \"a\"\nimage = \"photos/a.exr\"\ncamera = \"cameras/a.json\"\nlighting = \"lighting/sunny.toml\"\n\n[[photo]]\nid = \"b\"\nimage = \"photos/b.exr\"\ncamera = \"cameras/b.json\"\nlighting = \"lighting/overcast.toml\"\n"
        );
        assert_eq!(toml::from_str::<SurveyFile>(&text).unwrap(), f);
    }

    #[test]
    fn extensions_round_trip_and_unknown_keys_are_refused() {
        let mut p = photo("p", "x");
        p.lighting = None;
        p.radiometry = Some("r.json".into());
        p.probe = Some(ProbeEntry {
            image: "probe.exr".into(),
            camera: "probe.json".into(),
            board: "board.json".into(),
        });
        let f = SurveyFile {
            site: SiteSection {
                prepared: Some("site.igi".into()),
                ..SiteSection::default()
            },
            brdf: Some(BrdfSection {
                samples: "brdf/samples.csv".into(),
            }),
            radiometry: Some(RadiometrySection {
                camera: "radiometry.json".into(),
            }),
            photo: vec![p],
        };
        let text = f.to_toml(&[]).unwrap();
        assert_eq!(toml::from_str::<SurveyFile>(&text).unwrap(), f, "{text}");
        let e = toml::from_str::<SurveyFile>("[site]\nmesh = \"a.ply\"\ncolour = 1\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("colour"), "{e}");
    }
}
