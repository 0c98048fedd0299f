//! The view model: everything the pages, the metrics and the exports show, built from the
//! server's recording records ([`ViewState::apply`]) — live, from records as the server makes
//! them, or from a recording played back.
//!
//! The model follows the server's own bookkeeping through its decisions: a head's local track
//! is bound to a global id by `NewGlobal`, `Claimed`, `Merged` and `Split`, owned by the head
//! `NewGlobal`, `Split`, `Handover` and `OwnerChanged` name, and removed by `Absorbed` and
//! `Lost`. A global track's position is its owner's latest report, as the server's posterior
//! is. Since the server records a report before the decisions it causes, the latest report of
//! every local track is kept and applied when a decision binds it or hands its global to its
//! head. Node health comes from `NodeStatus` (mode, sync, drops, rejected), track reports
//! (late contributions, steps), the server's `Rejected` decisions and gaps in each sender's
//! sequence numbers (frames lost on the way to the server).
//!
//! Serialized as JSON for the pages and `/api/state`: `{"time", "nodes": [...], "tracks":
//! [...], ...}`; the bookkeeping that only [`ViewState::apply`] needs is not serialized.

use crate::geo::Geo;
use crate::geometry::{CameraGeometry, Ellipse};
use proto::Mode;
use proto::msg::TrackReport;
use proto::scenario::{NodeRole, Scenario};
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, VecDeque};
use std::sync::Arc;

mod apply;
mod live;
#[cfg(test)]
mod tests;

pub use apply::Change;
pub use live::kind_of;

/// How much trail each track keeps, ns.
pub const TRAIL_NS: i64 = 10_000_000_000;
/// A node that is up but has not been heard from for this long is stale, ns.
pub const STALE_NS: i64 = 3_000_000_000;
/// Handovers kept for the pages.
pub const RECENT_HANDOVERS: usize = 20;
/// Distinct problems kept (the oldest is dropped first).
pub const MAX_PROBLEMS: usize = 20;

/// The whole view.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ViewState {
    /// The scenario's name (empty until a scenario is known).
    pub scenario: String,
    /// The newest record's server time, seconds and nanoseconds (cluster time: since the Unix
    /// epoch for a launched cluster, since the start for a simulation).
    pub time: f64,
    pub time_ns: i64,
    /// The filter's step period, ms (the rate the pages are updated at).
    pub step_ms: u64,
    pub world: WorldView,
    /// Where the world is on Earth, if the scenario says.
    pub geo: Option<Geo>,
    #[serde(with = "as_list")]
    pub nodes: BTreeMap<u32, NodeView>,
    #[serde(with = "as_list")]
    pub tracks: BTreeMap<u32, TrackView>,
    /// The latest handovers and owner changes, oldest first.
    pub handovers: VecDeque<HandoverView>,
    pub totals: Totals,
    /// What is wrong with the input (a scenario that does not parse, undecodable records, a
    /// torn recording, refused nodes), oldest first.
    pub problems: VecDeque<Problem>,
    #[serde(skip)]
    book: Bookkeeping,
}

/// The room.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct WorldView {
    /// Bounds `[x, y, z]`, metres; z = 0 is the floor.
    pub min: [f64; 3],
    pub max: [f64; 3],
    pub walls: Vec<WallView>,
}

/// A wall from the floor to `height`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct WallView {
    pub from: [f64; 2],
    pub to: [f64; 2],
    pub height: f64,
}

/// What a node is.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NodeKind {
    Camera,
    Head,
    Server,
    /// A two-microphone acoustic node (paper 001).
    Acoustic,
    /// A visualization node.
    Viewer,
    /// Heard from but not in the scenario (yet).
    #[default]
    Unknown,
}

/// One node.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct NodeView {
    pub id: u32,
    pub role: NodeKind,
    /// The server counts it as up (admitted and not marked down).
    pub up: bool,
    /// Up, but nothing heard from it for [`STALE_NS`].
    pub stale: bool,
    /// Server time of its last message, ns.
    pub last_heard_ns: Option<i64>,
    /// A camera's sensing mode, from its latest status.
    pub mode: Option<Mode>,
    /// A camera's head.
    pub head: Option<u32>,
    /// A head's region `[xmin, ymin, xmax, ymax]`.
    pub region: Option<[f64; 4]>,
    /// A camera's field of view (shared between copies of the state: it never changes).
    #[serde(with = "shared")]
    pub camera: Option<Arc<CameraGeometry>>,
    pub health: Health,
}

/// A node's health.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Health {
    /// Its clock's error and offset to the server's, ms, once synchronized.
    pub sync_error_ms: Option<f64>,
    pub sync_offset_ms: Option<f64>,
    /// Messages it could not deliver (its own count).
    pub dropped: u64,
    /// Frames it received and rejected (its own count).
    pub rejected: u64,
    /// Its messages the server rejected.
    pub rejected_by_server: u64,
    /// A head's contributions that arrived after their step's deadline (cumulative).
    pub late: u64,
    /// Its frames that never reached the server (gaps in its sequence numbers).
    pub lost: u64,
    /// A camera's frames and detections; a head's last filter step.
    pub frames: u64,
    pub detections: u64,
    pub steps: u64,
}

/// One global track.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TrackView {
    /// The global id.
    pub global: u32,
    /// The head that owns it, and that head's local id for it.
    pub owner: u32,
    pub local: u32,
    /// Time of the estimate (the owner's clock), ns.
    pub time_ns: i64,
    /// Server time of the last update, ns.
    pub updated_ns: i64,
    /// Position and velocity, m and m/s.
    pub position: [f64; 3],
    pub velocity: [f64; 3],
    /// Floor position covariance `[σxx, σxy, σyy]`, m².
    pub cov_xy: [f64; 3],
    /// √ trace of the 3-D position covariance, m.
    pub sigma_m: f64,
    /// The 2σ floor ellipse (none for a covariance that is not positive semi-definite).
    pub ellipse: Option<Ellipse>,
    /// Height of the target, m, if known. Reports carry no measured height: it is taken as
    /// twice the tracked centre's z (cameras measure the region's centre) when that is between
    /// 0.05 and 1.5 m, else unknown.
    pub height_m: Option<f64>,
    /// Nodes whose camera measurement / RSSI reading went into the estimate.
    pub cameras: Vec<u32>,
    pub rssi: Vec<u32>,
    /// `[server time s, x, y]` over the last [`TRAIL_NS`], oldest first.
    pub trail: VecDeque<[f64; 3]>,
}

/// A track moving from one head to another.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HandoverView {
    /// Increases by one per handover: the pages flash the ones they have not seen.
    pub seq: u64,
    pub time: f64,
    pub global: u32,
    pub from: Option<u32>,
    pub to: u32,
    /// `region`, `failover` or `owner_changed`.
    pub reason: String,
    /// Where the track was, if known.
    pub position: Option<[f64; 2]>,
}

/// Counts over everything applied.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Totals {
    pub records: u64,
    pub received: u64,
    pub decisions: u64,
    /// Inputs the server rejected.
    pub rejected: u64,
    pub handovers: u64,
    /// Filter steps, summed over heads (each head's last step number).
    pub steps: u64,
    /// Records that could not be read (another build or protocol version).
    pub undecodable: u64,
}

/// Something wrong with the input, with how often it happened.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Problem {
    pub text: String,
    pub count: u64,
    pub last_ns: i64,
}

/// What only [`ViewState::apply`] needs.
#[derive(Clone, Debug, Default, PartialEq)]
struct Bookkeeping {
    /// `(head, local)` → global.
    bindings: BTreeMap<(u32, u32), u32>,
    /// The latest report of each local track, with its server time.
    latest: BTreeMap<(u32, u32), (i64, TrackReport)>,
    /// The last sequence number from each sender.
    last_seq: BTreeMap<u32, u64>,
    handover_seq: u64,
    /// The live feed's round being received.
    round: live::Round,
}

impl ViewState {
    /// An empty view; a `Scenario` record (or [`ViewState::set_scenario`]) fills in the site.
    pub fn new() -> Self {
        ViewState::default()
    }

    /// The view of a scenario before anything happened.
    pub fn with_scenario(scenario: &Scenario) -> Self {
        let mut v = ViewState::new();
        v.set_scenario(scenario);
        v
    }

    /// Take the site from a scenario: the room, walls, every node with its role, a camera's
    /// field of view, a head's region. What was learnt about the nodes so far is kept.
    pub fn set_scenario(&mut self, sc: &Scenario) {
        self.scenario = sc.name.clone();
        if sc.world.geo.is_some() {
            self.geo = sc.world.geo;
        }
        self.step_ms = sc.method.step_ms;
        self.world = WorldView {
            min: sc.world.min,
            max: sc.world.max,
            walls: sc
                .world
                .walls
                .iter()
                .map(|w| WallView {
                    from: w.from,
                    to: w.to,
                    height: w.height,
                })
                .collect(),
        };
        let clusters = sc.clusters();
        let mut problems = Vec::new();
        for spec in &sc.nodes {
            let node = self.nodes.entry(spec.id).or_insert_with(|| NodeView {
                id: spec.id,
                ..NodeView::default()
            });
            node.role = match spec.role {
                NodeRole::Camera => NodeKind::Camera,
                NodeRole::Head => NodeKind::Head,
                NodeRole::Server => NodeKind::Server,
                NodeRole::Acoustic => NodeKind::Acoustic,
            };
            node.region = spec.region;
            if spec.role == NodeRole::Server {
                node.up = true; // the server is the one recording
            }
            if spec.role == NodeRole::Camera {
                node.head = node.head.or_else(|| {
                    clusters
                        .iter()
                        .find(|(_, cams)| cams.iter().any(|c| c.0 == spec.id))
                        .map(|(h, _)| h.0)
                });
                match sc.camera_model(spec.id) {
                    Ok(model) => {
                        node.camera = Some(Arc::new(CameraGeometry::new(&model, sc.world.min, sc.world.max)))
                    }
                    Err(e) => problems.push(format!("camera {}: no field of view: {e}", spec.id)),
                }
            }
        }
        for text in problems {
            self.note_problem(self.time_ns, text);
        }
    }

    /// Set or clear where the site is on Earth.
    pub fn set_geo(&mut self, geo: Option<Geo>) {
        self.geo = geo;
    }

    /// Record a problem with the input (repeats are counted, not listed again).
    pub fn note_problem(&mut self, at_ns: i64, text: String) {
        if let Some(p) = self.problems.iter_mut().find(|p| p.text == text) {
            p.count += 1;
            p.last_ns = at_ns;
            return;
        }
        if self.problems.len() >= MAX_PROBLEMS {
            self.problems.pop_front();
        }
        self.problems.push_back(Problem {
            text,
            count: 1,
            last_ns: at_ns,
        });
    }

    /// Move the view's clock forward to `at_ns` (never back): trails older than [`TRAIL_NS`]
    /// are cut and nodes not heard from for [`STALE_NS`] become stale.
    pub fn advance(&mut self, at_ns: i64) {
        if at_ns < self.time_ns {
            return;
        }
        self.time_ns = at_ns;
        self.time = self.time_ns as f64 * 1e-9;
        let cut = (self.time_ns.saturating_sub(TRAIL_NS)) as f64 * 1e-9;
        for t in self.tracks.values_mut() {
            while t.trail.front().is_some_and(|p| p[0] < cut) {
                t.trail.pop_front();
            }
        }
        for n in self.nodes.values_mut() {
            n.stale = n.up
                && n.role != NodeKind::Server
                && n.last_heard_ns
                    .is_none_or(|h| self.time_ns.saturating_sub(h) > STALE_NS);
        }
    }

    /// Nodes of a kind, by id.
    pub fn nodes_of(&self, kind: NodeKind) -> impl Iterator<Item = &NodeView> {
        self.nodes.values().filter(move |n| n.role == kind)
    }
}

/// A shared value serializes as the value (serde's `rc` feature would do the same, but turning
/// it on rebuilds serde and everything above it for the whole workspace).
mod shared {
    use serde::{Deserialize, Deserializer, Serialize, Serializer};
    use std::sync::Arc;

    pub fn serialize<S: Serializer, T: Serialize>(v: &Option<Arc<T>>, s: S) -> Result<S::Ok, S::Error> {
        v.as_deref().serialize(s)
    }

    pub fn deserialize<'de, D, T>(d: D) -> Result<Option<Arc<T>>, D::Error>
    where
        D: Deserializer<'de>,
        T: Deserialize<'de>,
    {
        Ok(Option::<T>::deserialize(d)?.map(Arc::new))
    }
}

/// Maps keyed by id serialize as the list of their values (the id is in each value).
mod as_list {
    use serde::{Deserialize, Deserializer, Serialize, Serializer};
    use std::collections::BTreeMap;

    pub trait Keyed {
        fn key(&self) -> u32;
    }

    impl Keyed for super::NodeView {
        fn key(&self) -> u32 {
            self.id
        }
    }

    impl Keyed for super::TrackView {
        fn key(&self) -> u32 {
            self.global
        }
    }

    pub fn serialize<S: Serializer, V: Serialize>(map: &BTreeMap<u32, V>, s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(map.values())
    }

    pub fn deserialize<'de, D, V>(d: D) -> Result<BTreeMap<u32, V>, D::Error>
    where
        D: Deserializer<'de>,
        V: Deserialize<'de> + Keyed,
    {
        let list = Vec::<V>::deserialize(d)?;
        Ok(list.into_iter().map(|v| (v.key(), v)).collect())
    }
}
