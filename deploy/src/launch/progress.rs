//! Live progress of a launch: follows the server's recording as it grows
//! ([`Tailer`] reads only what was appended since the last update) through a server core fed
//! record by record, as `ocelli export` does over a whole file, and keeps each global track's
//! latest owner row. An estimate that has not been renewed for a while is marked stale (the
//! server or every camera seeing the target may be down), never shown as if it were current.

use node_server::export::{TrackRow, track_row};
use node_server::tail::Tailer;
use node_server::{ServerConfig, ServerNode};
use proto::scenario::Scenario;
use proto::{ClusterTime, NodeId};
use std::collections::BTreeMap;
use std::path::Path;

/// An estimate older than this (cluster time) is marked stale, seconds.
pub const STALE_AFTER_S: f64 = 3.0;

pub struct Progress {
    tail: Tailer,
    node: ServerNode,
    pub(crate) latest: BTreeMap<u32, TrackRow>,
}

impl Progress {
    pub fn new(record: &Path, scenario: &Scenario) -> Self {
        let server = scenario.server().map_or(NodeId(0), |n| NodeId(n.id));
        let mut cfg = ServerConfig::from_scenario(scenario.clone(), server);
        cfg.journal = false;
        Progress {
            tail: Tailer::new(record),
            node: ServerNode::new(cfg),
            latest: BTreeMap::new(),
        }
    }

    /// Read what the server appended and take it in.
    pub fn update(&mut self) {
        let records = match self.tail.poll() {
            Ok(r) => r,
            Err(e) => {
                tracing::debug!(error = %e, "progress: recording not readable yet");
                return;
            }
        };
        for s in &records {
            self.node.feed(s);
            if let Some(row) = track_row(&self.node, s).filter(|r| r.owner) {
                self.latest.insert(row.global, row);
            }
        }
    }

    /// One line per global track reported within two seconds of the newest estimate: time,
    /// position, σ, sensors, head and, with truth, error; marked stale when the newest
    /// estimate is older than [`STALE_AFTER_S`] at `now`.
    pub fn lines(&self, targets: &[world::Target], epoch: ClusterTime, now: ClusterTime) -> Vec<String> {
        let newest = self
            .latest
            .values()
            .map(|r| r.t)
            .fold(f64::NEG_INFINITY, f64::max);
        let age = now.as_secs_f64() - newest;
        let stale = if age > STALE_AFTER_S {
            format!("  STALE: no estimate for {age:.0} s")
        } else {
            String::new()
        };
        self.latest
            .values()
            .filter(|r| r.t >= newest - 2.0)
            .map(|r| {
                let err = targets
                    .iter()
                    .map(|t| {
                        let x = t.truth_at(r.t - epoch.as_secs_f64());
                        ((x[0] - r.x).powi(2) + (x[1] - r.y).powi(2) + (x[2] - r.z).powi(2)).sqrt()
                    })
                    .min_by(f64::total_cmp)
                    .map_or(String::new(), |e| format!("  error {e:.2} m"));
                format!(
                    "t={:6.1}s  target g{:<3} ({:6.2}, {:6.2}, {:5.2}) m  σ {:.2} m  cameras {:2}  rssi {:2}  head {}{err}{stale}",
                    r.t - epoch.as_secs_f64(), r.global, r.x, r.y, r.z, r.sigma_m, r.cameras, r.rssi_nodes, r.head
                )
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use node_server::Recorder;
    use node_server::analysis::Loaded;
    use node_server::export::track_rows;
    use sim::{Level, Sim, SimOptions};

    /// Progress read in pieces while the recording grows ends where a reading of the whole
    /// file does: the same latest owner row for every global track.
    #[test]
    fn progress_follows_the_growing_recording_like_a_whole_reading() {
        let scenario = Scenario::default_scenario();
        let opts = SimOptions {
            seed: 4,
            duration_s: 6.0,
            level: Level::Measurement,
            ..SimOptions::default()
        };
        let records = Sim::new(scenario.clone(), opts).unwrap().run().records;
        let dir = std::env::temp_dir().join(format!("ocelli-launch-progress-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("rec.ocrec");
        let mut progress = Progress::new(&path, &scenario);
        progress.update();
        assert!(progress.latest.is_empty(), "no file yet");
        let mut rec = Recorder::create(&path, &scenario.name).unwrap();
        let mut polls = 0;
        for chunk in records.chunks(records.len() / 20 + 1) {
            for s in chunk {
                rec.append(s).unwrap();
            }
            progress.update();
            polls += 1;
        }
        assert!(polls > 10);
        let whole = Loaded {
            scenario: scenario.clone(),
            records,
            skipped: Vec::new(),
        };
        let mut expected: BTreeMap<u32, TrackRow> = BTreeMap::new();
        for r in track_rows(&whole).into_iter().filter(|r| r.owner) {
            expected.insert(r.global, r);
        }
        assert!(!expected.is_empty(), "the sim tracked something");
        assert_eq!(progress.latest, expected);
        let targets = world::targets(&scenario).unwrap();
        let newest = expected.values().map(|r| r.t).fold(f64::NEG_INFINITY, f64::max);
        let at = |s: f64| ClusterTime((s * 1e9) as i64);
        let fresh = progress.lines(&targets, ClusterTime::ZERO, at(newest + 1.0));
        assert!(!fresh.is_empty());
        assert!(
            fresh.iter().all(|l| !l.contains("STALE") && l.contains("error")),
            "{fresh:?}"
        );
        // The server went quiet: the same estimates, marked stale with their age.
        let stale = progress.lines(&targets, ClusterTime::ZERO, at(newest + 10.0));
        assert_eq!(stale.len(), fresh.len());
        assert!(
            stale.iter().all(|l| l.ends_with("STALE: no estimate for 10 s")),
            "{stale:?}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
