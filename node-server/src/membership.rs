//! Membership: who is in the network, who is alive, and which head each camera reports to.
//!
//! Nodes are admitted by the handshake (`Hello`) if the scenario declares them with that role;
//! tools are admitted by handshake without being declared. Liveness rests on the transport's
//! links: a node whose link is up (the transport's heartbeats flow) is up, a link going down
//! marks it down at once. Only a node without a link report (the simulation runtime, a
//! restored state) falls back to messages: any accepted message counts as a sign of life,
//! and one silent for `liveness_timeout_ms` is marked down on the next tick. A down node that
//! speaks again is re-admitted. Cameras start on their scenario head (a camera with
//! none goes to the head whose region covers the floor point it looks at); while that head
//! is down they are moved to the live head whose region is nearest (paper 002's clusters keep
//! tracking while a head is away), and they move back when it returns. A declared head that
//! has not come up [`STARTUP_GRACE_NS`] (or the liveness timeout, if longer) after the first
//! node was admitted is down as well: its floor would otherwise stay untracked for good, its
//! cameras reporting to nobody and the other heads leaving its region to it.

use crate::decision::Decision;
use proto::scenario::{NodeRole, PoseSpec, Scenario};
use proto::{ClusterTime, NodeId, Role};
use std::collections::BTreeMap;

/// One admitted node.
#[derive(Clone, Debug, PartialEq)]
pub struct Member {
    pub role: Role,
    pub up: bool,
    pub last_seen: ClusterTime,
    /// The transport reports a live link to it: it is up whatever it says or does not say.
    pub linked: bool,
}

/// The membership table.
#[derive(Clone, Debug)]
pub struct Membership {
    /// Roles the scenario declares.
    declared: BTreeMap<NodeId, Role>,
    /// Scenario head of each camera.
    home: BTreeMap<NodeId, NodeId>,
    /// Head regions `[xmin, ymin, xmax, ymax]`.
    regions: BTreeMap<NodeId, [f64; 4]>,
    /// Current head of each camera.
    assigned: BTreeMap<NodeId, NodeId>,
    members: BTreeMap<NodeId, Member>,
    timeout_ns: i64,
    /// When the first declared node was admitted (or the server resumed): a declared head
    /// still unseen a grace period later is down. Taken from an admission (a received message)
    /// or a resume, both recorded, so a replay comes to the same decision at the same tick.
    first_admitted: Option<ClusterTime>,
}

/// How long after the first admission a declared head may take to come up before it is
/// down, ns (the liveness timeout when that is longer): processes started together connect
/// within a few seconds, and a head marked down a moment too soon only moves its cameras
/// away and back.
pub const STARTUP_GRACE_NS: i64 = 10_000_000_000;

fn role_of(r: NodeRole) -> Role {
    match r {
        NodeRole::Camera => Role::Camera,
        NodeRole::Head => Role::Head,
        NodeRole::Server => Role::Server,
        NodeRole::Acoustic => Role::Acoustic,
    }
}

use proto::region::{distance_to_region, inside_region};

/// Where a camera's optical axis meets the floor (z = 0); its position if it looks up or level.
fn floor_point(pose: &PoseSpec) -> Option<(f64, f64)> {
    if let PoseSpec::LookAt { look_at, .. } = pose {
        return Some((look_at[0], look_at[1]));
    }
    let p = pose.to_pose()?;
    let c = p.centre();
    let axis = p.rotation.inverse() * nalgebra::Vector3::z();
    if axis.z < -1e-9 && c.z > 0.0 {
        let s = -c.z / axis.z;
        Some((c.x + s * axis.x, c.y + s * axis.y))
    } else {
        Some((c.x, c.y))
    }
}

fn centre(r: &[f64; 4]) -> (f64, f64) {
    (0.5 * (r[0] + r[2]), 0.5 * (r[1] + r[3]))
}

impl Membership {
    pub fn new(scenario: &Scenario) -> Self {
        let declared = scenario
            .nodes
            .iter()
            .map(|n| (NodeId(n.id), role_of(n.role)))
            .collect();
        let mut home = BTreeMap::new();
        for (head, cams) in scenario.clusters() {
            for c in cams {
                home.insert(c, head);
            }
        }
        let regions: BTreeMap<NodeId, [f64; 4]> = scenario
            .heads()
            .filter_map(|h| h.region.map(|r| (NodeId(h.id), r)))
            .collect();
        // A camera the scenario gives no head goes to the head whose region covers the floor
        // point it looks at (nearest region if none covers it).
        for c in scenario.cameras().filter(|c| c.head.is_none()) {
            let Some((x, y)) = c.camera.as_ref().and_then(|cam| floor_point(cam.pose.as_ref()?)) else {
                continue;
            };
            if let Some((h, _)) = regions
                .iter()
                .map(|(h, r)| (*h, distance_to_region(r, x, y)))
                .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)))
            {
                home.insert(NodeId(c.id), h);
            }
        }
        Membership {
            declared,
            assigned: home.clone(),
            home,
            regions,
            members: BTreeMap::new(),
            timeout_ns: i64::try_from(scenario.network.liveness_timeout_ms)
                .unwrap_or(i64::MAX / 1_000_000)
                .saturating_mul(1_000_000),
            first_admitted: None,
        }
    }

    pub fn declared_role(&self, node: NodeId) -> Option<Role> {
        self.declared.get(&node).copied()
    }

    pub fn member(&self, node: NodeId) -> Option<&Member> {
        self.members.get(&node)
    }

    pub fn members(&self) -> impl Iterator<Item = (NodeId, &Member)> {
        self.members.iter().map(|(k, v)| (*k, v))
    }

    pub fn is_up(&self, node: NodeId) -> bool {
        self.members.get(&node).is_some_and(|m| m.up)
    }

    pub fn region(&self, head: NodeId) -> Option<&[f64; 4]> {
        self.regions.get(&head)
    }

    /// The head a camera currently reports to.
    pub fn head_of(&self, camera: NodeId) -> Option<NodeId> {
        self.assigned.get(&camera).copied()
    }

    /// Cameras currently assigned to `head`.
    pub fn cameras_of(&self, head: NodeId) -> Vec<NodeId> {
        self.assigned
            .iter()
            .filter(|(_, h)| **h == head)
            .map(|(c, _)| *c)
            .collect()
    }

    /// Heads that are up, in id order.
    pub fn live_heads(&self) -> Vec<NodeId> {
        self.members
            .iter()
            .filter(|(_, m)| m.up && m.role == Role::Head)
            .map(|(id, _)| *id)
            .collect()
    }

    /// The live head whose region contains `(x, y)` (shrunk by `margin`), lowest id first.
    pub fn live_head_covering(&self, x: f64, y: f64, margin: f64, except: NodeId) -> Option<NodeId> {
        self.live_heads().into_iter().find(|h| {
            *h != except
                && self
                    .regions
                    .get(h)
                    .is_some_and(|r| inside_region(r, x, y, margin))
        })
    }

    /// Whether `(x, y)` lies in some head's region, live or not.
    pub fn in_any_region(&self, x: f64, y: f64) -> bool {
        self.regions.values().any(|r| inside_region(r, x, y, 0.0))
    }

    /// The live head nearest to `(x, y)` by region (heads without a region come last), except
    /// `except`; ties go to the lowest id.
    pub fn nearest_live_head(&self, x: f64, y: f64, except: NodeId) -> Option<NodeId> {
        self.live_heads()
            .into_iter()
            .filter(|h| *h != except)
            .min_by(|a, b| {
                let d = |h: &NodeId| {
                    self.regions
                        .get(h)
                        .map_or(f64::INFINITY, |r| distance_to_region(r, x, y))
                };
                d(a).total_cmp(&d(b)).then(a.cmp(b))
            })
    }

    /// Record a sign of life from `node` at `now`. Returns `Up` if it was down. The node must
    /// already be a member.
    pub fn seen(&mut self, now: ClusterTime, node: NodeId) -> Option<Decision> {
        let m = self.members.get_mut(&node)?;
        if now > m.last_seen {
            m.last_seen = now;
        }
        if m.up {
            None
        } else {
            m.up = true;
            Some(Decision::Up { node })
        }
    }

    /// Admit `node` as `role` (handshake or implicit). Returns the decision if it was not an
    /// up member already.
    pub fn admit(&mut self, now: ClusterTime, node: NodeId, role: Role) -> Option<Decision> {
        // A tool or viewer attached before the nodes start does not start the heads' grace.
        if self.declared.contains_key(&node) {
            self.first_admitted.get_or_insert(now);
        }
        match self.members.get(&node) {
            Some(m) if m.role == role => self.seen(now, node),
            _ => {
                self.members.insert(
                    node,
                    Member {
                        role,
                        up: true,
                        last_seen: now,
                        linked: false,
                    },
                );
                Some(Decision::Admitted { node, role })
            }
        }
    }

    /// Record what the transport says of `node`'s link (it must already be a member).
    pub fn set_linked(&mut self, node: NodeId, linked: bool) {
        if let Some(m) = self.members.get_mut(&node) {
            m.linked = linked;
        }
    }

    /// Nodes without a live link silent past the timeout at `now`, marked down.
    pub fn expire(&mut self, now: ClusterTime) -> Vec<Decision> {
        let mut out = Vec::new();
        for (id, m) in &mut self.members {
            if m.up && !m.linked && m.role != Role::Tool && now - m.last_seen > self.timeout_ns {
                m.up = false;
                out.push(Decision::Down {
                    node: *id,
                    silent_ms: u64::try_from((now - m.last_seen) / 1_000_000).unwrap_or(0),
                });
            }
        }
        out.extend(self.expire_unseen_heads(now));
        out
    }

    /// Declared heads never admitted, a grace period after the first admission: members from
    /// now on, down (`Down` with the silence since that admission). One that comes up later is
    /// admitted as any down node that speaks again.
    fn expire_unseen_heads(&mut self, now: ClusterTime) -> Vec<Decision> {
        let Some(start) = self.first_admitted else {
            return Vec::new();
        };
        if now - start <= STARTUP_GRACE_NS.max(self.timeout_ns) {
            return Vec::new();
        }
        let unseen: Vec<NodeId> = self
            .declared
            .iter()
            .filter(|&(id, &role)| role == Role::Head && !self.members.contains_key(id))
            .map(|(id, _)| *id)
            .collect();
        unseen
            .into_iter()
            .map(|node| {
                self.members.insert(
                    node,
                    Member {
                        role: Role::Head,
                        up: false,
                        last_seen: start,
                        linked: false,
                    },
                );
                Decision::Down {
                    node,
                    silent_ms: u64::try_from((now - start) / 1_000_000).unwrap_or(0),
                }
            })
            .collect()
    }

    /// Mark a member down at once (its link closed). `None` if it was not up.
    pub fn mark_down(&mut self, now: ClusterTime, node: NodeId) -> Option<Decision> {
        let m = self.members.get_mut(&node)?;
        if !m.up || m.role == Role::Tool {
            return None;
        }
        m.up = false;
        Some(Decision::Down {
            node,
            silent_ms: u64::try_from((now - m.last_seen) / 1_000_000).unwrap_or(0),
        })
    }

    /// Give every up member a fresh grace period from `now` (after a server restart). The old
    /// process's links are gone: members are unlinked until the transport reports new ones.
    pub fn refresh_all(&mut self, now: ClusterTime) {
        // Heads not seen yet get a fresh start-up grace too (the restart is recorded, so a
        // replay comes to the same decisions).
        if self.first_admitted.is_some() {
            self.first_admitted = Some(now);
        }
        for m in self.members.values_mut() {
            m.linked = false;
            if m.up {
                m.last_seen = now;
            }
        }
    }

    /// Where each camera should report given which heads are up: its scenario head unless that
    /// head went down, else the live head whose region is nearest to that head's region centre. Returns the changes.
    pub fn rebalance(&mut self) -> Vec<Decision> {
        let mut out = Vec::new();
        let homes: Vec<(NodeId, NodeId)> = self.home.iter().map(|(c, h)| (*c, *h)).collect();
        for (cam, home) in homes {
            // Only a head that is down loses its cameras; one not seen yet (at start-up) keeps
            // them until its grace runs out (`expire_unseen_heads`).
            let down = self.members.get(&home).is_some_and(|m| !m.up);
            let want = if !down || self.live_heads().is_empty() {
                home
            } else {
                let (x, y) = self.regions.get(&home).map_or((0.0, 0.0), centre);
                self.nearest_live_head(x, y, home).unwrap_or(home)
            };
            if self.assigned.get(&cam) != Some(&want) {
                let from = self.assigned.insert(cam, want);
                out.push(Decision::Assigned {
                    camera: cam,
                    head: want,
                    from,
                });
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(v: i64) -> ClusterTime {
        ClusterTime::from_millis(v)
    }

    #[test]
    fn silent_nodes_go_down_and_come_back() {
        let s = crate::testkit::scenario();
        let mut m = Membership::new(&s);
        assert!(m.admit(ms(0), NodeId(10), Role::Camera).is_some());
        assert!(m.admit(ms(0), NodeId(2), Role::Head).is_some());
        assert!(m.expire(ms(900)).is_empty());
        m.seen(ms(900), NodeId(2));
        let down = m.expire(ms(1500));
        assert_eq!(
            down,
            vec![Decision::Down {
                node: NodeId(10),
                silent_ms: 1500
            }]
        );
        assert!(!m.is_up(NodeId(10)));
        assert!(m.is_up(NodeId(2)));
        assert_eq!(
            m.seen(ms(1600), NodeId(10)),
            Some(Decision::Up { node: NodeId(10) })
        );
        assert_eq!(m.seen(ms(1700), NodeId(10)), None);
    }

    #[test]
    fn a_node_with_a_live_link_stays_up_however_long_it_is_quiet() {
        let s = crate::testkit::scenario();
        let mut m = Membership::new(&s);
        m.admit(ms(0), NodeId(10), Role::Camera);
        m.set_linked(NodeId(10), true);
        // The heads up and linked: a head never admitted would go down after the start-up
        // grace (`expire_unseen_heads`), and only the camera is looked at here.
        for h in [2, 3] {
            m.admit(ms(0), NodeId(h), Role::Head);
            m.set_linked(NodeId(h), true);
        }
        assert!(m.expire(ms(60_000)).is_empty(), "the transport vouches for it");
        m.set_linked(NodeId(10), false);
        assert_eq!(m.expire(ms(60_000)).len(), 1);
        // After a restart nobody is linked until the transport says so again.
        m.seen(ms(60_001), NodeId(10));
        m.set_linked(NodeId(10), true);
        m.refresh_all(ms(60_002));
        for h in [2, 3] {
            m.set_linked(NodeId(h), true);
        }
        assert_eq!(m.expire(ms(62_000)).len(), 1);
    }

    #[test]
    fn cameras_move_to_the_nearest_live_head_and_back() {
        let s = crate::testkit::scenario();
        let mut m = Membership::new(&s);
        m.admit(ms(0), NodeId(2), Role::Head);
        m.admit(ms(0), NodeId(3), Role::Head);
        assert!(m.rebalance().is_empty());
        let mine = m.cameras_of(NodeId(2));
        assert!(!mine.is_empty());
        m.seen(ms(1500), NodeId(3));
        assert_eq!(m.expire(ms(1500)).len(), 1); // head 2 silent
        let moves = m.rebalance();
        assert_eq!(moves.len(), mine.len());
        assert!(mine.iter().all(|c| m.head_of(*c) == Some(NodeId(3))));
        m.seen(ms(1600), NodeId(2));
        assert_eq!(m.rebalance().len(), mine.len());
        assert_eq!(m.cameras_of(NodeId(2)), mine);
    }

    #[test]
    fn a_head_that_never_comes_up_is_down_after_the_grace_and_its_cameras_move() {
        let s = crate::testkit::scenario();
        let mut m = Membership::new(&s);
        m.admit(ms(0), NodeId(2), Role::Head);
        m.set_linked(NodeId(2), true);
        let theirs = m.cameras_of(NodeId(3));
        assert!(!theirs.is_empty());
        // Within the grace head 3 keeps its cameras: it may still be starting.
        assert!(m.expire(ms(10_000)).is_empty());
        assert!(m.rebalance().is_empty());
        let down = m.expire(ms(10_001));
        assert_eq!(
            down,
            vec![Decision::Down {
                node: NodeId(3),
                silent_ms: 10_001
            }]
        );
        assert!(m.expire(ms(20_000)).is_empty(), "down once");
        assert_eq!(m.rebalance().len(), theirs.len());
        assert!(theirs.iter().all(|c| m.head_of(*c) == Some(NodeId(2))));
        // It comes up at last: admitted as any node back from down, and its cameras go home.
        assert_eq!(
            m.admit(ms(30_000), NodeId(3), Role::Head),
            Some(Decision::Up { node: NodeId(3) })
        );
        assert_eq!(m.rebalance().len(), theirs.len());
        assert_eq!(m.cameras_of(NodeId(3)), theirs);
    }

    #[test]
    fn the_start_up_grace_runs_from_the_first_declared_node_and_again_after_a_restart() {
        let s = crate::testkit::scenario();
        let mut m = Membership::new(&s);
        // A tool (undeclared) attached early starts nothing.
        m.admit(ms(0), NodeId(99), Role::Tool);
        m.admit(ms(5_000), NodeId(2), Role::Head);
        m.set_linked(NodeId(2), true);
        assert!(
            m.expire(ms(15_000)).is_empty(),
            "10 s from head 2, not from the tool"
        );
        // A restart at 14 s gives head 3 a fresh grace.
        m.refresh_all(ms(14_000));
        m.set_linked(NodeId(2), true);
        assert!(m.expire(ms(24_000)).is_empty());
        assert_eq!(m.expire(ms(24_001)).len(), 1);
    }

    #[test]
    fn a_camera_without_a_head_joins_the_head_covering_what_it_sees() {
        let mut s = crate::testkit::scenario();
        let mut cam = s.node(11).unwrap().clone();
        cam.id = 12;
        cam.head = None;
        // Looks straight down from (9, 4): head 3's region (the scenario default would be the
        // first head, 2).
        cam.camera.as_mut().unwrap().pose = Some(PoseSpec::Rodrigues {
            rvec: [std::f64::consts::PI, 0.0, 0.0],
            tvec: [-9.0, 4.0, 3.0],
        });
        s.nodes.push(cam);
        let m = Membership::new(&s);
        assert_eq!(m.head_of(NodeId(12)), Some(NodeId(3)));
        assert_eq!(m.head_of(NodeId(10)), Some(NodeId(2)));
    }
}
