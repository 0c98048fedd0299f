//! The identity measures (Ristani et al. 2016): IDTP from one optimal matching of truth ids to
//! hypothesis ids over the whole run.
//!
//! A truth–hypothesis pair scores one IDTP in every frame where both are present and within
//! the threshold (whether or not CLEAR MOT matched them that frame). The matching maximises the
//! total; py-motmetrics states the same problem as a min-cost assignment over an
//! (objects + hypotheses)² matrix with dummy rows and columns, whose cost is the total of
//! frames minus twice the IDTP, so both give the same IDTP.

use super::Frame;
use assign::max_weight_matching_exact;
use std::collections::{BTreeMap, BTreeSet, HashMap};

/// The counts the matching needs.
#[derive(Debug, Default)]
pub(super) struct Identity {
    truths: BTreeSet<u32>,
    hyps: BTreeSet<u32>,
    /// Frames each truth and each hypothesis is present in.
    truth_frames: HashMap<u32, i64>,
    hyp_frames: HashMap<u32, i64>,
    /// Frames in which the pair (truth, hypothesis) was within the threshold.
    together: HashMap<(u32, u32), i64>,
}

/// The matching's result.
#[derive(Debug)]
pub(super) struct Identities {
    pub idtp: usize,
    /// The hypothesis each truth was matched to, when they share at least one frame.
    pub identity: BTreeMap<u32, u32>,
    /// Each truth's IDF1: 2 × the frames it shares with its hypothesis over its frames plus
    /// that hypothesis's (0 for a truth matched to none).
    pub idf1: BTreeMap<u32, f64>,
    pub unique_hypotheses: usize,
}

impl Identity {
    /// Counts one frame; `d` is its truth-major distance matrix.
    pub fn frame<const D: usize>(&mut self, frame: &Frame<D>, d: &[f64], threshold: f64) {
        let nh = frame.hyps.len();
        self.truths.extend(frame.truth.iter().map(|(id, _)| *id));
        self.hyps.extend(frame.hyps.iter().map(|(id, _)| *id));
        for (id, _) in &frame.truth {
            *self.truth_frames.entry(*id).or_default() += 1;
        }
        for (id, _) in &frame.hyps {
            *self.hyp_frames.entry(*id).or_default() += 1;
        }
        for (i, (oid, _)) in frame.truth.iter().enumerate() {
            for (j, (hid, _)) in frame.hyps.iter().enumerate() {
                if d[i * nh + j] <= threshold {
                    *self.together.entry((*oid, *hid)).or_default() += 1;
                }
            }
        }
    }

    pub fn finish(self) -> Identities {
        let truths: Vec<u32> = self.truths.into_iter().collect();
        let hyps: Vec<u32> = self.hyps.into_iter().collect();
        let weight = |r: usize, c: usize| self.together.get(&(truths[r], hyps[c])).copied().unwrap_or(0);
        let matching = max_weight_matching_exact(truths.len(), hyps.len(), weight);
        let mut idtp = 0;
        let mut identity = BTreeMap::new();
        let mut idf1 = BTreeMap::new();
        for (r, c) in matching.into_iter().enumerate() {
            let frames = self.truth_frames.get(&truths[r]).copied().unwrap_or(0);
            let (shared, hyp_frames) = match c {
                Some(c) => {
                    idtp += weight(r, c) as usize;
                    identity.insert(truths[r], hyps[c]);
                    (weight(r, c), self.hyp_frames.get(&hyps[c]).copied().unwrap_or(0))
                }
                None => (0, 0),
            };
            if frames + hyp_frames > 0 {
                idf1.insert(truths[r], 2.0 * shared as f64 / (frames + hyp_frames) as f64);
            }
        }
        Identities {
            idtp,
            identity,
            idf1,
            unique_hypotheses: hyps.len(),
        }
    }
}
