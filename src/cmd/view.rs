//! `igi view`: a local web viewer of a result, hull or light-field folder.
use crate::report::Ctx;
use igi_view::{ViewEvent, ViewRequest};
use std::io::Write;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct ViewArgs {
    /// A result folder of `igi solve`, an opacity-hull folder of `igi hull build` or a
    /// surface-light-field folder of `igi slf build`.
    pub dir: PathBuf,
    /// Lighting files the page offers to light the site with (each sets the sun and the sky;
    /// e.g. the survey's `lighting/*.toml`). Repeatable.
    #[arg(long = "lighting")]
    pub lightings: Vec<PathBuf>,
    /// Port on 127.0.0.1 (default: 8765, or any free port when it is taken; a port given here
    /// that is in use is an error; 0: any free port).
    #[arg(long)]
    pub port: Option<u16>,
    /// The survey folder (or its survey.toml): the page overlays its photographs from their
    /// capture cameras (the panel's `photograph`), and its `[site]`, when it gives a latitude
    /// and longitude, places the sun and sky the page computes for a date and time (igi-sky,
    /// as `igi sky --survey`).
    #[arg(long)]
    pub survey: Option<PathBuf>,
    /// The site directly, for the page's date and time: `LAT,LON[,NORTH_DEG]` (as `igi sky
    /// --site`; it overrides the survey's `[site]`).
    #[arg(long, value_parser = crate::cmd::sky::parse_site, allow_hyphen_values = true)]
    pub site: Option<(f64, f64, f64)>,
    /// Camera files (contract JSON) the page may look through, as it looks through a
    /// photograph's camera (the panel's `photograph` lists them after the survey's photos).
    /// Repeatable.
    #[arg(long = "camera")]
    pub cameras: Vec<PathBuf>,
    /// Open the page in the desktop's browser (xdg-open).
    #[arg(long)]
    pub open: bool,
}

/// Serve until interrupted. The first line of standard output is the page's URL; the page's
/// title becomes `igi: ready` once its first frame is drawn, and what the page says (its
/// title, its frame time) is printed as `page: ...` on standard error.
pub fn run(a: ViewArgs, _ctx: &Ctx) -> anyhow::Result<()> {
    let req = ViewRequest {
        dir: a.dir,
        lightings: a.lightings,
        port: a.port,
        sky_place: a.site.map(|(latitude_deg, longitude_deg, north_deg)| {
            igi_sky::job::Place::Site {
                latitude_deg,
                longitude_deg,
                north_deg,
            }
        }),
        survey: a.survey,
        cameras: a.cameras,
    };
    igi_view::serve(&req, &mut |event| match event {
        ViewEvent::Ready(url) => {
            println!("{url}");
            let _ = std::io::stdout().flush();
            if a.open {
                open_browser(url);
            }
        }
        ViewEvent::Page(text) => eprintln!("page: {text}"),
    })?;
    Ok(())
}

fn open_browser(url: &str) {
    if let Err(e) = std::process::Command::new("xdg-open").arg(url).spawn() {
        eprintln!("warning: could not open a browser ({e}); open {url} by hand");
    }
}
