//! `ocelli acoustic`: the two-microphone acoustic node of paper 001, and its two tools.
//!
//! - `ocelli acoustic --id N [--scenario FILE] [--audio synthetic|wav:FILE|live:DEVICE]`: run
//!   acoustic node N as a process (node-acoustic's `process::run`) until SIGINT/SIGTERM;
//! - `ocelli acoustic survey --positions FILE.csv --out FINGERPRINTS [--scenario FILE]`: the
//!   fingerprint database from recordings at known positions (CSV `x,y,wav`);
//! - `ocelli acoustic locate --fingerprints F --wav FILE [--frame-ms 250] [--json]
//!   [--scenario FILE]`: the grid estimator on the acoustic likelihood alone, one line per
//!   frame (`{"t", "x", "y", "sigma_m"}` with `--json`).

use super::common::{
    ExitSummaryArg, SecurityArgs, TransportArg, load_scenario, run_node, transport_or_scenario,
};
use anyhow::{Context, Result, bail};
use node_acoustic::process::{OpenAudio, ProcessConfig, run};
use node_acoustic::source::WavSource;
use node_head::grid::locate::{LocateParams, Locator, survey_world};
use proto::acoustic::{FingerprintDb, IldSettings};
use proto::scenario::{Scenario, World, low_band};
use proto::sensor::AudioSource;
use proto::{ClusterTime, NodeId};
use runtime::HostClock;
use runtime::config::transport_config;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

#[derive(clap::Args, Debug)]
#[command(args_conflicts_with_subcommands = true)]
pub struct Args {
    #[command(subcommand)]
    pub tool: Option<Tool>,
    #[command(flatten)]
    pub node: NodeArgs,
}

#[derive(clap::Subcommand, Debug)]
pub enum Tool {
    /// Build a fingerprint database from recordings at known positions.
    Survey(SurveyArgs),
    /// Locate a sound source in a recording from fingerprints alone.
    Locate(LocateArgs),
}

#[derive(clap::Args, Debug)]
pub struct NodeArgs {
    /// This acoustic node's id in the scenario.
    #[arg(long)]
    pub id: Option<u32>,
    /// Scenario file (default: the embedded default scenario).
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// Transport (default: the scenario's `network.transport`).
    #[arg(long, value_enum)]
    pub transport: Option<TransportArg>,
    #[command(flatten)]
    pub security: SecurityArgs,
    #[command(flatten)]
    pub exit: ExitSummaryArg,
    /// Audio: `synthetic` (the scenario's simulated room), `wav:FILE` (played in real time,
    /// looping) or `live:DEVICE` (`live:default`; needs the `cpal` feature).
    #[arg(long, default_value = "synthetic")]
    pub audio: String,
    /// Seed of the simulated room's noise.
    #[arg(long, default_value_t = super::camera::SYNTHETIC_SEED)]
    pub seed: u64,
    /// Cluster time (ns since the Unix epoch) of scenario time 0 (the simulated room).
    #[arg(long)]
    pub epoch_ns: Option<i64>,
}

#[derive(clap::Args, Debug)]
pub struct SurveyArgs {
    /// CSV with a header `x,y,wav`: metres and a 2-channel WAV relative to the CSV.
    #[arg(long)]
    pub positions: PathBuf,
    /// Where to write the fingerprint database (JSON).
    #[arg(long)]
    pub out: PathBuf,
    /// The room (its box and walls): positions outside it are refused and the database is
    /// valid only there. Default: the positions' bounding box, grown by half a metre.
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// Sample rate of the recordings, Hz (default: the first recording's).
    #[arg(long)]
    pub sample_rate: Option<u32>,
}

#[derive(clap::Args, Debug)]
pub struct LocateArgs {
    /// The fingerprint database (`ocelli acoustic survey`).
    #[arg(long)]
    pub fingerprints: PathBuf,
    /// A 2-channel WAV recorded at the fingerprints' sample rate.
    #[arg(long)]
    pub wav: PathBuf,
    /// Audio per estimate, ms.
    #[arg(long, default_value_t = 250.0)]
    pub frame_ms: f64,
    /// One JSON object per frame: `{"t", "x", "y", "sigma_m"}`.
    #[arg(long)]
    pub json: bool,
    /// The room's walls (the fingerprints must have been surveyed in it). Default: the
    /// survey's region without walls.
    #[arg(long)]
    pub scenario: Option<PathBuf>,
}

pub fn run_cmd(args: Args) -> Result<ExitCode> {
    match args.tool {
        Some(Tool::Survey(a)) => survey(&a),
        Some(Tool::Locate(a)) => locate(&a),
        None => node(args.node),
    }
}

/// The audio source a `--audio` value names, and whether the process paces it.
fn audio_source(
    spec: &str,
    scenario: &Scenario,
    id: u32,
    seed: u64,
    epoch: ClusterTime,
) -> Result<(OpenAudio, bool)> {
    let rate = scenario
        .node(id)
        .and_then(|n| n.acoustic.as_ref())
        .map_or(8000, |a| a.ild.sample_rate);
    if spec == "synthetic" {
        let audio = world::sources::SyntheticAudio::new(scenario, id, seed, epoch)?;
        return Ok((
            Box::new(move || Ok(Box::new(audio) as Box<dyn AudioSource>)),
            true,
        ));
    }
    if let Some(path) = spec.strip_prefix("wav:") {
        // Read now, so a bad file fails the command with its reason before anything starts.
        let source = WavSource::open(Path::new(path), rate)?.looping(true);
        return Ok((
            Box::new(move || Ok(Box::new(source) as Box<dyn AudioSource>)),
            true,
        ));
    }
    if let Some(device) = spec.strip_prefix("live:") {
        #[cfg(feature = "cpal")]
        {
            let device = device.to_string();
            let open: OpenAudio = Box::new(move || {
                Ok(Box::new(node_acoustic::live::LiveSource::open(&device, rate)?) as Box<dyn AudioSource>)
            });
            return Ok((open, false));
        }
        #[cfg(not(feature = "cpal"))]
        bail!("live:{device}: this build has no live audio capture (build with --features cpal)");
    }
    bail!("unknown --audio {spec:?}: expected synthetic, wav:FILE or live:DEVICE")
}

fn node(args: NodeArgs) -> Result<ExitCode> {
    let Some(id) = args.id else {
        bail!("`ocelli acoustic` needs --id N (or a tool: survey, locate)");
    };
    let scenario = load_scenario(args.scenario.as_ref())?;
    let kind = transport_or_scenario(args.transport, &scenario);
    let clock = HostClock::follower();
    let transport = transport_config(
        &scenario,
        NodeId(id),
        kind,
        &clock,
        None,
        &args.security.link_security(),
    )?;
    let epoch = args.epoch_ns.map_or_else(|| clock.now(), ClusterTime);
    let (audio, paced) = audio_source(&args.audio, &scenario, id, args.seed, epoch)?;
    let leader = scenario.server().map(|s| NodeId(s.id));
    let cfg = ProcessConfig {
        id,
        process: runtime::ProcessConfig::new(transport, leader, Duration::from_millis(100)),
        audio,
        paced,
        scenario,
    };
    let summary = run_node(|shutdown| async move { Ok(run(cfg, clock, shutdown).await?) })?;
    args.exit.write(&summary.run);
    let c = summary.counters;
    println!(
        "{}",
        serde_json::json!({
            "event": "stopped",
            "node": id,
            "frames": c.frames,
            "silent": c.silent,
            "clipped": c.clipped,
            "rejected": c.rejected,
            "stalls": c.stalls,
            "dropped": c.dropped,
            "frames_lost": summary.frames_lost,
            "send_failures": summary.run.send_failures,
        })
    );
    Ok(ExitCode::SUCCESS)
}

/// The ILD settings a survey uses: the scenario's first acoustic node's (or the default
/// band), at the recordings' sample rate.
fn survey_settings(
    scenario: Option<&Scenario>,
    positions: &Path,
    rows: &[node_acoustic::survey::SurveyRow],
    rate: Option<u32>,
) -> Result<IldSettings> {
    let mut s = scenario
        .and_then(|s| s.acoustic_nodes().find_map(|n| n.acoustic.as_ref()))
        .map_or_else(low_band, |a| a.ild.clone());
    s.sample_rate = match rate {
        Some(r) => r,
        None => {
            let first = rows.first().context("no positions")?;
            if !first.wav.is_file() {
                bail!(
                    "{}: row 1: recording {} does not exist",
                    positions.display(),
                    first.wav.display()
                );
            }
            hound::WavReader::open(&first.wav)
                .with_context(|| format!("{}: cannot read as WAV", first.wav.display()))?
                .spec()
                .sample_rate
        }
    };
    Ok(s)
}

fn survey(a: &SurveyArgs) -> Result<ExitCode> {
    let scenario = a.scenario.as_deref().map(Scenario::load).transpose()?;
    let rows = node_acoustic::survey::read_positions(&a.positions)?;
    let world: World = match &scenario {
        Some(s) => s.world.clone(),
        None => node_acoustic::survey::bounding_world(&rows, 0.5),
    };
    let settings = survey_settings(scenario.as_ref(), &a.positions, &rows, a.sample_rate)?;
    let db = node_acoustic::survey::survey(&a.positions, &world, &settings)?;
    db.save(&a.out)?;
    eprintln!(
        "surveyed {} positions on a {}x{} lattice at {} Hz into {}",
        db.fingerprints().len(),
        db.lattice().shape[0],
        db.lattice().shape[1],
        settings.sample_rate,
        a.out.display()
    );
    Ok(ExitCode::SUCCESS)
}

fn locate(a: &LocateArgs) -> Result<ExitCode> {
    let db = FingerprintDb::load(&a.fingerprints)?;
    let origin = a.fingerprints.display().to_string();
    let world = match &a.scenario {
        Some(path) => {
            let s = Scenario::load(path)?;
            db.check_room(&s.world, &origin)?;
            s.world
        }
        None => survey_world(&db),
    };
    let settings = db.settings().clone();
    let clip = node_acoustic::read_stereo(&a.wav, settings.sample_rate)?;
    let (frames, counts) = node_acoustic::frames::frame_ilds(&clip, &settings, a.frame_ms)?;
    let mut locator = Locator::new(&world, db, &LocateParams::default())?;
    for f in &frames {
        let fix = locator.step(f.t, f.ild.as_ref())?;
        if a.json {
            println!(
                "{}",
                serde_json::json!({"t": fix.t, "x": fix.x, "y": fix.y, "sigma_m": fix.sigma_m})
            );
        } else {
            let note = if fix.corrected {
                ""
            } else {
                "  (skipped: silent or clipped)"
            };
            println!(
                "t={:7.2}s  x={:6.2} m  y={:6.2} m  σ {:.2} m{note}",
                fix.t, fix.x, fix.y, fix.sigma_m
            );
        }
    }
    if counts.good == 0 {
        bail!("{}: no frame free of silence and clipping", a.wav.display());
    }
    Ok(ExitCode::SUCCESS)
}
