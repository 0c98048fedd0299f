//! Which tag rides on which track. A tag's reading says where *that tag* is, not which of the
//! head's tracks it belongs to: fused into every track, one tagged person's readings pulled a
//! second person's track toward them and kept a duplicate of the tagged one alive beside it
//! (issue 16). So the head weighs every fresh reading against every track it could be of, and
//! fuses a tag's readings only into the one track it is bound to.
//!
//! The evidence for "tag g is on track k" is a log-likelihood ratio summed over g's readings
//! and forgotten with a half-life of [`EVIDENCE_HALF_LIFE_S`]: the reading under the track's
//! RSSI model at the track's position when it was received (with the position's uncertainty),
//! against the reading under "the tag is on no track" — a flat density over
//! [`RSSI_SPAN_DB`]. A tag is bound to a confirmed track once that track's evidence reaches
//! [`BIND_LLR`] and leads every other track's (tentative ones and those holding other tags
//! included) by as much; it moves to another track only when that one leads by as much, and
//! is unbound when its track's evidence falls to −[`BIND_LLR`] (the tag is clearly elsewhere)
//! or the track is gone. A track holds at most one tag.
//!
//! A radio-only cluster (no camera can start a track) binds a tag to its track at once: the
//! track exists for the tag (`head/radio.rs`).
//!
//! Across clusters, a tag's readings go into the tracks of one person only: at the tag's
//! *home*, named by the server. A far tag's readings are weak at every node of a cluster and
//! fit what most of its tracks predict, so against "on no track" each of several heads found
//! its best track a good fit and one tag was bound in four heads at once (docs/multi-target.md).
//! Each head tells the server how loud its cluster hears each tag, where its loudest node is,
//! and which track the tag is bound to ([`TagBook::tell`]); the server names each tag's home
//! (`node_server::tag_homes` has the rule) and says whether this head's bound track is the
//! home's person. A track takes the readings of its tag only at home or when shared
//! ([`TagBook::fused_tag_of`]); bindings themselves follow the evidence as before, so a track
//! takes its tag's readings again the moment the home comes back. Without word from the
//! server for [`HOME_TTL_NS`] a head fuses by its own bindings alone.

use crate::track::Track;
use proto::models::{RssiModel, rssi_aged};
use proto::msg::{TagHeard, TagHome};
use proto::observation::RssiReading;
use proto::{ClusterTime, NodeId, TagId, TargetId};
use std::collections::{BTreeMap, BTreeSet};

/// Half-life of the binding evidence, seconds: long enough that a crossing (two people within
/// a metre or two for a second or two, where RSSI cannot tell them apart) does not move a tag,
/// short enough that a tag follows its person within a few seconds when a camera track swapped.
pub const EVIDENCE_HALF_LIFE_S: f64 = 4.0;
/// Log-likelihood ratio (natural log) a track needs, over "no track" and over every other
/// track, to be bound to a tag: e⁶ ≈ 400 to 1.
pub const BIND_LLR: f64 = 6.0;
/// The span of RSSI a tag's reading may take when it is on no track, dB (−40 to −100 dBm): the
/// flat density of "no track".
pub const RSSI_SPAN_DB: f64 = 60.0;
/// Bounds on one reading's log-likelihood ratio: one multipath fade or one lucky reading moves
/// the evidence by at most this much.
pub const READING_LLR_BOUNDS: (f64, f64) = (-3.0, 2.0);
/// Most tags a head keeps evidence of; readings of further tags are ignored and counted (a
/// flood of forged tag ids must not grow the book without bound).
pub const MAX_TAGS: usize = 256;
/// Most readings a head queues in one step; more are refused and counted (readings no longer
/// ride on detections, whose per-step limit bounded them before).
pub const MAX_READINGS_PER_STEP: usize = 4096;
/// How long a reading's (node, tag, reception time) is remembered at least, ns: a node repeats
/// its newest reading of a tag in every answer while it is fresh, and a reading is information
/// once. [`TagBook::new`] takes the longer of this and twice the freshness bound.
pub const TAKEN_MEMORY_NS: i64 = 10_000_000_000;
/// How long a tag no node heard and no track holds is kept, ns.
const FORGET_NS: i64 = 30_000_000_000;
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
struct Loud {
    dbm: f64,
    /// Reception time of the newest reading in it.
    at: ClusterTime,
}

/// A reading a member node sent: the node's slot in the head's table, and the reading.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Heard {
    pub slot: usize,
    pub reading: RssiReading,
}

/// What the head knows of one tag.
#[derive(Clone, Debug)]
struct Tag {
    /// Log-likelihood ratio per track (local id) that the tag is on it.
    evidence: BTreeMap<TargetId, f64>,
    bound: Option<TargetId>,
    /// The track was started for this tag (a radio track): it keeps the tag whatever the
    /// evidence says, until it is gone.
    own: bool,
    last_heard: ClusterTime,
    /// Each member node's smoothed readings of the tag (by slot).
    loud: BTreeMap<usize, Loud>,
    /// The server's word on the tag's home: the head, whether this head's bound track shares
    /// it (the same person), and when the word came.
    home: Option<(NodeId, bool, ClusterTime)>,
}

/// A binding made or undone, for the log.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Change {
    Bound {
        tag: TagId,
        track: TargetId,
    },
    Moved {
        tag: TagId,
        from: TargetId,
        to: TargetId,
    },
    Unbound {
        tag: TagId,
        track: TargetId,
    },
    /// The server made another head the tag's home: its track here takes none of its
    /// readings (the binding stays, by evidence's rules).
    Away {
        tag: TagId,
        track: TargetId,
        home: NodeId,
    },
}

/// The head's tags: the step's fresh readings, the evidence, the bindings.
#[derive(Clone, Debug)]
pub struct TagBook {
    fresh: Vec<Heard>,
    /// (reception time, node slot, tag) of the readings taken in the last [`TAKEN_MEMORY_NS`],
    /// ordered by time so the old ones go in one split.
    taken: BTreeSet<(ClusterTime, usize, TagId)>,
    /// How long `taken` remembers a reading, ns.
    memory_ns: i64,
    tags: BTreeMap<TagId, Tag>,
    /// When evidence was last weighed (its forgetting runs on the time that passed).
    weighed_at: Option<ClusterTime>,
    /// Readings refused: the book was full of other tags, or the step of readings.
    pub refused: u64,
    /// This head's id, and the tags whose home is another head (as of the last
    /// [`TagBook::refresh_homes`]).
    me: Option<NodeId>,
    away: BTreeSet<TagId>,
    /// The claims last told the server (tag → claiming track).
    told: BTreeMap<TagId, TargetId>,
    /// Whether the last word named any tag.
    told_any: bool,
    /// Each node slot's radio position on the floor, `[x, y]` (what the server is told a tag
    /// is near).
    positions: Vec<[f64; 2]>,
}

impl Default for TagBook {
    fn default() -> Self {
        TagBook::new(TAKEN_MEMORY_NS)
    }
}

impl TagBook {
    /// A book that remembers taken readings for `memory_ns` (at least [`TAKEN_MEMORY_NS`]; the
    /// head passes twice its freshness bound, so a repeated reading is never taken again).
    pub fn new(memory_ns: i64) -> Self {
        TagBook {
            fresh: Vec::new(),
            taken: BTreeSet::new(),
            memory_ns: memory_ns.max(TAKEN_MEMORY_NS),
            tags: BTreeMap::new(),
            weighed_at: None,
            refused: 0,
            me: None,
            away: BTreeSet::new(),
            told: BTreeMap::new(),
            told_any: false,
            positions: Vec::new(),
        }
    }

    /// The book of head `me` (whose tags' homes the server names), whose node slots' radios
    /// are at `positions` (`[x, y]` on the floor).
    pub fn for_head(mut self, me: NodeId, positions: Vec<[f64; 2]>) -> Self {
        self.me = Some(me);
        self.positions = positions;
        self
    }

    /// Queue a reading for this step unless it was queued before (a node repeats its newest
    /// reading in every answer), the book is full of other tags or the step holds
    /// [`MAX_READINGS_PER_STEP`]; returns whether it was queued.
    pub fn offer(&mut self, slot: usize, reading: RssiReading, now: ClusterTime) -> bool {
        let key = (reading.time, slot, reading.tag);
        if self.taken.contains(&key) {
            return false;
        }
        if self.fresh.len() >= MAX_READINGS_PER_STEP {
            self.refused += 1;
            return false;
        }
        if !self.tags.contains_key(&reading.tag) {
            if self.tags.len() >= MAX_TAGS {
                self.refused += 1;
                return false;
            }
            self.tags.insert(
                reading.tag,
                Tag {
                    evidence: BTreeMap::new(),
                    bound: None,
                    own: false,
                    last_heard: now,
                    loud: BTreeMap::new(),
                    home: None,
                },
            );
        }
        if let Some(t) = self.tags.get_mut(&reading.tag) {
            t.last_heard = now;
            let fresh = Loud {
                dbm: reading.dbm,
                at: reading.time,
            };
            let l = t.loud.entry(slot).or_insert(fresh);
            if reading.time - l.at > LOUD_WINDOW_NS {
                *l = fresh;
            } else if reading.time > l.at {
                l.dbm += LOUD_SMOOTHING * (reading.dbm - l.dbm);
                l.at = reading.time;
            }
        }
        self.taken.insert(key);
        self.fresh.push(Heard { slot, reading });
        true
    }

    /// Take the step's readings; forget old ones and tags long unheard and unbound.
    pub fn take_step(&mut self, now: ClusterTime) -> Vec<Heard> {
        let oldest = ClusterTime(now.0.saturating_sub(self.memory_ns - 1));
        self.taken = self.taken.split_off(&(oldest, 0, TagId(0)));
        self.tags
            .retain(|_, t| t.bound.is_some() || now - t.last_heard < FORGET_NS);
        std::mem::take(&mut self.fresh)
    }

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

    /// The readings queued for this step.
    pub fn queued(&self) -> &[Heard] {
        &self.fresh
    }

    /// The tag bound to track `local`, if any.
    pub fn tag_of(&self, local: TargetId) -> Option<TagId> {
        self.tags
            .iter()
            .find_map(|(&id, t)| (t.bound == Some(local)).then_some(id))
    }

    /// The track tag `tag` is bound to, if any.
    pub fn track_of(&self, tag: TagId) -> Option<TargetId> {
        self.tags.get(&tag).and_then(|t| t.bound)
    }

    /// The evidence that `tag` is on track `local` (0 when none was weighed).
    pub fn evidence(&self, tag: TagId, local: TargetId) -> f64 {
        self.tags
            .get(&tag)
            .and_then(|t| t.evidence.get(&local))
            .copied()
            .unwrap_or(0.0)
    }

    /// The strongest evidence any track has that it holds `tag` (−∞ when none was weighed):
    /// how far the tag is from being some track's (`crate::unseen`).
    pub fn strongest_claim(&self, tag: TagId) -> f64 {
        self.tags.get(&tag).map_or(f64::NEG_INFINITY, |t| {
            t.evidence.values().copied().fold(f64::NEG_INFINITY, f64::max)
        })
    }

    /// Bind `tag` to track `local` as evidence would (it may move or unbind it again): a radio
    /// track started for a tag no camera sees (`crate::unseen`).
    pub fn give(&mut self, tag: TagId, local: TargetId) {
        self.set(tag, local, false);
    }

    /// Give `tag` to track `local` for good (a radio track started for the tag: it keeps the
    /// tag whatever the evidence says, until it is gone), undoing any binding either had.
    pub fn bind(&mut self, tag: TagId, local: TargetId) {
        self.set(tag, local, true);
    }

    fn set(&mut self, tag: TagId, local: TargetId, own: bool) {
        for t in self.tags.values_mut() {
            if t.bound == Some(local) {
                t.bound = None;
                t.own = false;
            }
        }
        if let Some(t) = self.tags.get_mut(&tag) {
            t.bound = Some(local);
            t.own = own;
        }
    }

    /// Track `gone` was merged into `kept`: `kept` takes `gone`'s tag unless it holds one, as
    /// evidence would give it (the evidence may move or unbind it again).
    pub fn merged(&mut self, gone: TargetId, kept: TargetId) {
        if self.tag_of(kept).is_some() {
            return;
        }
        if let Some(tag) = self.tag_of(gone) {
            self.set(tag, kept, false);
        }
    }

    /// Tags heard in `heard` that no track holds, in order.
    pub fn unbound_in(&self, heard: &[Heard]) -> Vec<TagId> {
        let mut out: Vec<TagId> = heard
            .iter()
            .map(|h| h.reading.tag)
            .filter(|&g| !self.away(g) && self.tags.get(&g).is_some_and(|t| t.bound.is_none()))
            .collect();
        out.sort_unstable();
        out.dedup();
        out
    }

    /// Forget the evidence of the time since the last weighing, then add `heard`'s at `now`
    /// against every track that could be a tag's: those cameras measured, and those holding a
    /// tag. `model(track, slot)` is the RSSI model the track would fuse the node's reading
    /// with (widened as its fusion widens it); `position(slot)` the node's.
    pub fn weigh(
        &mut self,
        heard: &[Heard],
        tracks: &[Track],
        now: ClusterTime,
        model: impl Fn(&Track, usize) -> RssiModel,
        position: impl Fn(usize) -> nalgebra::Vector3<f64>,
    ) {
        let dt_s = self.weighed_at.map_or(0.0, |t| now.secs_since(t).max(0.0));
        self.weighed_at = Some(now);
        let keep = 0.5f64.powf(dt_s / EVIDENCE_HALF_LIFE_S);
        let live: Vec<TargetId> = tracks.iter().map(|t| t.local).collect();
        for tag in self.tags.values_mut() {
            tag.evidence.retain(|k, _| live.contains(k));
            for e in tag.evidence.values_mut() {
                *e *= keep;
            }
        }
        for h in heard {
            let bound = self.track_of(h.reading.tag);
            let Some(tag) = self.tags.get_mut(&h.reading.tag) else {
                continue;
            };
            for t in tracks
                .iter()
                .filter(|t| t.camera_steps > 0 || bound == Some(t.local))
            {
                let llr = reading_llr(&model(t, h.slot), &position(h.slot), t, &h.reading);
                *tag.evidence.entry(t.local).or_insert(0.0) += llr;
            }
        }
    }

    /// Bind, move and unbind tags by the evidence (see the module's rules); `bindable(track)`:
    /// whether a track may take a tag (confirmed, measured by cameras). A track given its tag
    /// for good ([`TagBook::bind`]: a radio track) keeps it whatever the evidence says.
    pub fn decide(&mut self, tracks: &[Track], bindable: impl Fn(&Track) -> bool) -> Vec<Change> {
        let mut changes = Vec::new();
        let ids: Vec<TagId> = self.tags.keys().copied().collect();
        for id in ids {
            let holders: Vec<TargetId> = self
                .tags
                .iter()
                .filter(|&(&g, _)| g != id)
                .filter_map(|(_, t)| t.bound)
                .collect();
            let tag = self.tags.get_mut(&id).expect("a key of the map");
            let track = |k: TargetId| tracks.iter().find(|t| t.local == k);
            if let Some(k) = tag.bound {
                match track(k) {
                    None => {
                        tag.bound = None;
                        tag.own = false;
                        changes.push(Change::Unbound { tag: id, track: k });
                    }
                    Some(_) if tag.own => continue,
                    Some(_) => {}
                }
            }
            let e = |k: TargetId| tag.evidence.get(&k).copied().unwrap_or(0.0);
            // The best track that may take the tag, and the best evidence of any other track.
            let best = tracks
                .iter()
                .filter(|t| bindable(t) && !holders.contains(&t.local))
                .map(|t| (t.local, e(t.local)))
                .max_by(|a, b| a.1.total_cmp(&b.1));
            let runner_up = |k: TargetId| {
                tag.evidence
                    .iter()
                    .filter(|&(&j, _)| j != k)
                    .map(|(_, &v)| v)
                    .fold(f64::NEG_INFINITY, f64::max)
            };
            match tag.bound {
                Some(k) => {
                    // Moving asks what binding asks: the new track leads every other, the
                    // current one included.
                    if let Some((j, ej)) = best
                        && j != k
                        && ej >= BIND_LLR
                        && ej - runner_up(j) >= BIND_LLR
                    {
                        tag.bound = Some(j);
                        changes.push(Change::Moved {
                            tag: id,
                            from: k,
                            to: j,
                        });
                    } else if e(k) <= -BIND_LLR {
                        tag.bound = None;
                        tag.own = false;
                        changes.push(Change::Unbound { tag: id, track: k });
                    }
                }
                None => {
                    if let Some((j, ej)) = best
                        && ej >= BIND_LLR
                        && ej - runner_up(j) >= BIND_LLR
                    {
                        tag.bound = Some(j);
                        changes.push(Change::Bound { tag: id, track: j });
                    }
                }
            }
        }
        changes
    }
}

/// One reading's log-likelihood ratio "on track `t`" against "on no track", within
/// [`READING_LLR_BOUNDS`]: the reading under `model` for a node at `node` with the track where
/// it was when the reading came, its variance widened by the track's position uncertainty.
pub fn reading_llr(model: &RssiModel, node: &nalgebra::Vector3<f64>, t: &Track, r: &RssiReading) -> f64 {
    let (h, jac) = rssi_aged(model, node, t.filter.mean(), t.time.secs_since(r.time));
    let s = model.variance() + (jac * t.filter.cov() * jac.transpose())[(0, 0)];
    if !(s.is_finite() && s > 0.0 && r.dbm.is_finite()) {
        return 0.0;
    }
    let nu = r.dbm - h;
    let log_on = -0.5 * (nu * nu / s + (std::f64::consts::TAU * s).ln());
    let log_off = -RSSI_SPAN_DB.ln();
    (log_on - log_off).clamp(READING_LLR_BOUNDS.0, READING_LLR_BOUNDS.1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix6, Vector3};
    use proto::models::State;

    const MODEL: RssiModel = RssiModel::LogDistance {
        a: -22.0,
        b: -45.0,
        variance: 16.0,
    };

    fn track(local: u32, x: f64, y: f64) -> Track {
        let mut t = Track::new(
            TargetId(local),
            None,
            State::new(x, y, 1.0, 0.0, 0.0, 0.0),
            Matrix6::identity() * 0.01,
            ClusterTime::ZERO,
            4,
            MODEL,
            10,
            0.1,
        )
        .unwrap();
        t.camera_steps = 10;
        t.confirm();
        t
    }

    /// Four nodes at the room's corners.
    fn node(slot: usize) -> Vector3<f64> {
        [
            Vector3::new(0.0, 0.0, 2.5),
            Vector3::new(10.0, 0.0, 2.5),
            Vector3::new(0.0, 10.0, 2.5),
            Vector3::new(10.0, 10.0, 2.5),
        ][slot]
    }

    /// One reading of `tag` at every node, as a tag at `at` would give them without noise,
    /// received at `time`.
    fn readings(book: &mut TagBook, tag: TagId, at: Vector3<f64>, time: ClusterTime) -> Vec<Heard> {
        for slot in 0..4 {
            let dbm = MODEL.predict((at - node(slot)).norm());
            book.offer(slot, RssiReading { tag, dbm, time }, time);
        }
        book.take_step(time)
    }

    /// Run `steps` steps of 0.2 s in which `tag` is heard at `at`; returns every change.
    fn run(book: &mut TagBook, tracks: &[Track], tag: TagId, at: Vector3<f64>, steps: u32) -> Vec<Change> {
        let mut changes = Vec::new();
        for s in 0..steps {
            let time = ClusterTime::from_millis(200 * i64::from(s));
            let heard = readings(book, tag, at, time);
            book.weigh(&heard, tracks, time, |_, _| MODEL, node);
            changes.extend(book.decide(tracks, |t| t.past_tentative()));
        }
        changes
    }

    #[test]
    fn a_tag_binds_to_the_track_it_moves_with_and_not_to_the_other() {
        let tracks = [track(1, 2.0, 3.0), track(2, 7.0, 6.0)];
        let mut book = TagBook::default();
        let tag = TagId(0xaa);
        let changes = run(&mut book, &tracks, tag, Vector3::new(7.0, 6.0, 1.0), 10);
        assert_eq!(
            changes,
            vec![Change::Bound {
                tag,
                track: TargetId(2)
            }]
        );
        assert_eq!(book.tag_of(TargetId(2)), Some(tag));
        assert_eq!(book.tag_of(TargetId(1)), None);
        assert!(book.evidence(tag, TargetId(2)) - book.evidence(tag, TargetId(1)) >= BIND_LLR);
    }

    /// Steps of 0.2 s from `from_s` to `to_s` seconds in which `tag` is heard at `at`, the
    /// server's word on homes taken as the head takes it; returns every change.
    fn run_between(
        book: &mut TagBook,
        tracks: &[Track],
        tag: TagId,
        at: Vector3<f64>,
        from_s: f64,
        to_s: f64,
    ) -> Vec<Change> {
        let mut changes = Vec::new();
        let mut t = from_s;
        while t < to_s {
            let time = ClusterTime::from_millis((t * 1000.0).round() as i64);
            let heard = readings(book, tag, at, time);
            book.weigh(&heard, tracks, time, |_, _| MODEL, node);
            changes.extend(book.refresh_homes(time));
            changes.extend(book.decide(tracks, |t| t.past_tentative()));
            t += 0.2;
        }
        changes
    }

    #[test]
    fn a_tag_whose_home_is_another_head_feeds_no_track_here_until_it_comes_back() {
        let tracks = [track(1, 7.0, 6.0)];
        let tag = TagId(0xaa);
        let at = Vector3::new(7.0, 6.0, 1.0);
        let mut book =
            TagBook::default().for_head(NodeId(3), (0..4).map(|s| [node(s).x, node(s).y]).collect());
        run_between(&mut book, &tracks, tag, at, 0.0, 2.0);
        assert_eq!(book.fused_tag_of(TargetId(1)), Some(tag));
        // The server names head 4 the tag's home: the track takes none of its readings while
        // the word holds; the binding stays (by the evidence), so the track still claims it.
        let home = [TagHome {
            tag,
            head: NodeId(4),
            shared: false,
        }];
        book.set_homes(&home, ClusterTime::from_millis(2000));
        let changes = run_between(&mut book, &tracks, tag, at, 2.0, 4.0);
        assert_eq!(
            changes,
            vec![Change::Away {
                tag,
                track: TargetId(1),
                home: NodeId(4)
            }]
        );
        assert!(book.away(tag));
        assert_eq!(book.fused_tag_of(TargetId(1)), None);
        assert_eq!(book.track_of(tag), Some(TargetId(1)));
        assert_eq!(
            book.loudest(ClusterTime::from_millis(4000))[0].track,
            Some(TargetId(1))
        );
        // Its own word does not hold it back; nor does a word older than HOME_TTL_NS.
        book.set_homes(
            &[TagHome {
                tag,
                head: NodeId(3),
                shared: false,
            }],
            ClusterTime::from_millis(4000),
        );
        run_between(&mut book, &tracks, tag, at, 4.0, 4.4);
        assert_eq!(book.fused_tag_of(TargetId(1)), Some(tag));
        book.set_homes(&home, ClusterTime::from_millis(4400));
        run_between(&mut book, &tracks, tag, at, 4.4, 5.0);
        assert_eq!(book.fused_tag_of(TargetId(1)), None);
        let after = 4.4 + HOME_TTL_NS as f64 / 1e9;
        run_between(&mut book, &tracks, tag, at, 5.0, after + 0.4);
        assert!(!book.away(tag), "the server's word lapsed");
        assert_eq!(book.fused_tag_of(TargetId(1)), Some(tag));
    }

    #[test]
    fn a_track_the_server_says_is_the_homes_person_takes_an_away_tag() {
        let tracks = [track(1, 7.0, 6.0)];
        let tag = TagId(0xaa);
        let mut book =
            TagBook::default().for_head(NodeId(3), (0..4).map(|s| [node(s).x, node(s).y]).collect());
        run_between(&mut book, &tracks, tag, Vector3::new(7.0, 6.0, 1.0), 0.0, 2.0);
        let home = |shared| TagHome {
            tag,
            head: NodeId(4),
            shared,
        };
        book.set_homes(&[home(true)], ClusterTime::from_millis(2000));
        book.refresh_homes(ClusterTime::from_millis(2000));
        assert!(book.away(tag));
        assert_eq!(book.fused_tag_of(TargetId(1)), Some(tag));
        book.set_homes(&[home(false)], ClusterTime::from_millis(2200));
        book.refresh_homes(ClusterTime::from_millis(2200));
        assert_eq!(book.fused_tag_of(TargetId(1)), None);
    }

    #[test]
    fn the_server_is_told_each_tags_claim_and_an_empty_list_once() {
        let tracks = [track(1, 7.0, 6.0)];
        let tag = TagId(0xaa);
        let mut book =
            TagBook::default().for_head(NodeId(3), (0..4).map(|s| [node(s).x, node(s).y]).collect());
        assert_eq!(book.tell(ClusterTime::ZERO), None, "nothing heard, nothing told");
        run_between(&mut book, &tracks, tag, Vector3::new(7.0, 6.0, 1.0), 0.0, 2.0);
        assert!(book.claims_changed(ClusterTime::from_millis(2000)));
        let told = book.tell(ClusterTime::from_millis(2000)).unwrap();
        assert_eq!(told[0].track, Some(TargetId(1)));
        assert_eq!(told[0].near, [10.0, 10.0], "the node nearest (7, 6)");
        assert!(!book.claims_changed(ClusterTime::from_millis(2000)));
        // Silence past the window: the list empties, told once.
        let later = ClusterTime::from_millis(2000) + LOUD_WINDOW_NS + 1;
        assert_eq!(book.tell(later), Some(Vec::new()));
        assert_eq!(book.tell(later), None);
    }

    #[test]
    fn an_away_tag_gets_no_radio_track() {
        let mut book =
            TagBook::default().for_head(NodeId(3), (0..4).map(|s| [node(s).x, node(s).y]).collect());
        let tag = TagId(0xbb);
        let heard = readings(&mut book, tag, Vector3::new(5.0, 5.0, 1.0), ClusterTime::ZERO);
        assert_eq!(book.unbound_in(&heard), vec![tag]);
        book.set_homes(
            &[TagHome {
                tag,
                head: NodeId(4),
                shared: false,
            }],
            ClusterTime::ZERO,
        );
        book.refresh_homes(ClusterTime::ZERO);
        assert!(book.unbound_in(&heard).is_empty());
    }

    #[test]
    fn the_cluster_hears_a_tag_as_loud_as_its_loudest_node_lately() {
        let mut book =
            TagBook::default().for_head(NodeId(3), (0..4).map(|s| [node(s).x, node(s).y]).collect());
        let tag = TagId(5);
        let at = Vector3::new(1.0, 1.0, 1.0);
        for s in 0..5 {
            readings(&mut book, tag, at, ClusterTime::from_millis(200 * s));
        }
        let heard = book.loudest(ClusterTime::from_millis(800));
        let nearest = MODEL.predict((at - node(0)).norm()) as f32;
        assert_eq!(heard.len(), 1);
        assert_eq!(heard[0].tag, tag);
        assert!(
            (heard[0].dbm - nearest).abs() < 1e-3,
            "{} vs {nearest}",
            heard[0].dbm
        );
        // One loud reading moves the smoothed loudness by a quarter of the difference.
        book.offer(
            0,
            RssiReading {
                tag,
                dbm: f64::from(nearest) + 20.0,
                time: ClusterTime::from_millis(1000),
            },
            ClusterTime::from_millis(1000),
        );
        let heard = book.loudest(ClusterTime::from_millis(1000));
        assert!((heard[0].dbm - (nearest + 5.0)).abs() < 1e-3, "{}", heard[0].dbm);
        // Nothing heard in the window: the cluster does not hear it.
        assert!(
            book.loudest(ClusterTime::from_millis(1000) + LOUD_WINDOW_NS + 1)
                .is_empty()
        );
    }

    #[test]
    fn a_tag_between_two_tracks_binds_to_neither() {
        // Two people 0.3 m apart: RSSI cannot tell them apart.
        let tracks = [track(1, 5.0, 5.0), track(2, 5.3, 5.0)];
        let mut book = TagBook::default();
        let changes = run(&mut book, &tracks, TagId(1), Vector3::new(5.15, 5.0, 1.0), 50);
        assert!(changes.is_empty(), "{changes:?}");
    }

    #[test]
    fn a_tag_on_no_track_stays_unbound_and_a_bound_tag_that_leaves_is_unbound() {
        let tracks = [track(1, 1.0, 1.0)];
        let mut book = TagBook::default();
        let tag = TagId(3);
        assert!(run(&mut book, &tracks, tag, Vector3::new(9.0, 9.0, 1.0), 30).is_empty());
        let mut book = TagBook::default();
        run(&mut book, &tracks, tag, Vector3::new(1.0, 1.0, 1.0), 10);
        assert_eq!(book.track_of(tag), Some(TargetId(1)));
        let changes = run(&mut book, &tracks, tag, Vector3::new(9.0, 9.0, 1.0), 30);
        assert_eq!(
            changes,
            vec![Change::Unbound {
                tag,
                track: TargetId(1)
            }]
        );
    }

    #[test]
    fn a_tag_moves_to_the_track_that_explains_it_and_a_track_holds_one_tag() {
        let mut tracks = vec![track(1, 2.0, 2.0), track(2, 8.0, 8.0)];
        let mut book = TagBook::default();
        let (a, b) = (TagId(1), TagId(2));
        run(&mut book, &tracks, a, Vector3::new(2.0, 2.0, 1.0), 10);
        assert_eq!(book.track_of(a), Some(TargetId(1)));
        // The camera tracks swap places (an identity switch): the tag follows its person.
        tracks[0] = track(1, 8.0, 2.0);
        tracks[1] = track(2, 2.0, 2.0);
        let changes = run(&mut book, &tracks, a, Vector3::new(2.0, 2.0, 1.0), 40);
        assert!(changes.contains(&Change::Moved {
            tag: a,
            from: TargetId(1),
            to: TargetId(2)
        }));
        // A second tag where track 2 is cannot take it while `a` holds it.
        run(&mut book, &tracks, b, Vector3::new(2.0, 2.0, 1.0), 20);
        assert_eq!(book.track_of(a), Some(TargetId(2)));
        assert_ne!(book.track_of(b), Some(TargetId(2)));
    }

    #[test]
    fn a_reading_counts_once_and_a_flood_of_tags_is_bounded() {
        let mut book = TagBook::default();
        let r = RssiReading {
            tag: TagId(1),
            dbm: -60.0,
            time: ClusterTime::ZERO,
        };
        assert!(book.offer(0, r, ClusterTime::ZERO));
        assert!(!book.offer(0, r, ClusterTime::ZERO), "the same reading again");
        assert!(book.offer(1, r, ClusterTime::ZERO), "another node's");
        for g in 0..2 * MAX_TAGS as u64 {
            book.offer(
                0,
                RssiReading {
                    tag: TagId(100 + g),
                    ..r
                },
                ClusterTime::ZERO,
            );
        }
        assert_eq!(book.tags.len(), MAX_TAGS);
        assert_eq!(book.refused, MAX_TAGS as u64 + 1);
    }

    #[test]
    fn a_tag_taken_over_in_a_merge_answers_to_the_evidence_and_a_step_of_readings_is_bounded() {
        let tracks = [track(1, 1.0, 1.0)];
        let mut book = TagBook::default();
        let tag = TagId(4);
        readings(&mut book, tag, Vector3::new(1.0, 1.0, 1.0), ClusterTime::ZERO);
        book.bind(tag, TargetId(2));
        book.merged(TargetId(2), TargetId(1));
        let changes = run(&mut book, &tracks, tag, Vector3::new(9.0, 9.0, 1.0), 30);
        assert!(
            changes.contains(&Change::Unbound {
                tag,
                track: TargetId(1)
            }),
            "a merge's binding is not for good: {changes:?}"
        );
        let mut book = TagBook::default();
        let n = MAX_READINGS_PER_STEP as i64 + 10;
        for k in 0..n {
            let r = RssiReading {
                tag,
                dbm: -60.0,
                time: ClusterTime(k),
            };
            book.offer(0, r, ClusterTime(n));
        }
        assert_eq!(book.queued().len(), MAX_READINGS_PER_STEP);
        assert_eq!(book.refused, 10);
    }

    #[test]
    fn a_track_merged_away_hands_its_tag_to_the_kept_one() {
        let mut book = TagBook::default();
        let tag = TagId(9);
        readings(&mut book, tag, Vector3::new(2.0, 3.0, 1.0), ClusterTime::ZERO);
        book.bind(tag, TargetId(2));
        book.merged(TargetId(2), TargetId(1));
        assert_eq!(book.track_of(tag), Some(TargetId(1)));
    }
}
