//! Re-running a logging run's recording through the heads with another fusion method and
//! activation policy (paper 002 logged every measurement once and processed it offline with
//! each method).
//!
//! The recording's `Record::Measured` frames replace sensing in the simulation runtime
//! ([`Sim::replaying`]): the same camera, head and server cores as a run, on a virtual clock.
//! A camera answers each head's `Prior` from its recorded measurement linearized at the
//! broadcast μ̄ (node-camera's own code), the heads fuse and switch sensors with the replayed
//! method and policy, and a camera the replayed policy switched off ignores its recorded
//! frames (its RSSI too while its radio sleeps). Estimates and the report come from the
//! replay's own server records, exactly as `ocelli export` / `ocelli report` compute them.
//!
//! With the run's scenario, method, policy, seed and network options, the replay's records
//! equal the run's (less the measurements): every input a core sees is bit for bit the
//! same, at the same virtual time, in the same order.

use crate::sim::logged::Recorded;
use crate::sim::runtime::{NetCounters, Sim, SimOptions};
use anyhow::{Context, Result};
use node_server::replay::{Loaded, measured_frames};
use node_server::{Record, Stamped};
use proto::ClusterTime;
use proto::scenario::{Activation, Fusion, NodeRole, Scenario};

/// How to re-run a recording.
#[derive(Clone, Debug)]
pub struct RerunOptions {
    /// Fusion method of the replay (default: the recorded scenario's).
    pub fusion: Option<Fusion>,
    /// Activation policy of the replay (default: the recorded scenario's).
    pub activation: Option<Activation>,
    /// Seed, network model and tick periods of the replay's simulated network and clocks.
    /// `duration_s` is ignored: the replay runs to the recording's last record.
    pub sim: SimOptions,
    /// Cluster time of scenario time 0 in the recording (0 for `ocelli sim`).
    pub t0: ClusterTime,
}

/// What a replay leaves behind.
#[derive(Debug)]
pub struct Rerun {
    /// The recorded scenario with the replayed method and policy.
    pub scenario: Scenario,
    /// The replay's server records (its recording).
    pub records: Vec<Stamped>,
    pub net: NetCounters,
    /// Recorded camera frames, and those of cameras the scenario does not have.
    pub frames: u64,
    pub unknown_camera_frames: u64,
    /// Frames passed over because a newer one was due at the same frame event (a recording
    /// made at another frame rate).
    pub superseded_frames: u64,
}

impl Rerun {
    /// The replay as a loaded recording, for `node_server::{export, report}`.
    pub fn loaded(&self) -> Loaded {
        Loaded {
            scenario: self.scenario.clone(),
            records: self.records.clone(),
            tail: None,
        }
    }
}

/// Re-run `loaded`'s recorded measurements through fresh cores.
///
/// # Errors
/// A recording without measurements (not a logging run), or a scenario the simulation cannot
/// build.
pub fn rerun(loaded: &Loaded, opts: &RerunOptions) -> Result<Rerun> {
    let mut scenario = loaded.scenario.clone();
    if let Some(f) = opts.fusion {
        scenario.method.fusion = f;
    }
    if let Some(a) = opts.activation {
        scenario.method.activation = a;
    }
    let cameras: std::collections::BTreeSet<u32> = scenario
        .nodes
        .iter()
        .filter(|n| n.role == NodeRole::Camera)
        .map(|n| n.id)
        .collect();
    let (mut frames, mut unknown) = (0u64, 0u64);
    let known = measured_frames(loaded).filter(|(_, f)| {
        frames += 1;
        let ok = cameras.contains(&f.camera.0);
        unknown += u64::from(!ok);
        ok
    });
    let recorded = Recorded::new(known, opts.t0);
    anyhow::ensure!(
        frames > 0,
        "the recording holds no camera measurements: make a logging run (`ocelli sim \
         --record-measurements --record FILE`)"
    );
    if unknown > 0 {
        tracing::warn!(
            frames = unknown,
            "replay: frames of cameras the scenario does not have, skipped"
        );
    }
    let last_ns = loaded
        .records
        .iter()
        .map(|s| s.at.0 - opts.t0.0)
        .max()
        .unwrap_or(0)
        .max(recorded.last_ns().unwrap_or(0));
    let sim_opts = SimOptions {
        duration_s: last_ns as f64 * 1e-9,
        ..opts.sim.clone()
    };
    let sim = Sim::replaying(scenario.clone(), sim_opts, recorded).context("building the replay's nodes")?;
    let outcome = sim.run();
    Ok(Rerun {
        scenario,
        records: outcome.records,
        net: outcome.net,
        frames,
        unknown_camera_frames: unknown,
        superseded_frames: outcome.superseded_frames,
    })
}

/// The server records of a run or replay that are not recorded measurements.
pub fn without_measurements(records: &[Stamped]) -> Vec<&Stamped> {
    records
        .iter()
        .filter(|s| !matches!(s.record, Record::Measured(_)))
        .collect()
}
