//! `ocelli experiment NAME|all [--runs N] [--seed S] [--json] [--plot DIR] [--markdown]`: run
//! the papers' experiments in the simulation runtime and print our table beside the paper's
//! (see `experiment`).

use anyhow::Result;
use lab::experiment::{self, NAMES, Options, plot, table};
use sim::Level;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Experiment name (`paper000-table1`, `paper001`, `paper002-table1`, `paper002-occlusion`,
    /// `paper002-rssi-only`, `paper002-robustness`, `paper004`), `all` (those seven), or
    /// `ble-rssi` (real BLE data from shared/datasets/ble-rssi; not part of `all`), or `crowd`
    /// (ten people in the default room, issue 16's multi-target metrics; slow, not part of
    /// `all`).
    pub name: String,
    /// Seeded runs per method.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..=10_000))]
    pub runs: u32,
    /// Seed of the first run (run k uses seed + k).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Print only JSON (`{"experiment", "rows": [...]}`; one object per line with `all`).
    #[arg(long)]
    pub json: bool,
    /// Print a Markdown section per experiment (for docs/results.md).
    #[arg(long, conflicts_with = "json")]
    pub markdown: bool,
    /// Write PNG figures (first run of each method) into this directory.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Override the experiment's level: `pixel` or `measurement`.
    #[arg(long, value_enum)]
    pub level: Option<super::sim::LevelArg>,
    /// Override the simulated seconds per run.
    #[arg(long, value_parser = super::common::seconds)]
    pub duration: Option<f64>,
}

pub fn run(args: Args) -> Result<ExitCode> {
    let names: Vec<&str> = if args.name == "all" {
        NAMES.to_vec()
    } else {
        vec![args.name.as_str()]
    };
    let opts = Options {
        runs: args.runs,
        seed: args.seed,
        level: args.level.map(|l| match l {
            super::sim::LevelArg::Pixel => Level::Pixel,
            super::sim::LevelArg::Measurement => Level::Measurement,
        }),
        duration_s: args.duration,
    };
    let bar = super::bar::study_runs(&args.name);
    for name in names {
        if let Some(b) = &bar {
            b.set_prefix(name.to_string());
        }
        let outcome = experiment::run(name, &opts)?;
        let figures = match &args.plot {
            Some(dir) => plot::write_all(&outcome, dir)?,
            None => Vec::new(),
        };
        let print = || -> Result<()> {
            if args.json {
                println!("{}", serde_json::to_string(&table::to_json(&outcome))?);
            } else if args.markdown {
                let mut command = format!(
                    "ocelli experiment {name} --runs {} --seed {}",
                    args.runs, args.seed
                );
                if let Some(d) = args.duration {
                    command.push_str(&format!(" --duration {d}"));
                }
                if args.level.is_some() {
                    command.push_str(&format!(
                        " --level {}",
                        serde_json::to_value(outcome.level)?.as_str().unwrap_or("?")
                    ));
                }
                let names: Vec<String> = figures
                    .iter()
                    .filter_map(|p| p.file_name().map(|f| format!("figures/{}", f.to_string_lossy())))
                    .collect();
                print!("{}", table::to_markdown(&outcome, &command, &names));
            } else {
                println!("{}", table::to_text(&outcome));
                for f in &figures {
                    println!("figure: {}", f.display());
                }
            }
            Ok(())
        };
        // The table is printed with the bar cleared, then the bar comes back.
        match &bar {
            Some(b) => b.suspend(print)?,
            None => print()?,
        }
    }
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    Ok(ExitCode::SUCCESS)
}
