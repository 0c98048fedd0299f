//! `ocelli report`: the run report of a recording (error against ground truth when the
//! recording says its world was simulated, sensors per step, energy, messages, sync), as a
//! table or JSON — the same report `ocelli launch` printed for it (`lab::report`).

use super::common::{ScenarioArg, warn_damage};
use anyhow::{Context, Result};
use lab::report::{Scoring, of_recording};
use proto::ClusterTime;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// The server's recording file.
    #[arg(value_name = "RECORDING")]
    pub recording: PathBuf,
    /// Replaces the scenario stored in the recording.
    #[command(flatten)]
    pub scenario: ScenarioArg,
    /// Print only JSON instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Also write the JSON report to this file.
    #[arg(long, value_name = "FILE")]
    pub write: Option<PathBuf>,
    /// Score against the scenario's simulated targets as if they started at this cluster time
    /// (ns), whatever the recording says (default: the recording's own time origin, and no
    /// score at all for a real deployment's recording).
    #[arg(long, value_name = "NS")]
    pub t0_ns: Option<i64>,
    /// Also write every scored frame to this file as JSON Lines (`-`: standard output, instead
    /// of the report): the truth and the global tracks on the floor, and what CLEAR MOT counted
    /// in it — the pairs (`switch` when the person was last paired with another track), the
    /// misses and the false positives. Where MOTA and the id switches come from.
    #[arg(long, value_name = "FILE")]
    pub events: Option<PathBuf>,
}

pub fn run(args: Args) -> Result<ExitCode> {
    let scenario = args.scenario.load_given()?;
    let r = of_recording(&args.recording, scenario, args.t0_ns.map(ClusterTime))?;
    warn_damage(&args.recording, &r.loaded);
    match r.scoring {
        Scoring::NoTruth if !r.loaded.scenario.targets.is_empty() => tracing::info!(
            "not scored: the recording does not say its world was simulated (give --t0-ns to \
             score against the scenario's targets anyway)"
        ),
        Scoring::Given(t0) => tracing::info!(t0_ns = t0.0, "scored from the given time origin"),
        _ => {}
    }
    if let Some(path) = &args.events {
        let Some(frames) = lab::report::scored_frames(&r)? else {
            anyhow::bail!(
                "no events: the report is not scored (the recording does not say its world was \
                 simulated; --t0-ns scores it against the scenario's targets)"
            );
        };
        let mut text = String::new();
        for f in &frames {
            text += &serde_json::to_string(f)?;
            text.push('\n');
        }
        if path.as_os_str() == "-" {
            print!("{text}");
            return Ok(ExitCode::SUCCESS);
        }
        std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))?;
        eprintln!("{} scored frames written to {}", frames.len(), path.display());
    }
    let json = serde_json::to_string_pretty(&crate::launch::latency::report_json(&r.report, &r.loaded)?)?;
    if let Some(p) = &args.write {
        std::fs::write(p, &json).with_context(|| format!("writing {}", p.display()))?;
    }
    if args.json {
        println!("{json}");
    } else {
        print!("{}", r.report.to_table());
        if let Some(age) = crate::launch::latency::of(&r.loaded) {
            print!("{}", crate::launch::latency::to_line(&age));
        }
    }
    Ok(ExitCode::SUCCESS)
}
