//! Each radio tag's *home*: the cluster whose track the tag's readings go into
//! (`node_head::tags`). A head weighs a tag's readings against its own tracks only, and a far
//! tag's weak readings fit many tracks about as well as the one it is on, so without a rule
//! across clusters one tag was bound in four heads at once (docs/multi-target.md). The server
//! sees every cluster: each head tells it, with its status and whenever a claim changes, every
//! tag it hears, how loud its loudest node hears it, where that node is, and the track the
//! tag is bound to, its claim (`TagsHeard`: a complete list, so a tag left out is no longer
//! heard there); the answer names each of those tags' home (`TagHomes`).
//!
//! The rule needs no radio model shared across heads: RSSI falls with distance, so the
//! loudest node any head hears the tag at is near it, and the home is the cluster whose
//! claiming track is nearest that node. Heads whose claiming track is the one the server
//! reports for its person (the head owns the track's global) compete first, then any that
//! claims: a head's fresh duplicate without a global must not take the tag from the track
//! that is reported. While no head claims the tag the loudest cluster is home. A home moves
//! only for a track [`HOME_MARGIN_M`] nearer (or, without positions, a cluster
//! [`HOME_MARGIN_DB`] louder), so a person on a boundary does not flip their tag between two
//! heads at every fade; a home whose head stopped naming the tag (or fell silent for
//! [`HEARD_STALE_NS`]) goes to the best of the others, and the former home is told at once.
//! One person's tracks in two clusters may both take the person's tag: the answer says
//! whether the asker's track is the home's person by the server's books
//! ([`TagHomes::answer`]); what must not happen is one tag in two people's tracks.

use proto::msg::{TagHeard, TagHome};
use proto::{ClusterTime, NodeId, TagId, TargetId};
use std::collections::BTreeMap;

/// How long a head's word on a tag counts, ns: three of the heads' status periods (a head
/// that stopped hearing the tag stops naming it).
pub const HEARD_STALE_NS: i64 = 3_000_000_000;
/// How much louder another cluster must hear a tag to become its home (when no track's
/// distance is known), dB.
pub const HOME_MARGIN_DB: f32 = 3.0;
/// How much nearer to the tag another cluster's claiming track must be to become its home, m.
pub const HOME_MARGIN_M: f64 = 1.0;
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

/// What the server knows of the heads' tracks that the rule asks.
pub trait Tracked {
    /// The global id of head `head`'s track `local`, and the head that owns that global.
    fn global_of(&self, head: NodeId, local: TargetId) -> Option<(TargetId, NodeId)>;
    /// Where that track was last reported, `[x, y]` metres.
    fn position_of(&self, head: NodeId, local: TargetId) -> Option<[f64; 2]>;
}

/// One head's word on one tag.
#[derive(Clone, Copy, Debug)]
struct Word {
    dbm: f32,
    /// Where the head's loudest node is.
    near: [f32; 2],
    /// The head's track that claims the tag.
    track: Option<TargetId>,
    at: ClusterTime,
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
    /// Head `head` hears `tags` (each once: all it hears, so a tag it leaves out it no longer
    /// hears) at `now`: note it, and answer each of those tags' home (in `tags`' order), with
    /// the homes that moved (whose former home [`TagHomes::answer`] should reach too).
    pub fn heard(
        &mut self,
        now: ClusterTime,
        head: NodeId,
        tags: &[TagHeard],
        tracks: &impl Tracked,
    ) -> (Vec<TagHome>, Vec<Moved>) {
        let global_of = |k: NodeId, t: TargetId| tracks.global_of(k, t);
        let named: std::collections::BTreeSet<TagId> = tags.iter().map(|h| h.tag).collect();
        for (g, t) in &mut self.tags {
            t.heard
                .retain(|&k, w| now - w.at < HEARD_STALE_NS && (k != head || named.contains(g)));
        }
        self.tags.retain(|_, t| !t.heard.is_empty());
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
                    near: h.near,
                    track: h.track,
                    at: now,
                },
            );
            // Who competes: the heads whose claiming track is the one the server reports for
            // its person (the head owns the track's global), else those that claim it, else all.
            let standing = |k: NodeId, w: &Word| match w.track {
                Some(t) if global_of(k, t).is_some_and(|(_, owner)| owner == k) => 2,
                Some(_) => 1,
                None => 0,
            };
            let best = tag
                .heard
                .iter()
                .map(|(&k, w)| standing(k, w))
                .max()
                .expect("the head just noted");
            let competes = |k: NodeId, w: &Word| standing(k, w) == best;
            // How far each competitor is from the tag: a claiming track's distance to the
            // loudest node any head hears it at; a head without a claiming track (or a track of
            // unknown position) ranks by its loudness alone, behind every known distance.
            let near = tag
                .heard
                .values()
                .max_by(|a, b| a.dbm.total_cmp(&b.dbm))
                .expect("the head just noted")
                .near;
            let far = |k: NodeId, w: &Word| -> (f64, f32) {
                let at = w.track.and_then(|t| tracks.position_of(k, t));
                match at {
                    Some(p) => (
                        (p[0] - f64::from(near[0])).hypot(p[1] - f64::from(near[1])),
                        -w.dbm,
                    ),
                    None => (f64::INFINITY, -w.dbm),
                }
            };
            // The nearest of them (then the loudest, then the lower id, so the answer never
            // depends on order).
            let (&best_head, best_word) = tag
                .heard
                .iter()
                .filter(|&(&k, w)| competes(k, w))
                .min_by(|a, b| {
                    let (da, la) = far(*a.0, a.1);
                    let (db, lb) = far(*b.0, b.1);
                    da.total_cmp(&db).then(la.total_cmp(&lb)).then(a.0.cmp(b.0))
                })
                .expect("the best standing is someone's");
            let (best_d, best_l) = far(best_head, best_word);
            let current = tag.home.and_then(|k| {
                tag.heard
                    .get(&k)
                    .filter(|w| competes(k, w))
                    .map(|w| (k, far(k, w)))
            });
            // The home stays unless another is clearly better: nearer by the margin, or (among
            // unknown distances) louder by the margin.
            let home = match current {
                Some((k, (d, _))) if d.is_finite() && best_d > d - HOME_MARGIN_M => k,
                Some((k, (d, l)))
                    if d.is_infinite() && best_d.is_infinite() && -best_l < -l + HOME_MARGIN_DB =>
                {
                    k
                }
                _ => best_head,
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
        }
        let homes = tags
            .iter()
            .filter_map(|h| self.answer(h.tag, head, tracks))
            .collect();
        (homes, moved)
    }

    /// What head `asker` is told of `tag`: its home, and whether the asker's claiming track is
    /// the home's person by the server's books (then it takes the readings too: one person's
    /// tracks in two clusters, a track handed back to its first head). The server decides,
    /// not the head, whose label of its track may be stale after a split or a merge.
    pub fn answer(&self, tag: TagId, asker: NodeId, tracks: &impl Tracked) -> Option<TagHome> {
        let t = self.tags.get(&tag)?;
        let home = t.home?;
        let person = |k: NodeId| {
            t.heard
                .get(&k)
                .and_then(|w| w.track)
                .and_then(|local| tracks.global_of(k, local))
                .map(|(g, _)| g)
        };
        let shared = asker != home && person(asker).is_some() && person(asker) == person(home);
        Some(TagHome {
            tag,
            head: home,
            shared,
        })
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

    /// The server's tracks as the tests need them: (head, local) → (global, owner, position).
    #[derive(Default)]
    struct Book(BTreeMap<(u32, u32), (u32, u32, [f64; 2])>);

    impl Tracked for Book {
        fn global_of(&self, head: NodeId, local: TargetId) -> Option<(TargetId, NodeId)> {
            let &(g, owner, _) = self.0.get(&(head.0, local.0))?;
            Some((TargetId(g), NodeId(owner)))
        }
        fn position_of(&self, head: NodeId, local: TargetId) -> Option<[f64; 2]> {
            self.0.get(&(head.0, local.0)).map(|e| e.2)
        }
    }

    /// No track has a global yet.
    #[allow(non_upper_case_globals)]
    const none: &Book = &Book(BTreeMap::new());

    /// Words on tags that a track claims (where no track's position is known, `near` says
    /// nothing).
    use proto::examples::claimed_tags as heard;

    fn unclaimed(tag: u64, dbm: f32) -> Vec<TagHeard> {
        vec![TagHeard {
            tag: TagId(tag),
            dbm,
            near: [0.0, 0.0],
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

    fn word(dbm: f32, near: [f32; 2], track: u32) -> Vec<TagHeard> {
        vec![TagHeard {
            tag: TagId(7),
            dbm,
            near,
            track: Some(TargetId(track)),
        }]
    }

    #[test]
    fn the_cluster_whose_track_is_nearest_the_loudest_node_is_home() {
        // Two people: head 3's track 1 (global 100) at (2, 2), head 4's track 9 (global 200)
        // at (20, 5); both claim the tag.
        let book = Book(BTreeMap::from([
            ((3, 1), (100, 3, [2.0, 2.0])),
            ((4, 9), (200, 4, [20.0, 5.0])),
        ]));
        let mut h = TagHomes::default();
        h.heard(ClusterTime(0), NodeId(3), &word(-55.0, [3.0, 2.0], 1), &book);
        let (homes, _) = h.heard(ClusterTime(0), NodeId(4), &word(-70.0, [18.0, 5.0], 9), &book);
        assert_eq!(home_of(&homes, 7), NodeId(3));
        assert!(!homes[0].shared, "another person's track");
        // The tag walked to head 4's person: head 4's node hears it loudest now.
        h.heard(ClusterTime(S), NodeId(3), &word(-75.0, [3.0, 2.0], 1), &book);
        let (homes, _) = h.heard(ClusterTime(S), NodeId(4), &word(-50.0, [19.0, 5.0], 9), &book);
        assert_eq!(home_of(&homes, 7), NodeId(4));
        assert_eq!(h.moves, 1);
    }

    #[test]
    fn a_cluster_whose_claiming_track_is_reported_is_home_and_shares_with_its_persons_tracks() {
        // One person, global 100, owned by head 3 (track 1 at (5, 5)); head 4 tracks them too
        // (track 2, 2 m nearer the loudest node) and has a fresh track 5 the server has no
        // global for.
        let book = Book(BTreeMap::from([
            ((3, 1), (100, 3, [5.0, 5.0])),
            ((4, 2), (100, 3, [7.0, 5.0])),
        ]));
        let mut h = TagHomes::default();
        h.heard(ClusterTime(0), NodeId(4), &word(-55.0, [7.0, 5.0], 2), &book);
        let (homes, _) = h.heard(ClusterTime(0), NodeId(3), &word(-70.0, [4.0, 5.0], 1), &book);
        assert_eq!(home_of(&homes, 7), NodeId(3), "the owner's track, though farther");
        assert!(!homes[0].shared, "the home itself");
        // Head 4's track of the same person takes the readings too; its fresh one does not.
        let (homes, _) = h.heard(ClusterTime(S), NodeId(4), &word(-55.0, [7.0, 5.0], 2), &book);
        assert_eq!(home_of(&homes, 7), NodeId(3));
        assert!(homes[0].shared);
        let (homes, _) = h.heard(ClusterTime(S), NodeId(4), &word(-55.0, [7.0, 5.0], 5), &book);
        assert!(!homes[0].shared);
    }

    #[test]
    fn a_head_that_stops_naming_a_tag_no_longer_competes_for_it() {
        let mut h = TagHomes::default();
        h.heard(ClusterTime(0), NodeId(3), &heard(&[(7, -55.0), (8, -60.0)]), none);
        h.heard(ClusterTime(0), NodeId(4), &heard(&[(7, -70.0)]), none);
        assert_eq!(h.home(TagId(7)), Some(NodeId(3)));
        // Head 3 hears only tag 8 now: its word on 7 is gone at once, not after staleness.
        h.heard(ClusterTime(S), NodeId(3), &heard(&[(8, -60.0)]), none);
        let (homes, moved) = h.heard(ClusterTime(S), NodeId(4), &heard(&[(7, -70.0)]), none);
        assert_eq!(home_of(&homes, 7), NodeId(4));
        assert_eq!(
            moved,
            vec![Moved {
                tag: TagId(7),
                from: Some(NodeId(3)),
                to: NodeId(4)
            }]
        );
        assert_eq!(
            h.answer(TagId(7), NodeId(3), none).map(|a| a.head),
            Some(NodeId(4))
        );
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
                near: [0.0, 0.0],
                track: Some(TargetId(1)),
            })
            .collect();
        // (Each head's list is all it hears: five heads name a share each.)
        for (i, chunk) in (0u32..).zip(many.chunks(256)) {
            h.heard(ClusterTime(0), NodeId(3 + i), chunk, none);
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
