//! `ocelli scenario`: print the embedded default scenario, check a scenario file, or survey a
//! scenario's simulated room for its default RSSI model.

use anyhow::Result;
use proto::models::{RssiModel, fit_log_distance};
use proto::scenario::{DEFAULT_SCENARIO_TOML, Scenario};
use std::path::PathBuf;
use std::process::ExitCode;
use world::radio::{SURVEY_READINGS_PER_PAIR, survey};

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    pub action: Action,
}

#[derive(clap::Subcommand, Debug)]
pub enum Action {
    /// Print the embedded default scenario (TOML).
    Default,
    /// Check a scenario file as deeply as a deployment would (fields, addresses, calibration
    /// files, what each camera sees, targets inside the world); print a summary.
    Check {
        /// The scenario file to check.
        #[arg(value_name = "FILE")]
        path: PathBuf,
    },
    /// Survey the scenario's simulated room (every RSSI node reads every other's beacon) and
    /// print the default RSSI model fitted to it, as paper 002 fitted its testbed's.
    Survey {
        #[command(flatten)]
        scenario: super::common::ScenarioArg,
        /// Seed of the simulated room (a launch's cameras use 1; `ocelli sim --seed`).
        #[arg(long, default_value_t = super::camera::SYNTHETIC_SEED)]
        seed: u64,
    },
}

/// Every check a deployment would otherwise fail on later.
///
/// # Errors
/// The first problem, naming the file and the field.
pub fn check(path: &std::path::Path) -> Result<Scenario> {
    let s = Scenario::load(path)?;
    s.check_deployment()?;
    // The simulated world's part: targets parse and drive inside the room.
    let targets = world::targets(&s)?;
    let (lo, hi) = (s.world.min, s.world.max);
    for t in &targets {
        if let Some(w) = t
            .trajectory
            .waypoints()
            .iter()
            .find(|w| !(lo[0]..=hi[0]).contains(&w[0]) || !(lo[1]..=hi[1]).contains(&w[1]))
        {
            anyhow::bail!(
                "scenario {}: targets[id={}].trajectory.waypoints: [{}, {}] is outside the world [{}, {}] x [{}, {}]",
                path.display(),
                t.id,
                w[0],
                w[1],
                lo[0],
                hi[0],
                lo[1],
                hi[1]
            );
        }
    }
    Ok(s)
}

pub fn run(args: Args) -> Result<ExitCode> {
    match args.action {
        Action::Default => print!("{DEFAULT_SCENARIO_TOML}"),
        Action::Check { path } => {
            let s = check(&path)?;
            println!(
                "{}: {} cameras, {} heads, {} targets — ok",
                s.name,
                s.cameras().count(),
                s.heads().count(),
                s.targets.len()
            );
        }
        Action::Survey { scenario, seed } => {
            let s = scenario.load()?;
            let pairs = survey(&s, seed, SURVEY_READINGS_PER_PAIR);
            let Some(RssiModel::LogDistance { a, b, variance }) = fit_log_distance(&pairs) else {
                anyhow::bail!(
                    "{}: {} survey readings cannot determine a model (it needs at least two RSSI nodes at different distances)",
                    s.name,
                    pairs.len()
                );
            };
            println!(
                "# {}: {} readings between {} RSSI nodes, seed {seed}",
                s.name,
                pairs.len(),
                s.cameras().filter(|c| c.rssi).count()
            );
            println!(
                "rssi-default = {{ kind = \"log-distance\", a = {a:.2}, b = {b:.2}, variance = {variance:.1} }}"
            );
        }
    }
    Ok(ExitCode::SUCCESS)
}
