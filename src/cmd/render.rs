//! `igi render` (filled in by the render work).
use crate::report::Ctx;
#[derive(clap::Args, Debug)]
pub struct RenderArgs {}
pub fn run(_a: RenderArgs, _ctx: &Ctx) -> anyhow::Result<()> { anyhow::bail!("todo") }
