//! How global tracks move in time and between heads: two globals that stay together become one,
//! a track that leaves its owner's region is handed over, a dead owner's tracks fail over, and
//! silent tracks are lost or forgotten. The rules are listed in the parent module's docs.

use super::{Binding, Tracks};
use crate::decision::{Decision, HandoverReason};
use crate::membership::Membership;
use proto::region::distance_to_region;
use proto::{ClusterTime, NodeId, TargetId};

impl Tracks {
    /// Two global tracks that stay together are one target (paper 004 §3.3.3): after the
    /// younger one's owner reported it within the gate of an older live global for
    /// `hysteresis` consecutive reports, it is absorbed into the older one and its local tracks
    /// rebound to it.
    pub(super) fn merge_globals(&mut self, now: ClusterTime, g: TargetId) -> Vec<Decision> {
        let Some(gt) = self.globals.get(&g) else {
            return Vec::new();
        };
        let p = [gt.mean[0], gt.mean[1], gt.mean[2]];
        let t = gt.time;
        let near = self
            .globals
            .range(..g)
            .filter(|(_, o)| now - o.last_report <= self.params.owner_stale_ns)
            // Two people of other colours standing together stay two.
            .filter(|(_, o)| self.looks_like(o, &gt.appearance))
            // So do two that one head tracks as two: its own duplicate merge would have made
            // them one if its cameras saw one target (two people side by side, or meeting).
            .filter(|(id, _)| !self.one_head_feeds_both(now, g, **id))
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

    /// Whether some head feeds `a` and `b` each with a live local track of its own (bound or
    /// pending).
    fn one_head_feeds_both(&self, now: ClusterTime, a: TargetId, b: TargetId) -> bool {
        let heads = |g: TargetId| -> Vec<NodeId> {
            self.locals
                .iter()
                .filter(|(_, l)| {
                    matches!(l.binding, Binding::Bound(x) | Binding::Pending(x) if x == g)
                        && l.released.is_none()
                        && now - l.last <= self.params.owner_stale_ns
                })
                .map(|((h, _), _)| *h)
                .collect()
        };
        let of_a = heads(a);
        heads(b).iter().any(|h| of_a.contains(h))
    }

    /// Hand `g` to the head whose region it entered, if it left its owner's.
    pub(super) fn region_handover(
        &mut self,
        now: ClusterTime,
        g: TargetId,
        members: &Membership,
    ) -> Option<Decision> {
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
                l.released = Some(now);
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
        // A waiting track silent for the timeout is gone (one still reporting keeps its wait,
        // however long: the timeout and the duplicate wait are both 3 s by default).
        self.waiting.retain(|_, (_, last)| now - *last <= timeout);
        for (head, local) in stale {
            self.locals.remove(&(head, local));
            out.push(Decision::Forgotten { head, local });
        }
        let orphans: Vec<TargetId> = self
            .globals
            .iter()
            .filter(|(_, gt)| !members.is_up(gt.owner))
            .map(|(g, _)| *g)
            .collect();
        for g in orphans {
            out.extend(self.failover(now, g, members));
        }
        out
    }

    /// Move `g` away from its dead owner: to a live head that follows it (a local track bound
    /// or pending on it that reported within the owner staleness; the most recent), which
    /// continues from its own estimate if that is newer; else to the live head covering its
    /// last position, else the nearest one.
    fn failover(&mut self, now: ClusterTime, g: TargetId, members: &Membership) -> Vec<Decision> {
        let mut out = Vec::new();
        let Some(gt) = self.globals.get(&g) else {
            return out;
        };
        let dead = gt.owner;
        let follower = self
            .locals
            .iter()
            .filter(|((h, _), l)| {
                matches!(l.binding, Binding::Bound(x) | Binding::Pending(x) if x == g)
                    && l.released.is_none()
                    && *h != dead
                    && members.is_up(*h)
                    && now - l.last <= self.params.owner_stale_ns
            })
            .max_by(|a, b| a.1.last.cmp(&b.1.last).then(b.0.cmp(a.0)))
            .map(|(k, _)| *k);
        let (x, y) = (gt.mean[0], gt.mean[1]);
        let to = follower.map(|(h, _)| h).or_else(|| {
            members
                .live_head_covering(x, y, 0.0, dead)
                .or_else(|| members.nearest_live_head(x, y, dead))
        });
        let Some(to) = to else {
            return out;
        };
        out.push(Decision::Handover {
            global: g,
            from: Some(dead),
            to,
            reason: HandoverReason::Failover,
        });
        let mut posterior = None;
        if let Some(key) = follower
            && let Some(l) = self.locals.get_mut(&key)
        {
            if l.binding == Binding::Pending(g) {
                l.binding = Binding::Bound(g);
                l.agree = 0;
                l.disagree = 0;
                out.push(Decision::Merged {
                    head: key.0,
                    local: key.1,
                    global: g,
                });
            }
            posterior = Some(l.posterior);
        }
        let gt = self.globals.get_mut(&g).expect("present");
        gt.owner = to;
        // A stand-in owner hands the track back as soon as a live head covers it.
        gt.entered = true;
        gt.owner_report = now;
        gt.last_report = now;
        if let Some((t, mean, cov)) = posterior.filter(|p| p.0 > gt.time) {
            gt.time = t;
            gt.mean = mean;
            gt.cov = cov;
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
