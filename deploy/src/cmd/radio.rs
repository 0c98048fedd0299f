//! A camera node's real radio, as `ocelli camera --radio SPEC` or the scenario's node
//! `radio = "…"` names it (`proto::scenario::RadioSpec`): recorded `.mbd` readings replayed at
//! real time from the launch's epoch, or a BlueZ adapter (feature `ble`).

use anyhow::Result;
use proto::ClusterTime;
use proto::scenario::RadioSpec;
use proto::sensor::RadioSource;
use runtime::HostClock;

/// Open the radio `spec` names; `epoch` is when a recorded file's first packet plays.
///
/// # Errors
/// The file cannot be read or holds no reading of the sensor; BLE in a build without it.
pub fn open(spec: &RadioSpec, clock: &HostClock, epoch: ClusterTime) -> Result<Box<dyn RadioSource + Send>> {
    match spec {
        RadioSpec::File { path, sensor } => Ok(Box::new(node_camera::radio_file::RecordedRadio::open(
            path, *sensor, epoch,
        )?)),
        #[cfg(feature = "ble")]
        RadioSpec::Ble { adapter } => {
            let clock = clock.clone();
            Ok(Box::new(node_camera::ble::BleRadio::open(
                adapter.clone(),
                std::sync::Arc::new(move || clock.now()),
                node_camera::radio::DEFAULT_CAPACITY,
            )?))
        }
        #[cfg(not(feature = "ble"))]
        RadioSpec::Ble { .. } => {
            let _ = clock;
            anyhow::bail!("radio {spec}: this build has no BLE support (build with --features ble)")
        }
    }
}
