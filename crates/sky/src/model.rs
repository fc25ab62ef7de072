//! The sky as the lighting estimation uses it: radiance in a world direction (Z up), a lat-long
//! map in igi's convention (`igi_imaging::latlong`, docs/FORMATS.md) and the sun's disk as a
//! lighting file describes it.

use crate::hosek::{self, HosekWilkie};
use crate::overcast::CieOvercast;
use crate::sun::{sun_direction, SunPosition};
use crate::SkyError;
use glam::DVec3;
use igi_formats::lighting::{disk_one_minus_cos, SunSection};
use igi_imaging::{latlong, HdrImage};
use std::f64::consts::PI;

/// The angular radius given to the sun's disk in a lighting file, degrees: the sun's mean
/// apparent radius (16 arc minutes; 0.5334 degrees across).
pub const SUN_ANGULAR_RADIUS_DEG: f64 = 0.2667;

/// The sun as a lighting file's `[sun]` describes it: a uniform disk.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SunDisk {
    /// Unit world direction toward the disk's centre.
    pub direction: DVec3,
    /// The disk's angular radius, degrees.
    pub angular_radius_deg: f64,
    /// The disk's uniform RGB radiance (the sky's units).
    pub radiance: [f64; 3],
}

impl SunDisk {
    /// The disk's solid angle, steradians (as `igi_formats::lighting` computes it).
    pub fn solid_angle(&self) -> f64 {
        2.0 * PI * disk_one_minus_cos(2.0 * self.angular_radius_deg)
    }

    /// The irradiance the disk gives a surface facing it: radiance times solid angle.
    pub fn irradiance(&self) -> [f64; 3] {
        let omega = self.solid_angle();
        self.radiance.map(|l| l * omega)
    }

    /// The lighting file's `[sun]` section of this disk.
    pub fn to_section(&self) -> SunSection {
        SunSection {
            direction: self.direction.to_array(),
            radiance: self.radiance,
            angular_diameter_deg: 2.0 * self.angular_radius_deg,
        }
    }
}

/// Zenith angle and unit vector of a world direction; `None` for a zero or non-finite one.
fn unit(d: DVec3) -> Option<DVec3> {
    let len = d.length();
    (len > 0.0 && len.is_finite()).then(|| d / len)
}

/// The angle between two unit vectors, accurate near 0 and pi.
fn angle(a: DVec3, b: DVec3) -> f64 {
    a.cross(b).length().atan2(a.dot(b))
}

/// A lat-long map (igi's convention: `igi_imaging::latlong`, row 0 at the zenith) of
/// `radiance` at each pixel's centre direction; `width` and `height` at least 1.
fn latlong_map(
    width: usize,
    height: usize,
    radiance: impl Fn(DVec3) -> [f64; 3],
) -> Result<HdrImage, SkyError> {
    if width == 0 || height == 0 {
        return Err(SkyError::MapSize(width, height));
    }
    Ok(latlong::map_from_fn(width, height, |d| {
        radiance(d.as_dvec3()).map(|v| v as f32)
    }))
}

/// A clear sky: Hosek-Wilkie's RGB sky dome and solar disk for one turbidity, ground albedo
/// and sun direction.
#[derive(Clone, Debug, PartialEq)]
pub struct Sky {
    turbidity: f64,
    albedo: [f64; 3],
    sun: DVec3,
    model: HosekWilkie,
}

impl Sky {
    /// The clear sky of this turbidity (1 to 10) and ground albedo (0 to 1 per channel) with
    /// the sun toward the world direction `sun` (any length, on or above the horizon).
    pub fn new(turbidity: f64, albedo: [f64; 3], sun: DVec3) -> Result<Self, SkyError> {
        let sun = unit(sun).ok_or(SkyError::SunDirection(sun.to_array()))?;
        let elevation = sun.z.clamp(-1.0, 1.0).asin();
        let model = HosekWilkie::new(turbidity, albedo, elevation)?;
        Ok(Sky {
            turbidity,
            albedo,
            sun,
            model,
        })
    }

    /// The clear sky with the sun at `position` for a site whose true north is `north`
    /// (through [`sun_direction`]).
    pub fn at_position(
        turbidity: f64,
        albedo: [f64; 3],
        position: SunPosition,
        north: [f64; 3],
    ) -> Result<Self, SkyError> {
        Sky::new(turbidity, albedo, sun_direction(position, north)?)
    }

    /// Atmospheric turbidity, 1 (very clear) to 10 (hazy).
    pub fn turbidity(&self) -> f64 {
        self.turbidity
    }

    /// Ground albedo per channel, 0 to 1.
    pub fn albedo(&self) -> [f64; 3] {
        self.albedo
    }

    /// Unit world direction toward the sun (Z up), at most 90 degrees from the zenith.
    pub fn sun(&self) -> DVec3 {
        self.sun
    }

    /// The sun's elevation above the horizon, radians.
    pub fn solar_elevation_rad(&self) -> f64 {
        self.model.solar_elevation_rad()
    }

    /// The Hosek-Wilkie model behind this sky.
    pub fn model(&self) -> &HosekWilkie {
        &self.model
    }

    /// The sky dome's RGB radiance arriving from the world direction `d` (toward the sky; any
    /// length), without the solar disk: zero below the horizon and for a zero or non-finite
    /// direction. The model's fit dips below zero in one or two channels near the horizon for
    /// a sun near the horizon (down to -0.38, in 0.014 % of the directions scanned over its
    /// whole range: docs/SKY.md); such values are set to zero here.
    pub fn radiance(&self, d: DVec3) -> [f64; 3] {
        match unit(d) {
            None => [0.0; 3],
            Some(d) => self
                .model
                .radiance(angle(d, DVec3::Z), angle(d, self.sun))
                .map(|v| v.max(0.0)),
        }
    }

    /// The irradiance of the model's solar disk (0.51 degrees across) on a surface facing it,
    /// RGB, as the model gives it (a channel may be negative for a sun so red that it lies
    /// outside the Rec. 709 gamut).
    pub fn solar_irradiance(&self) -> [f64; 3] {
        hosek::solar_irradiance_rgb(self.turbidity, self.model.solar_elevation_rad())
    }

    /// The sun as a uniform disk of [`SUN_ANGULAR_RADIUS_DEG`] giving the model's solar
    /// irradiance ([`Sky::solar_irradiance`], negative channels set to zero).
    pub fn sun_disk(&self) -> SunDisk {
        self.sun_disk_of_radius(SUN_ANGULAR_RADIUS_DEG)
            .expect("the default radius is valid")
    }

    /// The sun as a uniform disk of `angular_radius_deg` (in (0, 90)) giving the model's solar
    /// irradiance, negative channels set to zero.
    pub fn sun_disk_of_radius(&self, angular_radius_deg: f64) -> Result<SunDisk, SkyError> {
        if !(angular_radius_deg > 0.0 && angular_radius_deg < 90.0) {
            return Err(SkyError::SunRadius(angular_radius_deg));
        }
        let mut disk = SunDisk {
            direction: self.sun,
            angular_radius_deg,
            radiance: [0.0; 3],
        };
        let omega = disk.solid_angle();
        disk.radiance = self.solar_irradiance().map(|e| e.max(0.0) / omega);
        Ok(disk)
    }

    /// The sky dome (without the disk) as a `width` x `height` lat-long map in igi's
    /// convention, each pixel the radiance at its centre direction.
    pub fn latlong(&self, width: usize, height: usize) -> Result<HdrImage, SkyError> {
        latlong_map(width, height, |d| self.radiance(d))
    }
}

impl CieOvercast {
    /// The radiance arriving from the world direction `d` (any length; zero below the horizon
    /// and for a zero or non-finite direction).
    pub fn radiance_from(&self, d: DVec3) -> [f64; 3] {
        match unit(d) {
            None => [0.0; 3],
            Some(d) => self.radiance(d.z),
        }
    }

    /// The sky as a `width` x `height` lat-long map in igi's convention.
    pub fn latlong(&self, width: usize, height: usize) -> Result<HdrImage, SkyError> {
        latlong_map(width, height, |d| self.radiance_from(d))
    }
}
