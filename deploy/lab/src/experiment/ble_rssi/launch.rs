//! The BLE dataset as a deployment: one radio-only node per sensor at its surveyed position,
//! replaying that sensor's packets of one trajectory at real time (`radio = "file:…@MAC"`), one
//! head over the room tracking from RSSI alone, a server. `ocelli launch` runs it as real
//! processes and scores its report against the file's positions (`sim::RecordedTruth`).
//!
//! The head's RSSI model is the log-distance law fitted on the *other* trajectories (as the
//! experiment's "fitted law (LOTO)" row), its target plane their mean beacon height: nothing
//! of the replayed trajectory's truth reaches a node.

use super::data::{Dataset, TRACK_SUFFIX};
use super::fold;
use crate::{LabError, Result};
use proto::scenario::Scenario;
use std::fmt::Write as _;

/// First node id of the sensors (server 1, head 2).
pub const FIRST_SENSOR_ID: u32 = 10;
/// How far the world reaches beyond the sensors, metres.
pub const WORLD_MARGIN_M: f64 = 3.0;
/// The head's step, ms: the experiment's 2 Hz.
pub const STEP_MS: u64 = 500;

/// The scenario replaying trajectory `i` of `ds` (TOML; file paths absolute).
///
/// # Errors
/// No such trajectory, or the other trajectories cannot be fitted.
pub fn scenario_toml(ds: &Dataset, i: usize) -> Result<String> {
    let traj = ds
        .trajectories
        .get(i)
        .ok_or_else(|| LabError::failed("the BLE launch scenario", format!("no trajectory {i}")))?;
    let (fit, height) = fold(ds, i).ok_or_else(|| {
        LabError::failed(
            "the BLE launch scenario",
            format!("no law fits the trajectories without {}", traj.name),
        )
    })?;
    let file = ds.dir.join("trk").join(format!("{}{TRACK_SUFFIX}", traj.name));
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for s in &ds.sensors {
        for a in 0..2 {
            lo[a] = lo[a].min(s.pos[a]);
            hi[a] = hi[a].max(s.pos[a]);
        }
    }
    // The beacon walks up to the sensors' walls; a track near them must not leave the world.
    let m = WORLD_MARGIN_M;
    let (min, max) = ([lo[0].min(0.0) - m, lo[1].min(0.0) - m], [hi[0] + m, hi[1] + m]);
    let mut t = String::new();
    let _ = write!(
        t,
        r#"name = "ble-rssi-{name}"
description = "The BLE RSSI dataset's {name} trajectory replayed by one radio-only node per sensor; RSSI-only tracking"

[world]
min = [{x0:.2}, {y0:.2}, 0.0]
max = [{x1:.2}, {y1:.2}, 3.0]

[network]
transport = "ipc"
domain = "ocelli-ble"
heartbeat-ms = 200
liveness-timeout-ms = 1000
sync-beacon-ms = 1000
queue-len = 256

[method]
fusion = "distributed-eif"
activation = "three-mode"
segmentation = "adaptive-background"
step-ms = {STEP_MS}
deadline-ms = 200
pixel-sigma = 18.0
rssi-window = 20
rssi-epsilon = 0.001
energy-weight = 0.0
previous-point = false
track-timeout-ms = 5000
gate-chi2 = 13.8
motion = {{ accel-psd = [0.25, 0.25, 0.01] }}
target-plane-z = {height:.3}
rssi-default = {{ kind = "log-distance", a = {a:.4}, b = {b:.4}, variance = {var:.4} }}

[power]
camera-mw = 650.0
node-active-mw = 69.0
node-low-power-mw = 7.2

[[nodes]]
id = 1
role = "server"
rssi = false

[[nodes]]
id = 2
role = "head"
region = [{x0:.2}, {y0:.2}, {x1:.2}, {y1:.2}]
"#,
        name = traj.name,
        x0 = min[0],
        y0 = min[1],
        x1 = max[0],
        y1 = max[1],
        a = fit.a,
        b = fit.b,
        var = fit.sd_db.powi(2),
    );
    for (k, s) in ds.sensors.iter().enumerate() {
        let _ = write!(
            t,
            r#"
# {alias}
[[nodes]]
id = {id}
role = "camera"
head = 2
position = [{x:.3}, {y:.3}, {z:.3}]
radio = "file:{file}@{mac}"
"#,
            alias = s.alias,
            id = FIRST_SENSOR_ID + k as u32,
            x = s.pos.x,
            y = s.pos.y,
            z = s.pos.z,
            file = file.display(),
            mac = s.mac,
        );
    }
    Ok(t)
}

/// [`scenario_toml`] parsed and checked.
///
/// # Errors
/// As [`scenario_toml`], or the scenario does not validate.
pub fn scenario(ds: &Dataset, i: usize) -> Result<Scenario> {
    let text = scenario_toml(ds, i)?;
    Ok(Scenario::from_toml(&text, "ble-rssi launch")?)
}

#[cfg(test)]
mod tests {
    use super::super::data;
    use super::*;

    /// Needs the shared dataset; fails loudly (naming the path) when it is absent.
    #[test]
    fn the_dataset_becomes_one_radio_only_node_per_sensor() {
        let ds = data::load(&data::default_dir()).expect("the BLE RSSI dataset (shared/datasets/ble-rssi)");
        let s = scenario(&ds, 0).unwrap();
        let nodes: Vec<_> = s.cameras().collect();
        assert_eq!(nodes.len(), ds.sensors.len());
        for (n, sensor) in nodes.iter().zip(&ds.sensors) {
            assert!(n.radio_only());
            assert_eq!(s.sensor_position(n.id).unwrap(), sensor.pos);
        }
        assert_eq!(s.clusters().len(), 1);
    }
}
