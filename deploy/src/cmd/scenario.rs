//! `ocelli scenario`: print the embedded default scenario, check a scenario file, or survey a
//! scenario's simulated room for its default RSSI model.

use anyhow::Result;
use proto::models::{RssiModel, fit_log_distance};
use proto::scenario::{CameraTracker, DEFAULT_SCENARIO_TOML, Scenario};
use std::path::PathBuf;
use std::process::ExitCode;
use world::radio::{SURVEY_READINGS_PER_PAIR, survey};

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    pub action: Action,
}

/// `--camera-tracker`: what a generated hall's cameras make of their frames.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum TrackerArg {
    /// Paper 004's colour particle filters, each person sent as a floor position.
    Particle,
    /// Segmented regions, each sent as a pin-hole point.
    Segmentation,
}

impl From<TrackerArg> for CameraTracker {
    fn from(t: TrackerArg) -> CameraTracker {
        match t {
            TrackerArg::Particle => CameraTracker::Particle,
            TrackerArg::Segmentation => CameraTracker::Segmentation,
        }
    }
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
    /// Print a generated hall: cameras on the walls and on a grid of posts aimed to cover the
    /// floor, heads whose regions tile it, people crossing it (every third tagged); checked as
    /// `check` does, with the floor's coverage by two cameras or more printed on stderr.
    Generate {
        #[arg(long, default_value_t = 100)]
        cameras: u32,
        #[arg(long, default_value_t = 5)]
        heads: u32,
        #[arg(long, default_value_t = 10)]
        people: u32,
        /// Floor size, metres: WIDTHxDEPTH.
        #[arg(long, default_value = "30x20")]
        size: String,
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// What the cameras make of their frames.
        #[arg(long, value_enum, default_value_t = TrackerArg::Particle)]
        camera_tracker: TrackerArg,
    },
    /// Print a deployment replaying one trajectory of the BLE RSSI dataset: one radio-only node
    /// per sensor at its surveyed position, one head tracking from RSSI alone (the law fitted
    /// on the other trajectories). `ocelli launch` it to score it against the file's truth.
    BleRssi {
        /// Trajectory name (`straight_01`, …; default: the first).
        #[arg(long)]
        trajectory: Option<String>,
        /// The dataset's directory (default: `$OCELLI_BLE_RSSI_DIR`, else
        /// `shared/datasets/ble-rssi` beside the repository).
        #[arg(long)]
        dataset: Option<PathBuf>,
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
        Action::Generate {
            cameras,
            heads,
            people,
            size,
            seed,
            camera_tracker,
        } => {
            use world::generate::{HallSpec, coverage, generate};
            let parse = |v: Option<&str>| v.and_then(|v| v.trim().parse::<f64>().ok());
            let mut it = size.split('x');
            let (Some(w), Some(d)) = (parse(it.next()), parse(it.next())) else {
                anyhow::bail!("--size {size:?}: expected WIDTHxDEPTH in metres, e.g. 30x20");
            };
            let spec = HallSpec {
                cameras,
                heads,
                people,
                size: [w, d],
                seed,
                camera_tracker: camera_tracker.into(),
                ..HallSpec::default()
            };
            let (s, text) = generate(&spec)?;
            eprintln!(
                "{}: floor seen by two cameras or more: {:.1}% (0.5 m grid)",
                s.name,
                100.0 * coverage(&s, 0.5, 0.0, 2)
            );
            print!("{text}");
        }
        Action::BleRssi { trajectory, dataset } => {
            use lab::experiment::ble_rssi::{data, launch};
            let dir = dataset.unwrap_or_else(data::default_dir);
            let ds = data::load(&dir)?;
            let i = match &trajectory {
                None => 0,
                Some(name) => ds
                    .trajectories
                    .iter()
                    .position(|t| &t.name == name)
                    .ok_or_else(|| {
                        let names: Vec<&str> = ds.trajectories.iter().map(|t| t.name.as_str()).collect();
                        anyhow::anyhow!(
                            "no trajectory {name:?} in {} (there are {names:?})",
                            dir.display()
                        )
                    })?,
            };
            print!("{}", launch::scenario_toml(&ds, i)?);
        }
    }
    Ok(ExitCode::SUCCESS)
}
