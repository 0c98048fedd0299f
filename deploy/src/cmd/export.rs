//! `ocelli export`: write the tracks of a recording as CSV or JSON Lines.

use super::common::{ScenarioArg, warn_damage};
use anyhow::{Context, Result};
use node_server::analysis::load;
use node_server::export::{Format, track_rows, write_rows};
use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum FormatArg {
    Csv,
    Jsonl,
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
    /// Replaces the scenario stored in the recording.
    #[command(flatten)]
    pub scenario: ScenarioArg,
}

pub fn run(args: Args) -> Result<ExitCode> {
    let scenario = args.scenario.load_given()?;
    let loaded = load(&args.recording, scenario)?;
    warn_damage(&args.recording, &loaded);
    let rows = track_rows(&loaded);
    let format = match args.format {
        FormatArg::Csv => Format::Csv,
        FormatArg::Jsonl => Format::JsonLines,
    };
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
