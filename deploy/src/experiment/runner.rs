//! Runs one method of an experiment over N seeded simulations and aggregates what
//! node-server's report computes from each outcome: errors pooled over every run's samples,
//! sensors per step, camera measurements per run, power of the camera nodes.

use super::{Options, Row};
use crate::sim::faults::Faults;
use crate::sim::runtime::{Level, Sim, SimOptions};
use node_server::export::track_rows;
use node_server::replay::Loaded;
use node_server::report::{self, Report};
use proto::ClusterTime;
use proto::scenario::Scenario;
use serde::Serialize;

/// One owner estimate of the (single) true target, scored against the truth.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Sample {
    /// Scenario seconds.
    pub t: f64,
    pub est: [f64; 3],
    pub truth: [f64; 3],
    /// √ trace of the position covariance, m.
    pub sigma_m: f64,
    /// Horizontal-plus-vertical (3-D) distance to the truth, m.
    pub error_m: f64,
    pub cameras: u32,
    pub rssi_nodes: u32,
}

/// A method: its label, scenario and faults.
#[derive(Clone, Debug)]
pub struct Method {
    pub label: String,
    pub scenario: Scenario,
    pub faults: Faults,
    /// Whether the method takes RSSI (the RSSI column is n/a otherwise).
    pub uses_rssi: bool,
    /// Association gate of the report, m: a global track farther than this from the target on
    /// average is scored as a false track (node-server's default unless an experiment needs
    /// every track of its single target scored, however far it strays).
    pub gate_m: f64,
    /// ML depth handling of the heads (their default when `None`).
    pub ml_depth: Option<node_head::ml::DepthHandling>,
}

/// Every run of one method.
#[derive(Clone, Debug)]
pub struct Runs {
    pub row: Row,
    /// Each run's samples, in run order.
    pub samples: Vec<Vec<Sample>>,
}

impl Runs {
    /// Mean and standard deviation of the errors of every run's samples with `t` in
    /// `[from, to)`; `None` without samples.
    pub fn errors_in(&self, from: f64, to: f64) -> Option<(f64, f64, usize)> {
        self.errors_where(|t| t >= from && t < to)
    }

    /// The same for the samples outside `[from, to)`.
    pub fn errors_out(&self, from: f64, to: f64) -> Option<(f64, f64, usize)> {
        self.errors_where(|t| t < from || t >= to)
    }

    fn errors_where(&self, keep: impl Fn(f64) -> bool) -> Option<(f64, f64, usize)> {
        let e: Vec<f64> = self
            .samples
            .iter()
            .flatten()
            .filter(|s| keep(s.t))
            .map(|s| s.error_m)
            .collect();
        mean_std(&e).map(|(m, s)| (m, s, e.len()))
    }
}

/// Mean and (population) standard deviation.
pub fn mean_std(xs: &[f64]) -> Option<(f64, f64)> {
    if xs.is_empty() {
        return None;
    }
    let n = xs.len() as f64;
    let m = xs.iter().sum::<f64>() / n;
    Some((m, (xs.iter().map(|x| (x - m).powi(2)).sum::<f64>() / n).sqrt()))
}

/// One simulation of a method: the report and the scored samples.
///
/// # Errors
/// A scenario the simulation cannot build.
pub fn run_once(
    m: &Method,
    seed: u64,
    level: Level,
    duration_s: f64,
) -> anyhow::Result<(Report, Vec<Sample>)> {
    let opts = SimOptions {
        seed,
        duration_s,
        level,
        faults: m.faults.clone(),
        ml_depth: m.ml_depth,
        ..SimOptions::default()
    };
    let outcome = Sim::new(m.scenario.clone(), opts)?.run();
    let loaded = Loaded {
        scenario: m.scenario.clone(),
        records: outcome.records,
        tail: None,
    };
    let report = report::compute_with(&loaded, ClusterTime(0), m.gate_m);
    // The report associates global tracks with the true target; score exactly those.
    let globals = report
        .targets
        .first()
        .map(|t| t.globals.clone())
        .unwrap_or_default();
    let target = m.scenario.targets.first();
    let samples = track_rows(&loaded)
        .into_iter()
        .filter(|r| r.owner && globals.contains(&r.global))
        .filter_map(|r| {
            let x = target?.truth_at(r.t);
            let truth = [x[0], x[1], x[2]];
            let est = [r.x, r.y, r.z];
            let error_m = est
                .iter()
                .zip(&truth)
                .map(|(a, b)| (a - b).powi(2))
                .sum::<f64>()
                .sqrt();
            Some(Sample {
                t: r.t,
                est,
                truth,
                sigma_m: r.sigma_m,
                error_m,
                cameras: r.cameras,
                rssi_nodes: r.rssi_nodes,
            })
        })
        .collect();
    Ok((report, samples))
}

/// Run a method `opts.runs` times (seeds `seed`, `seed + 1`, …) and aggregate.
///
/// # Errors
/// A scenario the simulation cannot build.
pub fn run_method(m: &Method, opts: &Options, level: Level, duration_s: f64) -> anyhow::Result<Runs> {
    let runs = opts.runs.max(1);
    let (mut cams, mut rssi, mut meas, mut power) = (0.0, 0.0, 0.0, 0.0);
    let mut samples = Vec::new();
    let mut untracked = 0u32;
    for k in 0..runs {
        let seed = opts.seed.wrapping_add(u64::from(k));
        let (rep, s) = run_once(m, seed, level, duration_s)?;
        tracing::debug!(method = %m.label, seed, samples = s.len(), "experiment run done");
        cams += rep.active_cameras_mean;
        rssi += rep.rssi_nodes_mean;
        meas += rep.active_cameras_mean * rep.steps as f64;
        power += camera_power(&m.scenario, &rep);
        if s.is_empty() {
            untracked += 1;
        }
        samples.push(s);
    }
    let n = f64::from(runs);
    let errors: Vec<f64> = samples.iter().flatten().map(|s| s.error_m).collect();
    let stats = mean_std(&errors);
    Ok(Runs {
        row: Row {
            method: m.label.clone(),
            mean_error_m: stats.map(|s| s.0),
            std_m: stats.map(|s| s.1),
            measurements: Some(meas / n),
            active_cameras: Some(cams / n),
            rssi_measurements: m.uses_rssi.then_some(rssi / n),
            power_mw: Some(power / n),
            param: None,
            untracked_runs: Some(untracked),
        },
        samples,
    })
}

/// Mean total power of the scenario's camera nodes (the papers count no head or server).
fn camera_power(scenario: &Scenario, rep: &Report) -> f64 {
    rep.energy
        .iter()
        .filter(|e| scenario.cameras().any(|c| c.id == e.node))
        .map(|e| e.mean_power_mw)
        .sum::<f64>()
        + 0.0
}
