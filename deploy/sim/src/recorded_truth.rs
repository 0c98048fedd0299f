//! The truth of a run whose radio-only nodes replay recorded readings (`radio =
//! "file:PATH.mbd@SENSOR"`): where each beacon of the recording truly was, as the file's
//! position columns say, on the cluster clock of the launch that replayed it (the file's first
//! packet at its epoch, as `node_camera::radio_file` plays it). Only the launcher and tests
//! read it; no node does.

use node_server::report::Truth;
use proto::scenario::{RadioSpec, Scenario};
use proto::sensor::mbd;
use proto::{ClusterTime, TagId};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use thiserror::Error;

/// A track is a recorded beacon's if its mean distance to it is within this, metres: RSSI-only
/// tracks err metres (the BLE experiment's fitted law, 2.9 m on average), where the report's
/// camera-level gate is 2 m.
pub const ASSOCIATION_GATE_M: f64 = 8.0;

/// A recording that cannot be scored against.
#[derive(Debug, Error)]
pub enum RecordedTruthError {
    #[error("{path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{0}: no packet with a position")]
    Empty(PathBuf),
    #[error("nodes replay different files ({0} and {1}); one recording is one truth")]
    Files(PathBuf, PathBuf),
}

/// Where one beacon was: (cluster seconds, position), in time order.
type Path3 = Vec<(f64, [f64; 3])>;

/// Each beacon's positions over time (cluster seconds), targets numbered 1.. in MAC order.
#[derive(Clone, Debug)]
pub struct RecordedTruth {
    beacons: Vec<(TagId, Path3)>,
    skipped: usize,
}

impl RecordedTruth {
    /// The truth of the file `scenario`'s nodes replay, its first packet at `epoch`; `None`
    /// when no node replays one.
    ///
    /// # Errors
    /// The file cannot be read or has no usable packet; nodes replay different files.
    pub fn of(scenario: &Scenario, epoch: ClusterTime) -> Result<Option<RecordedTruth>, RecordedTruthError> {
        let mut file: Option<&Path> = None;
        for n in &scenario.nodes {
            if let Some(RadioSpec::File { path, .. }) = &n.radio {
                match file {
                    Some(f) if f != path => return Err(RecordedTruthError::Files(f.into(), path.clone())),
                    _ => file = Some(path),
                }
            }
        }
        let Some(path) = file else { return Ok(None) };
        let text = std::fs::read_to_string(path).map_err(|source| RecordedTruthError::Io {
            path: path.into(),
            source,
        })?;
        let truth = RecordedTruth::from_text(&text, epoch);
        if truth.beacons.is_empty() {
            return Err(RecordedTruthError::Empty(path.into()));
        }
        Ok(Some(truth))
    }

    /// From an `.mbd` file's text (lines that do not parse are skipped and counted).
    pub fn from_text(text: &str, epoch: ClusterTime) -> RecordedTruth {
        let mut by_beacon: BTreeMap<TagId, Path3> = BTreeMap::new();
        let mut skipped = 0;
        let mut t0 = f64::INFINITY;
        for line in text.lines() {
            match mbd::parse_line(line) {
                Ok(Some(r)) => {
                    t0 = t0.min(r.time_s);
                    by_beacon
                        .entry(r.beacon)
                        .or_default()
                        .push((r.time_s, r.position));
                }
                Ok(None) => {}
                Err(_) => skipped += 1,
            }
        }
        let e = epoch.as_secs_f64();
        let beacons = by_beacon
            .into_iter()
            .map(|(tag, mut v)| {
                for p in &mut v {
                    p.0 = p.0 - t0 + e;
                }
                v.sort_by(|a, b| a.0.total_cmp(&b.0));
                (tag, v)
            })
            .collect();
        RecordedTruth { beacons, skipped }
    }

    /// The beacons, in target order (target `k + 1` is the `k`-th).
    pub fn beacons(&self) -> Vec<TagId> {
        self.beacons.iter().map(|b| b.0).collect()
    }

    /// Lines of the file that did not parse.
    pub fn skipped(&self) -> usize {
        self.skipped
    }

    /// Cluster seconds of the first and last packet.
    pub fn span(&self) -> (f64, f64) {
        let ts = self.beacons.iter().flat_map(|b| b.1.iter().map(|p| p.0));
        ts.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), t| {
            (a.min(t), b.max(t))
        })
    }
}

impl Truth for RecordedTruth {
    fn ids(&self) -> Vec<u32> {
        (1..=self.beacons.len() as u32).collect()
    }

    /// Linear between the packets around `t`; the first or last before or after them.
    fn position(&self, index: usize, t: f64) -> [f64; 3] {
        let Some((_, track)) = self.beacons.get(index) else {
            return [f64::NAN; 3];
        };
        let k = track.partition_point(|p| p.0 <= t);
        match (k.checked_sub(1).map(|i| track[i]), track.get(k)) {
            (Some(a), Some(b)) if b.0 > a.0 => {
                let w = (t - a.0) / (b.0 - a.0);
                std::array::from_fn(|i| a.1[i] + w * (b.1[i] - a.1[i]))
            }
            (Some(a), _) => a.1,
            (None, Some(b)) => b.1,
            (None, None) => [f64::NAN; 3],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ORIENT: &str = "1,0,0,0,1,0,0,0,1";

    #[test]
    fn positions_play_from_the_epoch_and_interpolate() {
        let text = format!(
            "100.0,b827eb4521b4,e78f135624ce,-80,1,2,1.8,{ORIENT}\nbad\n102.0,000000000101,e78f135624ce,-70,3,2,1.8,{ORIENT}\n"
        );
        let t = RecordedTruth::from_text(&text, ClusterTime::from_secs_f64(50.0));
        assert_eq!(t.ids(), vec![1]);
        assert_eq!(t.skipped(), 1);
        assert_eq!(t.span(), (50.0, 52.0));
        assert_eq!(t.position(0, 51.0), [2.0, 2.0, 1.8]);
        assert_eq!(t.position(0, 10.0), [1.0, 2.0, 1.8]);
        assert_eq!(t.position(0, 99.0), [3.0, 2.0, 1.8]);
        assert!(t.position(1, 51.0)[0].is_nan());
    }
}
