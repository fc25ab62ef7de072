//! `igi camera ...` (filled in by the imaging work).
use crate::report::Ctx;
#[derive(clap::Subcommand, Debug)]
pub enum CameraCmd { Undistort }
pub fn run(_c: CameraCmd, _ctx: &Ctx) -> anyhow::Result<()> { anyhow::bail!("todo") }
