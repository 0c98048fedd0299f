//! Frames lost on the way to the server, from the senders' sequence numbers.
//!
//! A sender numbers every frame it puts on a link (+1 each), so a number that never arrives is a
//! lost frame. Frames of one sender may arrive out of order: over iceoryx2 a node's heartbeats
//! leave from the transport's own thread, its messages from the runtime's, and a heartbeat
//! numbered before a status can land after it. Counting each jump forward as a loss took such
//! a swap for two or more lost frames (a 60 s hall over iceoryx2 reported 8 of its 19 drops
//! that way with nothing lost). So a number is lost only if it never arrives; a late one fills
//! its gap. A number at or below the highest seen that fills no gap starts a new sequence (the
//! sender restarted): what the old one still missed is lost.

use proto::NodeId;
use std::collections::{BTreeMap, BTreeSet};

/// A jump forward this large is taken as lost at once, not remembered number by number (it
/// bounds the memory a forged or corrupt sequence number can take).
const MAX_REMEMBERED_GAP: u64 = 10_000;

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
            if gap > MAX_REMEMBERED_GAP {
                self.lost += gap;
            } else {
                s.missing.extend(s.highest + 1..seq);
            }
            s.highest = seq;
        } else if !s.missing.remove(&seq) {
            self.lost += s.missing.len() as u64;
            s.missing.clear();
            s.highest = seq;
        }
    }

    /// Frames lost so far: given up on, and still missing.
    pub fn lost(&self) -> u64 {
        self.lost + self.senders.values().map(|s| s.missing.len() as u64).sum::<u64>()
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
    fn a_restarted_sender_starts_again_and_its_old_gaps_stay_lost() {
        assert_eq!(
            lost(&[(5, 1), (5, 2), (5, 1), (5, 2), (5, 3)]),
            0,
            "a restart at 1"
        );
        assert_eq!(
            lost(&[(5, 1), (5, 4), (5, 0), (5, 1)]),
            2,
            "2 and 3 of the old run"
        );
    }

    #[test]
    fn a_huge_jump_is_counted_without_being_remembered() {
        let mut g = SequenceGaps::default();
        g.see(NodeId(5), 1);
        g.see(NodeId(5), u64::MAX);
        assert_eq!(g.lost(), u64::MAX - 2);
        assert!(g.senders[&NodeId(5)].missing.is_empty());
    }
}
