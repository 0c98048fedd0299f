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
use proto::observation::RssiReading;
use proto::{ClusterTime, NodeId, TagId, TargetId};
use std::collections::{BTreeMap, BTreeSet};

mod homes;
pub use homes::{HOME_TTL_NS, LOUD_SMOOTHING, LOUD_WINDOW_NS};

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
    loud: BTreeMap<usize, homes::Loud>,
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
            homes::note_loudness(&mut t.loud, slot, &reading);
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
mod tests;
