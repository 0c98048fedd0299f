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
//!
//! Recorded times map onto the replay's virtual clock by subtracting `t0`, the cluster time
//! of scenario time 0 ([`recording_t0`]: the recording's origin, 0 for `ocelli sim`). The
//! replay's own records, estimates and report are in virtual time, i.e. seconds since `t0`.
//!
//! A logging run of real processes (`ocelli launch --record-measurements`) replays only
//! approximately: its records are stamped with the server's wall clock when each frame
//! *arrived*, so the replay sees every frame shifted by its transport and scheduling delay
//! and re-quantized onto its own frame ticks (a recorded frame is used at the first replayed
//! frame event of that camera at or after it; two in one period supersede each other); the
//! heads step on the replay's simulated network and clocks rather than the run's; frames the
//! run's transport dropped under backpressure are missing. The live run's decisions are not reproduced record for record —
//! the methods and policies are compared on the same measurements, which is what matters.

use crate::Result;
use node_server::analysis::{Loaded, measured_frames};
use node_server::export::{TrackRow, track_rows};
use node_server::report::Report;
use node_server::{Record, Stamped};
use proto::ClusterTime;
use proto::scenario::{Activation, Fusion, NodeRole, Scenario};
use sim::logged::Recorded;
use sim::{NetCounters, Sim, SimOptions};

/// How to re-run a recording.
#[derive(Clone, Debug)]
pub struct RerunOptions {
    /// Fusion method of the replay (default: the recorded scenario's).
    pub fusion: Option<Fusion>,
    /// Activation policy of the replay (default: the recorded scenario's).
    pub activation: Option<Activation>,
    /// Seed, network model and tick periods of the replay's simulated network and clocks.
    /// `duration_s` is ignored: the replay runs to the recording's last record. `level` is the
    /// level the recording was made at (`Pixel`, the default, for a launch's).
    pub sim: SimOptions,
    /// Cluster time of scenario time 0 in the recording (0 for `ocelli sim`; see
    /// [`recording_t0`]).
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
            skipped: Vec::new(),
        }
    }
}

/// Longest recording a replay re-runs, ns (a week): more means a wrong `t0`.
pub const MAX_REPLAY_NS: i64 = 7 * 24 * 3600 * 1_000_000_000;

/// The cluster time of scenario time 0 in a recording when nobody says otherwise: the one its
/// origin record states (`ocelli sim`: 0; `ocelli launch`: the epoch its cameras' synthetic
/// world started at), else its first record's (older recordings).
pub fn recording_t0(loaded: &Loaded) -> ClusterTime {
    loaded
        .origin()
        .map(|o| o.t0)
        .or_else(|| loaded.records.first().map(|s| s.at))
        .unwrap_or(ClusterTime(0))
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
    if frames == 0 {
        return Err(crate::LabError::failed(
            "replay",
            "the recording holds no camera measurements: make a logging run (`ocelli sim \
             --record-measurements --record FILE` or `ocelli launch --record-measurements`)",
        ));
    }
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
    if last_ns > MAX_REPLAY_NS {
        return Err(crate::LabError::failed(
            "replay",
            format!(
                "the recording ends {:.0} s after t0 = {} ns: is t0 right? (default: the first \
         record's time)",
                last_ns as f64 * 1e-9,
                opts.t0.0
            ),
        ));
    }
    let sim_opts = SimOptions {
        duration_s: last_ns as f64 * 1e-9,
        ..opts.sim.clone()
    };
    let sim = Sim::replaying(scenario.clone(), sim_opts, recorded)?;
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

/// Re-run the recording at `path` (with `scenario` instead of the recorded one, if given):
/// the replay's owner track rows (one per global track and step) and its report, scored as
/// `crate::report::Scoring` says (`given_t0`: a time origin the user gave). `t0` of the
/// options: the option's, or the recording's (see [`recording_t0`]).
///
/// # Errors
/// An unreadable recording or scenario, or a recording without measurements.
pub fn replay_recording(
    path: &std::path::Path,
    scenario: Option<Scenario>,
    given_t0: Option<ClusterTime>,
    opts: impl FnOnce(&Loaded) -> RerunOptions,
) -> Result<(Vec<TrackRow>, Report)> {
    let loaded = node_server::analysis::load(path, scenario)?;
    let scored = crate::report::Scoring::of(&loaded, given_t0).t0().is_some();
    let opts = opts(&loaded);
    let replay = rerun(&loaded, &opts)?;
    tracing::info!(
        frames = replay.frames,
        unknown_camera_frames = replay.unknown_camera_frames,
        superseded_frames = replay.superseded_frames,
        fusion = replay.scenario.method.fusion.name(),
        activation = replay.scenario.method.activation.name(),
        "replay done"
    );
    let replayed = replay.loaded();
    let rows = track_rows(&replayed).into_iter().filter(|r| r.owner).collect();
    // The replay's records are on its own virtual clock, where scenario time 0 is 0.
    let truth = if scored {
        sim::WorldTruth::of(&replayed.scenario, ClusterTime(0))?
    } else {
        None
    };
    let report = node_server::report::compute(
        &replayed,
        truth.as_ref().map(|t| t as &dyn node_server::report::Truth),
    );
    Ok((rows, report))
}

#[cfg(test)]
mod tests {
    use super::*;
    use sim::Level;

    /// A logging run whose records are stamped in wall-clock time (as a launch's are) replays
    /// exactly like the same run stamped from 0, with `t0` taken from its first record.
    #[test]
    fn wall_clock_recordings_replay_from_their_first_record() {
        let scenario = Scenario::default_scenario();
        let sim = SimOptions {
            duration_s: 4.0,
            level: Level::Measurement,
            record_measurements: true,
            ..SimOptions::default()
        };
        let run = Sim::new(scenario.clone(), sim.clone()).unwrap().run();
        let first = Stamped::new(ClusterTime(0), Record::Scenario(scenario.to_toml()));
        let at_zero: Vec<Stamped> = std::iter::once(first).chain(run.records).collect();
        let wall = 1_763_740_000_123_456_789;
        let shifted = at_zero
            .iter()
            .map(|s| Stamped::new(ClusterTime(s.at.0 + wall), s.record.clone()))
            .collect();
        let loaded = |records| Loaded {
            scenario: scenario.clone(),
            records,
            skipped: Vec::new(),
        };
        let (from_zero, from_wall) = (loaded(at_zero), loaded(shifted));
        assert_eq!(recording_t0(&from_zero), ClusterTime(0));
        assert_eq!(recording_t0(&from_wall), ClusterTime(wall));
        let opts = |t0| RerunOptions {
            fusion: None,
            activation: Some(Activation::AllOn),
            sim: sim.clone(),
            t0,
        };
        let a = rerun(&from_zero, &opts(recording_t0(&from_zero))).unwrap();
        let b = rerun(&from_wall, &opts(recording_t0(&from_wall))).unwrap();
        assert!(a.records.len() > 100, "{} records", a.records.len());
        assert_eq!(a.records, b.records);
        // Without the shift the recording would end decades after scenario time 0.
        let e = rerun(&from_wall, &opts(ClusterTime(0))).unwrap_err().to_string();
        assert!(e.contains("is t0 right?"), "{e}");
    }
}
