//! A head's track report against the global table: the binding state machine of one local
//! track (unknown → pending → bound, and back), then the bound global's refresh. The rules are
//! listed in the parent module's docs; each state has its own function here.

use super::{Binding, LocalTrack, Tracks};
use crate::decision::Decision;
use crate::membership::Membership;
use proto::msg::TrackReport;
use proto::region::distance_to_region;
use proto::{ClusterTime, NodeId, TargetId};

/// One report being taken, with what every state needs to know about it.
struct Report<'a> {
    now: ClusterTime,
    head: NodeId,
    r: &'a TrackReport,
    members: &'a Membership,
    /// Consecutive reports needed to merge or split (the hysteresis, at least 1).
    n: u32,
    /// The report lies outside its head's region, where another live head covers it (or,
    /// beyond every region, lies clearly nearer): it may not found a global.
    foreign: bool,
}

impl Report<'_> {
    fn key(&self) -> (NodeId, TargetId) {
        (self.head, self.r.target)
    }

    fn merged(&self, global: TargetId) -> Decision {
        Decision::Merged {
            head: self.head,
            local: self.r.target,
            global,
        }
    }

    fn new_global(&self, global: TargetId) -> Decision {
        Decision::NewGlobal {
            head: self.head,
            local: self.r.target,
            global,
        }
    }
}

impl Tracks {
    /// Take one report from `head`; returns the decisions it caused.
    pub fn observe(
        &mut self,
        now: ClusterTime,
        head: NodeId,
        r: &TrackReport,
        members: &Membership,
    ) -> Vec<Decision> {
        let rep = Report {
            now,
            head,
            r,
            members,
            n: self.params.hysteresis.max(1),
            foreign: self.foreign(head, r, members),
        };
        let mut out = Vec::new();
        if let Some(l) = self.locals.get(&rep.key())
            && let Some(released) = l.released
        {
            let (Binding::Bound(g) | Binding::Pending(g)) = l.binding;
            // A late report: its estimate is older than the handover, so the head sent it
            // before it could know. Or a report of the very track the head was told to drop
            // (it carries the global) while the global is another head's. Either is no word
            // on the global. (If the head somehow kept the named track, it falls silent here,
            // is forgotten after the track timeout, and is then claimed afresh.)
            if r.time <= released
                || (r.global == Some(g) && self.globals.get(&g).is_some_and(|gt| gt.owner != head))
            {
                return out;
            }
            // Otherwise the head's track is looked at afresh, as one first seen: a track of its
            // own that the server had bound and the head kept (it dropped another), or the
            // global came back to this head, which named this track by that handover. Taken
            // as the owner's word when the global came back, a kept track moved the global to
            // wherever it was, and two such tracks on two heads handed one global back and
            // forth every report (the crowd, seed 1: 120 handovers of one id in about 20 s).
            self.locals.remove(&rep.key());
            self.waiting.remove(&rep.key());
        }
        // `None`: the track waits without a global id; nothing more to do for this report.
        let binding = match self.locals.get(&rep.key()).map(|l| l.binding) {
            None => self.bind_unknown(&rep, &mut out),
            Some(Binding::Pending(g)) => self.update_pending(&rep, g, &mut out),
            Some(Binding::Bound(g)) => self.update_bound(&rep, g, &mut out),
        };
        if let Some(Binding::Bound(g)) = binding {
            self.refresh_global(&rep, g, &mut out);
        }
        out
    }

    /// A local track seen for the first time: claimed by the id it carries, pending on (or
    /// merged into) the nearest global it does not feed yet, waiting, or founding a global.
    fn bind_unknown(&mut self, rep: &Report, out: &mut Vec<Decision>) -> Option<Binding> {
        let (now, head, r) = (rep.now, rep.head, rep.r);
        if let Some(g) = r.global.filter(|g| self.globals.contains_key(g)) {
            out.push(Decision::Claimed {
                head,
                local: r.target,
                global: g,
            });
            self.locals
                .insert(rep.key(), LocalTrack::new(Binding::Bound(g), now, r));
            return Some(Binding::Bound(g));
        }
        match self.candidate(now, head, r) {
            Some(g) if rep.n <= 1 => {
                out.push(rep.merged(g));
                self.locals
                    .insert(rep.key(), LocalTrack::new(Binding::Bound(g), now, r));
                Some(Binding::Bound(g))
            }
            Some(g) => {
                let mut l = LocalTrack::new(Binding::Pending(g), now, r);
                l.agree = 1;
                self.locals.insert(rep.key(), l);
                Some(Binding::Pending(g))
            }
            // A foreign track near no global waits unbound; its next report is looked at
            // afresh.
            None if rep.foreign => None,
            // So does a track lying on a global its own head already feeds: the head's
            // duplicate of that target (after a failover the survivor may briefly hold two),
            // which the head merges away. Given an id at once, it was a second id for seconds;
            // if it is another target, it founds one once it parts or the head has kept it for
            // the duplicate wait.
            None if self.waits_as_duplicate(now, head, r) => None,
            None => {
                self.waiting.remove(&rep.key());
                let g = self.new_global(now, head, r);
                out.push(rep.new_global(g));
                self.locals
                    .insert(rep.key(), LocalTrack::new(Binding::Bound(g), now, r));
                Some(Binding::Bound(g))
            }
        }
    }

    /// A pending track: bound after `n` agreeing reports (at once when it follows a global
    /// whose owner is gone); after `n` disagreeing ones, bound to another global it now lies
    /// on, else founding its own; founding its own after the duplicate wait on a global its
    /// head feeds with another track.
    fn update_pending(&mut self, rep: &Report, g: TargetId, out: &mut Vec<Decision>) -> Option<Binding> {
        let (now, head, r, n) = (rep.now, rep.head, rep.r, rep.n);
        let local = r.target;
        let agrees = self.agrees(g, r);
        let owner = self.globals.get(&g).map(|gt| gt.owner);
        let gone = self.owner_gone(now, g, rep.members);
        // The head follows g: it was told this track is g, or it lies on g.
        let follows = r.global == Some(g) || agrees;
        // Its head already feeds g with another track: two tracks of one head on one global
        // would take turns moving its posterior. It is the head's duplicate, merged away soon;
        // one the head keeps on g past the duplicate wait is a second person, who founds a
        // global of their own.
        let other = self.feeds_other(head, local, g, now);
        let takes = follows
            && match owner {
                Some(o) if o == head => !other,
                Some(_) => gone,
                None => false,
            };
        let waited_out =
            agrees && other && now - self.waited_since(now, rep.key()) >= self.params.duplicate_wait_ns;
        let l = self.locals.get_mut(&rep.key()).expect("present");
        l.last = now;
        l.posterior = (r.time, r.mean, r.cov);
        if agrees {
            l.agree += 1;
            l.disagree = 0;
        } else if !gone {
            l.disagree += 1;
            l.agree = 0;
        }
        // While g's owner is gone, g's posterior is its last word and ages: missing it is no
        // evidence, so disagreement is not counted (above), and a track that follows g is g's
        // best estimate: it is bound and its head takes g over. The same when g was handed to
        // this very head (failover). Without this the order of the survivor's reports and the
        // failover tick decides whether g lives on.
        if takes {
            l.binding = Binding::Bound(g);
            l.agree = 0;
            l.disagree = 0;
            out.push(rep.merged(g));
            if let Some(o) = owner.filter(|o| *o != head)
                && let Some(gt) = self.globals.get_mut(&g)
            {
                gt.owner = head;
                gt.entered = false;
                out.push(Decision::OwnerChanged {
                    global: g,
                    from: o,
                    to: head,
                });
            }
            Some(Binding::Bound(g))
        } else if agrees && l.agree >= n && !other {
            l.binding = Binding::Bound(g);
            out.push(rep.merged(g));
            Some(Binding::Bound(g))
        } else if rep.foreign && !self.globals.contains_key(&g) {
            self.locals.remove(&rep.key());
            None
        } else if !rep.foreign
            && (!self.globals.contains_key(&g) || (!agrees && l.disagree >= n) || waited_out)
        {
            self.waiting.remove(&rep.key());
            // Left g (or g is gone) and now lies on another global: that one is its target, as
            // for a bound track leaving its global (`leave_global`). Founding here gave a
            // target a second id until the two globals were absorbed (the hall, seed 1: head
            // 4's track on a person head 5 tracked, twice, 0.4 s each). `candidate` passes
            // over g: this track feeds it. One that waited out the duplicate wait is a second
            // person beside g's and founds its own.
            if !waited_out && let Some(c) = self.candidate(now, head, r) {
                return self.join(rep, c, out);
            }
            let g = self.new_global(now, head, r);
            *self.locals.get_mut(&rep.key()).expect("present") = LocalTrack::new(Binding::Bound(g), now, r);
            out.push(rep.new_global(g));
            Some(Binding::Bound(g))
        } else {
            Some(Binding::Pending(g))
        }
    }

    /// A bound track: its head keeps, takes over (owner gone, or the target is in its own
    /// region) or, after `n` disagreeing reports, leaves the global for another one, back to
    /// pending (foreign) or a global of its own (`Split`).
    fn update_bound(&mut self, rep: &Report, g: TargetId, out: &mut Vec<Decision>) -> Option<Binding> {
        let (now, head, r) = (rep.now, rep.head, rep.r);
        let owner = self.globals.get(&g).map(|gt| gt.owner);
        let agrees = self.agrees(g, r);
        let stale = self.owner_gone(now, g, rep.members);
        let home = agrees && self.in_my_region_not_owners(rep, g);
        let l = self.locals.get_mut(&rep.key()).expect("present");
        l.last = now;
        l.posterior = (r.time, r.mean, r.cov);
        match owner {
            None => {
                let g = self.new_global(now, head, r);
                *self.locals.get_mut(&rep.key()).expect("present") =
                    LocalTrack::new(Binding::Bound(g), now, r);
                out.push(rep.new_global(g));
                Some(Binding::Bound(g))
            }
            Some(o) if o == head => Some(Binding::Bound(g)),
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
                Some(Binding::Bound(g))
            }
            Some(_) if agrees => {
                l.disagree = 0;
                Some(Binding::Bound(g))
            }
            Some(_) => {
                l.disagree += 1;
                if l.disagree >= rep.n {
                    self.leave_global(rep, g, out)
                } else {
                    Some(Binding::Bound(g))
                }
            }
        }
    }

    /// A member head whose own region covers the target, while the owner's does not, takes
    /// the track over: it is the cluster responsible for that area and already tracks it, so
    /// no posterior needs to move.
    fn in_my_region_not_owners(&self, rep: &Report, g: TargetId) -> bool {
        self.globals.get(&g).is_some_and(|gt| {
            let (x, y) = (gt.mean[0], gt.mean[1]);
            let outside_owner = rep
                .members
                .region(gt.owner)
                .is_some_and(|reg| distance_to_region(reg, x, y) > self.params.handover_margin_m);
            let inside_me = rep
                .members
                .region(rep.head)
                .is_some_and(|reg| distance_to_region(reg, x, y) == 0.0);
            outside_owner && inside_me
        })
    }

    /// A bound track that disagreed with `g` `n` times left it for good. If it now sits on
    /// another global, it joins that one (hysteresis enough); a foreign track near nothing
    /// goes back to pending (no id while it disagrees); only a track of its own region splits
    /// off.
    fn leave_global(&mut self, rep: &Report, g: TargetId, out: &mut Vec<Decision>) -> Option<Binding> {
        let (now, head, r) = (rep.now, rep.head, rep.r);
        if let Some(c) = self.candidate(now, head, r) {
            self.join(rep, c, out)
        } else if rep.foreign {
            *self.locals.get_mut(&rep.key()).expect("present") = LocalTrack::new(Binding::Pending(g), now, r);
            None
        } else {
            let ng = self.new_global(now, head, r);
            *self.locals.get_mut(&rep.key()).expect("present") = LocalTrack::new(Binding::Bound(ng), now, r);
            out.push(Decision::Split {
                head,
                local: r.target,
                from: g,
                global: ng,
            });
            Some(Binding::Bound(ng))
        }
    }

    /// Bind a track that left another global to `c`, which it lies on, at once: the reports
    /// that disagreed with the one it left were its hysteresis.
    fn join(&mut self, rep: &Report, c: TargetId, out: &mut Vec<Decision>) -> Option<Binding> {
        *self.locals.get_mut(&rep.key()).expect("present") =
            LocalTrack::new(Binding::Bound(c), rep.now, rep.r);
        out.push(rep.merged(c));
        Some(Binding::Bound(c))
    }

    /// A report bound to `g` refreshes it; the owner's report moves its posterior and may hand
    /// it over or merge it with another global.
    fn refresh_global(&mut self, rep: &Report, g: TargetId, out: &mut Vec<Decision>) {
        let Some(gt) = self.globals.get_mut(&g) else {
            return;
        };
        gt.last_report = rep.now;
        if gt.owner != rep.head {
            return;
        }
        gt.owner_report = rep.now;
        if rep.r.time >= gt.time {
            gt.time = rep.r.time;
            gt.mean = rep.r.mean;
            gt.cov = rep.r.cov;
            if !rep.r.appearance.is_empty() {
                gt.appearance.clone_from(&rep.r.appearance);
            }
        }
        if let Some(d) = self.region_handover(rep.now, g, rep.members) {
            out.push(d);
        }
        out.extend(self.merge_globals(rep.now, g));
    }
}
