//! The run's standard multi-target metrics (CLEAR MOT, IDF1, GOSPA: [`crate::metrics`]) from
//! its owner track rows and the truth.
//!
//! Frames are taken on a fixed grid, one per filter step (`method.step-ms`), from
//! [`Scoring::warmup_s`] after the recording's first record to its last: heads step
//! unsynchronized with each other, so a frame holds, for every global track, its newest owner
//! row at most [`Scoring::max_age_steps`] steps old, moved to the frame's time along the row's
//! velocity; the truth is every true target at the frame's time. Both are compared on the
//! floor plane (x, y): a person's and a robot's centres are at different heights, and the
//! 3-D error is the report's own column.

use super::Truth;
use crate::export::TrackRow;
use crate::metrics::{Frame, FrameEvents, MetricsConfig, MotMetrics, evaluate};
use proto::scenario::Scenario;
use std::collections::BTreeMap;

/// How a run is scored.
#[derive(Clone, Debug, PartialEq)]
pub struct Scoring {
    /// Seconds between frames.
    pub frame_s: f64,
    /// Seconds after the start before the first frame: tracks are born and confirmed in the
    /// first second or two, before which no tracker could have reported anything.
    pub warmup_s: f64,
    /// A global track's newest owner row counts in a frame while it is at most this many
    /// frame periods old (a report lost or late for one step is not a miss).
    pub max_age_steps: f64,
    pub metrics: MetricsConfig,
}

impl Scoring {
    /// One frame per filter step, 2 s of warm-up, the metrics' default thresholds (1 m).
    pub fn for_scenario(scenario: &Scenario) -> Scoring {
        Scoring {
            frame_s: (scenario.method.step_ms as f64 * 1e-3).max(1e-3),
            warmup_s: 2.0,
            max_age_steps: 1.5,
            metrics: MetricsConfig::default(),
        }
    }
}

/// The metrics of the owner rows `rows` (recording order) against `truth`, on frames from
/// `start + warmup` to `end` (seconds of cluster time); `None` when no frame fits or the
/// metrics refuse the frames (which the construction rules out).
pub fn score(rows: &[TrackRow], truth: &dyn Truth, start: f64, end: f64, s: &Scoring) -> Option<MotMetrics> {
    let frames = frames(rows, truth, start, end, s);
    if frames.is_empty() {
        return None;
    }
    evaluate(&frames, &s.metrics).ok()
}

/// The frames (see the module docs) with what CLEAR MOT counted in each
/// ([`crate::metrics::events`]): where [`score`]'s counts come from. `None` exactly when
/// [`score`] is: no frame fits, or the metrics refuse the frames.
pub fn frame_events(
    rows: &[TrackRow],
    truth: &dyn Truth,
    start: f64,
    end: f64,
    s: &Scoring,
) -> Option<Vec<(Frame<2>, FrameEvents)>> {
    let frames = frames(rows, truth, start, end, s);
    if frames.is_empty() {
        return None;
    }
    let events = crate::metrics::events(&frames, &s.metrics).ok()?;
    Some(frames.into_iter().zip(events).collect())
}

/// The frames (see the module docs).
pub fn frames(rows: &[TrackRow], truth: &dyn Truth, start: f64, end: f64, s: &Scoring) -> Vec<Frame<2>> {
    let ids = truth.ids();
    let mut by_global: BTreeMap<u32, Vec<&TrackRow>> = BTreeMap::new();
    for r in rows.iter().filter(|r| r.owner) {
        by_global.entry(r.global).or_default().push(r);
    }
    for rs in by_global.values_mut() {
        rs.sort_by(|a, b| a.t.total_cmp(&b.t));
    }
    let mut cursor: BTreeMap<u32, usize> = BTreeMap::new();
    let max_age = s.max_age_steps * s.frame_s;
    let mut out = Vec::new();
    let mut k = 0u64;
    loop {
        let t = start + s.warmup_s + k as f64 * s.frame_s;
        if t > end {
            break;
        }
        k += 1;
        let mut hyps = Vec::new();
        for (g, rs) in &by_global {
            // The newest row at or before t.
            let c = cursor.entry(*g).or_insert(0);
            // (Rows and frames on the same grid differ by rounding only.)
            while *c < rs.len() && rs[*c].t <= t + 1e-9 {
                *c += 1;
            }
            let Some(r) = c.checked_sub(1).map(|i| rs[i]) else {
                continue;
            };
            let age = t - r.t;
            if age <= max_age {
                hyps.push((*g, [r.x + r.vx * age, r.y + r.vy * age]));
            }
        }
        let truth: Vec<(u32, [f64; 2])> = ids
            .iter()
            .enumerate()
            .map(|(i, id)| {
                let p = truth.position(i, t);
                (*id, [p[0], p[1]])
            })
            .collect();
        out.push(Frame { t, truth, hyps });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two targets standing still at x = 0 and x = 5.
    struct Still;
    impl Truth for Still {
        fn ids(&self) -> Vec<u32> {
            vec![1, 2]
        }
        fn position(&self, index: usize, _: f64) -> [f64; 3] {
            [index as f64 * 5.0, 0.0, 0.25]
        }
    }

    fn row(t: f64, global: u32, x: f64, vx: f64) -> TrackRow {
        TrackRow {
            t,
            global,
            head: 2,
            local: global,
            step: 0,
            x,
            y: 0.0,
            z: 0.9,
            vx,
            vy: 0.0,
            vz: 0.0,
            sigma_m: 0.1,
            owner: true,
            cameras: 2,
            rssi_nodes: 0,
        }
    }

    fn scoring() -> Scoring {
        Scoring {
            frame_s: 1.0,
            warmup_s: 0.0,
            max_age_steps: 1.5,
            metrics: MetricsConfig::default(),
        }
    }

    #[test]
    fn frames_hold_each_globals_newest_row_moved_to_the_frame() {
        // Global 7 reports at 0.5 s and 1.5 s moving 1 m/s, global 8 once at 0.9 s.
        let rows = [
            row(0.5, 7, 0.0, 1.0),
            row(0.9, 8, 5.1, 0.0),
            row(1.5, 7, 0.2, 1.0),
        ];
        let f = frames(&rows, &Still, 0.0, 4.0, &scoring());
        assert_eq!(
            f.iter().map(|f| f.t).collect::<Vec<_>>(),
            vec![0.0, 1.0, 2.0, 3.0, 4.0]
        );
        assert!(f[0].hyps.is_empty(), "nothing reported yet");
        assert_eq!(f[1].hyps, vec![(7, [0.5, 0.0]), (8, [5.1, 0.0])]);
        // At 2 s global 8's row is 1.1 s old (kept), at 3 s 2.1 s (gone); global 7's newest
        // row is at 1.5 s: 0.5 s and 1.5 s old.
        assert_eq!(f[2].hyps, vec![(7, [0.7, 0.0]), (8, [5.1, 0.0])]);
        assert_eq!(f[3].hyps, vec![(7, [1.7, 0.0])]);
        assert!(f[4].hyps.is_empty());
        assert_eq!(f[1].truth, vec![(1, [0.0, 0.0]), (2, [5.0, 0.0])]);
        // Rows that are not the owner's never count.
        let mut other = row(0.9, 9, 5.0, 0.0);
        other.owner = false;
        assert!(frames(&[other], &Still, 0.0, 1.0, &scoring())[1].hyps.is_empty());
    }

    #[test]
    fn a_run_scores_its_misses_and_switches() {
        // Target 1 tracked throughout by global 7; target 2 by global 8, then 9 (a switch),
        // and missed in the frame between.
        let mut rows = Vec::new();
        for k in 0..10 {
            let t = k as f64;
            rows.push(row(t, 7, 0.1, 0.0));
            match k {
                0..=3 => rows.push(row(t, 8, 5.0, 0.0)),
                5.. => rows.push(row(t, 9, 5.0, 0.0)),
                _ => {}
            }
        }
        let s = Scoring {
            max_age_steps: 0.5,
            ..scoring()
        };
        let m = score(&rows, &Still, 0.0, 9.0, &s).unwrap();
        assert_eq!((m.frames, m.objects, m.misses, m.id_switches), (10, 20, 1, 1));
        assert_eq!(m.mota, Some(1.0 - 2.0 / 20.0));
        assert_eq!(m.unique_hypotheses, 3);
        assert!(score(&rows, &Still, 0.0, -1.0, &s).is_none(), "no frame");
    }
}
