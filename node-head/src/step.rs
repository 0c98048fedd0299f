//! The distributed step's bookkeeping (paper 002 §III): which (node, track) pairs are expected
//! to answer, which did, and what to do with each (node, track) answer a node's `Answers`
//! bring — apply it, or count it as late or duplicate so it is never applied twice.
//!
//! The answered table is a flat `nodes × tracks` array of step numbers, sized when a step
//! opens; offering an answer is an index and a compare, no allocation.

use proto::ClusterTime;

/// What to do with an arriving (node, track) answer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Offer {
    /// New and in time: sum it.
    Apply,
    /// For a step that is closed, or past the deadline.
    Late,
    /// This (node, track) already answered this step.
    Duplicate,
    /// For a step that has not started: a confused or forged sender.
    Future,
}

/// Counters of one step.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StepCounts {
    pub applied: u64,
    pub late: u64,
    pub duplicate: u64,
    pub future: u64,
}

/// The current step's window.
#[derive(Clone, Debug, Default)]
pub struct StepWindow {
    step: u64,
    open: bool,
    deadline: ClusterTime,
    nodes: usize,
    tracks: usize,
    /// `answered[n * tracks + t]` = last step node `n` answered track `t`.
    answered: Vec<u64>,
    expected: Vec<bool>,
    remaining: usize,
    counts: StepCounts,
}

impl StepWindow {
    /// Open step `step` (strictly greater than the last) for `nodes × tracks` with `expected[n]`
    /// saying whether node `n` must answer.
    pub fn open(&mut self, step: u64, deadline: ClusterTime, tracks: usize, expected: &[bool]) {
        self.step = step;
        self.open = true;
        self.deadline = deadline;
        self.nodes = expected.len();
        self.tracks = tracks;
        self.answered.clear();
        self.answered.resize(self.nodes * tracks, 0);
        self.expected.clear();
        self.expected.extend_from_slice(expected);
        self.remaining = expected.iter().filter(|&&e| e).count() * tracks;
        self.counts = StepCounts::default();
    }

    pub fn close(&mut self) {
        self.open = false;
    }

    pub fn is_open(&self) -> bool {
        self.open
    }

    pub fn step(&self) -> u64 {
        self.step
    }

    pub fn deadline(&self) -> ClusterTime {
        self.deadline
    }

    pub fn counts(&self) -> StepCounts {
        self.counts
    }

    /// Every expected (node, track) answered.
    pub fn complete(&self) -> bool {
        self.open && self.remaining == 0
    }

    pub fn past_deadline(&self, now: ClusterTime) -> bool {
        self.open && now > self.deadline
    }

    /// Classify the answer of node `node` for track `track` of step `step` at `now`,
    /// and record it when it is to be applied. Indices out of range are `Future` (unknown).
    pub fn offer(&mut self, node: usize, track: usize, step: u64, now: ClusterTime) -> Offer {
        let verdict = if step > self.step || node >= self.nodes || track >= self.tracks {
            Offer::Future
        } else if step < self.step || !self.open || now > self.deadline {
            Offer::Late
        } else if self.answered[node * self.tracks + track] == step {
            Offer::Duplicate
        } else {
            self.answered[node * self.tracks + track] = step;
            if self.expected[node] {
                self.remaining -= 1;
            }
            Offer::Apply
        };
        match verdict {
            Offer::Apply => self.counts.applied += 1,
            Offer::Late => self.counts.late += 1,
            Offer::Duplicate => self.counts.duplicate += 1,
            Offer::Future => self.counts.future += 1,
        }
        verdict
    }

    /// Classify an answer by its step alone (it names no (node, track) of the open step): late
    /// for an earlier step, or this one closed or past its deadline; else future (a step not
    /// started, or a part this step never had).
    pub fn classify(&mut self, step: u64, now: ClusterTime) -> Offer {
        if step < self.step || (step == self.step && (!self.open || now > self.deadline)) {
            self.counts.late += 1;
            Offer::Late
        } else {
            self.counts.future += 1;
            Offer::Future
        }
    }

    /// Stop waiting for node `node` (it went down or was commanded Inactive).
    pub fn release(&mut self, node: usize) {
        if node >= self.nodes || !self.expected[node] {
            return;
        }
        self.expected[node] = false;
        let unanswered = (0..self.tracks)
            .filter(|&t| self.answered[node * self.tracks + t] != self.step)
            .count();
        self.remaining -= unanswered;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn accounting_of_late_duplicate_and_completion() {
        let mut w = StepWindow::default();
        let t0 = ClusterTime::from_millis(0);
        let dl = ClusterTime::from_millis(80);
        w.open(1, dl, 2, &[true, true, false]);
        assert_eq!(w.offer(0, 0, 1, t0), Offer::Apply);
        assert_eq!(w.offer(0, 0, 1, t0), Offer::Duplicate);
        assert_eq!(w.offer(0, 1, 1, t0), Offer::Apply);
        assert_eq!(w.offer(2, 0, 1, t0), Offer::Apply); // not expected, still welcome
        assert!(!w.complete());
        assert_eq!(w.offer(1, 0, 2, t0), Offer::Future);
        assert_eq!(w.offer(1, 0, 0, t0), Offer::Late);
        assert_eq!(w.offer(1, 0, 1, ClusterTime::from_millis(81)), Offer::Late);
        w.release(1);
        assert!(w.complete());
        assert_eq!(
            w.counts(),
            StepCounts {
                applied: 3,
                late: 2,
                duplicate: 1,
                future: 1
            }
        );
        w.close();
        assert_eq!(w.offer(1, 1, 1, t0), Offer::Late);
        assert!(!w.complete());
    }

    #[test]
    fn release_counts_only_unanswered() {
        let mut w = StepWindow::default();
        w.open(7, ClusterTime::from_millis(10), 3, &[true, true]);
        w.offer(0, 0, 7, ClusterTime::ZERO);
        w.offer(1, 0, 7, ClusterTime::ZERO);
        w.offer(1, 1, 7, ClusterTime::ZERO);
        w.offer(1, 2, 7, ClusterTime::ZERO);
        w.release(0);
        assert!(w.complete());
    }
}
