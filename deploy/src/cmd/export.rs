//! `ocelli export`: write the tracks of a recording as CSV or JSON Lines, as KML for Google
//! Earth (each global track a time-stamped `gx:Track`; needs `[world.geo]`) or as MCAP for
//! Foxglove Studio (its well-known schemas; location fixes when `[world.geo]` is set).

use super::common::{ScenarioArg, warn_damage};
use anyhow::{Context, Result};
use node_server::analysis::{Loaded, load};
use node_server::export::{Format, track_rows, write_rows};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum FormatArg {
    Csv,
    Jsonl,
    /// Google Earth (needs `[world.geo]` in the recorded scenario or `--scenario`).
    Kml,
    /// Foxglove Studio (a file: needs `--out`).
    Mcap,
}

#[derive(clap::Args, Debug)]
pub struct Args {
    /// The server's recording file.
    #[arg(value_name = "RECORDING")]
    pub recording: PathBuf,
    #[arg(long, value_enum, default_value = "csv")]
    pub format: FormatArg,
    /// Write here instead of standard output.
    #[arg(long, short)]
    pub out: Option<PathBuf>,
    /// Replaces the scenario stored in the recording; its `[world.geo]` places the KML and MCAP
    /// exports.
    #[command(flatten)]
    pub scenario: ScenarioArg,
}

pub fn run(args: Args) -> Result<ExitCode> {
    let scenario = args.scenario.load_given()?;
    let loaded = load(&args.recording, scenario)?;
    warn_damage(&args.recording, &loaded);
    let format = match args.format {
        FormatArg::Csv => Format::Csv,
        FormatArg::Jsonl => Format::JsonLines,
        FormatArg::Kml => return export_kml(&loaded, args.out.as_deref()),
        FormatArg::Mcap => return export_mcap(&loaded, args.out.as_deref()),
    };
    let rows = track_rows(&loaded);
    match &args.out {
        Some(p) => {
            let mut f = std::io::BufWriter::new(
                std::fs::File::create(p).with_context(|| format!("creating {}", p.display()))?,
            );
            write_rows(&rows, format, &mut f)?;
            f.flush()?;
            eprintln!("{} track rows written to {}", rows.len(), p.display());
        }
        None => {
            let stdout = std::io::stdout();
            let mut lock = stdout.lock();
            write_rows(&rows, format, &mut lock)?;
            lock.flush()?;
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// A whole recording as KML: each global track a `gx:Track` Google Earth's time slider plays.
fn export_kml(loaded: &Loaded, out: Option<&Path>) -> Result<ExitCode> {
    let Some(geo) = loaded.scenario.world.geo else {
        anyhow::bail!("cannot export KML: {}", view::kml::NO_GEO.replace("\n", "\n  "));
    };
    let summary = match out {
        Some(p) => {
            let mut f = std::io::BufWriter::new(
                std::fs::File::create(p).with_context(|| format!("creating {}", p.display()))?,
            );
            let s = view::kml::kml_for_recording(loaded, &geo, &mut f)?;
            f.flush()?;
            s
        }
        None => {
            let mut lock = std::io::stdout().lock();
            let s = view::kml::kml_for_recording(loaded, &geo, &mut lock)?;
            lock.flush()?;
            s
        }
    };
    eprintln!(
        "KML: {} tracks ({} points), {} cameras",
        summary.tracks, summary.points, summary.cameras
    );
    Ok(ExitCode::SUCCESS)
}

/// A whole recording as MCAP for Foxglove Studio.
fn export_mcap(loaded: &Loaded, out: Option<&Path>) -> Result<ExitCode> {
    let Some(p) = out else {
        anyhow::bail!("MCAP is a binary file: give it a path with --out FILE.mcap");
    };
    let geo = loaded.scenario.world.geo;
    if geo.is_none() {
        eprintln!("no [world.geo] in the scenario: the MCAP has no location fixes");
    }
    let f = std::io::BufWriter::new(
        std::fs::File::create(p).with_context(|| format!("creating {}", p.display()))?,
    );
    let summary = view::mcap::write_mcap(loaded, geo.as_ref(), f)?;
    let total: u64 = summary.messages.values().sum();
    eprintln!(
        "{total} messages on {} channels written to {}",
        summary.messages.len(),
        p.display()
    );
    Ok(ExitCode::SUCCESS)
}
