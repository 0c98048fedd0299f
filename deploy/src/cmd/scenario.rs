//! `ocelli scenario`: print the embedded default scenario, or check a scenario file.

use anyhow::Result;
use proto::scenario::{DEFAULT_SCENARIO_TOML, Scenario};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    pub action: Action,
}

#[derive(clap::Subcommand, Debug)]
pub enum Action {
    /// Print the embedded default scenario (TOML).
    Default,
    /// Parse and validate a scenario file; print a summary.
    Check { path: PathBuf },
}

pub fn run(args: Args) -> Result<ExitCode> {
    match args.action {
        Action::Default => print!("{DEFAULT_SCENARIO_TOML}"),
        Action::Check { path } => {
            let s = Scenario::load(&path)?;
            println!(
                "{}: {} cameras, {} heads, {} targets — ok",
                s.name,
                s.cameras().count(),
                s.heads().count(),
                s.targets.len()
            );
        }
    }
    Ok(ExitCode::SUCCESS)
}
