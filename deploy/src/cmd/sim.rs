//! `ocelli sim`: the scenario's nodes in one process on a virtual clock (see `sim::runtime`).
//! Same seed, same bytes out.

use super::common::{NetArgs, ScenarioArg, seconds};
use anyhow::{Context, Result};
use node_server::analysis::Loaded;
use node_server::report;
use proto::ClusterTime;
use sim::{Level, Sim, SimOptions, WorldTruth};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub scenario: ScenarioArg,
    /// Seed of everything random in the run (world noise, network, clocks).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Simulated seconds.
    #[arg(long, default_value_t = 20.0, value_parser = seconds)]
    pub duration: f64,
    /// Print only JSON on standard output (the report, level, network counters).
    #[arg(long)]
    pub json: bool,
    /// `pixel` (rendered and segmented frames) or `measurement` (truth projected plus noise).
    #[arg(long, value_enum, default_value = "pixel")]
    pub level: LevelArg,
    #[command(flatten)]
    pub net: NetArgs,
    /// Write the server's recording here (it must not exist, unless --force).
    #[arg(long, value_name = "FILE")]
    pub record: Option<PathBuf>,
    /// Replace an existing recording.
    #[arg(long, requires = "record")]
    pub force: bool,
    /// A logging run: every camera measures every frame whatever its mode, and the
    /// measurements go into the recording, for `ocelli replay RECORDING --fusion … --activation …`.
    #[arg(long, requires = "record")]
    pub record_measurements: bool,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum LevelArg {
    Pixel,
    Measurement,
}

impl LevelArg {
    pub fn level(self) -> Level {
        match self {
            LevelArg::Pixel => Level::Pixel,
            LevelArg::Measurement => Level::Measurement,
        }
    }
}

pub fn run(args: Args) -> Result<ExitCode> {
    let scenario = args.scenario.load()?;
    if let Some(path) = &args.record
        && path.exists()
        && !args.force
    {
        anyhow::bail!(
            "recording {} already exists; name another with --record, or --force to replace it",
            path.display()
        );
    }
    let opts = SimOptions {
        seed: args.seed,
        duration_s: args.duration,
        level: args.level.level(),
        network: args.net.model(),
        record_measurements: args.record_measurements,
        ..SimOptions::default()
    };
    let bar = super::bar::simulated_seconds(args.duration);
    let outcome = Sim::new(scenario, opts)?.run_telling(|s| {
        if let Some(b) = &bar {
            b.set_position(s);
        }
    });
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    if let Some(path) = &args.record {
        if path.exists() {
            std::fs::remove_file(path).with_context(|| format!("replacing {}", path.display()))?;
        }
        outcome.write_recording(path)?;
    }
    let truth = WorldTruth::of(&outcome.scenario, ClusterTime(0))?;
    let loaded = Loaded {
        scenario: outcome.scenario,
        records: outcome.records,
        skipped: Vec::new(),
    };
    let report = report::compute(&loaded, truth.as_ref().map(|t| t as &dyn report::Truth));
    let level = match outcome.level {
        Level::Pixel => "pixel",
        Level::Measurement => "measurement (truth projected plus noise)",
    };
    if args.json {
        let v = serde_json::json!({
            "level": level,
            "seed": args.seed,
            "report": report,
            "network": outcome.net,
            "frames_rendered": outcome.frames_rendered,
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        println!("level: {level}, seed {}", args.seed);
        print!("{}", report.to_table());
        println!(
            "network: {} sent, {} delivered, {} lost, {} partitioned; {} frames rendered",
            outcome.net.sent,
            outcome.net.delivered,
            outcome.net.lost,
            outcome.net.partitioned,
            outcome.frames_rendered
        );
    }
    Ok(ExitCode::SUCCESS)
}
