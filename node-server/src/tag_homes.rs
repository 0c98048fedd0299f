//! Each radio tag's *home*: the cluster that hears it loudest, the only head that binds it to a
//! track (`node_head::tags`). A head weighs a tag's readings against its own tracks only, and a
//! far tag's weak readings fit many tracks about as well as the one it is on, so without a rule
//! across clusters one tag was bound in four heads at once (docs/multi-target.md). The server
//! sees every cluster: each head tells it, every second, how loud its loudest node hears each
//! tag (`TagsHeard`), and the answer names each of those tags' home (`TagHomes`).
//!
//! Loudness is the rule because it needs no model shared across heads: RSSI falls with
//! distance, so the loudest node is near the tag, and nodes belong to the cluster around them.
//! Only clusters where a track claims the tag (holds it, or has the evidence to) compete while
//! any does: a person tracked just inside one cluster may be heard loudest by a node just
//! across the boundary, whose head has no track of them. And when the loudest claimer's track
//! is a person whose global another claimer owns (two heads tracking one person near their
//! boundary), the owner is home: the owner's track is the one the server reports, so it is the
//! one the readings must sharpen. A home moves only when another cluster hears the tag
//! [`HOME_MARGIN_DB`] louder, so a person on a boundary does not flip their tag between two
//! heads at every fade; a home whose head stopped hearing the tag for [`HEARD_STALE_NS`] goes
//! to the loudest of the others.

use proto::msg::{TagHeard, TagHome};
use proto::{ClusterTime, NodeId, TagId, TargetId};
use std::collections::BTreeMap;

/// How long a head's word on a tag counts, ns: three of the heads' status periods (a head
/// that stopped hearing the tag stops naming it).
pub const HEARD_STALE_NS: i64 = 3_000_000_000;
/// How much louder another cluster must hear a tag to become its home, dB.
pub const HOME_MARGIN_DB: f32 = 3.0;
/// Most tags the server keeps homes of; further ones get none (counted) until some go quiet.
pub const MAX_TAGS: usize = 1024;

/// What the server knows of one tag.
#[derive(Clone, Debug, Default)]
struct Tag {
    home: Option<NodeId>,
    /// Each head's last word: how loud, whether a track there claims the tag, and when it
    /// came.
    heard: BTreeMap<NodeId, Word>,
}

/// One head's word on one tag.
#[derive(Clone, Copy, Debug)]
struct Word {
    dbm: f32,
    /// The head's track that claims the tag.
    track: Option<TargetId>,
    at: ClusterTime,
}

impl Word {
    fn claimed(&self) -> bool {
        self.track.is_some()
    }
}

/// A tag's home moved (or was first named).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Moved {
    pub tag: TagId,
    pub from: Option<NodeId>,
    pub to: NodeId,
}

/// Every tag's home.
#[derive(Clone, Debug, Default)]
pub struct TagHomes {
    tags: BTreeMap<TagId, Tag>,
    /// Homes that moved from one head to another.
    pub moves: u64,
    /// Tags named past [`MAX_TAGS`], given no home.
    pub refused: u64,
}

impl TagHomes {
    /// Head `head` hears `tags` (each once) at `now`: note it, and name each of those tags'
    /// home (in `tags`' order), with the homes that moved. `global_of(head, local)` is the
    /// global id of a head's track and the head that owns that global.
    pub fn heard(
        &mut self,
        now: ClusterTime,
        head: NodeId,
        tags: &[TagHeard],
        global_of: impl Fn(NodeId, TargetId) -> Option<(TargetId, NodeId)>,
    ) -> (Vec<TagHome>, Vec<Moved>) {
        for t in self.tags.values_mut() {
            t.heard.retain(|_, w| now - w.at < HEARD_STALE_NS);
        }
        self.tags.retain(|_, t| !t.heard.is_empty());
        let mut homes = Vec::with_capacity(tags.len());
        let mut moved = Vec::new();
        for h in tags {
            if !self.tags.contains_key(&h.tag) && self.tags.len() >= MAX_TAGS {
                self.refused += 1;
                continue;
            }
            let tag = self.tags.entry(h.tag).or_default();
            tag.heard.insert(
                head,
                Word {
                    dbm: h.dbm,
                    track: h.track,
                    at: now,
                },
            );
            // Those that claim it compete, or all when none does.
            let any_claims = tag.heard.values().any(Word::claimed);
            let competes = |w: &Word| w.claimed() || !any_claims;
            // The loudest of them (the lower id on a tie, so the answer never depends on order).
            let (&loudest, loudest_word) = tag
                .heard
                .iter()
                .filter(|(_, w)| competes(w))
                .max_by(|a, b| a.1.dbm.total_cmp(&b.1.dbm).then(b.0.cmp(a.0)))
                .expect("the head just noted competes, or one that claims");
            let current = tag
                .home
                .and_then(|k| tag.heard.get(&k).filter(|w| competes(w)).map(|w| (k, w.dbm)));
            let louder = match current {
                Some((k, dbm)) if loudest_word.dbm < dbm + HOME_MARGIN_DB => k,
                _ => loudest,
            };
            // The owner of the person the chosen head's track is, if its own track is them too.
            let global = |k: NodeId| {
                tag.heard
                    .get(&k)
                    .and_then(|w| w.track)
                    .and_then(|t| global_of(k, t))
            };
            let home = match global(louder) {
                Some((g, owner)) if owner != louder && global(owner).is_some_and(|(g2, _)| g2 == g) => owner,
                _ => louder,
            };
            if tag.home != Some(home) {
                if tag.home.is_some() {
                    self.moves += 1;
                }
                moved.push(Moved {
                    tag: h.tag,
                    from: tag.home,
                    to: home,
                });
                tag.home = Some(home);
            }
            homes.push(TagHome {
                tag: h.tag,
                head: home,
            });
        }
        (homes, moved)
    }

    /// The home of `tag`, if one was named and some head still hears it.
    pub fn home(&self, tag: TagId) -> Option<NodeId> {
        self.tags.get(&tag).and_then(|t| t.home)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const S: i64 = 1_000_000_000;

    /// No track has a global yet.
    fn none(_: NodeId, _: TargetId) -> Option<(TargetId, NodeId)> {
        None
    }

    /// Words on tags that a track claims.
    fn heard(tags: &[(u64, f32)]) -> Vec<TagHeard> {
        tags.iter()
            .map(|&(t, dbm)| TagHeard {
                tag: TagId(t),
                dbm,
                track: Some(TargetId(1)),
            })
            .collect()
    }

    fn unclaimed(tag: u64, dbm: f32) -> Vec<TagHeard> {
        vec![TagHeard {
            tag: TagId(tag),
            dbm,
            track: None,
        }]
    }

    fn home_of(homes: &[TagHome], tag: u64) -> NodeId {
        homes.iter().find(|h| h.tag == TagId(tag)).expect("named").head
    }

    #[test]
    fn a_tag_heard_by_one_head_is_at_home_there() {
        let mut h = TagHomes::default();
        let (homes, moved) = h.heard(ClusterTime(0), NodeId(3), &heard(&[(7, -80.0)]), none);
        assert_eq!(home_of(&homes, 7), NodeId(3));
        assert_eq!(moved.len(), 1);
        assert_eq!(h.moves, 0, "a first home is no move");
    }

    #[test]
    fn the_loudest_cluster_is_home_and_a_home_moves_only_by_the_margin() {
        let mut h = TagHomes::default();
        h.heard(ClusterTime(0), NodeId(3), &heard(&[(7, -75.0)]), none);
        // Head 4 hears it louder by more than the margin: the home moves, and head 3 is told
        // so at its next word.
        let (homes, _) = h.heard(ClusterTime(S / 2), NodeId(4), &heard(&[(7, -60.0)]), none);
        assert_eq!(home_of(&homes, 7), NodeId(4));
        let (homes, _) = h.heard(ClusterTime(S), NodeId(3), &heard(&[(7, -75.0)]), none);
        assert_eq!(home_of(&homes, 7), NodeId(4));
        assert_eq!(h.moves, 1);
        // Head 3 now hears it a little louder than head 4, within the margin: it stays.
        let (homes, _) = h.heard(ClusterTime(2 * S), NodeId(3), &heard(&[(7, -58.5)]), none);
        assert_eq!(home_of(&homes, 7), NodeId(4));
        // … and by more than the margin: it moves back.
        let (homes, _) = h.heard(ClusterTime(3 * S), NodeId(3), &heard(&[(7, -56.0)]), none);
        assert_eq!(home_of(&homes, 7), NodeId(3));
        assert_eq!(h.moves, 2);
    }

    #[test]
    fn a_cluster_whose_tracks_claim_the_tag_is_home_over_a_louder_one_whose_do_not() {
        let mut h = TagHomes::default();
        // Nobody claims it: the loudest is home.
        h.heard(ClusterTime(0), NodeId(3), &unclaimed(7, -70.0), none);
        h.heard(ClusterTime(0), NodeId(4), &unclaimed(7, -60.0), none);
        assert_eq!(h.home(TagId(7)), Some(NodeId(4)));
        // Head 3's track claims it (the person is tracked there, heard loudest across the
        // boundary): head 3 is home, however much louder head 4 hears it.
        let (homes, _) = h.heard(ClusterTime(S), NodeId(3), &heard(&[(7, -72.0)]), none);
        assert_eq!(home_of(&homes, 7), NodeId(3));
        let (homes, _) = h.heard(ClusterTime(S), NodeId(4), &unclaimed(7, -50.0), none);
        assert_eq!(home_of(&homes, 7), NodeId(3));
        // Once head 4 claims it too, loudness decides between them.
        let (homes, _) = h.heard(ClusterTime(2 * S), NodeId(4), &heard(&[(7, -50.0)]), none);
        assert_eq!(home_of(&homes, 7), NodeId(4));
    }

    #[test]
    fn when_two_clusters_track_one_person_the_owner_of_their_global_is_home() {
        let mut h = TagHomes::default();
        // Head 3's track 1 and head 4's track 2 are both global 100, which head 3 owns; head
        // 4 hears the tag louder.
        let global_of = |head: NodeId, local: TargetId| match (head.0, local.0) {
            (3, 1) | (4, 2) => Some((TargetId(100), NodeId(3))),
            (4, 9) => Some((TargetId(200), NodeId(4))),
            _ => None,
        };
        let word = |dbm: f32, track: u32| {
            vec![TagHeard {
                tag: TagId(7),
                dbm,
                track: Some(TargetId(track)),
            }]
        };
        h.heard(ClusterTime(0), NodeId(3), &word(-70.0, 1), global_of);
        let (homes, _) = h.heard(ClusterTime(0), NodeId(4), &word(-55.0, 2), global_of);
        assert_eq!(home_of(&homes, 7), NodeId(3));
        // Head 4's claiming track is someone else (global 200): the louder cluster is home.
        let (homes, _) = h.heard(ClusterTime(S), NodeId(4), &word(-55.0, 9), global_of);
        assert_eq!(home_of(&homes, 7), NodeId(4));
    }

    #[test]
    fn a_home_that_stopped_hearing_the_tag_passes_to_the_others() {
        let mut h = TagHomes::default();
        h.heard(ClusterTime(0), NodeId(3), &heard(&[(7, -55.0)]), none);
        h.heard(ClusterTime(0), NodeId(4), &heard(&[(7, -70.0)]), none);
        assert_eq!(h.home(TagId(7)), Some(NodeId(3)));
        // Head 3 says nothing of the tag for longer than the staleness bound.
        let (homes, _) = h.heard(
            ClusterTime(HEARD_STALE_NS + 1),
            NodeId(4),
            &heard(&[(7, -70.0)]),
            none,
        );
        assert_eq!(home_of(&homes, 7), NodeId(4));
    }

    #[test]
    fn a_tie_keeps_the_home_and_one_word_names_every_tag() {
        let mut a = TagHomes::default();
        a.heard(ClusterTime(0), NodeId(4), &heard(&[(7, -60.0)]), none);
        let (homes_a, _) = a.heard(ClusterTime(0), NodeId(3), &heard(&[(7, -60.0)]), none);
        let mut b = TagHomes::default();
        b.heard(ClusterTime(0), NodeId(3), &heard(&[(7, -60.0)]), none);
        let (homes_b, _) = b.heard(ClusterTime(0), NodeId(4), &heard(&[(7, -60.0)]), none);
        // The first named keeps it either way: a tie passes no margin.
        assert_eq!(home_of(&homes_a, 7), NodeId(4));
        assert_eq!(home_of(&homes_b, 7), NodeId(3));
        let mut c = TagHomes::default();
        let (homes_c, _) = c.heard(ClusterTime(0), NodeId(5), &heard(&[(7, -60.0), (8, -61.0)]), none);
        assert_eq!(homes_c.len(), 2);
    }

    #[test]
    fn the_book_is_bounded_and_quiet_tags_are_forgotten() {
        let mut h = TagHomes::default();
        let many: Vec<TagHeard> = (0..MAX_TAGS as u64 + 10)
            .map(|t| TagHeard {
                tag: TagId(t),
                dbm: -70.0,
                track: Some(TargetId(1)),
            })
            .collect();
        for chunk in many.chunks(256) {
            h.heard(ClusterTime(0), NodeId(3), chunk, none);
        }
        assert_eq!(h.refused, 10);
        assert_eq!(h.home(TagId(MAX_TAGS as u64 + 5)), None);
        // Three seconds on, none was heard again: all are forgotten, and room is made.
        let (homes, _) = h.heard(
            ClusterTime(HEARD_STALE_NS),
            NodeId(3),
            &heard(&[(99_999, -60.0)]),
            none,
        );
        assert_eq!(homes.len(), 1);
        assert_eq!(h.home(TagId(0)), None);
    }
}
