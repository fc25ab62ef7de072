//! Subcommands that belong to the planned toolkit but are not built yet.
//! They accept any arguments and fail with a clear message naming the issue that adds them.

use anyhow::bail;

#[derive(clap::Args, Debug)]
pub struct PlannedArgs {
    /// Arguments (this command is not implemented yet).
    #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
    pub args: Vec<String>,
}

pub fn run(name: &str, issue: u32, _args: PlannedArgs) -> anyhow::Result<()> {
    bail!("`igi {name}` is planned but not implemented in this build (tracked as issue {issue})")
}
