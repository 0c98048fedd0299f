//! The Foxglove well-known messages the MCAP export writes, as JSON (`message encoding json`,
//! `schema encoding jsonschema`), with JSON Schemas written here for the fields we use.
//! Foxglove Studio recognises a message kind by its schema name (`foxglove.SceneUpdate`, ...).

use serde::Serialize;
use serde_json::{Value, json};

#[derive(Clone, Copy, Debug, Serialize)]
pub struct Time {
    pub sec: u32,
    pub nsec: u32,
}

impl Time {
    /// From nanoseconds since the epoch (negative times clamp to 0).
    pub fn from_ns(ns: i64) -> Time {
        let ns = ns.max(0);
        Time {
            sec: u32::try_from(ns / 1_000_000_000).unwrap_or(u32::MAX),
            nsec: u32::try_from(ns % 1_000_000_000).unwrap_or(0),
        }
    }
}

#[derive(Clone, Copy, Debug, Serialize)]
pub struct Duration {
    pub sec: i32,
    pub nsec: u32,
}

#[derive(Clone, Copy, Debug, Serialize)]
pub struct Vector3 {
    pub x: f64,
    pub y: f64,
    pub z: f64,
}

pub fn v3(p: [f64; 3]) -> Vector3 {
    Vector3 {
        x: p[0],
        y: p[1],
        z: p[2],
    }
}

#[derive(Clone, Copy, Debug, Serialize)]
pub struct Quaternion {
    pub x: f64,
    pub y: f64,
    pub z: f64,
    pub w: f64,
}

pub const IDENTITY: Quaternion = Quaternion {
    x: 0.0,
    y: 0.0,
    z: 0.0,
    w: 1.0,
};

/// A rotation about z by `yaw` radians.
pub fn yaw(yaw: f64) -> Quaternion {
    let (s, c) = (0.5 * yaw).sin_cos();
    Quaternion {
        x: 0.0,
        y: 0.0,
        z: s,
        w: c,
    }
}

#[derive(Clone, Copy, Debug, Serialize)]
pub struct Pose {
    pub position: Vector3,
    pub orientation: Quaternion,
}

pub fn at(p: [f64; 3]) -> Pose {
    Pose {
        position: v3(p),
        orientation: IDENTITY,
    }
}

#[derive(Clone, Copy, Debug, Serialize)]
pub struct Color {
    pub r: f64,
    pub g: f64,
    pub b: f64,
    pub a: f64,
}

pub const fn rgba(r: f64, g: f64, b: f64, a: f64) -> Color {
    Color { r, g, b, a }
}

/// `type`: 0 line strip, 1 line loop, 2 line list.
#[derive(Clone, Debug, Serialize)]
pub struct LinePrimitive {
    #[serde(rename = "type")]
    pub kind: u8,
    pub pose: Pose,
    pub thickness: f64,
    pub scale_invariant: bool,
    pub points: Vec<Vector3>,
    pub color: Color,
    pub colors: Vec<Color>,
    pub indices: Vec<u32>,
}

pub const LINE_STRIP: u8 = 0;
pub const LINE_LOOP: u8 = 1;
pub const LINE_LIST: u8 = 2;

pub fn line(kind: u8, points: Vec<Vector3>, thickness: f64, color: Color) -> LinePrimitive {
    LinePrimitive {
        kind,
        pose: at([0.0; 3]),
        thickness,
        scale_invariant: true,
        points,
        color,
        colors: Vec::new(),
        indices: Vec::new(),
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct CubePrimitive {
    pub pose: Pose,
    pub size: Vector3,
    pub color: Color,
}

#[derive(Clone, Debug, Serialize)]
pub struct CylinderPrimitive {
    pub pose: Pose,
    pub size: Vector3,
    pub bottom_scale: f64,
    pub top_scale: f64,
    pub color: Color,
}

#[derive(Clone, Debug, Serialize)]
pub struct TextPrimitive {
    pub pose: Pose,
    pub billboard: bool,
    pub font_size: f64,
    pub scale_invariant: bool,
    pub color: Color,
    pub text: String,
}

pub fn label(p: [f64; 3], text: String) -> TextPrimitive {
    TextPrimitive {
        pose: at(p),
        billboard: true,
        font_size: 14.0,
        scale_invariant: true,
        color: rgba(1.0, 1.0, 1.0, 1.0),
        text,
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct KeyValuePair {
    pub key: String,
    pub value: String,
}

#[derive(Clone, Debug, Serialize)]
pub struct SceneEntity {
    pub timestamp: Time,
    pub frame_id: String,
    pub id: String,
    pub lifetime: Duration,
    pub frame_locked: bool,
    pub metadata: Vec<KeyValuePair>,
    pub arrows: Vec<Value>,
    pub cubes: Vec<CubePrimitive>,
    pub spheres: Vec<Value>,
    pub cylinders: Vec<CylinderPrimitive>,
    pub lines: Vec<LinePrimitive>,
    pub triangles: Vec<Value>,
    pub texts: Vec<TextPrimitive>,
    pub models: Vec<Value>,
}

impl SceneEntity {
    /// An empty entity in the world frame that stays until replaced or deleted.
    pub fn new(id: String, ns: i64) -> SceneEntity {
        SceneEntity {
            timestamp: Time::from_ns(ns),
            frame_id: "world".into(),
            id,
            lifetime: Duration { sec: 0, nsec: 0 },
            frame_locked: false,
            metadata: Vec::new(),
            arrows: Vec::new(),
            cubes: Vec::new(),
            spheres: Vec::new(),
            cylinders: Vec::new(),
            lines: Vec::new(),
            triangles: Vec::new(),
            texts: Vec::new(),
            models: Vec::new(),
        }
    }
}

/// `type`: 0 the entity with `id`, 1 every entity of the topic.
#[derive(Clone, Debug, Serialize)]
pub struct SceneEntityDeletion {
    pub timestamp: Time,
    #[serde(rename = "type")]
    pub kind: u8,
    pub id: String,
}

#[derive(Clone, Debug, Default, Serialize)]
pub struct SceneUpdate {
    pub deletions: Vec<SceneEntityDeletion>,
    pub entities: Vec<SceneEntity>,
}

#[derive(Clone, Debug, Serialize)]
pub struct FrameTransform {
    pub timestamp: Time,
    pub parent_frame_id: String,
    pub child_frame_id: String,
    pub translation: Vector3,
    pub rotation: Quaternion,
}

/// `position_covariance_type`: 0 unknown, 1 approximated, 2 diagonal known, 3 known.
#[derive(Clone, Debug, Serialize)]
pub struct LocationFix {
    pub timestamp: Time,
    pub frame_id: String,
    pub latitude: f64,
    pub longitude: f64,
    pub altitude: f64,
    pub position_covariance: [f64; 9],
    pub position_covariance_type: u8,
}

// ------------------------------------------------------------------ JSON Schemas

fn num() -> Value {
    json!({"type": "number"})
}

fn int() -> Value {
    json!({"type": "integer"})
}

fn obj(title: &str, props: &[(&str, Value)]) -> Value {
    let properties: serde_json::Map<String, Value> =
        props.iter().map(|(k, v)| ((*k).to_string(), v.clone())).collect();
    let required: Vec<&str> = props.iter().map(|(k, _)| *k).collect();
    json!({"title": title, "type": "object", "properties": properties, "required": required})
}

fn arr(items: Value) -> Value {
    json!({"type": "array", "items": items})
}

fn time() -> Value {
    obj("time", &[("sec", int()), ("nsec", int())])
}

fn xyz(title: &str) -> Value {
    obj(title, &[("x", num()), ("y", num()), ("z", num())])
}

fn quaternion() -> Value {
    obj(
        "foxglove.Quaternion",
        &[("x", num()), ("y", num()), ("z", num()), ("w", num())],
    )
}

fn pose() -> Value {
    obj(
        "foxglove.Pose",
        &[
            ("position", xyz("foxglove.Vector3")),
            ("orientation", quaternion()),
        ],
    )
}

fn color() -> Value {
    obj(
        "foxglove.Color",
        &[("r", num()), ("g", num()), ("b", num()), ("a", num())],
    )
}

/// The schema of `foxglove.SceneUpdate` (the primitives this export uses; the others are
/// arrays it leaves empty).
pub fn scene_update_schema() -> Value {
    let bool_ = json!({"type": "boolean"});
    let string = json!({"type": "string"});
    let line = obj(
        "foxglove.LinePrimitive",
        &[
            ("type", int()),
            ("pose", pose()),
            ("thickness", num()),
            ("scale_invariant", bool_.clone()),
            ("points", arr(xyz("foxglove.Point3"))),
            ("color", color()),
            ("colors", arr(color())),
            ("indices", arr(int())),
        ],
    );
    let cube = obj(
        "foxglove.CubePrimitive",
        &[
            ("pose", pose()),
            ("size", xyz("foxglove.Vector3")),
            ("color", color()),
        ],
    );
    let cylinder = obj(
        "foxglove.CylinderPrimitive",
        &[
            ("pose", pose()),
            ("size", xyz("foxglove.Vector3")),
            ("bottom_scale", num()),
            ("top_scale", num()),
            ("color", color()),
        ],
    );
    let text = obj(
        "foxglove.TextPrimitive",
        &[
            ("pose", pose()),
            ("billboard", bool_.clone()),
            ("font_size", num()),
            ("scale_invariant", bool_.clone()),
            ("color", color()),
            ("text", string.clone()),
        ],
    );
    let entity = obj(
        "foxglove.SceneEntity",
        &[
            ("timestamp", time()),
            ("frame_id", string.clone()),
            ("id", string.clone()),
            ("lifetime", obj("duration", &[("sec", int()), ("nsec", int())])),
            ("frame_locked", bool_),
            (
                "metadata",
                arr(obj(
                    "foxglove.KeyValuePair",
                    &[("key", string.clone()), ("value", string.clone())],
                )),
            ),
            ("arrows", arr(json!({"type": "object"}))),
            ("cubes", arr(cube)),
            ("spheres", arr(json!({"type": "object"}))),
            ("cylinders", arr(cylinder)),
            ("lines", arr(line)),
            ("triangles", arr(json!({"type": "object"}))),
            ("texts", arr(text)),
            ("models", arr(json!({"type": "object"}))),
        ],
    );
    let deletion = obj(
        "foxglove.SceneEntityDeletion",
        &[("timestamp", time()), ("type", int()), ("id", string)],
    );
    obj(
        "foxglove.SceneUpdate",
        &[("deletions", arr(deletion)), ("entities", arr(entity))],
    )
}

pub fn frame_transform_schema() -> Value {
    let string = json!({"type": "string"});
    obj(
        "foxglove.FrameTransform",
        &[
            ("timestamp", time()),
            ("parent_frame_id", string.clone()),
            ("child_frame_id", string),
            ("translation", xyz("foxglove.Vector3")),
            ("rotation", quaternion()),
        ],
    )
}

pub fn location_fix_schema() -> Value {
    obj(
        "foxglove.LocationFix",
        &[
            ("timestamp", time()),
            ("frame_id", json!({"type": "string"})),
            ("latitude", num()),
            ("longitude", num()),
            ("altitude", num()),
            (
                "position_covariance",
                json!({"type": "array", "items": {"type": "number"}, "minItems": 9, "maxItems": 9}),
            ),
            ("position_covariance_type", int()),
        ],
    )
}

/// Ocelli's own JSON channels: a node's status, a handover.
pub fn node_status_schema() -> Value {
    json!({
        "title": "ocelli.NodeStatus",
        "description": "A node's liveness, mode and health as the server saw it",
        "type": "object",
        "properties": {
            "timestamp": time(),
            "node": int(), "role": {"type": "string"}, "up": {"type": "boolean"},
            "stale": {"type": "boolean"}, "mode": {"type": ["string", "null"]},
            "head": {"type": ["integer", "null"]},
            "health": {"type": "object"}
        },
        "required": ["timestamp", "node", "up"]
    })
}

pub fn handover_schema() -> Value {
    json!({
        "title": "ocelli.Handover",
        "description": "A global track moving to another head",
        "type": "object",
        "properties": {
            "timestamp": time(), "global": int(), "from": {"type": ["integer", "null"]},
            "to": int(), "reason": {"type": "string"}
        },
        "required": ["timestamp", "global", "to", "reason"]
    })
}
