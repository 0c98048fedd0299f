//! Frames lost on the way to the server, from the senders' sequence numbers.
//!
//! A sender numbers every frame it puts on a link (+1 each, from 0), so a number that never
//! arrives is a lost frame. Frames of one sender may arrive out of order: over iceoryx2 a
//! node's heartbeats leave from the transport's own thread, its messages from the runtime's,
//! and a heartbeat numbered before a status can land after it. Counting each jump forward as a
//! loss took every such swap for two or more lost frames. So a number is lost only if it never
//! arrives; a late one fills its gap. A number more than [`REORDER_WINDOW`] below the highest
//! seen starts a new sequence (the sender restarted): what the old one still missed is lost. A
//! number within the window that fills no gap (a duplicate, or a swap of a sender's first
//! frames) changes nothing.

use proto::NodeId;
use std::collections::{BTreeMap, BTreeSet};

/// How far below the highest number seen a frame may arrive and still be a late frame of the
/// same sequence, not the start of a new one.
const REORDER_WINDOW: u64 = 64;

/// Most numbers remembered as missing per sender: a jump forward beyond it, or gaps piling up
/// past it, are counted as lost at once (the oldest first), so a forged or corrupt sequence
/// number cannot take unbounded memory.
const MAX_REMEMBERED: usize = 10_000;

#[derive(Debug, Default)]
struct Sender {
    highest: u64,
    missing: BTreeSet<u64>,
}

/// Per sender, the numbers not yet seen below its highest, and the ones given up on.
#[derive(Debug, Default)]
pub struct SequenceGaps {
    senders: BTreeMap<NodeId, Sender>,
    lost: u64,
}

impl SequenceGaps {
    /// Note frame `seq` from `source`.
    pub fn see(&mut self, source: NodeId, seq: u64) {
        let Some(s) = self.senders.get_mut(&source) else {
            self.senders.insert(
                source,
                Sender {
                    highest: seq,
                    missing: BTreeSet::new(),
                },
            );
            return;
        };
        if seq > s.highest {
            let gap = seq - s.highest - 1;
            if gap > MAX_REMEMBERED as u64 {
                self.lost = self.lost.saturating_add(gap);
            } else {
                s.missing.extend(s.highest + 1..seq);
            }
            s.highest = seq;
            while s.missing.len() > MAX_REMEMBERED {
                s.missing.pop_first();
                self.lost = self.lost.saturating_add(1);
            }
        } else if !s.missing.remove(&seq) && seq.saturating_add(REORDER_WINDOW) < s.highest {
            self.lost = self.lost.saturating_add(s.missing.len() as u64);
            s.missing.clear();
            s.highest = seq;
        }
    }

    /// Frames lost so far: given up on, and still missing.
    pub fn lost(&self) -> u64 {
        self.senders
            .values()
            .fold(self.lost, |n, s| n.saturating_add(s.missing.len() as u64))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lost(seqs: &[(u32, u64)]) -> u64 {
        let mut g = SequenceGaps::default();
        for &(n, s) in seqs {
            g.see(NodeId(n), s);
        }
        g.lost()
    }

    #[test]
    fn a_number_that_never_arrives_is_lost_and_a_late_one_is_not() {
        assert_eq!(lost(&[(5, 1), (5, 2), (5, 3)]), 0);
        assert_eq!(lost(&[(5, 1), (5, 4), (5, 5)]), 2, "2 and 3 never came");
        // The hall's swap: 190 after 191–194.
        assert_eq!(
            lost(&[
                (5, 189),
                (5, 191),
                (5, 192),
                (5, 193),
                (5, 194),
                (5, 190),
                (5, 195)
            ]),
            0
        );
        assert_eq!(lost(&[(5, 10), (5, 12), (5, 11), (5, 13)]), 0);
        // Senders are counted apart.
        assert_eq!(lost(&[(5, 1), (6, 7), (5, 3), (6, 8)]), 1);
    }

    #[test]
    fn a_duplicate_or_a_swap_of_the_first_frames_loses_nothing() {
        assert_eq!(lost(&[(5, 1), (5, 2), (5, 3), (5, 2), (5, 4)]), 0);
        assert_eq!(lost(&[(5, 1), (5, 0), (5, 2), (5, 3)]), 0);
    }

    #[test]
    fn a_restarted_sender_starts_again_and_its_old_gaps_stay_lost() {
        let run = |from: u64, to: u64| (from..=to).map(|s| (5, s)).collect::<Vec<_>>();
        let restarted = [run(0, 100), run(0, 10)].concat();
        assert_eq!(lost(&restarted), 0);
        let mut with_gap = run(0, 100);
        with_gap.retain(|&(_, s)| s != 50 && s != 51);
        with_gap.extend(run(0, 10));
        assert_eq!(lost(&with_gap), 2, "50 and 51 of the old run");
        // The new run's own gaps count as well.
        with_gap.extend([(5, 13)]);
        assert_eq!(lost(&with_gap), 4);
    }

    #[test]
    fn what_a_sender_misses_is_bounded_in_memory_and_in_count() {
        let mut g = SequenceGaps::default();
        g.see(NodeId(5), 1);
        g.see(NodeId(5), u64::MAX);
        assert_eq!(g.lost(), u64::MAX - 2);
        assert!(g.senders[&NodeId(5)].missing.is_empty());
        g.see(NodeId(6), 0);
        g.see(NodeId(6), u64::MAX);
        assert_eq!(g.lost(), u64::MAX, "saturates");
        // Jumps of the remembered size pile up no further than the bound.
        let mut g = SequenceGaps::default();
        for k in 0..5u64 {
            g.see(NodeId(5), k * (MAX_REMEMBERED as u64 + 1));
        }
        assert_eq!(g.senders[&NodeId(5)].missing.len(), MAX_REMEMBERED);
        assert_eq!(g.lost(), 4 * MAX_REMEMBERED as u64);
    }
}
