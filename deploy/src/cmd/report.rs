//! `ocelli report`: the run report of a recording (error against ground truth when the
//! recording says its world was simulated, sensors per step, energy, messages, sync), as a
//! table or JSON — the same report `ocelli launch` printed for it (`lab::report`).

use super::common::{ScenarioArg, warn_damage};
use anyhow::{Context, Result};
use lab::report::{Scoring, of_recording};
use proto::ClusterTime;
use std::io::Write;
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
    /// of the report; not with --json or --write): the truth and the global tracks on the
    /// floor, and what CLEAR MOT counted in it — the pairs (`switch` when the person was last
    /// paired with another track), the misses and the false positives. Where MOTA and the id
    /// switches come from.
    #[arg(long, value_name = "FILE")]
    pub events: Option<PathBuf>,
}

pub fn run(args: Args) -> Result<ExitCode> {
    if args.events.as_ref().is_some_and(|p| p.as_os_str() == "-") && (args.json || args.write.is_some()) {
        anyhow::bail!(
            "--events - prints the scored frames instead of the report: give --events a file to \
             have both"
        );
    }
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
        let Some(frames) = lab::report::scored_frames(&r) else {
            anyhow::bail!("no events: {}", why_unscored(&r));
        };
        if path.as_os_str() == "-" {
            write_frames(&frames, &mut std::io::stdout().lock())?;
            return Ok(ExitCode::SUCCESS);
        }
        let mut f = std::io::BufWriter::new(
            std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?,
        );
        write_frames(&frames, &mut f).with_context(|| format!("writing {}", path.display()))?;
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

/// One JSON line per frame.
fn write_frames(frames: &[lab::report::ScoredFrame], out: &mut impl Write) -> Result<()> {
    for f in frames {
        serde_json::to_writer(&mut *out, f)?;
        out.write_all(b"\n")?;
    }
    out.flush()?;
    Ok(())
}

/// Why a recording's report has no MOT metrics, in words.
fn why_unscored(r: &lab::report::RecordingReport) -> &'static str {
    match r.scoring {
        Scoring::NoTruth => {
            "the report is not scored (the recording does not say its world was simulated; \
             --t0-ns scores it against the scenario's targets)"
        }
        _ if !r.report.truth => "there is nobody to score against (the scenario has no targets)",
        _ => "no frame was scored (the run is shorter than the scoring's warm-up)",
    }
}
