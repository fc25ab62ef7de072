//! `igi sky`: the lighting file (sky map + sun) of a place and time, from the sun's position
//! (NREL SPA) and the Hosek-Wilkie clear sky, or the CIE overcast sky.
use crate::report::{print_json, Ctx};
use igi_sky::job::{write_sky, Place, SkyRequest};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct SkyArgs {
    /// The survey folder (or its survey.toml) whose `[site]` gives latitude_deg, longitude_deg
    /// and north.
    #[arg(long, required_unless_present = "site", conflicts_with = "site")]
    survey: Option<PathBuf>,
    /// The site directly: `LAT,LON[,NORTH_DEG]` (degrees, north and east positive; NORTH_DEG:
    /// true north as world direction (sin a, cos a, 0), clockwise from +Y seen from above,
    /// default 0).
    #[arg(long, value_parser = parse_site, allow_hyphen_values = true)]
    site: Option<(f64, f64, f64)>,
    /// The time, RFC 3339 with its UTC offset, e.g. 2026-06-21T17:30:00+02:00.
    #[arg(long)]
    time: String,
    /// Atmospheric turbidity, 1 (very clear) to 10 (hazy).
    #[arg(long, default_value_t = 3.0)]
    turbidity: f64,
    /// Ground albedo, 0 to 1.
    #[arg(long, default_value_t = 0.2)]
    albedo: f64,
    /// Width of the lat-long sky map (height: half).
    #[arg(long, default_value_t = 512)]
    width: usize,
    /// Write the CIE overcast sky (no sun) instead of the clear sky; also for a sun below
    /// the horizon, which the clear sky refuses.
    #[arg(long)]
    overcast: bool,
    /// The overcast sky's zenith radiance (docs/SKY.md units; default 6, about 10,000 lx on
    /// the ground).
    #[arg(long, requires = "overcast")]
    zenith_radiance: Option<f64>,
    /// Print a JSON summary on stdout.
    #[arg(long)]
    json: bool,
    /// The lighting file (.toml); the sky map is written beside it as `STEM.exr` (STEM: the
    /// file's name without `.toml`).
    #[arg(short, long)]
    output: PathBuf,
}

pub(crate) fn parse_site(s: &str) -> Result<(f64, f64, f64), String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|p| p.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| format!("{s:?}: expected LAT,LON[,NORTH_DEG] ({e})"))?;
    match v[..] {
        [lat, lon] => Ok((lat, lon, 0.0)),
        [lat, lon, north] => Ok((lat, lon, north)),
        _ => Err(format!("{s:?}: expected LAT,LON[,NORTH_DEG]")),
    }
}

pub fn run(a: SkyArgs, ctx: &Ctx) -> anyhow::Result<()> {
    let place = match (a.survey, a.site) {
        (Some(path), _) => Place::Survey { path },
        (None, Some((latitude_deg, longitude_deg, north_deg))) => Place::Site {
            latitude_deg,
            longitude_deg,
            north_deg,
        },
        (None, None) => anyhow::bail!("give --survey or --site"),
    };
    let req = SkyRequest {
        place,
        time: a.time,
        turbidity: a.turbidity,
        albedo: a.albedo,
        width: a.width,
        overcast: a.overcast,
        zenith_radiance: a.zenith_radiance,
        output: a.output,
    };
    let r = write_sky(&req)?;
    if a.json {
        print_json(&r)?;
    } else if !ctx.quiet {
        eprintln!(
            "sky: {} sky at {} (UTC), sun azimuth {:.3} deg, elevation {:.3} deg, direction [{:.5}, {:.5}, {:.5}]; wrote {} and {}",
            r.sky,
            r.time_utc,
            r.sun_azimuth_deg,
            r.sun_elevation_deg,
            r.sun_direction[0],
            r.sun_direction[1],
            r.sun_direction[2],
            r.lighting.display(),
            r.map.display()
        );
    }
    Ok(())
}
