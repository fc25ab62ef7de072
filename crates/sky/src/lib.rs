//! The natural light of a place and time (issue 34).
//!
//! - [`sun`]: where the sun stands for a photo's time (`[[photo]] time`) at the site's location
//!   (`[site] latitude_deg`, `longitude_deg`): NREL's Solar Position Algorithm (Reda and
//!   Andreas 2004, through the `solar-positioning` crate, checked here against NREL's published
//!   example), with atmospheric refraction, turned into a unit direction of igi's world frame
//!   (Z up) by the site's `north`.
//!
//! The physical sky (Hosek-Wilkie with its solar disk, the CIE overcast sky) and the joint
//! estimation of the light with the albedo are the next parts of the issue; they will live here.

pub mod sun;

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
}
