//! Timings of the viewer's hot paths, for `ocelli bench view`: applying a record, publishing a
//! state (the copy the producer makes), serializing it for the pages, rendering the live KML and
//! the metrics. Measured, never asserted.

use crate::feed::{FeedStats, channel};
use crate::geo::Geo;
use crate::state::ViewState;
use node_server::{Decision, Record, Stamped};
use proto::msg::{Contributor, Kinds, Message, NodeStatus, ObservationKind, TrackReport};
use proto::scenario::Scenario;
use proto::{ClusterTime, Envelope, Mode, NodeId, TargetId};
use serde::Serialize;
use std::sync::Arc;

/// One measured path.
#[derive(Clone, Debug, Serialize)]
pub struct Timing {
    pub name: &'static str,
    /// Median and 90th percentile over the repeats, ns.
    pub median_ns: f64,
    pub p90_ns: f64,
    pub repeats: usize,
    /// What one repeat does.
    pub unit: &'static str,
}

#[allow(clippy::disallowed_methods)] // a benchmark owns its clock
fn time(name: &'static str, unit: &'static str, repeats: usize, mut f: impl FnMut()) -> Timing {
    let mut samples: Vec<f64> = (0..repeats.max(1))
        .map(|_| {
            let t = std::time::Instant::now();
            f();
            t.elapsed().as_nanos() as f64
        })
        .collect();
    samples.sort_by(f64::total_cmp);
    Timing {
        name,
        median_ns: samples[samples.len() / 2],
        p90_ns: samples[samples.len() * 9 / 10],
        repeats: samples.len(),
        unit,
    }
}

fn report(head: u32, local: u32, seq: u64, t: i64, x: f64) -> Stamped {
    let mut cov = [[0.0; 6]; 6];
    for (i, row) in cov.iter_mut().enumerate() {
        row[i] = 0.05;
    }
    Stamped::new(
        ClusterTime(t),
        Record::Received(Envelope {
            source: NodeId(head),
            seq,
            time: ClusterTime(t),
            body: Message::TrackReport(TrackReport {
                target: TargetId(local),
                global: None,
                step: seq,
                time: ClusterTime(t),
                mean: [x, 2.0 + f64::from(local), 0.25, 0.4, 0.0, 0.0],
                cov,
                contributors: (10..14)
                    .map(|n| Contributor {
                        node: NodeId(n),
                        kinds: Kinds::of(ObservationKind::Pinhole).union(Kinds::of(ObservationKind::Rssi)),
                    })
                    .collect(),
                power_mw: 2000.0,
                late: 0,
                appearance: Vec::new(),
                grid: None,
                captured: None,
            }),
        }),
    )
}

/// A busy view of the default scenario: 21 cameras reporting status, five tracks with full
/// 10 s trails.
fn busy_view() -> (ViewState, i64) {
    let mut v = ViewState::with_scenario(&Scenario::default_scenario());
    v.set_geo(Some(Geo {
        origin: [48.5, 9.06, 320.0],
        heading_deg: 0.0,
    }));
    for local in 0..5u32 {
        v.apply(&Stamped::new(
            ClusterTime(0),
            Record::Decision(Decision::NewGlobal {
                head: NodeId(2),
                local: TargetId(local),
                global: TargetId(local + 1),
            }),
        ));
    }
    let mut t = 0;
    for step in 0..60u64 {
        t = i64::try_from(step).unwrap_or(0) * 200_000_000;
        for local in 0..5 {
            v.apply(&report(
                2,
                local,
                step * 5 + u64::from(local),
                t,
                1.0 + step as f64 * 0.08,
            ));
        }
        for cam in 10..31u32 {
            let status = NodeStatus {
                mode: Mode::Active,
                time_in_mode_ns: [0; 3],
                frames: step,
                detections: step,
                dropped: 0,
                rejected: 0,
                sync_offset_ns: 0,
                sync_error_ns: 1000,
                bytes_sent: 0,
            };
            v.apply(&Stamped::new(
                ClusterTime(t),
                Record::Received(Envelope {
                    source: NodeId(cam),
                    seq: step,
                    time: ClusterTime(t),
                    body: Message::NodeStatus(status),
                }),
            ));
        }
    }
    (v, t)
}

/// Time the hot paths, each over `repeats` runs.
pub fn run(repeats: usize) -> Vec<Timing> {
    let (state, t) = busy_view();
    let mut out = Vec::new();
    let mut v = state.clone();
    let mut seq = 1_000u64;
    let mut now = t;
    out.push(time("apply_track_report", "one record", repeats, || {
        seq += 1;
        now += 1_000_000;
        v.apply(&report(2, 3, seq, now, 3.0));
    }));
    out.push(time("publish_state", "copy and publish one state", repeats, {
        let (mut p, _feed) = channel(ViewState::new());
        let s = state.clone();
        move || p.publish(Arc::new(s.clone()))
    }));
    out.push(time("state_json", "serialize one state", repeats, || {
        let s = serde_json::to_string(&state).unwrap_or_default();
        std::hint::black_box(s);
    }));
    out.push(time("tracks_kml", "render /tracks.kml", repeats, || {
        std::hint::black_box(crate::kml::live_document(&state).ok());
    }));
    let (mut p, feed) = channel(ViewState::new());
    p.publish(Arc::new(state.clone()));
    let stats = FeedStats::default();
    out.push(time("metrics", "render /metrics", repeats, || {
        std::hint::black_box(crate::metrics::render(&feed.latest(), &stats).ok());
    }));
    out.extend(seek_timings(repeats));
    out
}

/// Index a ten-minute recording once, then seek in it: the playback's slider.
fn seek_timings(repeats: usize) -> Vec<Timing> {
    let path = std::env::temp_dir().join(format!("ocelli-view-bench-{}.ocrec", std::process::id()));
    let Ok(mut rec) = node_server::Recorder::create(&path, "default") else {
        return Vec::new();
    };
    let sc = Scenario::default_scenario();
    let _ = rec.append(&Stamped::new(ClusterTime(0), Record::Scenario(sc.to_toml())));
    for step in 0..3000u64 {
        let t = i64::try_from(step).unwrap_or(0) * 200_000_000;
        for local in 0..2 {
            let _ = rec.append(&report(
                2,
                local,
                step * 2 + u64::from(local) + 1,
                t,
                1.0 + (step % 100) as f64 * 0.08,
            ));
        }
    }
    drop(rec);
    let mut index = None;
    let built = time(
        "index_recording",
        "index a 10 min recording (6 001 records)",
        1,
        || {
            index = crate::playback::RecordingIndex::build(&path, None)
                .ok()
                .map(Arc::new);
        },
    );
    let mut out = vec![built];
    if let Some(index) = index
        && let Ok(mut player) = crate::playback::Player::new(index)
    {
        let mut k = 0u64;
        out.push(time("seek", "seek to a random moment of 10 min", repeats, || {
            k = (k * 7919 + 104_729) % 600_000;
            let _ = player.seek(i64::try_from(k).unwrap_or(0) * 1_000_000);
        }));
    }
    let _ = std::fs::remove_file(&path);
    out
}

#[cfg(test)]
mod tests {
    #[test]
    fn every_path_is_timed() {
        let t = super::run(3);
        let names: Vec<_> = t.iter().map(|t| t.name).collect();
        assert_eq!(
            names,
            [
                "apply_track_report",
                "publish_state",
                "state_json",
                "tracks_kml",
                "metrics",
                "index_recording",
                "seek"
            ]
        );
        assert!(t.iter().all(|t| t.median_ns.is_finite() && t.median_ns > 0.0));
    }
}
