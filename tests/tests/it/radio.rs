//! Real radio in: the BLE RSSI dataset (`shared/datasets/ble-rssi`) replayed through real
//! processes — one radio-only node per sensor at its surveyed position replaying that
//! sensor's packets at real time, one head tracking from RSSI alone — and the launch's report
//! scored against the recording's truth. Needs the shared dataset; fails loudly without it.

use crate::harness::{EXE, now};
use serde_json::Value;
use std::process::{Command, Stdio};
use std::time::Duration;

/// Seconds of the trajectory replayed (of its 59).
const SECONDS: f64 = 25.0;
/// Mean error bound, metres. Over these seconds the beacon walks from x = 18 to x = 11 along
/// y ≈ 8.5; a track that stayed where it starts, the sensors' centroid, would err about 6 m on
/// average, and the offline RSSI-only EIF with the same law (`ocelli experiment ble-rssi`,
/// "fitted law (LOTO)") 2.9 m over whole trajectories.
const MEAN_ERROR_BOUND_M: f64 = 4.5;

fn ocelli(args: &[&str]) -> std::process::Output {
    Command::new(EXE).args(args).output().expect("running ocelli")
}

#[test]
fn ble_dataset_through_real_processes_tracks_the_beacon() {
    let dir = crate::harness::scratch("ble");
    let made = ocelli(&["scenario", "ble-rssi", "--trajectory", "straight_01"]);
    assert!(
        made.status.success(),
        "the BLE RSSI dataset is needed (shared/datasets/ble-rssi beside the repository, or \
         $OCELLI_BLE_RSSI_DIR): {}",
        String::from_utf8_lossy(&made.stderr)
    );
    let scenario = dir.join("ble.toml");
    std::fs::write(&scenario, &made.stdout).expect("writing the scenario");
    let mut child = Command::new(EXE)
        .arg("launch")
        .arg("--scenario")
        .arg(&scenario)
        .args(["--duration", &SECONDS.to_string(), "--json", "--quiet"])
        .arg("--run-dir")
        .arg(dir.join("run"))
        .arg("--record")
        .arg(dir.join("rec.ocrec"))
        .env("RUST_LOG", "info")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(std::fs::File::create(dir.join("launch.log")).expect("log"))
        .spawn()
        .expect("spawning ocelli launch");
    let deadline = now() + Duration::from_secs_f64(SECONDS + 60.0);
    while child.try_wait().expect("try_wait").is_none() {
        if now() >= deadline {
            let _ = child.kill();
            panic!("launch did not finish; see {}", dir.display());
        }
        std::thread::sleep(Duration::from_millis(200));
    }
    let out = child.wait_with_output().expect("launch output");
    assert!(out.status.success(), "launch failed; see {}", dir.display());
    let report: Value = serde_json::from_slice(&out.stdout).expect("the JSON report");
    assert_eq!(report["truth"], true, "scored against the recording's positions");
    let targets = report["targets"].as_array().expect("targets");
    assert_eq!(targets.len(), 1, "the one beacon tracked: {report}");
    let t = &targets[0];
    let mean = t["mean_error_m"].as_f64().expect("an error");
    assert!(mean < MEAN_ERROR_BOUND_M, "mean error {mean:.2} m: {t}");
    assert!(
        t["samples"].as_u64().unwrap_or(0) as f64 > SECONDS,
        "a report every step: {t}"
    );
    assert_eq!(report["false_tracks"], 0, "{report}");
    // Radio only: no camera ever on, the radios heard.
    assert_eq!(report["active_cameras_mean"].as_f64(), Some(0.0));
    assert!(
        report["rssi_nodes_mean"].as_f64().unwrap_or(0.0) >= 3.0,
        "{report}"
    );
}
