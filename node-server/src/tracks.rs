//! Global tracks: one global id per physical target across heads, which head owns each, and
//! when a track moves.
//!
//! - A head's local track `(head, local)` that carries a known global id (it continues a
//!   handed-over track) is bound to it at once (`Claimed`).
//! - Otherwise, if it lies within the merge gate of a live global track that no local track of
//!   the same head feeds, it is *pending*: after `hysteresis` consecutive agreeing reports it is
//!   merged into that global (`Merged`, paper 004 §3.3.3: proximity), after `hysteresis`
//!   consecutive disagreeing ones it gets its own global id. Pending tracks have no global id,
//!   so an id never appears only to vanish again.
//! - A track far from everything gets a new global id at once (`NewGlobal`), owned by its head.
//! - A merged track that disagrees with its global's owner for `hysteresis` consecutive reports
//!   joins another global it now lies on (`Merged`), or else is split off with a new global id
//!   (`Split`).
//! - Two global tracks whose owners keep reporting them within the gate of each other for
//!   `hysteresis` reports are one target: the younger is absorbed into the older (`Absorbed`)
//!   and its local tracks rebound to it (`Merged`).
//! - When the owner's estimate leaves the owner's region by more than the handover margin and
//!   lies in a live head's region, the track is handed over to that head (`Handover`, reason
//!   `Region`); the margin is the hysteresis band that stops a target on a border from
//!   bouncing between heads. Only a track that was inside its owner's region can leave it (see
//!   [`GlobalTrack::entered`]).
//! - A member head that reports the track inside its own region while it is outside the
//!   owner's takes ownership without a handover (`OwnerChanged`): it already tracks it.
//! - Authority follows regions: a head's track lying outside its region by more than the
//!   handover margin, where a live head's region covers it, is a second opinion from cameras
//!   at the edge of their range. It never founds a global (no `NewGlobal`, no `Split`): it is
//!   merged when it agrees with a global, otherwise it waits without an id (a disagreeing
//!   merged one goes back to pending) while the covering head, whose cameras see the place
//!   well, founds the target. Without this a far head's poor estimate of a target the owner
//!   tracks well turns into a second global id.
//! - On a handover the old head stops tracking the target, so its local tracks bound to the
//!   global are released: a track it starts again on the target merges back into the global
//!   instead of founding a new one (its old binding stays, so a late report of it still counts).
//! - When the owner is down, on the next tick the track goes to the live head covering its last
//!   position, else the nearest one (`Handover`, reason `Failover`).
//! - A global no head reported for the track timeout is dropped (`Lost`); a silent local track
//!   is forgotten.
//!
//! The gate compares positions in metres after extrapolating the global's last posterior to the
//! report's time with its velocity.

use crate::decision::{Decision, HandoverReason};
use crate::membership::{Membership, distance_to_region};
use proto::msg::{Mat6, TrackReport, Vec6};
use proto::{ClusterTime, NodeId, TargetId};
use std::collections::BTreeMap;

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
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Binding {
    Bound(TargetId),
    Pending(TargetId),
}

#[derive(Clone, Debug, PartialEq)]
struct LocalTrack {
    binding: Binding,
    last: ClusterTime,
    agree: u32,
    disagree: u32,
    /// Its global was handed away from this head, which drops the track: it no longer counts
    /// as the head feeding the global.
    released: bool,
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

impl Tracks {
    pub fn new(params: TrackParams) -> Self {
        Tracks {
            params,
            next_global: 1,
            globals: BTreeMap::new(),
            locals: BTreeMap::new(),
            close: BTreeMap::new(),
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

    /// The global id a head's local track is bound to (`None` while pending or unknown).
    pub fn global_of(&self, head: NodeId, local: TargetId) -> Option<TargetId> {
        match self.locals.get(&(head, local))?.binding {
            Binding::Bound(g) => Some(g),
            Binding::Pending(_) => None,
        }
    }

    fn agrees(&self, g: TargetId, r: &TrackReport) -> bool {
        self.globals
            .get(&g)
            .is_some_and(|gt| dist(gt.position_at(r.time), &r.mean) <= self.params.merge_gate_m)
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
            },
        );
        g
    }

    /// The nearest live global within the gate that `head` does not feed yet. A global whose
    /// only track from `head` fell silent (for the owner staleness) is a candidate again: the
    /// head dropped and restarted its track of that target.
    fn candidate(&self, now: ClusterTime, head: NodeId, r: &TrackReport) -> Option<TargetId> {
        let fed: Vec<TargetId> = self
            .locals
            .iter()
            .filter(|((h, _), l)| *h == head && now - l.last <= self.params.owner_stale_ns && !l.released)
            .map(|(_, l)| match l.binding {
                Binding::Bound(g) | Binding::Pending(g) => g,
            })
            .collect();
        self.globals
            .iter()
            .filter(|(g, gt)| !fed.contains(g) && now - gt.last_report <= self.params.track_timeout_ns)
            .map(|(g, gt)| (*g, dist(gt.position_at(r.time), &r.mean)))
            .filter(|(_, d)| *d <= self.params.merge_gate_m)
            .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)))
            .map(|(g, _)| g)
    }

    /// Whether `head`'s report lies outside its region by more than the handover margin, in a
    /// region a live head covers: then the report may not found a global.
    fn foreign(&self, head: NodeId, r: &TrackReport, members: &Membership) -> bool {
        let (x, y) = (r.mean[0], r.mean[1]);
        members
            .region(head)
            .is_some_and(|region| distance_to_region(region, x, y) > self.params.handover_margin_m)
            && members.live_head_covering(x, y, 0.0, head).is_some()
    }

    /// Take one report from `head`; returns the decisions it caused.
    pub fn observe(
        &mut self,
        now: ClusterTime,
        head: NodeId,
        r: &TrackReport,
        members: &Membership,
    ) -> Vec<Decision> {
        let key = (head, r.target);
        let local = r.target;
        let n = self.params.hysteresis.max(1);
        let foreign = self.foreign(head, r, members);
        let mut out = Vec::new();
        let binding = match self.locals.get(&key).map(|l| l.binding) {
            None => match r.global.filter(|g| self.globals.contains_key(g)) {
                Some(g) => {
                    out.push(Decision::Claimed {
                        head,
                        local,
                        global: g,
                    });
                    self.locals.insert(key, LocalTrack::new(Binding::Bound(g), now));
                    Binding::Bound(g)
                }
                None => match self.candidate(now, head, r) {
                    Some(g) if n <= 1 => {
                        out.push(Decision::Merged {
                            head,
                            local,
                            global: g,
                        });
                        self.locals.insert(key, LocalTrack::new(Binding::Bound(g), now));
                        Binding::Bound(g)
                    }
                    Some(g) => {
                        let mut l = LocalTrack::new(Binding::Pending(g), now);
                        l.agree = 1;
                        self.locals.insert(key, l);
                        Binding::Pending(g)
                    }
                    // A foreign track near no global waits unbound; its next report is looked
                    // at afresh.
                    None if foreign => return out,
                    None => {
                        let g = self.new_global(now, head, r);
                        out.push(Decision::NewGlobal {
                            head,
                            local,
                            global: g,
                        });
                        self.locals.insert(key, LocalTrack::new(Binding::Bound(g), now));
                        Binding::Bound(g)
                    }
                },
            },
            Some(Binding::Pending(g)) => {
                let agrees = self.agrees(g, r);
                let l = self.locals.get_mut(&key).expect("present");
                l.last = now;
                if agrees {
                    l.agree += 1;
                    l.disagree = 0;
                } else {
                    l.disagree += 1;
                    l.agree = 0;
                }
                if agrees && l.agree >= n {
                    l.binding = Binding::Bound(g);
                    out.push(Decision::Merged {
                        head,
                        local,
                        global: g,
                    });
                    Binding::Bound(g)
                } else if foreign && !self.globals.contains_key(&g) {
                    self.locals.remove(&key);
                    return out;
                } else if !foreign && (!self.globals.contains_key(&g) || (!agrees && l.disagree >= n)) {
                    let g = self.new_global(now, head, r);
                    let l = self.locals.get_mut(&key).expect("present");
                    *l = LocalTrack::new(Binding::Bound(g), now);
                    out.push(Decision::NewGlobal {
                        head,
                        local,
                        global: g,
                    });
                    Binding::Bound(g)
                } else {
                    Binding::Pending(g)
                }
            }
            Some(Binding::Bound(g)) => {
                let owner = self.globals.get(&g).map(|gt| gt.owner);
                let agrees = self.agrees(g, r);
                let stale = self
                    .globals
                    .get(&g)
                    .is_some_and(|gt| now - gt.owner_report > self.params.owner_stale_ns);
                // A member head whose own region covers the target, while the owner's does not,
                // takes the track over: it is the cluster responsible for that area and already
                // tracks it, so no posterior needs to move.
                let home = agrees
                    && self.globals.get(&g).is_some_and(|gt| {
                        let (x, y) = (gt.mean[0], gt.mean[1]);
                        let outside_owner = members
                            .region(gt.owner)
                            .is_some_and(|reg| distance_to_region(reg, x, y) > self.params.handover_margin_m);
                        let inside_me = members
                            .region(head)
                            .is_some_and(|reg| distance_to_region(reg, x, y) == 0.0);
                        outside_owner && inside_me
                    });
                let l = self.locals.get_mut(&key).expect("present");
                l.last = now;
                match owner {
                    None => {
                        let g = self.new_global(now, head, r);
                        *self.locals.get_mut(&key).expect("present") =
                            LocalTrack::new(Binding::Bound(g), now);
                        out.push(Decision::NewGlobal {
                            head,
                            local,
                            global: g,
                        });
                        Binding::Bound(g)
                    }
                    Some(o) if o == head => Binding::Bound(g),
                    Some(o) if stale || home => {
                        l.disagree = 0;
                        let gt = self.globals.get_mut(&g).expect("present");
                        gt.owner = head;
                        gt.entered = home;
                        out.push(Decision::OwnerChanged {
                            global: g,
                            from: o,
                            to: head,
                        });
                        Binding::Bound(g)
                    }
                    Some(_) => {
                        if agrees {
                            l.disagree = 0;
                            Binding::Bound(g)
                        } else {
                            l.disagree += 1;
                            if l.disagree >= n {
                                // It left g for good. If it now sits on another global, it joins
                                // that one (it disagreed with g n times: hysteresis enough); a
                                // foreign track near nothing goes back to pending (no id while
                                // it disagrees); only a track of its own region splits off.
                                if let Some(c) = self.candidate(now, head, r) {
                                    *self.locals.get_mut(&key).expect("present") =
                                        LocalTrack::new(Binding::Bound(c), now);
                                    out.push(Decision::Merged {
                                        head,
                                        local,
                                        global: c,
                                    });
                                    Binding::Bound(c)
                                } else if foreign {
                                    *self.locals.get_mut(&key).expect("present") =
                                        LocalTrack::new(Binding::Pending(g), now);
                                    return out;
                                } else {
                                    let ng = self.new_global(now, head, r);
                                    *self.locals.get_mut(&key).expect("present") =
                                        LocalTrack::new(Binding::Bound(ng), now);
                                    out.push(Decision::Split {
                                        head,
                                        local,
                                        from: g,
                                        global: ng,
                                    });
                                    Binding::Bound(ng)
                                }
                            } else {
                                Binding::Bound(g)
                            }
                        }
                    }
                }
            }
        };
        if let Binding::Bound(g) = binding
            && let Some(gt) = self.globals.get_mut(&g)
        {
            gt.last_report = now;
            if gt.owner == head {
                gt.owner_report = now;
                if r.time >= gt.time {
                    gt.time = r.time;
                    gt.mean = r.mean;
                    gt.cov = r.cov;
                }
                if let Some(d) = self.region_handover(g, members) {
                    out.push(d);
                }
                out.extend(self.merge_globals(now, g));
            }
        }
        out
    }

    /// Two global tracks that stay together are one target (paper 004 §3.3.3): after the
    /// younger one's owner reported it within the gate of an older live global for
    /// `hysteresis` consecutive reports, it is absorbed into the older one and its local tracks
    /// rebound to it.
    fn merge_globals(&mut self, now: ClusterTime, g: TargetId) -> Vec<Decision> {
        let Some(gt) = self.globals.get(&g) else {
            return Vec::new();
        };
        let p = [gt.mean[0], gt.mean[1], gt.mean[2]];
        let t = gt.time;
        let near = self
            .globals
            .range(..g)
            .filter(|(_, o)| now - o.last_report <= self.params.owner_stale_ns)
            .map(|(id, o)| {
                let q = o.position_at(t);
                (
                    *id,
                    ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt(),
                )
            })
            .filter(|(_, d)| *d <= self.params.merge_gate_m)
            .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)))
            .map(|(id, _)| id);
        self.close.retain(|(a, b), _| *b != g || Some(*a) == near);
        let Some(keep) = near else {
            return Vec::new();
        };
        let count = self.close.entry((keep, g)).or_insert(0);
        *count += 1;
        if *count < self.params.hysteresis.max(1) {
            return Vec::new();
        }
        let mut out = Vec::new();
        for ((head, local), l) in &mut self.locals {
            if matches!(l.binding, Binding::Bound(x) | Binding::Pending(x) if x == g) {
                l.binding = Binding::Bound(keep);
                l.agree = 0;
                l.disagree = 0;
                out.push(Decision::Merged {
                    head: *head,
                    local: *local,
                    global: keep,
                });
            }
        }
        self.globals.remove(&g);
        self.close.retain(|(a, b), _| *a != g && *b != g);
        out.push(Decision::Absorbed {
            global: g,
            into: keep,
        });
        out
    }

    /// Hand `g` to the head whose region it entered, if it left its owner's.
    fn region_handover(&mut self, g: TargetId, members: &Membership) -> Option<Decision> {
        let gt = self.globals.get_mut(&g)?;
        let region = members.region(gt.owner)?;
        let (x, y) = (gt.mean[0], gt.mean[1]);
        if distance_to_region(region, x, y) <= self.params.handover_margin_m {
            gt.entered = true;
            return None;
        }
        if !gt.entered {
            return None;
        }
        let to = members.live_head_covering(x, y, 0.0, gt.owner)?;
        let from = gt.owner;
        gt.owner = to;
        gt.entered = true; // `to` covers the estimate
        for ((h, _), l) in self.locals.iter_mut() {
            if *h == from && l.binding == Binding::Bound(g) {
                l.released = true;
            }
        }
        Some(Decision::Handover {
            global: g,
            from: Some(from),
            to,
            reason: HandoverReason::Region,
        })
    }

    /// Time-driven changes: lost globals, forgotten local tracks, failover away from dead heads.
    pub fn tick(&mut self, now: ClusterTime, members: &Membership) -> Vec<Decision> {
        let mut out = Vec::new();
        let timeout = self.params.track_timeout_ns;
        let lost: Vec<TargetId> = self
            .globals
            .iter()
            .filter(|(_, gt)| now - gt.last_report > timeout)
            .map(|(g, _)| *g)
            .collect();
        for g in lost {
            self.globals.remove(&g);
            self.close.retain(|(a, b), _| *a != g && *b != g);
            self.locals
                .retain(|_, l| !matches!(l.binding, Binding::Bound(x) | Binding::Pending(x) if x == g));
            out.push(Decision::Lost { global: g });
        }
        let stale: Vec<(NodeId, TargetId)> = self
            .locals
            .iter()
            .filter(|(_, l)| now - l.last > timeout)
            .map(|(k, _)| *k)
            .collect();
        for (head, local) in stale {
            self.locals.remove(&(head, local));
            out.push(Decision::Forgotten { head, local });
        }
        for (g, gt) in &mut self.globals {
            if members.is_up(gt.owner) {
                continue;
            }
            let (x, y) = (gt.mean[0], gt.mean[1]);
            let to = members
                .live_head_covering(x, y, 0.0, gt.owner)
                .or_else(|| members.nearest_live_head(x, y, gt.owner));
            if let Some(to) = to {
                out.push(Decision::Handover {
                    global: *g,
                    from: Some(gt.owner),
                    to,
                    reason: HandoverReason::Failover,
                });
                gt.owner = to;
                // A stand-in owner hands the track back as soon as a live head covers it.
                gt.entered = true;
                gt.owner_report = now;
                gt.last_report = now;
            }
        }
        out
    }

    /// After a server restart: every track gets a fresh timeout window from `now`.
    pub fn refresh_all(&mut self, now: ClusterTime) {
        for gt in self.globals.values_mut() {
            gt.last_report = now;
            gt.owner_report = now;
        }
        for l in self.locals.values_mut() {
            l.last = now;
        }
    }
}

impl LocalTrack {
    fn new(binding: Binding, now: ClusterTime) -> Self {
        LocalTrack {
            binding,
            last: now,
            agree: 0,
            disagree: 0,
            released: false,
        }
    }
}
