//! `ocelli export REC --format mcap`: a recording as an MCAP file that Foxglove Studio opens,
//! written with Foxglove's `mcap` crate in Foxglove's well-known JSON schemas.
//!
//! | topic | schema | messages |
//! |---|---|---|
//! | `/scene/room` | `foxglove.SceneUpdate` | the room's outline and walls, once |
//! | `/scene/cameras` | `foxglove.SceneUpdate` | each camera's frustum and id, coloured by mode (green Active, amber CameraOff, grey Inactive, red down): at the start and whenever that changes |
//! | `/scene/tracks` | `foxglove.SceneUpdate` | each track as an upright cylinder with its height, its global id, its 2σ ellipse and 10 s trail, at every owner report; a deletion when it is lost |
//! | `/tf` | `foxglove.FrameTransform` | `world` → `camera_<id>` (the pose) at the start, `world` → `track_<id>` at every report |
//! | `/location` | `foxglove.LocationFix` | each track in WGS84 at every report (only with `[world.geo]`) |
//! | `/ocelli/node_status` | `ocelli.NodeStatus` (JSON) | a node's liveness, mode and health whenever it changes |
//! | `/ocelli/handover` | `ocelli.Handover` (JSON) | every handover and owner change |
//!
//! Messages are stamped with the server's record time. The view is rebuilt record by record
//! ([`ViewState::apply`]) and a message is written for what each record changed. Chunks are
//! not compressed (the crate is built without zstd and lz4, which need C libraries on the Pi).

use crate::geo::Geo;
use crate::state::{Change, NodeKind, NodeView, TrackView, ViewState};
use ::mcap::records::MessageHeader;
use ::mcap::{McapError, WriteOptions, Writer};
use foxglove::*;
use node_server::analysis::Loaded;
use proto::Mode;
use serde::Serialize;
use std::collections::BTreeMap;
use std::io::{Seek, Write};
use thiserror::Error;

pub mod foxglove;

/// Topics.
pub const ROOM: &str = "/scene/room";
pub const CAMERAS: &str = "/scene/cameras";
pub const TRACKS: &str = "/scene/tracks";
pub const TF: &str = "/tf";
pub const LOCATION: &str = "/location";
pub const NODE_STATUS: &str = "/ocelli/node_status";
pub const HANDOVER: &str = "/ocelli/handover";

/// Why the MCAP file could not be written.
#[derive(Debug, Error)]
pub enum McapExportError {
    #[error("writing MCAP: {0}")]
    Mcap(#[from] McapError),
    #[error("encoding a message: {0}")]
    Json(#[from] serde_json::Error),
    #[error(transparent)]
    Geo(#[from] crate::geo::GeoError),
}

/// Messages written per topic.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct McapSummary {
    pub messages: BTreeMap<&'static str, u64>,
}

struct Out<W: Write + Seek> {
    writer: Writer<W>,
    channels: BTreeMap<&'static str, u16>,
    counts: BTreeMap<&'static str, u64>,
}

impl<W: Write + Seek> Out<W> {
    fn channel(
        &mut self,
        topic: &'static str,
        schema: &str,
        body: &serde_json::Value,
    ) -> Result<(), McapExportError> {
        let data = serde_json::to_vec(body)?;
        let schema_id = self.writer.add_schema(schema, "jsonschema", &data)?;
        let id = self
            .writer
            .add_channel(schema_id, topic, "json", &BTreeMap::new())?;
        self.channels.insert(topic, id);
        Ok(())
    }

    fn write(&mut self, topic: &'static str, ns: i64, msg: &impl Serialize) -> Result<(), McapExportError> {
        let Some(&channel_id) = self.channels.get(topic) else {
            return Ok(());
        };
        let count = self.counts.entry(topic).or_insert(0);
        *count += 1;
        let t = u64::try_from(ns.max(0)).unwrap_or(0);
        let header = MessageHeader {
            channel_id,
            sequence: u32::try_from(*count).unwrap_or(u32::MAX),
            log_time: t,
            publish_time: t,
        };
        self.writer
            .write_to_known_channel(&header, &serde_json::to_vec(msg)?)?;
        Ok(())
    }
}

const ACTIVE: Color = rgba(0.24, 0.71, 0.24, 1.0);
const CAMERA_OFF: Color = rgba(1.0, 0.65, 0.0, 1.0);
const INACTIVE: Color = rgba(0.56, 0.56, 0.56, 1.0);
const DOWN: Color = rgba(0.88, 0.13, 0.13, 1.0);
const TRACK: Color = rgba(1.0, 0.42, 0.16, 0.9);
const WALL: Color = rgba(0.55, 0.6, 0.7, 0.8);

fn room(s: &ViewState, ns: i64) -> SceneUpdate {
    let (lo, hi) = (s.world.min, s.world.max);
    let mut e = SceneEntity::new("room".into(), ns);
    let c = [[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]];
    let mut edges = Vec::new();
    for i in 0..4 {
        let (a, b) = (c[i], c[(i + 1) % 4]);
        for z in [lo[2], hi[2]] {
            edges.push(v3([a[0], a[1], z]));
            edges.push(v3([b[0], b[1], z]));
        }
        edges.push(v3([a[0], a[1], lo[2]]));
        edges.push(v3([a[0], a[1], hi[2]]));
    }
    e.lines
        .push(line(LINE_LIST, edges, 2.0, rgba(0.7, 0.7, 0.8, 0.6)));
    for w in &s.world.walls {
        let (dx, dy) = (w.to[0] - w.from[0], w.to[1] - w.from[1]);
        e.cubes.push(CubePrimitive {
            pose: Pose {
                position: v3([
                    (w.from[0] + w.to[0]) / 2.0,
                    (w.from[1] + w.to[1]) / 2.0,
                    w.height / 2.0,
                ]),
                orientation: yaw(dy.atan2(dx)),
            },
            size: v3([dx.hypot(dy), 0.1, w.height]),
            color: WALL,
        });
    }
    SceneUpdate {
        deletions: Vec::new(),
        entities: vec![e],
    }
}

/// How a camera is drawn; a new message is written when it changes.
fn camera_look(n: &NodeView) -> (bool, bool, Option<Mode>) {
    (n.up, n.stale, n.mode)
}

fn camera_entity(n: &NodeView, ns: i64) -> Option<SceneEntity> {
    let cam = n.camera.as_ref()?;
    let color = match (n.up, n.mode) {
        (false, _) => DOWN,
        (true, Some(Mode::CameraOff)) => CAMERA_OFF,
        (true, Some(Mode::Inactive)) => INACTIVE,
        (true, _) => ACTIVE,
    };
    let mut e = SceneEntity::new(format!("camera-{}", n.id), ns);
    let c = v3(cam.position);
    let mut pts = Vec::new();
    for (i, corner) in cam.frustum.iter().enumerate() {
        pts.push(c);
        pts.push(v3(*corner));
        pts.push(v3(*corner));
        pts.push(v3(cam.frustum[(i + 1) % 4]));
    }
    e.lines.push(line(LINE_LIST, pts, 1.5, color));
    e.texts.push(label(cam.position, format!("{}", n.id)));
    Some(e)
}

fn track_entity(t: &TrackView, ns: i64) -> SceneEntity {
    let mut e = SceneEntity::new(format!("track-{}", t.global), ns);
    let h = t.height_m.unwrap_or(1.7);
    let [x, y, _] = t.position;
    e.cylinders.push(CylinderPrimitive {
        pose: at([x, y, h / 2.0]),
        size: v3([0.45, 0.45, h]),
        bottom_scale: 1.0,
        top_scale: 1.0,
        color: TRACK,
    });
    e.texts.push(label([x, y, h + 0.3], format!("t{}", t.global)));
    if let Some(el) = t.ellipse {
        let (s, c) = el.angle.sin_cos();
        let ring = (0..32)
            .map(|i| {
                let a = f64::from(i) / 32.0 * std::f64::consts::TAU;
                let (u, v) = (el.semi_major * a.cos(), el.semi_minor * a.sin());
                v3([x + u * c - v * s, y + u * s + v * c, 0.02])
            })
            .collect();
        e.lines.push(line(LINE_LOOP, ring, 2.0, TRACK));
    }
    if t.trail.len() > 1 {
        let trail = t.trail.iter().map(|p| v3([p[1], p[2], 0.02])).collect();
        e.lines
            .push(line(LINE_STRIP, trail, 2.0, rgba(1.0, 0.42, 0.16, 0.5)));
    }
    e
}

/// A track's WGS84 fix with its floor covariance turned into east/north.
fn location(geo: &Geo, t: &TrackView, ns: i64) -> LocationFix {
    let g = geo.to_wgs84(t.position);
    let (s, c) = geo.heading_deg.to_radians().sin_cos();
    // east = c x + s y, north = −s x + c y: rotate the covariance by that matrix.
    let [xx, xy, yy] = t.cov_xy;
    let ee = c * c * xx + 2.0 * c * s * xy + s * s * yy;
    let nn = s * s * xx - 2.0 * c * s * xy + c * c * yy;
    let zz = (t.sigma_m * t.sigma_m - xx - yy).max(0.0);
    LocationFix {
        timestamp: Time::from_ns(ns),
        frame_id: format!("track_{}", t.global),
        latitude: g.lat,
        longitude: g.lon,
        altitude: g.alt,
        position_covariance: [ee, 0.0, 0.0, 0.0, nn, 0.0, 0.0, 0.0, zz],
        position_covariance_type: 2,
    }
}

#[derive(Serialize)]
struct NodeStatusMessage<'a> {
    timestamp: Time,
    node: u32,
    role: NodeKind,
    up: bool,
    stale: bool,
    mode: Option<Mode>,
    head: Option<u32>,
    health: &'a crate::state::Health,
}

#[derive(Serialize)]
struct HandoverMessage<'a> {
    timestamp: Time,
    global: u32,
    from: Option<u32>,
    to: u32,
    reason: &'a str,
}

fn transform(child: String, ns: i64, p: [f64; 3], q: Quaternion) -> FrameTransform {
    FrameTransform {
        timestamp: Time::from_ns(ns),
        parent_frame_id: "world".into(),
        child_frame_id: child,
        translation: v3(p),
        rotation: q,
    }
}

fn entities(entities: Vec<SceneEntity>) -> SceneUpdate {
    SceneUpdate {
        deletions: Vec::new(),
        entities,
    }
}

/// The view rebuilt record by record, and what has been drawn of it.
struct Export<'g, W: Write + Seek> {
    o: Out<W>,
    state: ViewState,
    looks: BTreeMap<u32, (bool, bool, Option<Mode>)>,
    geo: Option<&'g Geo>,
}

impl<W: Write + Seek> Export<'_, W> {
    /// The room, every camera and its pose, once the site is known.
    fn site(&mut self, ns: i64) -> Result<(), McapExportError> {
        self.o.write(ROOM, ns, &room(&self.state, ns))?;
        let mut update = SceneUpdate::default();
        for n in self.state.nodes.values() {
            update.entities.extend(camera_entity(n, ns));
            self.looks.insert(n.id, camera_look(n));
            if let Some(cam) = &n.camera {
                let [x, y, z, w] = cam.orientation;
                let q = Quaternion { x, y, z, w };
                self.o.write(
                    TF,
                    ns,
                    &transform(format!("camera_{}", n.id), ns, cam.position, q),
                )?;
            }
        }
        self.o.write(CAMERAS, ns, &update)
    }

    /// A node's status, and its camera again if it looks different now.
    fn node(&mut self, id: u32, ns: i64) -> Result<(), McapExportError> {
        let Some(n) = self.state.nodes.get(&id) else {
            return Ok(());
        };
        let msg = NodeStatusMessage {
            timestamp: Time::from_ns(ns),
            node: id,
            role: n.role,
            up: n.up,
            stale: n.stale,
            mode: n.mode,
            head: n.head,
            health: &n.health,
        };
        self.o.write(NODE_STATUS, ns, &msg)?;
        if self.looks.get(&id) != Some(&camera_look(n))
            && let Some(e) = camera_entity(n, ns)
        {
            self.looks.insert(id, camera_look(n));
            self.o.write(CAMERAS, ns, &entities(vec![e]))?;
        }
        Ok(())
    }

    /// A track's entity, frame and fix.
    fn track(&mut self, g: u32, ns: i64) -> Result<(), McapExportError> {
        let Some(t) = self.state.tracks.get(&g) else {
            return Ok(());
        };
        if t.updated_ns == 0 {
            return Ok(()); // owned, but no report seen yet
        }
        self.o.write(TRACKS, ns, &entities(vec![track_entity(t, ns)]))?;
        self.o
            .write(TF, ns, &transform(format!("track_{g}"), ns, t.position, IDENTITY))?;
        if let Some(geo) = self.geo {
            self.o.write(LOCATION, ns, &location(geo, t, ns))?;
        }
        Ok(())
    }

    fn change(&mut self, change: Change, ns: i64) -> Result<(), McapExportError> {
        match change {
            Change::Scenario => self.site(ns),
            Change::Node(id) => self.node(id, ns),
            Change::Track(g) => self.track(g, ns),
            Change::TrackRemoved(g) => {
                let deletion = SceneEntityDeletion {
                    timestamp: Time::from_ns(ns),
                    kind: 0,
                    id: format!("track-{g}"),
                };
                let update = SceneUpdate {
                    deletions: vec![deletion],
                    entities: Vec::new(),
                };
                self.o.write(TRACKS, ns, &update)
            }
            Change::Handover(seq) => {
                let Some(h) = self.state.handovers.iter().find(|h| h.seq == seq) else {
                    return Ok(());
                };
                let msg = HandoverMessage {
                    timestamp: Time::from_ns(ns),
                    global: h.global,
                    from: h.from,
                    to: h.to,
                    reason: &h.reason,
                };
                self.o.write(HANDOVER, ns, &msg)
            }
            Change::Problem => Ok(()),
        }
    }
}

/// Write a recording as MCAP; `geo` adds `/location`.
///
/// # Errors
/// IO errors of `out`; a `[world.geo]` that does not validate.
pub fn write_mcap<W: Write + Seek>(
    loaded: &Loaded,
    geo: Option<&Geo>,
    out: W,
) -> Result<McapSummary, McapExportError> {
    if let Some(g) = geo {
        g.validate()?;
    }
    let writer = WriteOptions::new().compression(None).profile("").create(out)?;
    let mut o = Out {
        writer,
        channels: BTreeMap::new(),
        counts: BTreeMap::new(),
    };
    let scene = scene_update_schema();
    o.channel(ROOM, "foxglove.SceneUpdate", &scene)?;
    o.channel(CAMERAS, "foxglove.SceneUpdate", &scene)?;
    o.channel(TRACKS, "foxglove.SceneUpdate", &scene)?;
    o.channel(TF, "foxglove.FrameTransform", &frame_transform_schema())?;
    if geo.is_some() {
        o.channel(LOCATION, "foxglove.LocationFix", &location_fix_schema())?;
    }
    o.channel(NODE_STATUS, "ocelli.NodeStatus", &node_status_schema())?;
    o.channel(HANDOVER, "ocelli.Handover", &handover_schema())?;
    let mut export = Export {
        o,
        state: ViewState::new(),
        looks: BTreeMap::new(),
        geo,
    };
    for s in &loaded.records {
        for change in export.state.apply(s) {
            export.change(change, s.at.0)?;
        }
    }
    export.o.writer.finish()?;
    Ok(McapSummary {
        messages: export.o.counts,
    })
}

#[cfg(test)]
mod tests;
