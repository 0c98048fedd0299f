//! Global tracks: one global id per physical target across heads, which head owns each, and
//! when a track moves.
//!
//! - A head's local track `(head, local)` that carries a known global id (it continues a
//!   handed-over track) is bound to it at once (`Claimed`).
//! - Otherwise, if it lies within the merge gate of a live global track that no local track of
//!   the same head feeds, it is *pending*: after `hysteresis` consecutive agreeing reports it is
//!   merged into that global (`Merged`, paper 004 §3.3.3: proximity), after `hysteresis`
//!   consecutive disagreeing ones it joins another global it now lies on (`Merged`), or else
//!   gets its own global id. Pending tracks have no global id, so an id never appears only to
//!   vanish again.
//! - A track far from everything gets a new global id at once (`NewGlobal`), owned by its head.
//! - A track within the merge gate of a global its own head already feeds is that head's
//!   duplicate of the target (after a failover the survivor may briefly hold two, until its
//!   duplicate merge drops one): it waits without an id, looked at afresh each report, and
//!   founds one once it lies outside that gate, or once the head has kept it for the
//!   duplicate wait — then it is a second person beside the first (side by side, meeting),
//!   whom the head tells apart. Given an id at once, the duplicate was a second global id for
//!   0.2–2.4 s in about half the end-to-end cluster runs; never given one, the second of two
//!   people walking side by side had none at all.
//! - A merged track that disagrees with its global's owner for `hysteresis` consecutive reports
//!   joins another global it now lies on (`Merged`), or else is split off with a new global id
//!   (`Split`).
//! - Two global tracks whose owners keep reporting them within the gate of each other for
//!   `hysteresis` reports are one target: the younger is absorbed into the older (`Absorbed`)
//!   and its local tracks rebound to it (`Merged`). Never two that one head feeds each with a
//!   live local track of its own: that head sees two targets (people side by side, or
//!   meeting), and would have merged its tracks if its cameras saw one.
//! - When the owner's estimate leaves the owner's region by more than the handover margin and
//!   lies in a live head's region, the track is handed over to that head (`Handover`, reason
//!   `Region`); the margin is the hysteresis band that stops a target on a border from
//!   bouncing between heads. Only a track that was inside its owner's region can leave it (see
//!   [`GlobalTrack::entered`]). The new head is sent its own live track's posterior when one of
//!   its tracks is bound to the global ([`Tracks::handover_posterior`]), so that it names that
//!   track instead of starting a second.
//! - A member head that reports the track inside its own region while it is outside the
//!   owner's takes ownership without a handover (`OwnerChanged`): it already tracks it.
//! - Authority follows regions: a head's track lying outside its region by more than the
//!   handover margin, where a live head's region covers it (or, beyond every head's region,
//!   where a live head's region lies nearer by more than the margin), is a second opinion
//!   from cameras at the edge of their range. It never founds a global (no `NewGlobal`, no
//!   `Split`): it is merged when it agrees with a global, otherwise it waits without an id (a
//!   disagreeing merged one goes back to pending) while the covering (or nearest) head, whose
//!   cameras see the place well, founds the target. Without this a far head's poor estimate
//!   of a target the owner tracks well turns into a second global id.
//! - On a handover the old head stops tracking the target, so its local tracks bound to the
//!   global are released: a track it starts again on the target merges back into the global
//!   instead of founding a new one. A released track does not speak for the global: a late
//!   report of it (its estimate older than the handover, or it carries the global's id while
//!   another head owns it) is ignored, and any other report of it (a track the head kept, or
//!   the global came back to this head) is looked at afresh, as a track first seen.
//! - When the owner is down, on the next tick the track goes to a live head that follows it (a
//!   local track bound or pending on it that reported recently), which continues from its own
//!   estimate when that is newer; else to the live head covering its last position, else the
//!   nearest one (`Handover`, reason `Failover`).
//! - While the owner is gone (down, or silent for the owner staleness) the global's posterior is
//!   the owner's last word and ages: disagreeing with it is no evidence, so it is not counted,
//!   and a head's track that follows the global (it carries the id, or lies within the gate)
//!   is bound to it and its head takes the global over (`OwnerChanged`), pending or not. A
//!   pending track of the head the global was handed to is bound on its next report. So the
//!   surviving head keeps the id whether its reports reach the server before or after the
//!   failover tick.
//! - A global no head reported for the track timeout is dropped (`Lost`); a silent local track
//!   is forgotten.
//!
//! The gate compares positions in metres after extrapolating the global's last posterior to the
//! report's time with its velocity. Appearance narrows it (paper 004's next step for its
//! handover): when both a report and a global carry a colour histogram, a report whose colours
//! are less alike than `min_appearance_similarity` never agrees with, merges into or counts as
//! a duplicate of that global, and two globals of other colours are never absorbed into one
//! (two people meeting stay two); among the globals a report may join, the least distance in
//! gates plus unlikeness (1 − similarity) wins. Without histograms (segmenting cameras),
//! position alone decides, as before.

use crate::membership::Membership;
use proto::msg::{Mat6, TrackReport, Vec6};
use proto::region::distance_to_region;
use proto::{ClusterTime, NodeId, TargetId};
use std::collections::BTreeMap;

mod moves;
mod report;

/// Tuning of merging and handover.
#[derive(Clone, Debug, PartialEq)]
pub struct TrackParams {
    /// Two tracks closer than this (metres) are the same target.
    pub merge_gate_m: f64,
    /// Consecutive agreeing (disagreeing) reports before a merge (split).
    pub hysteresis: u32,
    /// How far (metres) outside its owner's region a track must be before it is handed over.
    pub handover_margin_m: f64,
    /// A global not reported for this long is dropped, ns.
    pub track_timeout_ns: i64,
    /// An owner silent about a track for this long loses it to a head still reporting it, ns.
    pub owner_stale_ns: i64,
    /// Two tracks whose colour histograms are less alike than this (blended Bhattacharyya
    /// coefficient, `proto::appearance`) are different people however close they are.
    pub min_appearance_similarity: f32,
    /// How long a head's track lying on a global the same head already feeds waits without an
    /// id, ns: a duplicate the head merges away within it; a track the head still keeps beside
    /// the other after it is a second person (side by side, or meeting) and founds its own.
    pub duplicate_wait_ns: i64,
}

/// One global track.
#[derive(Clone, Debug, PartialEq)]
pub struct GlobalTrack {
    pub owner: NodeId,
    /// The last posterior (from the owner), with its time.
    pub time: ClusterTime,
    pub mean: Vec6,
    pub cov: Mat6,
    /// Server time of the last report from any head bound to it.
    pub last_report: ClusterTime,
    /// Server time of the owner's last report (or of the handover to it).
    pub owner_report: ClusterTime,
    /// Whether the owner's estimate has been inside the owner's region since it took the
    /// track. Only a track that was inside can *leave*: a head that starts a track of a target
    /// in another cluster's area keeps it (that cluster's own track will be merged with it)
    /// instead of pushing a posterior from distant cameras onto the other head.
    pub entered: bool,
    /// The colour histogram its owner last reported (empty until one came).
    pub appearance: Vec<f32>,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Binding {
    Bound(TargetId),
    Pending(TargetId),
}

#[derive(Clone, Debug, PartialEq)]
struct LocalTrack {
    binding: Binding,
    /// Server time of its last report, and that report's posterior (a failover to its head
    /// starts from it when it is newer than the dead owner's).
    last: ClusterTime,
    posterior: (ClusterTime, Vec6, Mat6),
    agree: u32,
    disagree: u32,
    /// When (server time) its global was handed away from this head, which drops the track:
    /// it no longer counts as the head feeding the global.
    released: Option<ClusterTime>,
}

/// The global track table.
#[derive(Clone, Debug)]
pub struct Tracks {
    params: TrackParams,
    next_global: u32,
    globals: BTreeMap<TargetId, GlobalTrack>,
    locals: BTreeMap<(NodeId, TargetId), LocalTrack>,
    /// Consecutive owner reports of the younger global found within the gate of the older one.
    close: BTreeMap<(TargetId, TargetId), u32>,
    /// Since when each local track has been waiting on a global its own head feeds, and the
    /// server time of its last report.
    waiting: BTreeMap<(NodeId, TargetId), (ClusterTime, ClusterTime)>,
}

impl GlobalTrack {
    /// Position extrapolated to `t` with the posterior's velocity (at most 2 s ahead).
    fn position_at(&self, t: ClusterTime) -> [f64; 3] {
        let dt = t.secs_since(self.time).clamp(0.0, 2.0);
        [
            self.mean[0] + self.mean[3] * dt,
            self.mean[1] + self.mean[4] * dt,
            self.mean[2] + self.mean[5] * dt,
        ]
    }
}

fn dist(a: [f64; 3], b: &Vec6) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// How alike two appearances are; 1 (no evidence against) when either is unknown.
fn alike(a: &[f32], b: &[f32]) -> f32 {
    proto::appearance::similarity(a, b).unwrap_or(1.0)
}

impl Tracks {
    pub fn new(params: TrackParams) -> Self {
        Tracks {
            params,
            next_global: 1,
            globals: BTreeMap::new(),
            locals: BTreeMap::new(),
            close: BTreeMap::new(),
            waiting: BTreeMap::new(),
        }
    }

    pub fn params(&self) -> &TrackParams {
        &self.params
    }

    pub fn global(&self, g: TargetId) -> Option<&GlobalTrack> {
        self.globals.get(&g)
    }

    pub fn globals(&self) -> impl Iterator<Item = (TargetId, &GlobalTrack)> {
        self.globals.iter().map(|(k, v)| (*k, v))
    }

    /// The posterior of `to`'s own live track bound to `g` (the most recent), which a handover
    /// of `g` gives `to` when it has one. A head takes a handover for one of its unnamed tracks
    /// only when the posterior lies on it; given the old owner's estimate instead, a head that
    /// already tracked the target started a second track beside its own, and its two tracks
    /// then took turns moving `g` (the crowd, seed 1: 172 of 2254 steps of a global).
    pub fn handover_posterior(
        &self,
        now: ClusterTime,
        g: TargetId,
        to: NodeId,
    ) -> Option<(ClusterTime, Vec6, Mat6)> {
        self.live_bound(now, to, g)
            .max_by(|a, b| a.1.last.cmp(&b.1.last).then(b.0.cmp(&a.0)))
            .map(|(_, l)| l.posterior)
    }

    /// `head`'s local tracks bound to `g` that are live: not released by a handover, and
    /// reported within the owner staleness.
    fn live_bound(
        &self,
        now: ClusterTime,
        head: NodeId,
        g: TargetId,
    ) -> impl Iterator<Item = (TargetId, &LocalTrack)> {
        self.locals
            .range((head, TargetId(0))..=(head, TargetId(u32::MAX)))
            .filter(move |(_, l)| {
                l.binding == Binding::Bound(g)
                    && l.released.is_none()
                    && now - l.last <= self.params.owner_stale_ns
            })
            .map(|((_, local), l)| (*local, l))
    }

    /// The global id a head's local track is bound to (`None` while pending or unknown).
    pub fn global_of(&self, head: NodeId, local: TargetId) -> Option<TargetId> {
        match self.locals.get(&(head, local))?.binding {
            Binding::Bound(g) => Some(g),
            Binding::Pending(_) => None,
        }
    }

    /// Whether `r` lies within the merge gate of `g` and does not look like someone else.
    fn agrees(&self, g: TargetId, r: &TrackReport) -> bool {
        self.globals.get(&g).is_some_and(|gt| {
            dist(gt.position_at(r.time), &r.mean) <= self.params.merge_gate_m
                && self.looks_like(gt, &r.appearance)
        })
    }

    /// Whether `appearance` is not clearly another person's than `gt`'s.
    fn looks_like(&self, gt: &GlobalTrack, appearance: &[f32]) -> bool {
        alike(&gt.appearance, appearance) >= self.params.min_appearance_similarity
    }

    fn new_global(&mut self, now: ClusterTime, head: NodeId, r: &TrackReport) -> TargetId {
        let g = TargetId(self.next_global);
        self.next_global += 1;
        self.globals.insert(
            g,
            GlobalTrack {
                owner: head,
                time: r.time,
                mean: r.mean,
                cov: r.cov,
                last_report: now,
                owner_report: now,
                entered: false,
                appearance: r.appearance.clone(),
            },
        );
        g
    }

    /// The best live global within the gate that `head` does not feed yet and that `r` does
    /// not look unlike: the least distance (in gates) plus unlikeness (1 − similarity), so of
    /// two people side by side the one with the same colours wins. A global whose only track
    /// from `head` fell silent (for the owner staleness) is a candidate again: the head dropped
    /// and restarted its track of that target.
    fn candidate(&self, now: ClusterTime, head: NodeId, r: &TrackReport) -> Option<TargetId> {
        let fed = self.fed_by(now, head);
        let gate = self.params.merge_gate_m;
        self.globals
            .iter()
            .filter(|(g, gt)| !fed.contains(g) && now - gt.last_report <= self.params.track_timeout_ns)
            .map(|(g, gt)| {
                (
                    *g,
                    dist(gt.position_at(r.time), &r.mean),
                    alike(&gt.appearance, &r.appearance),
                )
            })
            .filter(|(_, d, s)| *d <= gate && *s >= self.params.min_appearance_similarity)
            .map(|(g, d, s)| (g, d / gate + f64::from(1.0 - s)))
            .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)))
            .map(|(g, _)| g)
    }

    /// The globals `head` feeds: those its live (not silent, not released) local tracks are
    /// bound or pending to.
    fn fed_by(&self, now: ClusterTime, head: NodeId) -> Vec<TargetId> {
        self.locals
            .iter()
            .filter(|((h, _), l)| {
                *h == head && now - l.last <= self.params.owner_stale_ns && l.released.is_none()
            })
            .map(|(_, l)| match l.binding {
                Binding::Bound(g) | Binding::Pending(g) => g,
            })
            .collect()
    }

    /// Whether `head`'s track `r` lies on a global `head` already feeds and has waited less
    /// than the duplicate wait there (the wait starts with its first such report).
    fn waits_as_duplicate(&mut self, now: ClusterTime, head: NodeId, r: &TrackReport) -> bool {
        if !self.on_own_global(now, head, r) {
            self.waiting.remove(&(head, r.target));
            return false;
        }
        now - self.waited_since(now, (head, r.target)) < self.params.duplicate_wait_ns
    }

    /// When `key` began waiting as its head's second track on one global (now, if it did not
    /// wait before); notes the report.
    fn waited_since(&mut self, now: ClusterTime, key: (NodeId, TargetId)) -> ClusterTime {
        let w = self.waiting.entry(key).or_insert((now, now));
        w.1 = now;
        w.0
    }

    /// Whether `r` lies within the merge gate of a live global that `head` already feeds.
    fn on_own_global(&self, now: ClusterTime, head: NodeId, r: &TrackReport) -> bool {
        self.fed_by(now, head)
            .iter()
            .filter_map(|g| self.globals.get(g))
            .any(|gt| {
                now - gt.last_report <= self.params.track_timeout_ns
                    && dist(gt.position_at(r.time), &r.mean) <= self.params.merge_gate_m
                    && self.looks_like(gt, &r.appearance)
            })
    }

    /// Whether `head`'s report lies outside its region by more than the handover margin, in a
    /// region a live head covers, or beyond every head's region where a live head's region is
    /// nearer by more than that margin: then the report may not found a global. A place no
    /// region covers is the nearest region's edge of the watched area, and a far head's track
    /// there is most often its cameras' poor depth sliding a track of a person that the near
    /// head sees (four-people, seed 5: a second global at x = 12–12.8 m, outside the 12 m
    /// room, for 4 s). Inside a dead head's region that no live head covers, any head may found
    /// one, as before: the survivors share that floor until it comes back.
    fn foreign(&self, head: NodeId, r: &TrackReport, members: &Membership) -> bool {
        let (x, y) = (r.mean[0], r.mean[1]);
        let margin = self.params.handover_margin_m;
        let Some(own) = members
            .region(head)
            .map(|region| distance_to_region(region, x, y))
        else {
            return false;
        };
        if own <= margin {
            return false;
        }
        if members.in_any_region(x, y) {
            return members.live_head_covering(x, y, 0.0, head).is_some();
        }
        members
            .nearest_live_head(x, y, head)
            .and_then(|h| members.region(h))
            .is_some_and(|region| distance_to_region(region, x, y) + margin < own)
    }

    /// Whether `g`'s owner is down or has not reported it for the owner staleness: `g`'s
    /// posterior is then that owner's last word, ageing.
    fn owner_gone(&self, now: ClusterTime, g: TargetId, members: &Membership) -> bool {
        self.globals
            .get(&g)
            .is_some_and(|gt| !members.is_up(gt.owner) || now - gt.owner_report > self.params.owner_stale_ns)
    }

    /// Whether `head` has another live local track bound to `g`.
    fn feeds_other(&self, head: NodeId, local: TargetId, g: TargetId, now: ClusterTime) -> bool {
        self.live_bound(now, head, g).any(|(l, _)| l != local)
    }
}

impl LocalTrack {
    fn new(binding: Binding, now: ClusterTime, r: &TrackReport) -> Self {
        LocalTrack {
            binding,
            last: now,
            posterior: (r.time, r.mean, r.cov),
            agree: 0,
            disagree: 0,
            released: None,
        }
    }
}

impl crate::tag_homes::Tracked for Tracks {
    fn global_of(&self, head: NodeId, local: TargetId) -> Option<(TargetId, NodeId)> {
        let g = Tracks::global_of(self, head, local)?;
        Some((g, self.global(g)?.owner))
    }

    fn position_of(&self, head: NodeId, local: TargetId) -> Option<[f64; 2]> {
        let mean = self.locals.get(&(head, local))?.posterior.1;
        Some([mean[0], mean[1]])
    }
}
