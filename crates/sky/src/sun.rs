//! The sun's position for a time and place, and its direction in igi's world frame.
//!
//! [`sun_position`] is NREL's Solar Position Algorithm (Reda and Andreas 2004, stated accuracy
//! 0.0003 degrees for years -2000 to 6000) as the `solar-positioning` crate implements it: the
//! topocentric azimuth (degrees from true north, clockwise seen from above) and zenith angle of
//! the sun's centre, corrected for atmospheric refraction at the given pressure and
//! temperature ([`Refraction`]). Delta T (terrestrial minus universal time) comes from the
//! crate's polynomial estimate for the date (Espenak and Meeus), within a second or two of the
//! observed value for present dates; a second of time moves the sun by at most 0.004 degrees.
//!
//! [`sun_direction`] turns a position into the unit vector toward the sun in the world frame of
//! docs/FORMATS.md: Z up and true north along the site's `north` (default +Y), so east is
//! north x up.

use crate::SkyError;
use glam::DVec3;
use igi_formats::time::PhotoTime;
use solar_positioning::time::JulianDate;
use solar_positioning::{delta_t, Location, RefractionCorrection, SolarPositions};

/// Atmospheric refraction of the sun's apparent elevation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Refraction {
    /// None: the geometric position.
    None,
    /// The standard atmosphere's refraction at this pressure (hPa) and temperature (Celsius).
    Atmosphere {
        pressure_hpa: f64,
        temperature_c: f64,
    },
}

impl Refraction {
    /// The standard atmosphere at sea level: 1013.25 hPa, 15 degrees Celsius.
    pub const STANDARD: Refraction = Refraction::Atmosphere {
        pressure_hpa: 1013.25,
        temperature_c: 15.0,
    };
}

/// Where the sun's centre stands, seen from a place on the ground.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SunPosition {
    /// Degrees from true north, clockwise seen from above (90: east), in [0, 360).
    pub azimuth_deg: f64,
    /// Degrees from the zenith (90: on the horizon; above 90: below it).
    pub zenith_deg: f64,
}

impl SunPosition {
    /// Degrees above the horizon.
    pub fn elevation_deg(&self) -> f64 {
        90.0 - self.zenith_deg
    }
}

/// The sun's topocentric position at `time` for an observer at `latitude_deg` (north
/// positive), `longitude_deg` (east positive) and `height_m` above sea level, with
/// `refraction`.
pub fn sun_position(
    time: &PhotoTime,
    latitude_deg: f64,
    longitude_deg: f64,
    height_m: f64,
    refraction: Refraction,
) -> Result<SunPosition, SkyError> {
    let fail = |source| SkyError::Position {
        latitude_deg,
        longitude_deg,
        time: time.to_rfc3339(),
        source,
    };
    let u = time.utc();
    let dt = delta_t::estimate_from_date(u.year, u.month).map_err(fail)?;
    let jd = JulianDate::from_utc(u.year, u.month, u.day, u.hour, u.minute, u.second, dt)
        .map_err(fail)?;
    let refraction = match refraction {
        Refraction::None => None,
        Refraction::Atmosphere {
            pressure_hpa,
            temperature_c,
        } => Some(RefractionCorrection::new(pressure_hpa, temperature_c).map_err(fail)?),
    };
    let location = Location {
        latitude: latitude_deg,
        longitude: longitude_deg,
    };
    let p = SolarPositions::new()
        .at_from_julian(jd, location, height_m, refraction)
        .map_err(fail)?;
    Ok(SunPosition {
        azimuth_deg: p.azimuth(),
        zenith_deg: p.zenith_angle(),
    })
}

/// The unit world direction toward the sun at `position`, for a site whose true north is the
/// horizontal world direction `north` (any length; `[site] north`, default +Y).
pub fn sun_direction(position: SunPosition, north: [f64; 3]) -> Result<DVec3, SkyError> {
    let up = DVec3::Z;
    let n = DVec3::from(north);
    let horizontal = DVec3::new(n.x, n.y, 0.0);
    let flat = n.length() > 0.0 && n.z.abs() <= igi_formats::survey::NORTH_MAX_TILT * n.length();
    if !(flat && horizontal.length() > 0.0) {
        return Err(SkyError::North(north));
    }
    let n = horizontal.normalize();
    let east = n.cross(up);
    let (az, zen) = (
        position.azimuth_deg.to_radians(),
        position.zenith_deg.to_radians(),
    );
    Ok((zen.sin() * (az.sin() * east + az.cos() * n) + zen.cos() * up).normalize())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn time(t: &str) -> PhotoTime {
        PhotoTime::parse_rfc3339(t).unwrap()
    }

    /// NREL's published example (Reda and Andreas 2004, Table A4.1; NREL/TP-560-34302):
    /// 17 October 2003, 12:30:30 at UTC-7, latitude 39.742476, longitude -105.1786, 1830.14 m,
    /// 820 hPa, 11 C, delta T 67 s: topocentric zenith 50.11162 and azimuth 194.34024 degrees.
    /// The estimated delta T for 2003 differs from the example's 67 s by under a second.
    #[test]
    fn the_sun_of_nrels_published_example() {
        let p = sun_position(
            &time("2003-10-17T12:30:30-07:00"),
            39.742476,
            -105.1786,
            1830.14,
            Refraction::Atmosphere {
                pressure_hpa: 820.0,
                temperature_c: 11.0,
            },
        )
        .unwrap();
        assert!((p.zenith_deg - 50.11162).abs() < 5e-4, "{p:?}");
        assert!((p.azimuth_deg - 194.34024).abs() < 5e-4, "{p:?}");
        assert!((p.elevation_deg() - (90.0 - 50.11162)).abs() < 5e-4);
    }

    /// Refraction lifts the sun, by about 0.5 degrees at the horizon and a few hundredths of a
    /// degree 45 degrees up; the same instant written with another UTC offset is the same sun.
    #[test]
    fn refraction_lifts_the_sun_and_the_offset_names_the_same_instant() {
        let at = |t: &str, r| sun_position(&time(t), 48.21, 16.37, 0.0, r).unwrap();
        let geo = at("2025-06-21T12:00:00+02:00", Refraction::None);
        let apparent = at("2025-06-21T12:00:00+02:00", Refraction::STANDARD);
        let lift = geo.zenith_deg - apparent.zenith_deg;
        assert!(lift > 0.005 && lift < 0.03, "{lift}");
        assert!((geo.azimuth_deg - apparent.azimuth_deg).abs() < 1e-9);
        let utc = at("2025-06-21T10:00:00Z", Refraction::None);
        assert_eq!(utc, geo);
        // near sunset the lift is about half a degree
        let low = |r| at("2025-06-21T20:50:00+02:00", r).zenith_deg;
        let lift = low(Refraction::None) - low(Refraction::STANDARD);
        assert!(lift > 0.2 && lift < 0.7, "{lift}");
    }

    /// At an equinox noon on the equator the sun stands (almost) overhead; at a June noon in
    /// the north it is due south, and in the morning east of south.
    #[test]
    fn noon_and_morning_suns_point_where_they_should() {
        let noon = sun_position(
            &time("2025-06-21T12:00:00Z"),
            51.4779,
            0.0,
            0.0,
            Refraction::None,
        )
        .unwrap();
        // solar noon at Greenwich is within two minutes of 12:00 UTC in June
        assert!((noon.azimuth_deg - 180.0).abs() < 1.0, "{noon:?}");
        // elevation 90 - 51.48 + 23.44
        assert!((noon.elevation_deg() - 61.96).abs() < 0.1, "{noon:?}");
        let equinox = sun_position(
            &time("2025-03-20T12:07:00Z"),
            0.0,
            0.0,
            0.0,
            Refraction::None,
        )
        .unwrap();
        assert!(equinox.zenith_deg < 0.5, "{equinox:?}");
        let morning = sun_position(
            &time("2025-06-21T08:00:00+01:00"),
            51.4779,
            0.0,
            0.0,
            Refraction::None,
        )
        .unwrap();
        assert!(
            morning.azimuth_deg > 60.0 && morning.azimuth_deg < 120.0,
            "{morning:?}"
        );
    }

    #[test]
    fn the_direction_follows_the_sites_north() {
        let p = SunPosition {
            azimuth_deg: 90.0,
            zenith_deg: 60.0,
        };
        // north +Y: east is +X
        let d = sun_direction(p, [0.0, 1.0, 0.0]).unwrap();
        let want = DVec3::new(60f64.to_radians().sin(), 0.0, 0.5);
        assert!((d - want).length() < 1e-12, "{d}");
        // north along +X (any length): east is -Y
        let d = sun_direction(p, [5.0, 0.0, 0.0]).unwrap();
        let want = DVec3::new(0.0, -(60f64.to_radians().sin()), 0.5);
        assert!((d - want).length() < 1e-12, "{d}");
        // due north, on the horizon
        let d = sun_direction(
            SunPosition {
                azimuth_deg: 0.0,
                zenith_deg: 90.0,
            },
            [0.0, 1.0, 0.0],
        )
        .unwrap();
        assert!((d - DVec3::Y).length() < 1e-12, "{d}");
        for bad in [[0.0, 0.0, 1.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.5]] {
            let e = sun_direction(p, bad).unwrap_err().to_string();
            assert!(e.contains("north") && e.contains("horizontal"), "{e}");
        }
    }

    #[test]
    fn a_location_out_of_range_is_an_error_naming_it() {
        let e = sun_position(
            &time("2025-06-21T12:00:00Z"),
            95.0,
            0.0,
            0.0,
            Refraction::None,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("latitude 95") && e.contains("2025-06-21"), "{e}");
    }
}
