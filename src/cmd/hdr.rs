//! `igi hdr ...` (filled in by the imaging work).
use crate::report::Ctx;
#[derive(clap::Subcommand, Debug)]
pub enum HdrCmd { Merge }
pub fn run(_c: HdrCmd, _ctx: &Ctx) -> anyhow::Result<()> { anyhow::bail!("todo") }
