//! Where a real node's radio readings come from, as a scenario's node (`radio = "…"`) and
//! `ocelli camera --radio` name it: a BLE adapter through BlueZ, or a file of recorded readings
//! replayed at real time. The simulation ignores it: its nodes hear the simulated world.

use super::{Scenario, ScenarioError};
use crate::camera::{CameraModel, Distortion, Intrinsics, Pose};
use crate::ids::TagId;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use std::fmt;
use std::path::{Path, PathBuf};

/// A radio source, written `ble`, `ble:ADAPTER` or `file:PATH.mbd@SENSOR-MAC`.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub enum RadioSpec {
    /// BLE advertisements heard by a BlueZ adapter (`None`: the default adapter).
    Ble { adapter: Option<String> },
    /// Readings recorded in an `.mbd` file (`proto::sensor::mbd`), those of one sensor: the
    /// lines whose sensor MAC is `sensor`, replayed at real time from the node's epoch.
    File { path: PathBuf, sensor: TagId },
}

impl RadioSpec {
    /// Parse `ble`, `ble:ADAPTER` or `file:PATH@MAC` (the MAC with colons or bare).
    ///
    /// # Errors
    /// What was expected, naming the text.
    pub fn parse(s: &str) -> Result<RadioSpec, String> {
        if s == "ble" {
            return Ok(RadioSpec::Ble { adapter: None });
        }
        if let Some(a) = s.strip_prefix("ble:") {
            if a.is_empty() || a.contains(['/', ' ']) {
                return Err(format!(
                    "radio {s:?}: expected an adapter name such as `ble:hci0`"
                ));
            }
            return Ok(RadioSpec::Ble {
                adapter: Some(a.into()),
            });
        }
        if let Some(rest) = s.strip_prefix("file:") {
            let (path, mac) = rest.rsplit_once('@').ok_or_else(|| {
                format!("radio {s:?}: expected `file:PATH@SENSOR-MAC` (which sensor's readings)")
            })?;
            let sensor =
                TagId::parse_mac(mac).ok_or_else(|| format!("radio {s:?}: {mac:?} is not a MAC address"))?;
            if path.is_empty() {
                return Err(format!("radio {s:?}: no file"));
            }
            return Ok(RadioSpec::File {
                path: path.into(),
                sensor,
            });
        }
        Err(format!(
            "radio {s:?}: expected `ble`, `ble:ADAPTER` or `file:PATH.mbd@SENSOR-MAC`"
        ))
    }

    /// A file source's path made absolute against `base` (the scenario file's directory).
    pub fn resolved(self, base: &Path) -> RadioSpec {
        match self {
            RadioSpec::File { path, sensor } if path.is_relative() => RadioSpec::File {
                path: base.join(path),
                sensor,
            },
            other => other,
        }
    }
}

impl fmt::Display for RadioSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RadioSpec::Ble { adapter: None } => f.write_str("ble"),
            RadioSpec::Ble { adapter: Some(a) } => write!(f, "ble:{a}"),
            RadioSpec::File { path, sensor } => write!(f, "file:{}@{sensor}", path.display()),
        }
    }
}

impl TryFrom<String> for RadioSpec {
    type Error = String;
    fn try_from(s: String) -> Result<Self, String> {
        RadioSpec::parse(&s)
    }
}

impl From<RadioSpec> for String {
    fn from(r: RadioSpec) -> String {
        r.to_string()
    }
}

impl Scenario {
    /// Node `id`'s camera model, or for a radio-only node (a camera node without camera
    /// geometry) a [`blind_camera`] at its `position`: tables indexed by node keep one shape,
    /// and the cores never use it (such a node gets no frames, and heads expect no camera
    /// information from it).
    ///
    /// # Errors
    /// The node does not exist, or its camera geometry (or position) cannot be used.
    pub fn camera_or_blind(&self, id: u32) -> Result<CameraModel, ScenarioError> {
        match self.node(id) {
            Some(n) if n.radio_only() => Ok(blind_camera(self.sensor_position(id)?)),
            _ => self.camera_model(id),
        }
    }
}

/// A camera at `position` that sees nothing: it looks straight up through a one-pixel image
/// with a field of view of a microradian.
pub fn blind_camera(position: Vector3<f64>) -> CameraModel {
    let pose = Pose::look_at(position, position + Vector3::z(), Vector3::x()).unwrap_or(Pose {
        rotation: nalgebra::Rotation3::identity(),
        translation: -position,
    });
    CameraModel {
        intrinsics: Intrinsics {
            fx: 1e6,
            fy: 1e6,
            cx: 0.5,
            cy: 0.5,
            width: 1,
            height: 1,
        },
        distortion: Distortion::default(),
        pose,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn specs_parse_print_and_resolve() {
        for s in ["ble", "ble:hci1", "file:trk/a.mbd@b8:27:eb:45:21:b4"] {
            assert_eq!(RadioSpec::parse(s).unwrap().to_string(), s);
        }
        let bare = RadioSpec::parse("file:x@b827eb4521b4").unwrap();
        assert_eq!(
            bare,
            RadioSpec::File {
                path: "x".into(),
                sensor: TagId(0xb827_eb45_21b4)
            }
        );
        // A path may hold `@` and `:`; the MAC is after the last `@`.
        let odd = RadioSpec::parse("file:/d:1/a@b.mbd@000000000101").unwrap();
        assert!(matches!(&odd, RadioSpec::File { path, .. } if path == Path::new("/d:1/a@b.mbd")));
        assert_eq!(
            bare.resolved(Path::new("/base")).to_string(),
            "file:/base/x@b8:27:eb:45:21:b4"
        );
        for bad in [
            "",
            "bluetooth",
            "ble:",
            "file:x.mbd",
            "file:x@zz",
            "file:@000000000101",
        ] {
            assert!(RadioSpec::parse(bad).is_err(), "{bad:?}");
        }
    }

    #[test]
    fn a_blind_camera_sits_at_its_position_and_sees_nothing_around_it() {
        let at = Vector3::new(7.0, 7.09, 1.22);
        let cam = blind_camera(at);
        assert!((cam.pose.centre() - at).norm() < 1e-12);
        for p in [
            [7.0, 7.09, 0.0],
            [9.0, 3.0, 1.8],
            [7.5, 7.09, 3.0],
            [0.0, 0.0, 2.3],
        ] {
            assert!(
                cam.project(&Vector3::from(p))
                    .is_none_or(|px| { px.x < 0.0 || px.y < 0.0 || px.x > 1.0 || px.y > 1.0 }),
                "{p:?} seen"
            );
        }
    }
}
