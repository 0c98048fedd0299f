//! `ocelli sim`: the scenario's nodes in one process on a virtual clock (see `sim::runtime`).
//! Same seed, same bytes out.

use super::common::load_scenario;
use crate::sim::net::NetworkModel;
use crate::sim::runtime::{Level, Sim, SimOptions};
use anyhow::{Context, Result};
use node_server::replay::Loaded;
use node_server::report;
use proto::ClusterTime;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Scenario file (the embedded default when omitted).
    pub scenario: Option<PathBuf>,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Simulated seconds.
    #[arg(long, default_value_t = 20.0)]
    pub duration: f64,
    /// Print the report as JSON on standard output.
    #[arg(long)]
    pub json: bool,
    /// `pixel` (rendered and segmented frames) or `measurement` (truth projected plus noise).
    #[arg(long, value_enum, default_value = "pixel")]
    pub level: LevelArg,
    /// One-way network latency, ms.
    #[arg(long, default_value_t = 2.0)]
    pub latency_ms: f64,
    /// Uniform latency jitter, ms.
    #[arg(long, default_value_t = 1.0)]
    pub jitter_ms: f64,
    /// Message loss probability.
    #[arg(long, default_value_t = 0.0)]
    pub loss: f64,
    /// Largest per-node clock offset, ms.
    #[arg(long, default_value_t = 20.0)]
    pub clock_offset_ms: f64,
    /// Largest per-node clock drift, ppm.
    #[arg(long, default_value_t = 50.0)]
    pub clock_drift_ppm: f64,
    /// Write the server's recording here.
    #[arg(long)]
    pub record: Option<PathBuf>,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum LevelArg {
    Pixel,
    Measurement,
}

pub fn run(args: Args) -> Result<ExitCode> {
    let scenario = load_scenario(args.scenario.as_ref())?;
    let opts = SimOptions {
        seed: args.seed,
        duration_s: args.duration,
        level: match args.level {
            LevelArg::Pixel => Level::Pixel,
            LevelArg::Measurement => Level::Measurement,
        },
        network: NetworkModel {
            latency_ms: args.latency_ms,
            jitter_ms: args.jitter_ms,
            loss: args.loss,
            clock_offset_ms: args.clock_offset_ms,
            clock_drift_ppm: args.clock_drift_ppm,
            partitions: Vec::new(),
        },
        ..SimOptions::default()
    };
    let outcome = Sim::new(scenario.clone(), opts)?.run();
    if let Some(path) = &args.record {
        let mut rec = node_server::Recorder::create(path, &scenario.name)
            .with_context(|| format!("creating recording {}", path.display()))?;
        let has_scenario = outcome
            .records
            .iter()
            .any(|r| matches!(r.record, node_server::Record::Scenario(_)));
        if !has_scenario {
            rec.append(&node_server::Stamped::new(
                ClusterTime(0),
                node_server::Record::Scenario(scenario.to_toml()),
            ))?;
        }
        for r in &outcome.records {
            rec.append(r)?;
        }
        rec.sync()?;
    }
    let loaded = Loaded {
        scenario,
        records: outcome.records,
        tail: None,
    };
    let report = report::compute(&loaded, ClusterTime(0));
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
