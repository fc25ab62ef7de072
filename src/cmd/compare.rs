//! `igi compare` (filled in by the render work).
use crate::report::Ctx;
#[derive(clap::Args, Debug)]
pub struct CompareArgs {}
pub fn run(_a: CompareArgs, _ctx: &Ctx) -> anyhow::Result<()> { anyhow::bail!("todo") }
