//! `ocelli export`: write the tracks of a recording as CSV or JSON Lines.

use anyhow::{Context, Result};
use node_server::analysis::load;
use node_server::export::{Format, track_rows, write_rows};
use proto::scenario::Scenario;
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
    pub recording: PathBuf,
    #[arg(long, value_enum, default_value = "csv")]
    pub format: FormatArg,
    /// Write here instead of standard output.
    #[arg(long, short)]
    pub out: Option<PathBuf>,
    /// Scenario to replay with (default: the one stored in the recording).
    #[arg(long)]
    pub scenario: Option<PathBuf>,
}

pub fn run(args: Args) -> Result<ExitCode> {
    let scenario = args.scenario.as_deref().map(Scenario::load).transpose()?;
    let loaded = load(&args.recording, scenario)?;
    for s in &loaded.skipped {
        tracing::warn!(offset = s.offset, bytes = s.bytes, damage = ?s.damage, "recording: damaged stretch skipped; exported the records around it");
    }
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
