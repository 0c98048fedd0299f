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
    /// Frames in which the pair (truth, hypothesis) was within the threshold.
    together: HashMap<(u32, u32), i64>,
}

/// The matching's result.
#[derive(Debug)]
pub(super) struct Identities {
    pub idtp: usize,
    /// The hypothesis each truth was matched to, when they share at least one frame.
    pub identity: BTreeMap<u32, u32>,
    pub unique_hypotheses: usize,
}

impl Identity {
    /// Counts one frame; `d` is its truth-major distance matrix.
    pub fn frame<const D: usize>(&mut self, frame: &Frame<D>, d: &[f64], threshold: f64) {
        let nh = frame.hyps.len();
        self.truths.extend(frame.truth.iter().map(|(id, _)| *id));
        self.hyps.extend(frame.hyps.iter().map(|(id, _)| *id));
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
        for (r, c) in matching.into_iter().enumerate() {
            if let Some(c) = c {
                idtp += weight(r, c) as usize;
                identity.insert(truths[r], hyps[c]);
            }
        }
        Identities {
            idtp,
            identity,
            unique_hypotheses: hyps.len(),
        }
    }
}
