//! The survey file `survey.toml` (`docs/FORMATS.md`, "Survey folder", "Site location and photo
//! time", "Reference targets"): the site, the photographs with their cameras and lighting,
//! reference targets of known albedo, optional BRDF samples, and igi's extensions (a prepared
//! site, probe captures in place of lighting files, camera radiometry).
//!
//! ```toml
//! [site]
//! meshes = ["geometry/ground.ply", "geometry/block.ply"]   # or mesh = "...", or prepared = "site.igi"
//! latitude_deg = 37.9715        # optional, WGS84, with longitude_deg (both or neither)
//! longitude_deg = 23.7267
//! north = [0.0, 1.0, 0.0]       # optional: world direction of true north (default +Y)
//!
//! [[photo]]
//! id = "east-0930"
//! image = "photos/east-0930.exr"
//! camera = "cameras/east-0930.json"
//! time = "2026-06-21T09:30:00+03:00"     # optional: RFC 3339 with its UTC offset
//! lighting = "lighting/east-0930.toml"   # or a [photo.probe] capture, or neither
//!
//! [[reference]]                  # optional, any number: a surface of known diffuse albedo
//! center = [1.0, 2.0, 0.0]
//! normal = [0.0, 0.0, 1.0]
//! radius = 0.15
//! albedo = [0.18, 0.18, 0.18]
//! ```
//! Every key of every section is checked: unknown keys are refused. Reading checks the types
//! only; [`SurveyFile::check_site_and_references`] checks the values of the site location, the
//! photo times (read with [`PhotoTime`]) and the reference targets, each error naming the file
//! and the key. Whether each photo has a source of light (a lighting file, a probe, or a time
//! from the survey or its EXIF) is for the reader of the photos to decide, not this layer.
//! A `time` may also be written as a bare TOML date-time (`time = 2026-06-21T09:30:00+03:00`);
//! it is kept as text and written back as a string.

use crate::time::{PhotoTime, TimeProblem};
use crate::{FileKind, FormatsError, TomlFile};
use serde::{Deserialize, Deserializer, Serialize};
use std::path::{Path, PathBuf};

/// A survey file as written (paths relative to its folder).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SurveyFile {
    pub site: SiteSection,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub brdf: Option<BrdfSection>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radiometry: Option<RadiometrySection>,
    #[serde(default)]
    pub photo: Vec<PhotoEntry>,
    /// `[[reference]]`: surfaces of known diffuse albedo seen in the photos.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub reference: Vec<ReferenceTarget>,
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
    /// WGS84 latitude in degrees, north positive (given with `longitude_deg`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub latitude_deg: Option<f64>,
    /// WGS84 longitude in degrees, east positive (given with `latitude_deg`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub longitude_deg: Option<f64>,
    /// The world direction of true north (horizontal, any length); [`DEFAULT_NORTH`] if absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub north: Option<[f64; 3]>,
}

/// True north when `[site]` does not say: +Y (so x points east, y north, z up).
pub const DEFAULT_NORTH: [f64; 3] = [0.0, 1.0, 0.0];

/// How far from horizontal `north` may point: |z| at most this fraction of its length.
pub const NORTH_MAX_TILT: f64 = 1e-3;

impl SiteSection {
    /// `(latitude_deg, longitude_deg)` when both are given.
    pub fn location(&self) -> Option<(f64, f64)> {
        self.latitude_deg.zip(self.longitude_deg)
    }

    /// `north` as written, or [`DEFAULT_NORTH`].
    pub fn north_or_default(&self) -> [f64; 3] {
        self.north.unwrap_or(DEFAULT_NORTH)
    }
}

/// `[[photo]]`: one photograph, its camera and its lighting (a file, a probe capture, or the
/// sun and sky of its time and the site's place).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PhotoEntry {
    pub id: String,
    pub image: PathBuf,
    pub camera: PathBuf,
    /// When the photo was taken: RFC 3339 with its UTC offset, as written (read it with
    /// [`PhotoEntry::photo_time`]).
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "time_text"
    )]
    pub time: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lighting: Option<PathBuf>,
    /// The photo's exposure relative to the survey's radiometric scale (an igi extension,
    /// docs/FORMATS.md Part 2): its linear pixel values are divided by it when it is loaded, so
    /// photographs taken at different settings share one scale (from EXIF: exposure time x
    /// ISO / 100 / f-number^2, `igi_imaging::exif::PhotoExif::exposure`). Positive; 1 if absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub exposure: Option<f64>,
    /// The camera body that took the photo (an igi extension, docs/FORMATS.md Part 2; from
    /// EXIF: make, model and serial number). Photos of one body share its radiometric
    /// calibration; where light is estimated, each body but the first gets one exposure
    /// factor fitted (docs/SKY.md). Absent: the survey's one unnamed body.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub body: Option<String>,
    /// The camera radiometry applied to this photo (overrides `[radiometry]`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radiometry: Option<PathBuf>,
    /// An 8-bit photo's camera response (an igi extension): the CSV `igi hdr merge
    /// --response-out` writes, through which its codes are made linear (overrides
    /// `[radiometry] response`; not with `transfer`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub response: Option<PathBuf>,
    /// How the photo's stored values become linear when it has no `response` (an igi
    /// extension): `"srgb"` or `"linear"`; if absent, sRGB for 8-bit files and linear for
    /// 16-bit and float ones (docs/IMAGING.md, "Linearising photographs").
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub transfer: Option<PhotoTransfer>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub probe: Option<ProbeEntry>,
}

impl PhotoEntry {
    /// The photo's `time` read as an instant, or `None` when it has none.
    pub fn photo_time(&self) -> Option<Result<PhotoTime, TimeProblem>> {
        self.time.as_deref().map(PhotoTime::parse_rfc3339)
    }
}

/// A `time` written as a string, or as a bare TOML date-time (kept as its RFC 3339 text).
fn time_text<'de, D: Deserializer<'de>>(d: D) -> Result<Option<String>, D::Error> {
    struct Text;
    impl<'de> serde::de::Visitor<'de> for Text {
        type Value = String;
        fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
            f.write_str("an RFC 3339 time with its UTC offset, e.g. \"2026-06-21T09:30:00+03:00\"")
        }
        fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<String, E> {
            Ok(v.to_string())
        }
        fn visit_map<A: serde::de::MapAccess<'de>>(self, map: A) -> Result<String, A::Error> {
            let d = serde::de::value::MapAccessDeserializer::new(map);
            Ok(toml::value::Datetime::deserialize(d)?.to_string())
        }
    }
    d.deserialize_any(Text).map(Some)
}

/// `[[reference]]`: a disc of known diffuse albedo on a surface seen in the photos.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReferenceTarget {
    /// A point on the surface (world, metres).
    pub center: [f64; 3],
    /// Its outward normal (any length).
    pub normal: [f64; 3],
    /// Metres: the disc around `center` on the surface that has this albedo.
    pub radius: f64,
    /// Linear diffuse albedo, each channel in [0, 1].
    pub albedo: [f64; 3],
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

/// A photo's `transfer`: how its stored values become linear.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PhotoTransfer {
    /// Decode the sRGB curve (8- or 16-bit files).
    Srgb,
    /// The stored values are linear (`value / max code`).
    Linear,
}

/// `[radiometry]`: the camera radiometry file applied to every photograph on load, and the
/// camera response through which every 8-bit photograph without its own `response` or
/// `transfer` is made linear.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RadiometrySection {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera: Option<PathBuf>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub response: Option<PathBuf>,
}

impl TomlFile for SurveyFile {
    const KIND: FileKind = FileKind::Survey;
}

/// A value of a survey file that cannot mean what its key says (the message names the key).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SurveyProblem {
    /// `latitude_deg` or `longitude_deg` outside its range (or not a number).
    #[error("[site] {key} = {value} is out of range [{min}, {max}]")]
    OutOfRange {
        key: &'static str,
        value: f64,
        min: f64,
        max: f64,
    },
    /// One of `latitude_deg` and `longitude_deg` without the other.
    #[error(
        "[site] gives {given} without {missing}: give latitude_deg and longitude_deg together, \
         or neither"
    )]
    HalfLocation {
        given: &'static str,
        missing: &'static str,
    },
    /// `north` not finite, zero, or not horizontal.
    #[error("[site] north = {value:?} {why}")]
    North { value: [f64; 3], why: String },
    /// A photo's `time` that does not read as an instant.
    #[error("[[photo]] `{id}` time = {time:?}: {source}")]
    PhotoTime {
        id: String,
        time: String,
        #[source]
        source: TimeProblem,
    },
    /// A photo's `exposure` that is not a positive finite number.
    #[error("[[photo]] `{id}` exposure = {value} is not a positive number")]
    Exposure { id: String, value: f64 },
    /// A value of a `[[reference]]` target (counted from 1 in file order).
    #[error("[[reference]] {number}: {key} = {value} {why}")]
    Reference {
        number: usize,
        key: &'static str,
        value: String,
        why: &'static str,
    },
}

impl SurveyFile {
    /// Checks the values the site location, the photo times and the reference targets must
    /// have: latitude in [-90, 90] and longitude in [-180, 180], given together or not at all;
    /// `north` finite, non-zero and horizontal (|z| at most [`NORTH_MAX_TILT`] of its length);
    /// every photo `time` an RFC 3339 instant with its UTC offset, every `exposure` positive and
    /// finite; each reference's `center`
    /// finite, `normal` finite and non-zero, `radius` finite and > 0, `albedo` in [0, 1].
    /// `file` names the survey in errors. A photo with neither lighting nor a time is not an
    /// error here (its time may come from its EXIF).
    pub fn check_site_and_references(&self, file: &Path) -> Result<(), FormatsError> {
        let err = |problem| FormatsError::SurveyValue {
            path: file.to_path_buf(),
            problem: Box::new(problem),
        };
        check_site(&self.site).map_err(err)?;
        for p in &self.photo {
            if let (Some(time), Some(Err(source))) = (&p.time, p.photo_time()) {
                return Err(err(SurveyProblem::PhotoTime {
                    id: p.id.clone(),
                    time: time.clone(),
                    source,
                }));
            }
            if let Some(value) = p.exposure.filter(|e| !(e.is_finite() && *e > 0.0)) {
                return Err(err(SurveyProblem::Exposure {
                    id: p.id.clone(),
                    value,
                }));
            }
        }
        for (i, r) in self.reference.iter().enumerate() {
            check_reference(i + 1, r).map_err(err)?;
        }
        Ok(())
    }
}

fn check_site(site: &SiteSection) -> Result<(), SurveyProblem> {
    let range = |key, value: Option<f64>, max: f64| match value {
        Some(v) if !(-max..=max).contains(&v) => Err(SurveyProblem::OutOfRange {
            key,
            value: v,
            min: -max,
            max,
        }),
        _ => Ok(()),
    };
    range("latitude_deg", site.latitude_deg, 90.0)?;
    range("longitude_deg", site.longitude_deg, 180.0)?;
    match (site.latitude_deg, site.longitude_deg) {
        (Some(_), None) => Err(SurveyProblem::HalfLocation {
            given: "latitude_deg",
            missing: "longitude_deg",
        }),
        (None, Some(_)) => Err(SurveyProblem::HalfLocation {
            given: "longitude_deg",
            missing: "latitude_deg",
        }),
        _ => Ok(()),
    }?;
    if let Some(n) = site.north {
        let len = norm(n);
        let why = if !n.iter().all(|x| x.is_finite()) {
            Some("is not finite".to_string())
        } else if len == 0.0 {
            Some("is the zero vector: it gives no direction".to_string())
        } else if n[2].abs() > NORTH_MAX_TILT * len {
            Some(format!(
                "is not horizontal (|z| = {} is more than {NORTH_MAX_TILT:e} of its length {len}): \
                 true north lies in the ground plane, and z is up",
                n[2].abs()
            ))
        } else {
            None
        };
        if let Some(why) = why {
            return Err(SurveyProblem::North { value: n, why });
        }
    }
    Ok(())
}

fn check_reference(number: usize, r: &ReferenceTarget) -> Result<(), SurveyProblem> {
    let bad = |key, value: String, why| {
        Err(SurveyProblem::Reference {
            number,
            key,
            value,
            why,
        })
    };
    let finite = |v: [f64; 3]| v.iter().all(|x| x.is_finite());
    if !finite(r.center) {
        return bad("center", format!("{:?}", r.center), "is not finite");
    }
    if !finite(r.normal) || norm(r.normal) == 0.0 {
        let why = "must be a finite non-zero vector";
        return bad("normal", format!("{:?}", r.normal), why);
    }
    if !(r.radius.is_finite() && r.radius > 0.0) {
        return bad(
            "radius",
            r.radius.to_string(),
            "must be finite and > 0 (metres)",
        );
    }
    if !r.albedo.iter().all(|a| (0.0..=1.0).contains(a)) {
        let why = "must be in [0, 1] in each channel (a linear diffuse albedo)";
        return bad("albedo", format!("{:?}", r.albedo), why);
    }
    Ok(())
}

fn norm(v: [f64; 3]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn photo(id: &str, lighting: &str) -> PhotoEntry {
        PhotoEntry {
            id: id.into(),
            image: format!("photos/{id}.exr").into(),
            camera: format!("cameras/{id}.json").into(),
            time: None,
            lighting: Some(format!("lighting/{lighting}.toml").into()),
            exposure: None,
            body: None,
            radiometry: None,
            response: None,
            transfer: None,
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
            reference: Vec::new(),
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
        p.response = Some("camera_response.csv".into());
        p.transfer = Some(PhotoTransfer::Srgb);
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
                camera: Some("radiometry.json".into()),
                response: Some("camera_response.csv".into()),
            }),
            photo: vec![p],
            reference: Vec::new(),
        };
        let text = f.to_toml(&[]).unwrap();
        assert_eq!(toml::from_str::<SurveyFile>(&text).unwrap(), f, "{text}");
        let e = toml::from_str::<SurveyFile>("[site]\nmesh = \"a.ply\"\ncolour = 1\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("colour"), "{e}");
    }

    const LOCATED: &str = r#"
[site]
mesh = "geometry/site.ply"
latitude_deg = 37.9715
longitude_deg = 23.7267
north = [0.0, 1.0, 0.0]

[[photo]]
id = "east-0930"
image = "photos/east-0930.exr"
camera = "cameras/east-0930.json"
time = "2026-06-21T09:30:00+03:00"

[[reference]]
center = [1.0, 2.0, 0.0]
normal = [0.0, 0.0, 1.0]
radius = 0.15
albedo = [0.18, 0.18, 0.18]
"#;

    fn located() -> SurveyFile {
        toml::from_str(LOCATED).unwrap()
    }

    /// The message of `check_site_and_references` on `f`, named `survey.toml`.
    fn problem(f: &SurveyFile) -> String {
        f.check_site_and_references(Path::new("survey.toml"))
            .unwrap_err()
            .to_string()
    }

    #[test]
    fn location_time_and_references_read_check_and_write_back() {
        let f = located();
        assert_eq!(f.site.location(), Some((37.9715, 23.7267)));
        assert_eq!(f.site.north_or_default(), [0.0, 1.0, 0.0]);
        let p = &f.photo[0];
        assert!(p.lighting.is_none() && p.probe.is_none());
        let t = p.photo_time().unwrap().unwrap();
        assert_eq!(t.unix_seconds(), 1_782_023_400);
        assert_eq!(t.to_rfc3339_utc(), "2026-06-21T06:30:00Z");
        assert_eq!(
            f.reference,
            vec![ReferenceTarget {
                center: [1.0, 2.0, 0.0],
                normal: [0.0, 0.0, 1.0],
                radius: 0.15,
                albedo: [0.18; 3],
            }]
        );
        f.check_site_and_references(Path::new("survey.toml"))
            .unwrap();
        // written in the documented order, and read back the same
        let text = f.to_toml(&[]).unwrap();
        assert_eq!(text.trim(), LOCATED.trim());
        assert_eq!(toml::from_str::<SurveyFile>(&text).unwrap(), f);
        // none of it is needed: a photo with neither lighting nor time is not refused here
        let mut bare = f.clone();
        bare.site = SiteSection {
            mesh: Some("geometry/site.ply".into()),
            ..SiteSection::default()
        };
        bare.photo[0].time = None;
        bare.reference.clear();
        assert_eq!(bare.site.location(), None);
        assert_eq!(bare.site.north_or_default(), DEFAULT_NORTH);
        assert_eq!(bare.photo[0].photo_time(), None);
        bare.check_site_and_references(Path::new("survey.toml"))
            .unwrap();
        // unknown keys of a reference are refused
        let e = toml::from_str::<SurveyFile>(&LOCATED.replace("radius", "size"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("size"), "{e}");
    }

    #[test]
    fn a_bare_toml_datetime_is_kept_as_its_text() {
        let text = LOCATED.replace("\"2026-06-21T09:30:00+03:00\"", "2026-06-21T09:30:00+03:00");
        let f: SurveyFile = toml::from_str(&text).unwrap();
        assert_eq!(f, located());
        // a local date-time reads, and the check says its offset is missing
        let text = LOCATED.replace("\"2026-06-21T09:30:00+03:00\"", "2026-06-21T09:30:00");
        let f: SurveyFile = toml::from_str(&text).unwrap();
        assert_eq!(f.photo[0].time.as_deref(), Some("2026-06-21T09:30:00"));
        assert!(problem(&f).contains("the UTC offset is missing"));
        let e =
            toml::from_str::<SurveyFile>(&LOCATED.replace("\"2026-06-21T09:30:00+03:00\"", "930"))
                .unwrap_err()
                .to_string();
        assert!(e.contains("RFC 3339"), "{e}");
    }

    #[test]
    fn site_values_are_checked_naming_file_and_key() {
        let with = |edit: &dyn Fn(&mut SiteSection)| {
            let mut f = located();
            edit(&mut f.site);
            f
        };
        assert_eq!(
            problem(&with(&|s| s.latitude_deg = Some(95.0))),
            "survey.toml: [site] latitude_deg = 95 is out of range [-90, 90]"
        );
        assert_eq!(
            problem(&with(&|s| s.longitude_deg = Some(-180.5))),
            "survey.toml: [site] longitude_deg = -180.5 is out of range [-180, 180]"
        );
        assert!(problem(&with(&|s| s.latitude_deg = Some(f64::NAN))).contains("latitude_deg = NaN"));
        // the poles and the antimeridian are in range
        let f = with(&|s| (s.latitude_deg, s.longitude_deg) = (Some(-90.0), Some(180.0)));
        f.check_site_and_references(Path::new("s")).unwrap();
        assert_eq!(
            problem(&with(&|s| s.longitude_deg = None)),
            "survey.toml: [site] gives latitude_deg without longitude_deg: give latitude_deg and longitude_deg together, or neither"
        );
        assert!(problem(&with(&|s| s.latitude_deg = None))
            .contains("gives longitude_deg without latitude_deg"));
        assert_eq!(
            problem(&with(&|s| s.north = Some([0.0, 0.0, 0.0]))),
            "survey.toml: [site] north = [0.0, 0.0, 0.0] is the zero vector: it gives no direction"
        );
        assert!(
            problem(&with(&|s| s.north = Some([f64::INFINITY, 1.0, 0.0])))
                .contains("is not finite")
        );
        let e = problem(&with(&|s| s.north = Some([0.0, 1.0, 0.5])));
        assert!(
            e.starts_with("survey.toml: [site] north = [0.0, 1.0, 0.5] is not horizontal"),
            "{e}"
        );
        // a tilt within 1e-3 of the length is horizontal; any length is fine
        let f = with(&|s| s.north = Some([-3.0, 4.0, 0.004]));
        f.check_site_and_references(Path::new("s")).unwrap();
        assert!(problem(&with(&|s| s.north = Some([-3.0, 4.0, 0.006]))).contains("not horizontal"));
    }

    #[test]
    fn photo_times_are_checked_naming_the_photo() {
        let mut f = located();
        f.photo.push(photo("west-1400", "x"));
        f.photo[1].time = Some("2026-06-21T14:00:00".into());
        assert_eq!(
            problem(&f),
            "survey.toml: [[photo]] `west-1400` time = \"2026-06-21T14:00:00\": the UTC offset is \
             missing (end the time with `Z` for UTC or an offset such as `+03:00`): a local time \
             alone does not say when the photo was taken"
        );
        f.photo[1].time = Some("2026-02-30T14:00:00Z".into());
        assert_eq!(
            problem(&f),
            "survey.toml: [[photo]] `west-1400` time = \"2026-02-30T14:00:00Z\": 2026-02 has 28 days, not 30"
        );
        let e = f
            .check_site_and_references(Path::new("survey.toml"))
            .unwrap_err();
        let FormatsError::SurveyValue { problem, .. } = &e else {
            panic!("{e:?}")
        };
        assert!(matches!(
            **problem,
            SurveyProblem::PhotoTime {
                source: TimeProblem::Day { day: 30, .. },
                ..
            }
        ));
        f.photo[1].time = Some("2026-06-21T14:00:00+02:00".into());
        f.check_site_and_references(Path::new("survey.toml"))
            .unwrap();
    }

    #[test]
    fn reference_values_are_checked_naming_the_target() {
        let with = |edit: &dyn Fn(&mut ReferenceTarget)| {
            let mut f = located();
            f.reference.push(f.reference[0].clone());
            edit(&mut f.reference[1]);
            problem(&f)
        };
        assert_eq!(
            with(&|r| r.radius = 0.0),
            "survey.toml: [[reference]] 2: radius = 0 must be finite and > 0 (metres)"
        );
        assert!(with(&|r| r.radius = f64::INFINITY).contains("radius = inf must be"));
        assert_eq!(
            with(&|r| r.normal = [0.0; 3]),
            "survey.toml: [[reference]] 2: normal = [0.0, 0.0, 0.0] must be a finite non-zero vector"
        );
        assert!(with(&|r| r.normal = [f64::NAN, 0.0, 1.0]).contains("normal = [NaN, 0.0, 1.0]"));
        assert_eq!(
            with(&|r| r.albedo = [0.5, 1.2, 0.5]),
            "survey.toml: [[reference]] 2: albedo = [0.5, 1.2, 0.5] must be in [0, 1] in each channel (a linear diffuse albedo)"
        );
        assert!(with(&|r| r.albedo = [-0.1, 0.5, 0.5]).contains("albedo"));
        assert!(with(&|r| r.albedo = [f64::NAN, 0.5, 0.5]).contains("albedo"));
        assert_eq!(
            with(&|r| r.center = [0.0, f64::NAN, 0.0]),
            "survey.toml: [[reference]] 2: center = [0.0, NaN, 0.0] is not finite"
        );
        // albedo 0 and 1 are allowed
        let mut f = located();
        f.reference[0].albedo = [0.0, 1.0, 0.5];
        f.check_site_and_references(Path::new("s")).unwrap();
    }
}
