//! `igi demo` (filled in by the render work).
use crate::report::Ctx;
#[derive(clap::Args, Debug)]
pub struct DemoArgs {}
pub fn run(_a: DemoArgs, _ctx: &Ctx) -> anyhow::Result<()> { anyhow::bail!("todo") }
