//! Closing a step: association, fusion of each track (the method's [`crate::fusion::Fusion`]),
//! RSSI linearization and training, reports, births, activation.

use super::HeadNode;
use crate::activation::{Candidate, Expected, Variant};
use crate::association::{BIRTH_BOUNDS_MARGIN, Detection, births, gated_costs};
use crate::config::BIRTH_REGION_MARGIN_M;
use crate::lifecycle::{Ending, Lifecycle};
use crate::observe;
use crate::rssi_training::distance_variance;
use crate::stats::StepStats;
use nalgebra::Matrix6;
use proto::models::{Info, State, back_in_time, mat6_to_wire, position, vec6_to_wire};
use proto::msg::{Command, TrackReport};
use proto::node::Outgoing;
use proto::observation::{Kinds, ObservationKind};
use proto::region::{distance_to_region, inside_region};
use proto::scenario::Activation;
use proto::{ClusterTime, Message, Mode};
use tracing::{debug, info, warn};

impl HeadNode {
    pub(super) fn close_step(&mut self, now: ClusterTime, out: &mut Vec<Outgoing>) {
        let complete = self.window.complete();
        self.window.close();
        let counts = self.window.counts();
        // Associate detections; leftovers may start tracks.
        let dets = std::mem::take(&mut self.detections);
        // Radio tracks take no detection and gate none (`crate::unseen`): their width would
        // take whoever a camera sees nearby, and keep that person from a track of their own.
        let seen: Vec<usize> = (0..self.tracks.len())
            .filter(|&t| !self.tracks[t].is_radio())
            .collect();
        let priors: Vec<(State, Matrix6<f64>, ClusterTime)> = seen
            .iter()
            .map(|&t| {
                let t = &self.tracks[t];
                (*t.filter.mean(), *t.filter.cov(), t.time)
            })
            .collect();
        let costs = gated_costs(&priors, &dets, &self.cameras, self.cfg.method.gate_chi2);
        let assigned = costs
            .as_ref()
            .map_or_else(|| vec![None; dets.len()], assign::assign);
        let gated = |i: usize| costs.as_ref().is_some_and(|c| c.gated(i));
        let mut free = Vec::new();
        for (i, (d, a)) in dets.into_iter().zip(assigned).enumerate() {
            match a.map(|k| seen[k]) {
                Some(t) if !self.fusion.distributed() => {
                    self.tracks[t].last_seen = now;
                    self.tracks[t].detections.push(d);
                }
                // The head's own association pairs it with the track: the colours the camera
                // sent with it are that track's, though its position was the camera's to fold.
                Some(t) => {
                    if let Some(h) = &d.appearance {
                        self.tracks[t].see_colours(h);
                    }
                }
                // Distributed: detections reach the head only to start tracks, and one inside a
                // live track's gate that the assignment left over (a camera's second frame in
                // a step, or one sent before the track's first prior reached it) is that
                // track's, not a new person: such births made a second track of one robot.
                None if self.fusion.distributed() && gated(i) => {}
                None => free.push(d),
            }
        }
        let mut stats = StepStats {
            step: self.step,
            time: self.step_time,
            tracks: self.tracks.len(),
            applied: counts.applied,
            late: counts.late,
            duplicate: counts.duplicate,
            complete,
            ..StepStats::default()
        };
        let mut rssi_nodes = vec![false; self.nodes.len()];
        self.hand_sensed_to_fusion();
        self.hand_readings_to_tracks(now);
        if self.tags.claims_changed(now)
            && self
                .told_tags_at
                .is_none_or(|t| now - t >= super::TELL_TAGS_MIN_NS)
        {
            self.tell_tags(now, out);
        }
        for t in 0..self.tracks.len() {
            self.hold_height(t);
            self.fuse_track(t, now, &mut stats, &mut rssi_nodes);
        }
        stats.rssi_nodes = rssi_nodes.iter().filter(|&&b| b).count();
        self.merge_duplicates();
        let live: Vec<_> = self.tracks.iter().map(|t| t.local).collect();
        self.fusion.retain(&live);
        stats.tracks = self.tracks.len();
        for t in &self.tracks {
            stats.tentative += usize::from(t.state() == Lifecycle::Tentative);
            stats.coasting += usize::from(t.state() == Lifecycle::Coasting);
        }
        // A radio track is reported once a tag was heard for it (see `radio_search`).
        let evidenced = |t: &crate::track::Track| {
            t.global.is_some() || t.camera_steps > 0 || t.rssi_heard.iter().any(|&h| h)
        };
        for t in self.tracks.iter().filter(|t| t.past_tentative() && evidenced(t)) {
            if let Some(server) = self.cfg.server {
                out.push(Outgoing::new(
                    server,
                    Message::TrackReport(TrackReport {
                        target: t.local,
                        global: t.global,
                        step: self.step,
                        time: t.time,
                        mean: vec6_to_wire(t.filter.mean()),
                        cov: mat6_to_wire(t.filter.cov()),
                        contributors: t.contributors.clone(),
                        power_mw: self.power_mw(),
                        late: self.counters.late,
                        appearance: t.appearance.clone(),
                        grid: self.fusion.posterior(t.local),
                        captured: t.captured,
                    }),
                ));
            }
        }
        self.birth(&free, now);
        stats.decision = self.activate(out);
        stats.power_mw = self.power_mw();
        for n in self.nodes.iter().filter(|n| n.member && n.up) {
            stats.active_cameras += usize::from(n.mode == Mode::Active);
            stats.camera_off += usize::from(n.mode == Mode::CameraOff);
        }
        let c = &mut self.counters;
        c.steps += 1;
        c.sum_active_cameras += stats.active_cameras as u64;
        c.sum_rssi_nodes += stats.rssi_nodes as u64;
        c.sum_tentative += stats.tentative as u64;
        c.sum_coasting += stats.coasting as u64;
        c.sum_power_mw += stats.power_mw;
        self.last = stats;
        if self.keep_history {
            self.history.push(stats);
        }
    }

    /// Apply one track's step: the detections the head associated with it (centralized
    /// methods), RSSI, the fusion's update, then RSSI training.
    fn fuse_track(&mut self, t: usize, now: ClusterTime, stats: &mut StepStats, rssi_nodes: &mut [bool]) {
        let fuse_rssi = self.uses_rssi() && self.fusion.fuses_rssi();
        // A radio-only cluster holds its tracks' height itself (`hold_height`).
        let radio_only = self.radio_only_cluster();
        let track = &mut self.tracks[t];
        let mean_bar = *track.filter.mean();
        let dets = std::mem::take(&mut track.detections);
        for d in &dets {
            let node = &self.cfg.nodes[d.slot];
            self.fusion.absorb(track, d, node, &self.cfg);
            let kinds = Kinds::of(if d.ground.is_some() {
                ObservationKind::Ground
            } else {
                ObservationKind::Pinhole
            });
            track.note(node.id, kinds);
            track.fused_frame(d.captured);
            if let Some(h) = &d.appearance {
                track.see_colours(h);
            }
        }
        if !self.fusion.distributed() {
            stats.applied += dets.len() as u64;
        }
        // The camera-only filter takes this step's camera information first: RSSI below is
        // weighed by what the cameras know now.
        if !radio_only {
            observe::height_prior(&mut track.aux_acc, self.cfg.target_plane_z);
        }
        if track.aux.update(&track.aux_acc).is_err() {
            self.counters.numeric_failures += 1;
        }
        let aux_cov = track.aux.cov().fixed_view::<3, 3>(0, 0).into_owned();
        // RSSI, linearized here with the node's current model: Algorithm 1's choice first
        // re-run with what the cameras know of each node's distance now.
        let mut rssi_fused = false;
        if fuse_rssi {
            let aux_pos = position(track.aux.mean());
            for (trainer, node) in track.trainers.iter_mut().zip(&self.cfg.nodes) {
                trainer.recheck(distance_variance(&aux_pos, &aux_cov, &node.position));
            }
            let cov_bar = *track.filter.cov();
            for slot in observe::rssi(track, &self.cfg.nodes, &mean_bar, &cov_bar) {
                rssi_nodes[slot] = true;
                rssi_fused = true;
                track.last_seen = now;
            }
        }
        if !radio_only {
            observe::height_prior(&mut track.acc, self.cfg.target_plane_z);
        }
        let updated = self.fusion.update(track, now);
        if !updated.informed {
            stats.prediction_only += 1;
        }
        if let Some(e) = updated.failure {
            self.counters.numeric_failures += 1;
            warn!(target = %track.local, error = %e, "update failed; prediction only");
        }
        let trained_from_cameras = track.aux_acc.count > 0;
        let camera = trained_from_cameras || !dets.is_empty();
        track.end_step(camera, camera || rssi_fused);
        // Algorithm 1: pairs (distance from the camera-only filter, RSSI).
        if trained_from_cameras {
            // σ²_u is the paper's: from the auxiliary filter's covariance at the step. Taken at
            // the packet's time instead ([I, −age·I] Σ [I, −age·I]ᵀ), Table I's proposed method
            // erred 0.160 m instead of 0.142 and Method3 drew more power than Method2 (pixel
            // level, 5 runs, measured before Algorithm 1's per-step re-check and before RSSI was
            // weighed by its errors): Algorithm 1's σ²_tm ≤ σ²_D choice is that sensitive.
            for &(slot, dbm, age_s) in &track.rssi {
                // Paired with where the camera-only filter puts the target when the packet came.
                let aux_pos = position(&back_in_time(track.aux.mean(), age_s));
                let node = &self.nodes[slot].info.position;
                // At the node itself σ²_u is NaN (no direction), and the trainer skips the pair.
                let sigma_u2 = distance_variance(&aux_pos, &aux_cov, node);
                track.trainers[slot].push((aux_pos - node).norm(), dbm, sigma_u2);
            }
        }
        track.detections = dets;
        track.detections.clear();
    }

    fn birth(&mut self, free: &[Detection], now: ClusterTime) {
        if free.is_empty() {
            return;
        }
        let found = births(
            free,
            &self.cameras,
            self.cfg.method.gate_chi2,
            self.cfg.birth_min_cameras,
            self.cfg.target_plane_z,
            self.cfg.bounds,
        );
        for b in found {
            if self.on_another_heads_floor(b.mean[0], b.mean[1]) {
                self.counters.births_elsewhere += 1;
                continue;
            }
            let local = self.alloc_local();
            match self.new_track(local, None, b.mean, b.cov, now) {
                Ok(mut t) => {
                    // The colours a member camera sent with the person. A camera sends them with
                    // the first message that carries the person; a birth needs two or three
                    // cameras, so a camera's may have come a step before and been lost, and the
                    // track then waits for the next change or the 10 s refresh.
                    for h in b.members.iter().filter_map(|&i| free.get(i)?.appearance.as_ref()) {
                        t.see_colours(h);
                    }
                    info!(target = %local, cameras = b.members.len(), x = b.mean[0], y = b.mean[1], z = b.mean[2], "new track");
                    self.counters.births += 1;
                    self.tracks.push(t);
                }
                Err(e) => {
                    self.counters.numeric_failures += 1;
                    warn!(error = %e, "birth with an unusable covariance");
                }
            }
        }
    }

    /// Whether floor point `(x, y)` is a live head's, not this one's: more than
    /// [`BIRTH_REGION_MARGIN_M`] from this head's region and in another's that the server has
    /// not said is down, grown by the slack births have around the world's box (a birth just
    /// past a tiled wall is still that head's). Always false for a head without a region.
    pub(super) fn on_another_heads_floor(&self, x: f64, y: f64) -> bool {
        self.cfg
            .region
            .is_some_and(|r| distance_to_region(&r, x, y) > BIRTH_REGION_MARGIN_M)
            && self
                .cfg
                .other_regions
                .iter()
                .any(|(h, o)| !self.heads_down.contains(h) && inside_region(o, x, y, -BIRTH_BOUNDS_MARGIN))
    }

    /// The cluster's power with the current modes (nodes down draw nothing we can count).
    pub fn power_mw(&self) -> f64 {
        self.nodes
            .iter()
            .filter(|n| n.member && n.up)
            .map(|n| n.info.power.in_mode(n.mode))
            .sum()
    }

    /// Two tracks on one target (a track born next to another, or two converging on the same
    /// detections, which cameras may gate to both priors) would be updated together forever.
    /// When their states on the floor (horizontal position and velocity) agree within the gate
    /// (Mahalanobis with the summed covariances), keep the one with a global id, else the
    /// confirmed one, else the older, and drop the other. A tentative track (never reported)
    /// next to a confirmed one is dropped on position alone: its velocity is still a guess (a
    /// ghost's track swept onto a target, or a second track born on one target), and nobody
    /// knows it yet. Heights are left out: targets walk on the floor, so two tracks above one
    /// floor point are one target, and a duplicate that settled at another height (few
    /// cameras, steep views: the hall had pairs 1–2 m apart in height, one below the floor)
    /// was never merged when the test took the full position.
    fn merge_duplicates(&mut self) {
        let gate = self.cfg.method.gate_chi2;
        let mut i = 0;
        'outer: while i < self.tracks.len() {
            let mut j = i + 1;
            while j < self.tracks.len() {
                let (a, b) = (&self.tracks[i], &self.tracks[j]);
                // Position and velocity: two targets crossing are near but move apart.
                let same = if a.past_tentative() != b.past_tentative() {
                    floor_distance2(a, b, [0, 1])
                } else {
                    floor_distance2(a, b, [0, 1, 3, 4])
                }
                .is_some_and(|d2| d2 <= gate);
                // Two tracks holding two tags are two people, however close (asked only of a
                // pair that agrees: the book is searched per tag).
                let two_tags = || self.tags.tag_of(a.local).is_some() && self.tags.tag_of(b.local).is_some();
                // A radio track is as wide as its RSSI fix: its tag's evidence, not the gate,
                // says whether a camera track is its person (`crate::unseen`).
                let radio = a.is_radio() || b.is_radio();
                if same && !two_tags() && !radio {
                    // Prefer the track the server knows, then a confirmed one, then the older
                    // (lower index).
                    let rank = |t: &crate::track::Track| (t.global.is_some(), t.past_tentative());
                    let gone = if rank(b) > rank(a) { i } else { j };
                    let kept = if gone == i { j } else { i };
                    info!(kept = %self.tracks[kept].local, dropped = %self.tracks[gone].local, ending = ?Ending::Duplicate, "duplicate tracks merged");
                    self.counters.merges += 1;
                    self.tags.merged(self.tracks[gone].local, self.tracks[kept].local);
                    self.tracks.remove(gone);
                    if gone == i {
                        continue 'outer;
                    }
                } else {
                    j += 1;
                }
            }
            i += 1;
        }
    }

    pub(super) fn command(&mut self, slot: usize, mode: Mode, out: &mut Vec<Outgoing>) {
        let id = self.nodes[slot].info.id;
        self.nodes[slot].mode = mode;
        self.counters.commands += 1;
        out.push(Outgoing::new(id, Message::Command(Command { node: id, mode })));
    }

    /// Algorithm 2 (or all-on). Returns the greedy decision taken, if any.
    fn activate(&mut self, out: &mut Vec<Outgoing>) -> Option<crate::activation::Decision> {
        let variant = match self.cfg.method.activation {
            Activation::AllOn => None,
            Activation::CameraEntropy => Some(Variant::CameraOnly),
            Activation::FullNode => Some(Variant::FullNode),
            Activation::ThreeMode => Some(Variant::ThreeMode),
        };
        // All on, or no track a camera looks for (radio tracks are none: `Prior::radio`): wake
        // every member (search). The planner would put every camera to sleep for them.
        let radio_only_tracks = self.tracks.iter().all(|t| t.is_radio());
        if variant.is_none() || radio_only_tracks {
            for s in 0..self.nodes.len() {
                let n = &self.nodes[s];
                let on = n.info.working_mode(Mode::Active);
                if n.reachable() && n.mode != on {
                    self.command(s, on, out);
                }
            }
            return None;
        }
        let variant = variant?;
        // A tag no track holds and no fix places (`crate::unseen`): wake every sleeping radio
        // of the cluster to hear it; the planner may not put one to sleep while the search
        // lasts.
        let searching = self.unseen.searching() && self.uses_rssi();
        if searching {
            for s in 0..self.nodes.len() {
                let n = &self.nodes[s];
                if n.reachable() && n.info.rssi && !n.mode.radio_on() {
                    let on = n.info.working_mode(Mode::CameraOff);
                    self.command(s, on, out);
                }
            }
        }
        let dt = self.cfg.method.step_ms as f64 * 1e-3;
        let motion = self.cfg.method.motion;
        let mut predicted: Vec<Info> = Vec::with_capacity(self.tracks.len());
        let mut means: Vec<State> = Vec::with_capacity(self.tracks.len());
        for t in &self.tracks {
            let p = t.filter.predicted(&motion, dt).ok()?;
            predicted.push(*p.omega());
            means.push(*p.mean());
        }
        let slots: Vec<usize> = (0..self.nodes.len())
            .filter(|&s| self.nodes[s].reachable())
            .collect();
        let candidates: Vec<Candidate> = slots
            .iter()
            .map(|&s| Candidate {
                node: self.nodes[s].info.id,
                mode: self.nodes[s].mode,
                power: self.nodes[s].info.power,
                cost_factor: self.nodes[s].info.cost_factor,
            })
            .collect();
        let sigma = self.cfg.method.pixel_sigma;
        let (nodes, tracks, walls) = (&self.nodes, &self.tracks, &self.cfg.walls);
        let decision = self.planner.decide(
            variant,
            // Paper 002 §V: the cost is the difference in *energy*, set against the information
            // one step gains, so the power difference is held for one step:
            // nats/(mW·s) × s. (Weighing the raw power priced a camera at 0.71 nats a step,
            // dearer than all but the first camera's information: ~1 camera stayed on.)
            self.cfg.method.energy_weight * dt,
            &candidates,
            &predicted,
            |n, t| {
                let node = &nodes[slots[n]].info;
                let model = tracks[t]
                    .rssi_noise
                    .weighed(&tracks[t].trainers[slots[n]].model());
                let heard = node.rssi && tracks[t].rssi_heard[slots[n]];
                let rssi = heard.then_some((&model, &node.position));
                // No camera looks for a radio track (`Prior::radio`).
                let camera = (!node.radio_only && !tracks[t].is_radio()).then_some(&node.camera);
                Expected::at(camera, walls, sigma, rssi, &means[t])
            },
        )?;
        let slot = self.slots[&decision.node];
        let to = self.nodes[slot].info.working_mode(decision.to);
        if to == self.nodes[slot].mode {
            return Some(decision);
        }
        if searching && !to.radio_on() && self.nodes[slot].info.rssi {
            // Searching for an unseen tag: its radios stay on (no decision taken).
            return None;
        }
        debug!(node = %decision.node, from = ?decision.from, to = ?decision.to, reward = decision.reward, cost = decision.cost, "activation");
        self.command(slot, to, out);
        Some(decision)
    }
}

/// Squared Mahalanobis distance between two tracks' states restricted to the components
/// `idx`, with their summed covariances; `None` when that sum is not positive definite.
fn floor_distance2<const N: usize>(
    a: &crate::track::Track,
    b: &crate::track::Track,
    idx: [usize; N],
) -> Option<f64> {
    let (ma, mb, ca, cb) = (a.filter.mean(), b.filter.mean(), a.filter.cov(), b.filter.cov());
    // Fixed-size: this runs for every pair of tracks every step.
    let d = nalgebra::SVector::<f64, N>::from_fn(|r, _| ma[idx[r]] - mb[idx[r]]);
    let s = nalgebra::SMatrix::<f64, N, N>::from_fn(|r, c| ca[(idx[r], idx[c])] + cb[(idx[r], idx[c])]);
    let c = s.cholesky()?;
    Some(d.dot(&c.solve(&d)))
}
