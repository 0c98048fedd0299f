//! The papers' experiments (`ocelli experiment NAME`): each builds its scenario in code, runs
//! every method over N seeded runs in the simulation runtime ((crate `sim`)), scores the
//! outcome against ground truth with node-server's report, and sets our table beside the
//! paper's numbers (constants copied from `papers/README.md`, labelled "paper"). Ground truth is
//! only read for scoring; no estimate sees it.
//!
//! `ble-rssi` is the exception: it checks our RSSI models against a real dataset instead of a
//! simulation, and is not in [`NAMES`] (see [`REAL_DATA`]).
//!
//! One module per experiment, [`runner`] (run a method, aggregate runs), [`table`] (text,
//! JSON and Markdown) and [`plot`] (PNG figures).

pub mod ble_rssi;
pub mod crowd;
pub mod paper000_table1;
pub mod paper001;
pub mod paper002_occlusion;
pub mod paper002_robustness;
pub mod paper002_rssi_only;
pub mod paper002_table1;
pub mod paper004;
pub mod plot;
pub mod runner;
pub mod table;

use runner::Sample;
use serde::Serialize;
use sim::Level;

/// Every simulated experiment, in priority order: what `ocelli experiment all` runs.
pub const NAMES: [&str; 7] = [
    "paper000-table1",
    "paper001",
    "paper002-table1",
    "paper002-occlusion",
    "paper002-rssi-only",
    "paper002-robustness",
    paper004::NAME,
];

/// Experiments on real data from `shared/datasets/`: run by name only, never by `all`, so that
/// `all` works without the shared datasets (each fails with the dataset's path when absent).
pub const REAL_DATA: [&str; 1] = [ble_rssi::NAME];

/// Experiments too slow for `all` (minutes per run at pixel level): run by name only.
pub const SLOW: [&str; 1] = [crowd::NAME];

/// How to run an experiment.
#[derive(Clone, Debug)]
pub struct Options {
    pub runs: u32,
    /// Seed of the first run; run k uses `seed + k`.
    pub seed: u64,
    /// Overrides the experiment's level (pixel for the tables, measurement for the sweeps).
    pub level: Option<Level>,
    /// Overrides the experiment's simulated duration, s (for short test runs).
    pub duration_s: Option<f64>,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            runs: 5,
            seed: 1,
            level: None,
            duration_s: None,
        }
    }
}

impl Options {
    fn level_or(&self, default: Level) -> Level {
        self.level.unwrap_or(default)
    }
}

/// One row of a table: a method (or a method at one sweep point). `None` where n/a.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Row {
    pub method: String,
    pub mean_error_m: Option<f64>,
    pub std_m: Option<f64>,
    /// Camera measurements used per run.
    pub measurements: Option<f64>,
    /// Cameras with a measurement per filter step.
    pub active_cameras: Option<f64>,
    /// RSSI readings per filter step.
    pub rssi_measurements: Option<f64>,
    /// Mean total power of the camera nodes, mW.
    pub power_mw: Option<f64>,
    /// Sweep parameter of the row, if any.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub param: Option<f64>,
    /// Runs in which the target was never tracked (no error samples).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub untracked_runs: Option<u32>,
    /// Half-width of the 95% confidence interval of the mean error over these runs (Student's t
    /// on the runs' own means). Two runs or more.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mean_error_ci95_m: Option<f64>,
    /// Each run's own mean error, in run order (`None` for a run without samples): what the
    /// interval and the paired comparisons of the shape checks are computed from.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub run_errors_m: Vec<Option<f64>>,
    /// Each run's mean total power of the camera nodes, mW, in run order.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub run_power_mw: Vec<f64>,
    /// Figures of an experiment's own, outside the common columns (each a column of its
    /// table, in order of first appearance).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub extra: Vec<Extra>,
}

/// One named figure of a row outside the common columns.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Extra {
    pub name: String,
    pub value: Option<f64>,
    /// Decimals shown in the tables.
    #[serde(skip)]
    pub digits: usize,
}

impl Extra {
    pub fn new(name: &str, value: Option<f64>, digits: usize) -> Extra {
        Extra {
            name: name.to_string(),
            value,
            digits,
        }
    }
}

impl Row {
    /// This row with the error figures of `e` (none when there were no samples).
    pub fn with_errors(self, e: Option<runner::Errors>) -> Row {
        Row {
            mean_error_m: e.as_ref().map(|e| e.mean),
            std_m: e.as_ref().map(|e| e.std),
            mean_error_ci95_m: e.as_ref().and_then(|e| e.ci95),
            run_errors_m: e.map(|e| e.run_means).unwrap_or_default(),
            ..self
        }
    }
}

/// One of the paper's shape claims, checked on our rows.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Check {
    pub claim: String,
    pub holds: bool,
    /// Our numbers behind the verdict.
    pub ours: String,
}

impl Check {
    fn new(claim: &str, holds: bool, ours: String) -> Self {
        Check {
            claim: claim.to_string(),
            holds,
            ours,
        }
    }
}

/// The first run of one method, kept for the figures.
#[derive(Clone, Debug, Serialize)]
pub struct Trace {
    pub method: String,
    pub samples: Vec<Sample>,
    /// Scenario seconds of an interval the experiment is about (loss, occlusion), if any.
    pub window: Option<(f64, f64)>,
}

/// A particle-filter camera's first run, kept for paper 004's Figs. 6–7: the filters' pdf
/// over time and one frame with its samples.
#[derive(Clone, Debug, Default)]
pub struct ParticleTrace {
    pub method: String,
    /// The frame's size, px.
    pub width: u32,
    pub height: u32,
    /// Width of the marginals' bins, px.
    pub bin_px: u32,
    /// Every frame's marginals.
    pub frames: Vec<PdfSlice>,
    pub snapshot: Option<SampleSnapshot>,
}

/// One frame's pdf p(X_t | Z_t) projected on the image's columns and rows: the weight of every
/// live filter's samples per bin. Each filter's weights sum to 1, so the bins of a frame sum to
/// the number of people tracked.
#[derive(Clone, Debug, Default)]
pub struct PdfSlice {
    pub t: f64,
    pub columns: Vec<f32>,
    pub rows: Vec<f32>,
}

/// One frame as the camera saw it, every filter's samples `[x, y, weight]` (px, weight
/// normalised per filter) and each filter's mean `[x, y]`.
#[derive(Clone, Debug)]
pub struct SampleSnapshot {
    pub t: f64,
    pub image: image::RgbImage,
    pub samples: Vec<[f32; 3]>,
    pub means: Vec<[f32; 2]>,
    /// Why this frame: what was happening.
    pub why: String,
}

/// What an experiment produced.
#[derive(Clone, Debug, Serialize)]
pub struct Outcome {
    pub experiment: String,
    pub level: Level,
    pub runs: u32,
    pub seed: u64,
    pub duration_s: f64,
    pub rows: Vec<Row>,
    pub paper: Vec<Row>,
    pub shape: Vec<Check>,
    /// Setup choices the paper leaves open, and what differs.
    pub notes: Vec<String>,
    #[serde(skip)]
    pub traces: Vec<Trace>,
    #[serde(skip)]
    pub particles: Option<ParticleTrace>,
}

impl Outcome {
    /// An experiment's outcome before its rows: its name, level, runs and seed from `opts`, and
    /// the simulated seconds per run.
    pub fn new(experiment: &str, level: Level, opts: &Options, duration_s: f64) -> Outcome {
        Outcome {
            experiment: experiment.into(),
            level,
            runs: opts.runs.max(1),
            seed: opts.seed,
            duration_s,
            rows: Vec::new(),
            paper: Vec::new(),
            shape: Vec::new(),
            notes: Vec::new(),
            traces: Vec::new(),
            particles: None,
        }
    }

    /// The row of a method.
    pub fn row(&self, method: &str) -> Option<&Row> {
        self.rows.iter().find(|r| r.method == method)
    }
}

/// Run an experiment by name.
///
/// # Errors
/// An unknown name, or a scenario the simulation cannot build.
pub fn run(name: &str, opts: &Options) -> crate::Result<Outcome> {
    match name {
        "paper000-table1" => paper000_table1::run(opts),
        paper001::NAME => paper001::run(opts),
        "paper002-table1" => paper002_table1::run(opts),
        "paper002-occlusion" => paper002_occlusion::run(opts),
        "paper002-rssi-only" => paper002_rssi_only::run(opts),
        "paper002-robustness" => paper002_robustness::run(opts),
        paper004::NAME => paper004::run(opts),
        ble_rssi::NAME => ble_rssi::run(opts),
        crowd::NAME => crowd::run(opts),
        other => Err(crate::LabError::UnknownExperiment {
            name: other.into(),
            known: format!(
                "{}, {}, {}",
                NAMES.join(", "),
                REAL_DATA.join(", "),
                SLOW.join(", ")
            ),
        }),
    }
}

/// A paper row with only the figures the paper gives.
fn paper_row(method: &str, error_m: Option<f64>, std_m: Option<f64>) -> Row {
    Row {
        method: method.to_string(),
        mean_error_m: error_m,
        std_m,
        ..Row::default()
    }
}
