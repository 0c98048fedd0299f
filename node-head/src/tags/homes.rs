//! A tag's home across clusters (`node_server::tag_homes`): what the head tells the server
//! (how loud its cluster hears each tag, where, and the track it is bound to) and what the
//! server's word does here (a tag homed at another head feeds a track only if the server says
//! that track is the home's person). Bindings themselves are `super`'s: they follow the
//! evidence whatever the home.

use super::{Change, TagBook};
use proto::msg::{TagHeard, TagHome};
use proto::observation::RssiReading;
use proto::{ClusterTime, TagId, TargetId};
use std::collections::{BTreeMap, BTreeSet};

/// How long the server's word on a tag's home holds, ns: three of the heads' status periods
/// (the server answers each), so one lost answer changes nothing and a server gone leaves the
/// heads binding by their own evidence within seconds.
pub const HOME_TTL_NS: i64 = 3_000_000_000;
/// The window a node's readings of a tag count for its loudness, ns: a reading older than
/// this says nothing about where the tag is now (people walk 1–2 m/s).
pub const LOUD_WINDOW_NS: i64 = 4_000_000_000;
/// Weight of a new reading in a node's smoothed loudness of a tag: one multipath fade or one
/// lucky reading moves it by a quarter of its difference.
pub const LOUD_SMOOTHING: f64 = 0.25;

/// One node's smoothed readings of one tag.
#[derive(Clone, Copy, Debug)]
pub(super) struct Loud {
    pub(super) dbm: f64,
    /// Reception time of the newest reading in it.
    pub(super) at: ClusterTime,
}

/// Fold node `slot`'s `reading` into its smoothed loudness of the tag (restarted after a
/// silence of [`LOUD_WINDOW_NS`]; an older reading than the newest is ignored).
pub(super) fn note_loudness(loud: &mut BTreeMap<usize, Loud>, slot: usize, reading: &RssiReading) {
    let fresh = Loud {
        dbm: reading.dbm,
        at: reading.time,
    };
    let l = loud.entry(slot).or_insert(fresh);
    if reading.time - l.at > LOUD_WINDOW_NS {
        *l = fresh;
    } else if reading.time > l.at {
        l.dbm += LOUD_SMOOTHING * (reading.dbm - l.dbm);
        l.at = reading.time;
    }
}

impl TagBook {
    /// How loud the cluster hears each tag at `now`: the loudest node's smoothed readings
    /// among the nodes heard in the last [`LOUD_WINDOW_NS`] (each node's readings smoothed
    /// with weight [`LOUD_SMOOTHING`], restarted after a silence that long), where that node
    /// is, and the track the tag is bound to, in increasing tag order.
    pub fn loudest(&self, now: ClusterTime) -> Vec<TagHeard> {
        self.tags
            .iter()
            .filter_map(|(&tag, t)| {
                // (A node whose position is not known cannot say where the tag is.)
                let (near, dbm) = t
                    .loud
                    .iter()
                    .filter(|(_, l)| now - l.at <= LOUD_WINDOW_NS)
                    .filter_map(|(&slot, l)| Some((*self.positions.get(slot)?, l.dbm)))
                    .reduce(|a, b| if b.1 > a.1 { b } else { a })?;
                Some(TagHeard {
                    tag,
                    dbm: dbm as f32,
                    near: [near[0] as f32, near[1] as f32],
                    track: t.bound,
                })
            })
            .collect()
    }

    /// What to tell the server at `now` ([`TagBook::loudest`]), noted as told; `None` when
    /// there is nothing and nothing was told before (an empty list is told once: the server
    /// takes each list as all the head hears).
    pub fn tell(&mut self, now: ClusterTime) -> Option<Vec<TagHeard>> {
        let heard = self.loudest(now);
        if heard.is_empty() && !self.told_any {
            return None;
        }
        self.told_any = !heard.is_empty();
        self.told = heard.iter().filter_map(|h| Some((h.tag, h.track?))).collect();
        Some(heard)
    }

    /// Whether a claim changed since the server was last told (a track took a tag, or let it
    /// go): worth telling at once, not at the next status, since a home the server no longer
    /// gives this head holds its track's readings back until it hears.
    pub fn claims_changed(&self, now: ClusterTime) -> bool {
        let claims: BTreeMap<TagId, TargetId> = self
            .loudest(now)
            .iter()
            .filter_map(|h| Some((h.tag, h.track?)))
            .collect();
        claims != self.told
    }

    /// The server's word on tags' homes, at `now` (tags the book does not know are ignored:
    /// it asked about none of them).
    pub fn set_homes(&mut self, homes: &[TagHome], now: ClusterTime) {
        for h in homes {
            if let Some(t) = self.tags.get_mut(&h.tag) {
                t.home = Some((h.head, h.shared, now));
            }
        }
    }

    /// Which tags' home is another head at `now`: the server said so in the last
    /// [`HOME_TTL_NS`]. Their readings go into no track here ([`TagBook::fused_tag_of`]);
    /// a binding stays as evidence keeps it, so the track takes them again the moment the
    /// home comes back. Returns the bound tags that have just gone away.
    pub fn refresh_homes(&mut self, now: ClusterTime) -> Vec<Change> {
        let me = self.me;
        let away: BTreeSet<TagId> = self
            .tags
            .iter()
            .filter(|(_, t)| {
                t.home
                    .is_some_and(|(head, _, at)| Some(head) != me && now - at < HOME_TTL_NS)
            })
            .map(|(&g, _)| g)
            .collect();
        let changes = away
            .difference(&self.away)
            .filter_map(|g| {
                let t = &self.tags[g];
                Some(Change::Away {
                    tag: *g,
                    track: t.bound?,
                    home: t.home?.0,
                })
            })
            .collect();
        self.away = away;
        changes
    }

    /// The tag whose readings track `local` takes: the one bound to it, unless that tag's
    /// home is another head that does not share it with this head's track.
    pub fn fused_tag_of(&self, local: TargetId) -> Option<TagId> {
        self.tag_of(local).filter(|&g| {
            !self.away(g)
                || self
                    .tags
                    .get(&g)
                    .and_then(|t| t.home)
                    .is_some_and(|(_, shared, _)| shared)
        })
    }

    /// Whether `tag`'s home is another head (as of the last [`TagBook::refresh_homes`]).
    pub fn away(&self, tag: TagId) -> bool {
        self.away.contains(&tag)
    }
}
