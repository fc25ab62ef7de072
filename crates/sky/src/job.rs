//! `igi sky`: the lighting file of a place and time (docs/SKY.md, "Usage").
//!
//! [`write_sky`] takes a [`SkyRequest`] (the site from a survey's `[site]` or given directly,
//! an RFC 3339 time with its UTC offset, turbidity, ground albedo, map width) and writes a
//! contract lighting file (docs/FORMATS.md, "Lighting file"): the Hosek-Wilkie sky dome as a
//! lat-long EXR beside it (`[environment]`) and the sun's disk (`[sun]`), or with `overcast`
//! the CIE overcast sky alone. Everything is checked before the first byte is written; both
//! files are written atomically (the map first, so a lighting file never names a missing map).

use crate::{sun_direction, sun_position, CieOvercast, Refraction, Sky, SkyError};
use igi_formats::lighting::{EnvironmentSection, LightingFile};
use igi_formats::survey::{SurveyFile, DEFAULT_NORTH};
use igi_formats::time::{PhotoTime, TimeProblem};
use igi_formats::{FormatsError, TomlFile};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// The overcast sky's zenith radiance when none is given, per channel (docs/SKY.md units:
/// CIE-weighted W m^-2 sr^-1): about 4,100 cd m^-2 at the zenith and 10,000 lx on the ground,
/// a bright overcast day.
pub const DEFAULT_OVERCAST_ZENITH: f64 = 6.0;

/// Where the sky is wanted.
#[derive(Clone, Debug, PartialEq)]
pub enum Place {
    /// A survey folder (its `survey.toml`) or the file itself: `[site]` gives latitude,
    /// longitude and north.
    Survey {
        /// The folder or its `survey.toml`.
        path: PathBuf,
    },
    /// A site given directly.
    Site {
        /// Degrees, north positive, in [-90, 90].
        latitude_deg: f64,
        /// Degrees, east positive, in [-180, 180].
        longitude_deg: f64,
        /// True north as the world direction `(sin a, cos a, 0)`: degrees clockwise, seen
        /// from above, from +Y (0: north is +Y, the default).
        north_deg: f64,
    },
}

/// What `igi sky` is asked for.
#[derive(Clone, Debug, PartialEq)]
pub struct SkyRequest {
    pub place: Place,
    /// RFC 3339 with its UTC offset (e.g. `2026-06-21T17:30:00+02:00`).
    pub time: String,
    /// Atmospheric turbidity, 1 to 10.
    pub turbidity: f64,
    /// Ground albedo, 0 to 1 (grey).
    pub albedo: f64,
    /// Width of the lat-long map (its height is half, at least 1); at least 2.
    pub width: usize,
    /// Write the CIE overcast sky instead of the clear sky (no sun).
    pub overcast: bool,
    /// The overcast sky's zenith radiance (grey); [`DEFAULT_OVERCAST_ZENITH`] if absent.
    pub zenith_radiance: Option<f64>,
    /// The lighting file (`.toml`); the map is written beside it as `<stem>.exr`.
    pub output: PathBuf,
}

/// What was written.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SkyReport {
    pub lighting: PathBuf,
    pub map: PathBuf,
    /// `clear` or `overcast`.
    pub sky: &'static str,
    pub time_utc: String,
    pub latitude_deg: f64,
    pub longitude_deg: f64,
    pub sun_azimuth_deg: f64,
    pub sun_elevation_deg: f64,
    /// Unit world direction toward the sun (Z up).
    pub sun_direction: [f64; 3],
    /// The irradiance the sky dome (without the sun) gives a horizontal surface, per channel,
    /// integrated over the written map.
    pub sky_horizontal_irradiance: [f64; 3],
    /// The sun's irradiance on a horizontal surface (zero for the overcast sky).
    pub sun_horizontal_irradiance: [f64; 3],
}

/// Why `igi sky` wrote nothing.
#[derive(Debug, thiserror::Error)]
pub enum SkyJobError {
    #[error("--time {time:?}: {source}")]
    Time {
        time: String,
        #[source]
        source: TimeProblem,
    },
    #[error("{what} {value}: must be a finite number in [{min}, {max}]")]
    Range {
        what: String,
        value: f64,
        min: f64,
        max: f64,
    },
    #[error("--width {0}: the map must be at least 2 pixels wide")]
    Width(usize),
    #[error("{0}: has no survey.toml (give the survey folder or its survey.toml)")]
    NoSurvey(PathBuf),
    #[error("{0}: [site] has no latitude_deg and longitude_deg (docs/FORMATS.md, \"Site location and photo time\"); add them or give --site LAT,LON")]
    NoLocation(PathBuf),
    #[error(transparent)]
    Formats(#[from] FormatsError),
    #[error("the sun at {time} stands {elevation_deg:.2} deg below the horizon at latitude {latitude_deg} deg, longitude {longitude_deg} deg: the clear (Hosek-Wilkie) sky covers only a sun above the horizon; give --overcast for the CIE overcast sky, or a daytime --time")]
    BelowHorizon {
        time: String,
        elevation_deg: f64,
        latitude_deg: f64,
        longitude_deg: f64,
    },
    #[error("-o {0}: the lighting file must end in .toml")]
    OutputName(PathBuf),
    #[error("-o {0}: the folder does not exist")]
    OutputFolder(PathBuf),
    #[error(transparent)]
    Sky(#[from] SkyError),
    #[error("writing the sky map: {0}")]
    Map(#[from] igi_imaging::ImagingError),
}

fn check_range(what: &str, value: f64, min: f64, max: f64) -> Result<(), SkyJobError> {
    if value.is_finite() && value >= min && value <= max {
        Ok(())
    } else {
        Err(SkyJobError::Range {
            what: what.into(),
            value,
            min,
            max,
        })
    }
}

/// The survey file of a folder or the file itself.
fn survey_file(p: &Path) -> Result<PathBuf, SkyJobError> {
    let f = if p.is_dir() {
        p.join("survey.toml")
    } else {
        p.to_path_buf()
    };
    if f.is_file() {
        Ok(f)
    } else {
        Err(SkyJobError::NoSurvey(p.to_path_buf()))
    }
}

/// `(latitude, longitude, north)` of the request's place.
fn site(place: &Place) -> Result<(f64, f64, [f64; 3]), SkyJobError> {
    match place {
        Place::Survey { path: p } => {
            let file = survey_file(p)?;
            let s = SurveyFile::read(&file)?;
            let (lat, lon) = s
                .site
                .location()
                .ok_or_else(|| SkyJobError::NoLocation(file.clone()))?;
            let name = file.display();
            check_range(&format!("{name}: [site] latitude_deg"), lat, -90.0, 90.0)?;
            check_range(&format!("{name}: [site] longitude_deg"), lon, -180.0, 180.0)?;
            Ok((lat, lon, s.site.north.unwrap_or(DEFAULT_NORTH)))
        }
        Place::Site {
            latitude_deg,
            longitude_deg,
            north_deg,
        } => {
            check_range("--site latitude", *latitude_deg, -90.0, 90.0)?;
            check_range("--site longitude", *longitude_deg, -180.0, 180.0)?;
            check_range("--site north", *north_deg, -360.0, 360.0)?;
            let a = north_deg.to_radians();
            Ok((*latitude_deg, *longitude_deg, [a.sin(), a.cos(), 0.0]))
        }
    }
}

/// The irradiance a lat-long map gives a horizontal surface facing up (sum of radiance times
/// cos theta times pixel solid angle over the upper rows).
pub fn map_horizontal_irradiance(img: &igi_imaging::HdrImage) -> [f64; 3] {
    let (w, h) = (img.width, img.height);
    let mut e = [0.0f64; 3];
    for i in 0..h {
        let omega = igi_imaging::latlong::pixel_solid_angle(i, w, h) as f64;
        for j in 0..w {
            let cos = igi_imaging::latlong::pixel_center_direction(i, j, w, h).z as f64;
            if cos <= 0.0 {
                continue;
            }
            let p = img.pixels[i * w + j];
            for c in 0..3 {
                e[c] += p[c] as f64 * cos * omega;
            }
        }
    }
    e
}

/// Writes the lighting file of `req` and its map; see the module documentation.
pub fn write_sky(req: &SkyRequest) -> Result<SkyReport, SkyJobError> {
    // everything checked first
    let time = PhotoTime::parse_rfc3339(&req.time).map_err(|source| SkyJobError::Time {
        time: req.time.clone(),
        source,
    })?;
    check_range("--turbidity", req.turbidity, 1.0, 10.0)?;
    check_range("--albedo", req.albedo, 0.0, 1.0)?;
    if req.width < 2 {
        return Err(SkyJobError::Width(req.width));
    }
    if let Some(z) = req.zenith_radiance {
        check_range("--zenith-radiance", z, 0.0, 1e9)?;
    }
    if req.output.extension().and_then(|e| e.to_str()) != Some("toml") {
        return Err(SkyJobError::OutputName(req.output.clone()));
    }
    let folder = match req.output.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    if !folder.is_dir() {
        return Err(SkyJobError::OutputFolder(req.output.clone()));
    }
    let (lat, lon, north) = site(&req.place)?;
    let position = sun_position(&time, lat, lon, 0.0, Refraction::STANDARD)?;
    let direction = sun_direction(position, north)?;
    let (w, h) = (req.width, (req.width / 2).max(1));
    let (map, sun) = if req.overcast {
        let z = req.zenith_radiance.unwrap_or(DEFAULT_OVERCAST_ZENITH);
        (CieOvercast::new([z; 3])?.latlong(w, h)?, None)
    } else {
        if position.elevation_deg() < 0.0 {
            return Err(SkyJobError::BelowHorizon {
                time: time.to_rfc3339(),
                elevation_deg: -position.elevation_deg(),
                latitude_deg: lat,
                longitude_deg: lon,
            });
        }
        let sky = Sky::new(req.turbidity, [req.albedo; 3], direction)?;
        (sky.latlong(w, h)?, Some(sky.sun_disk()))
    };
    let stem = req
        .output
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "sky".into());
    let map_name = format!("{stem}.exr");
    let map_path = req.output.with_file_name(&map_name);
    let file = LightingFile {
        environment: Some(EnvironmentSection {
            map: map_name.into(),
            scale: 1.0,
        }),
        sun: sun.map(|s| s.to_section()),
    };
    let header = format!(
        "written by igi sky: {} sky at {} (latitude {lat} deg, longitude {lon} deg), sun azimuth {:.3} deg, elevation {:.3} deg",
        if req.overcast { "CIE overcast" } else { "Hosek-Wilkie clear" },
        time.to_rfc3339(),
        position.azimuth_deg,
        position.elevation_deg()
    );
    igi_imaging::io::write_exr(&map_path, &map)?;
    file.write(&req.output, &[&header])?;
    let sun_h = sun.map_or([0.0; 3], |s| {
        s.irradiance().map(|e| e * direction.z.max(0.0))
    });
    Ok(SkyReport {
        lighting: req.output.clone(),
        map: map_path,
        sky: if req.overcast { "overcast" } else { "clear" },
        time_utc: time.to_rfc3339_utc(),
        latitude_deg: lat,
        longitude_deg: lon,
        sun_azimuth_deg: position.azimuth_deg,
        sun_elevation_deg: position.elevation_deg(),
        sun_direction: direction.to_array(),
        sky_horizontal_irradiance: map_horizontal_irradiance(&map),
        sun_horizontal_irradiance: sun_h,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn request(out: &Path) -> SkyRequest {
        SkyRequest {
            place: Place::Site {
                latitude_deg: 48.85,
                longitude_deg: 2.35,
                north_deg: 0.0,
            },
            time: "2026-06-21T12:00:00Z".into(),
            turbidity: 3.0,
            albedo: 0.2,
            width: 32,
            overcast: false,
            zenith_radiance: None,
            output: out.to_path_buf(),
        }
    }

    #[test]
    fn north_deg_turns_the_sun_about_the_zenith() {
        let dir = tempfile::tempdir().unwrap();
        let mut r = request(&dir.path().join("a.toml"));
        let a = write_sky(&r).unwrap();
        r.place = Place::Site {
            latitude_deg: 48.85,
            longitude_deg: 2.35,
            north_deg: 90.0,
        };
        r.output = dir.path().join("b.toml");
        let b = write_sky(&r).unwrap();
        // north +X: what was (x, y) with north +Y is now (y, -x)
        let (da, db) = (a.sun_direction, b.sun_direction);
        assert!((db[0] - da[1]).abs() < 1e-12, "{da:?} {db:?}");
        assert!((db[1] + da[0]).abs() < 1e-12, "{da:?} {db:?}");
        assert!((db[2] - da[2]).abs() < 1e-12);
        // noon in Paris (10:00 UTC is 12:00 CEST; 12:00 UTC is after solar noon): sun in the
        // south-west, 60-65 deg up
        assert!(
            a.sun_elevation_deg > 55.0 && a.sun_elevation_deg < 66.0,
            "{a:?}"
        );
        assert!(da[0] < 0.0 && da[1] < 0.0, "{da:?}");
    }

    #[test]
    fn every_option_is_checked_before_writing() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("l.toml");
        type Change<'a> = Box<dyn Fn(&mut SkyRequest) + 'a>;
        let bad: Vec<(Change, &str)> = vec![
            (Box::new(|r| r.time = "2026-06-21 12:00".into()), "--time"),
            (Box::new(|r| r.turbidity = 0.5), "--turbidity"),
            (Box::new(|r| r.albedo = f64::NAN), "--albedo"),
            (Box::new(|r| r.width = 1), "--width"),
            (Box::new(|r| r.output = dir.path().join("l.txt")), ".toml"),
            (
                Box::new(|r| r.output = dir.path().join("none/l.toml")),
                "does not exist",
            ),
            (
                Box::new(|r| {
                    r.place = Place::Site {
                        latitude_deg: 0.0,
                        longitude_deg: 181.0,
                        north_deg: 0.0,
                    }
                }),
                "--site longitude",
            ),
            (
                Box::new(|r| {
                    r.place = Place::Survey {
                        path: r.output.with_file_name("missing"),
                    }
                }),
                "survey.toml",
            ),
        ];
        for (change, needle) in bad {
            let mut r = request(&out);
            change(&mut r);
            let e = write_sky(&r).unwrap_err().to_string();
            assert!(e.contains(needle), "{e}");
            assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0, "{e}");
        }
    }
}
