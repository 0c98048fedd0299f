//! A recording's report as every command computes it (`ocelli report`, the report `ocelli
//! launch` prints at the end, a replay's): one rule for what it is scored against, so the
//! same recording always gives the same numbers.
//!
//! The rule: a recording is scored against the scenario's simulated targets only when its
//! [`Origin`] record says the world was simulated, at the time origin it states. A real
//! deployment's recording (an origin that says so, or none at all) scores nothing it cannot
//! know — unless the user explicitly gives a time origin ([`Scoring::Given`]).

use node_server::Origin;
use node_server::analysis::{LoadError, Loaded, load};
use node_server::report::{self, Report, Truth};
use proto::ClusterTime;
use proto::scenario::{Scenario, ScenarioError};
use sim::{RecordedTruth, WorldTruth, recorded_truth::RecordedTruthError};
use std::path::Path;
use thiserror::Error;

/// What a report was scored against.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scoring {
    /// The simulated world's targets, from the recording's own origin.
    Recorded(ClusterTime),
    /// The simulated world's targets, from a time origin the user gave.
    Given(ClusterTime),
    /// Nothing: the recording says its world was real, or says nothing.
    NoTruth,
}

impl Scoring {
    /// The rule above, for a loaded recording and an optional user-given origin.
    pub fn of(loaded: &Loaded, given: Option<ClusterTime>) -> Scoring {
        match (given, loaded.origin()) {
            (Some(t0), _) => Scoring::Given(t0),
            (None, Some(Origin { t0, simulated: true })) => Scoring::Recorded(t0),
            (None, _) => Scoring::NoTruth,
        }
    }

    /// Where scenario time 0 is, if the report is scored.
    pub fn t0(self) -> Option<ClusterTime> {
        match self {
            Scoring::Recorded(t0) | Scoring::Given(t0) => Some(t0),
            Scoring::NoTruth => None,
        }
    }

    /// The truth to score against (none when the scenario has no targets either).
    ///
    /// # Errors
    /// The scenario's targets do not parse.
    pub fn truth(self, scenario: &Scenario) -> Result<Option<WorldTruth>, ScenarioError> {
        match self.t0() {
            Some(t0) => WorldTruth::of(scenario, t0),
            None => Ok(None),
        }
    }
}

/// A recording that cannot be reported on.
#[derive(Debug, Error)]
pub enum ReportError {
    #[error(transparent)]
    Load(#[from] LoadError),
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    #[error(transparent)]
    RecordedTruth(#[from] RecordedTruthError),
}

/// A recording's report and how it was scored.
#[derive(Debug)]
pub struct RecordingReport {
    pub loaded: Loaded,
    pub report: Report,
    pub scoring: Scoring,
    /// What it was scored against, kept for its frames ([`scored_frames`]).
    truth: Option<TruthSource>,
}

/// The report of the recording at `path` (`scenario` replaces the recorded one; `t0` scores
/// it against the scenario's simulated targets from that origin whatever the recording says).
///
/// # Errors
/// An unreadable recording, or a scenario whose targets do not parse.
pub fn of_recording(
    path: &Path,
    scenario: Option<Scenario>,
    t0: Option<ClusterTime>,
) -> Result<RecordingReport, ReportError> {
    let loaded = load(path, scenario)?;
    let scoring = Scoring::of(&loaded, t0);
    let truth = truth_of(&loaded, scoring)?;
    let report = match &truth {
        Some(TruthSource::World(t)) => report::compute(&loaded, Some(t as &dyn Truth)),
        // Radio-only nodes replaying a recorded file: its positions are the truth, and
        // RSSI-only tracks err metres, so a track is the beacon's within a wider gate.
        Some(TruthSource::Recorded(t)) => {
            report::compute_with(&loaded, Some(t), sim::recorded_truth::ASSOCIATION_GATE_M)
        }
        None => report::compute(&loaded, None),
    };
    Ok(RecordingReport {
        loaded,
        report,
        scoring,
        truth,
    })
}

/// The truth a recording is scored against.
#[derive(Debug)]
enum TruthSource {
    /// The simulated world's targets.
    World(WorldTruth),
    /// The positions a replayed radio file recorded.
    Recorded(RecordedTruth),
}

impl TruthSource {
    fn as_truth(&self) -> &dyn Truth {
        match self {
            TruthSource::World(t) => t,
            TruthSource::Recorded(t) => t,
        }
    }
}

/// The truth `scoring` scores `loaded` against, if any (see [`of_recording`]).
fn truth_of(loaded: &Loaded, scoring: Scoring) -> Result<Option<TruthSource>, ReportError> {
    Ok(match (scoring.truth(&loaded.scenario)?, scoring.t0()) {
        (Some(t), _) => Some(TruthSource::World(t)),
        (None, Some(t0)) => RecordedTruth::of(&loaded.scenario, t0)?.map(TruthSource::Recorded),
        (None, None) => None,
    })
}

/// One scored frame as `ocelli report --events` writes it: the truth and the global tracks on
/// the floor, and what CLEAR MOT counted (py-motmetrics' events, grouped by frame).
#[derive(Debug, serde::Serialize)]
pub struct ScoredFrame {
    /// Seconds of cluster time (the recording's clock: scenario time plus the run's origin).
    pub t: f64,
    pub truth: Vec<Placed>,
    pub tracks: Vec<Placed>,
    /// Sorted by truth id; each a match, or an identity switch (`switch`).
    pub pairs: Vec<ScoredPair>,
    /// Truth ids.
    pub misses: Vec<u32>,
    /// Global track ids.
    pub false_positives: Vec<u32>,
}

/// An id at a floor position, metres.
#[derive(Debug, serde::Serialize)]
pub struct Placed {
    pub id: u32,
    pub x: f64,
    pub y: f64,
}

/// A person and the global track CLEAR MOT paired them with in a frame.
#[derive(Debug, serde::Serialize)]
pub struct ScoredPair {
    pub truth: u32,
    pub track: u32,
    pub distance_m: f64,
    /// The person was last paired with another track.
    pub switch: bool,
}

/// The frames a recording's report scored, in order, with what each counted; `None` when the
/// report has no MOT metrics (no truth: see [`Scoring`]; nobody to track; a run shorter than
/// the warm-up).
pub fn scored_frames(r: &RecordingReport) -> Option<Vec<ScoredFrame>> {
    r.report.mot.as_ref()?;
    let frames = report::frame_events(&r.loaded, r.truth.as_ref()?.as_truth())?;
    let placed = |l: &[(u32, [f64; 2])]| -> Vec<Placed> {
        l.iter().map(|&(id, [x, y])| Placed { id, x, y }).collect()
    };
    Some(
        frames
            .into_iter()
            .map(|(f, events)| ScoredFrame {
                t: f.t,
                truth: placed(&f.truth),
                tracks: placed(&f.hyps),
                pairs: events
                    .pairs
                    .into_iter()
                    .map(|p| ScoredPair {
                        truth: p.truth,
                        track: p.hypothesis,
                        distance_m: p.distance_m,
                        switch: p.switch,
                    })
                    .collect(),
                misses: events.misses,
                false_positives: events.false_positives,
            })
            .collect(),
    )
}

/// What a reader of `loaded` skipped, in words, one line each (empty when it read everything):
/// the same warnings `report`, `export` and `replay` print.
pub fn damage(loaded: &Loaded) -> Vec<String> {
    loaded
        .skipped
        .iter()
        .map(|s| {
            format!(
                "{} byte(s) from offset {} could not be read ({}); the records around them were used",
                s.bytes,
                s.offset,
                damage_problem(&s.damage)
            )
        })
        .collect()
}

fn damage_problem(d: &node_server::recording::Damage) -> String {
    use node_server::recording::Damage;
    match d {
        Damage::ShortHeader => "the file ends inside a record header".into(),
        Damage::ShortPayload { len } => format!("the file ends inside a record of {len} bytes"),
        Damage::BadLength { len } => format!("impossible record length {len}"),
        Damage::Checksum => "a record's checksum does not match".into(),
        Damage::Undecodable => "an intact record this build cannot decode".into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use node_server::{Record, Stamped};

    fn loaded(records: Vec<Stamped>) -> Loaded {
        Loaded {
            scenario: Scenario::default_scenario(),
            records,
            skipped: Vec::new(),
        }
    }

    #[test]
    fn only_a_simulated_origin_or_a_given_one_is_scored() {
        let origin = |simulated| {
            Stamped::new(
                ClusterTime(5),
                Record::Origin(Origin {
                    t0: ClusterTime(7),
                    simulated,
                }),
            )
        };
        assert_eq!(Scoring::of(&loaded(vec![]), None), Scoring::NoTruth);
        assert_eq!(
            Scoring::of(&loaded(vec![origin(true)]), None),
            Scoring::Recorded(ClusterTime(7))
        );
        assert_eq!(Scoring::of(&loaded(vec![origin(false)]), None), Scoring::NoTruth);
        assert_eq!(
            Scoring::of(&loaded(vec![origin(false)]), Some(ClusterTime(3))),
            Scoring::Given(ClusterTime(3))
        );
        let s = Scenario::default_scenario();
        assert!(Scoring::NoTruth.truth(&s).unwrap().is_none());
        assert!(Scoring::Recorded(ClusterTime(0)).truth(&s).unwrap().is_some());
    }
}
