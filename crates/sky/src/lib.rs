//! The natural light of a place and time (issue 34).
//!
//! - [`sun`]: where the sun stands for a photo's time (`[[photo]] time`) at the site's location
//!   (`[site] latitude_deg`, `longitude_deg`): NREL's Solar Position Algorithm (Reda and
//!   Andreas 2004, through the `solar-positioning` crate, checked here against NREL's published
//!   example), with atmospheric refraction, turned into a unit direction of igi's world frame
//!   (Z up) by the site's `north`.
//! - [`hosek`]: the Hosek-Wilkie 2012 clear sky in linear Rec. 709 RGB and its 2013 solar disk
//!   (the reference implementation's spectral sun, integrated against the CIE 1931 functions),
//!   ported from the authors' code (3-clause BSD, `LICENSE-hosek-wilkie`) and tested against
//!   values that code prints (`datasets/sky/`).
//! - [`overcast`]: the CIE standard overcast sky, for photos in which no sun reaches the ground.
//! - [`model`]: the sky as the lighting estimation uses it: [`Sky`] (turbidity, ground albedo,
//!   sun direction) gives the radiance in a world direction, a lat-long map in igi's
//!   convention and the sun's disk ([`SunDisk`]) as a lighting file's `[sun]`.
//! - [`job`]: `igi sky`'s job, a lighting file (sky map + `[sun]`) for a survey's site or a
//!   given place at an RFC 3339 time ([`job::write_sky`]).
//!
//! docs/SKY.md describes the models, their data, units and checks. The joint estimation of the
//! light with the albedo is the next part of the issue.

#[rustfmt::skip]
mod cie_data;
#[rustfmt::skip]
mod hosek_data;

pub mod hosek;
pub mod job;
pub mod model;
pub mod overcast;
pub mod sun;

pub use hosek::HosekWilkie;
pub use model::{Sky, SunDisk, SUN_ANGULAR_RADIUS_DEG};
pub use overcast::CieOvercast;
pub use sun::{sun_direction, sun_position, Refraction, SunPosition};

/// Why the light of a place and time cannot be given.
#[derive(Debug, thiserror::Error)]
pub enum SkyError {
    /// The solar position algorithm refused its input (a location or time out of its range).
    #[error("the sun's position at latitude {latitude_deg} deg, longitude {longitude_deg} deg, {time}: {source}")]
    Position {
        latitude_deg: f64,
        longitude_deg: f64,
        time: String,
        #[source]
        source: solar_positioning::Error,
    },
    /// A north that is not a horizontal direction.
    #[error("north {0:?} is not a horizontal direction")]
    North([f64; 3]),
    /// A turbidity outside the Hosek-Wilkie model's range.
    #[error("turbidity {0}: the Hosek-Wilkie sky covers turbidity 1 to 10")]
    Turbidity(f64),
    /// A ground albedo outside [0, 1].
    #[error("ground albedo {0:?}: each channel must be in [0, 1]")]
    Albedo([f64; 3]),
    /// The sun below the horizon (or a non-finite elevation).
    #[error("solar elevation {0} deg: the Hosek-Wilkie sky covers the sun from the horizon (0 deg) to the zenith (90 deg)")]
    SolarElevation(f64),
    /// A sun direction that is zero or not finite.
    #[error("sun direction {0:?} is not a non-zero finite vector")]
    SunDirection([f64; 3]),
    /// A sun disk radius outside (0, 90) degrees.
    #[error("sun angular radius {0} deg: must be in (0, 90)")]
    SunRadius(f64),
    /// A radiance that is negative or not finite.
    #[error("sky radiance {0:?}: each channel must be finite and >= 0")]
    Radiance([f64; 3]),
    /// An irradiance that is negative or not finite.
    #[error("horizontal irradiance {0:?}: each channel must be finite and >= 0")]
    Irradiance([f64; 3]),
    /// A lat-long map without pixels.
    #[error("a lat-long sky map of {0} x {1} pixels: both must be at least 1")]
    MapSize(usize, usize),
}
