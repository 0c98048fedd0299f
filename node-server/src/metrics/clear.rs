//! CLEAR MOT, frame by frame, as py-motmetrics' `MOTAccumulator.update` counts it.
//!
//! Per frame: (1) every truth whose last matched hypothesis is present, unclaimed and within
//! the threshold keeps it (truths in input order); (2) the remaining truths and hypotheses are
//! paired by an optimal assignment that makes as many pairs as possible, then the least total
//! distance; a pair whose truth was last matched to another hypothesis is an id switch;
//! (3) unpaired truths are misses and unpaired hypotheses false positives. A truth's
//! fragmentations are the times it went from tracked to missed and was tracked again later
//! (motmetrics counts tracked → missed transitions between its first and last tracked frame).

use super::{Frame, FrameEvents, Pair};
use assign::max_weight_matching;
use std::collections::{BTreeMap, HashMap};

/// The running counts of a run.
#[derive(Debug, Default)]
pub(super) struct Clear {
    /// The hypothesis each truth was last matched to.
    last_match: HashMap<u32, u32>,
    pub targets: BTreeMap<u32, Target>,
    pub matches: usize,
    pub switches: usize,
    pub false_positives: usize,
    pub misses: usize,
    pub objects: usize,
    pub predictions: usize,
    /// Sum of the distances of matches and switches.
    pub distance_sum: f64,
}

/// One truth's counts.
#[derive(Debug, Default)]
pub(super) struct Target {
    pub frames: usize,
    pub tracked: usize,
    pub switches: usize,
    pub fragmentations: usize,
    pub hyp_ids: Vec<u32>,
    /// Sum of its matched distances (matches and switches).
    pub distance_sum: f64,
    /// Tracked before, and missed since the last time it was tracked.
    interrupted: bool,
}

impl Clear {
    /// Counts one frame; `d` is its truth-major distance matrix. Returns what it counted.
    pub fn frame<const D: usize>(&mut self, frame: &Frame<D>, d: &[f64], threshold: f64) -> FrameEvents {
        let (nt, nh) = (frame.truth.len(), frame.hyps.len());
        let mut hyp_of: Vec<Option<usize>> = vec![None; nt];
        let mut claimed = vec![false; nh];
        let mut events = FrameEvents {
            t: frame.t,
            ..FrameEvents::default()
        };
        let index: HashMap<u32, usize> = frame
            .hyps
            .iter()
            .enumerate()
            .map(|(j, (id, _))| (*id, j))
            .collect();
        // (1) Keep previous matches still within the threshold.
        for (i, (oid, _)) in frame.truth.iter().enumerate() {
            let Some(j) = self.last_match.get(oid).and_then(|h| index.get(h)).copied() else {
                continue;
            };
            if !claimed[j] && d[i * nh + j] <= threshold {
                claimed[j] = true;
                hyp_of[i] = Some(j);
                self.matches += 1;
                events.pairs.push(Pair {
                    truth: *oid,
                    hypothesis: frame.hyps[j].0,
                    distance_m: d[i * nh + j],
                    switch: false,
                });
                self.distance_sum += d[i * nh + j];
                self.targets.entry(*oid).or_default().distance_sum += d[i * nh + j];
            }
        }
        // (2) Optimal assignment of the rest: most pairs, then least total distance.
        let rows: Vec<usize> = (0..nt).filter(|&i| hyp_of[i].is_none()).collect();
        let cols: Vec<usize> = (0..nh).filter(|&j| !claimed[j]).collect();
        let pairs = max_weight_matching(rows.len(), cols.len(), threshold, true, |r, c| {
            let dist = d[rows[r] * nh + cols[c]];
            (dist <= threshold).then_some(threshold - dist)
        });
        for (r, c) in pairs.into_iter().enumerate() {
            let Some(c) = c else { continue };
            let (i, j) = (rows[r], cols[c]);
            let (oid, hid) = (frame.truth[i].0, frame.hyps[j].0);
            hyp_of[i] = Some(j);
            claimed[j] = true;
            self.distance_sum += d[i * nh + j];
            self.targets.entry(oid).or_default().distance_sum += d[i * nh + j];
            let switch = self.last_match.insert(oid, hid).is_some_and(|prev| prev != hid);
            if switch {
                self.switches += 1;
                self.targets.entry(oid).or_default().switches += 1;
            } else {
                self.matches += 1;
            }
            events.pairs.push(Pair {
                truth: oid,
                hypothesis: hid,
                distance_m: d[i * nh + j],
                switch,
            });
        }
        // (3) Misses, false positives, and each truth's tallies.
        self.objects += nt;
        self.predictions += nh;
        self.false_positives += claimed.iter().filter(|c| !**c).count();
        events.false_positives = (0..nh)
            .filter(|&j| !claimed[j])
            .map(|j| frame.hyps[j].0)
            .collect();
        for (i, (oid, _)) in frame.truth.iter().enumerate() {
            let t = self.targets.entry(*oid).or_default();
            t.frames += 1;
            match hyp_of[i] {
                Some(j) => {
                    let hid = frame.hyps[j].0;
                    t.tracked += 1;
                    if t.interrupted {
                        t.fragmentations += 1;
                        t.interrupted = false;
                    }
                    if !t.hyp_ids.contains(&hid) {
                        t.hyp_ids.push(hid);
                    }
                }
                None => {
                    self.misses += 1;
                    t.interrupted = t.tracked > 0;
                    events.misses.push(*oid);
                }
            }
        }
        // Step (1)'s kept pairs were listed before step (2)'s: by truth id instead, so a reader
        // finds a person in the same place whichever step paired them.
        events.pairs.sort_by_key(|m| m.truth);
        events
    }
}
