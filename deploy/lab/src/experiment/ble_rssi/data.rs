//! Reading the real BLE RSSI dataset (`shared/datasets/ble-rssi/`, Daniş et al. 2022): the
//! sensors' positions from `cnf/tetam.dev` and one time-ordered packet list per trajectory from
//! `trk/*_all_sensors.mbd`. A malformed or physically impossible packet line is skipped and
//! counted (the first few named by line and problem, [`Trajectory::skipped`]): one bad packet
//! does not cost a whole trajectory, and nothing is skipped silently.

use nalgebra::Vector3;
use proto::TagId;
use proto::sensor::mbd::{self, MbdError};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

pub use proto::sensor::mbd::MBD_FIELDS;
/// Suffix of the merged (all sensors) trajectory files.
pub const TRACK_SUFFIX: &str = "_all_sensors.mbd";
/// Environment variable that overrides the dataset directory.
pub const DIR_ENV: &str = "OCELLI_BLE_RSSI_DIR";

/// A fixed BLE sensor.
#[derive(Clone, Debug, PartialEq)]
pub struct Sensor {
    pub mac: String,
    pub alias: String,
    /// Position, m (the dataset's frame).
    pub pos: Vector3<f64>,
}

/// One received packet: which sensor heard the beacon, at what RSSI, and where the beacon truly
/// was (AR ground truth).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Packet {
    /// Seconds since the trajectory's first packet.
    pub t: f64,
    /// Index into [`Dataset::sensors`].
    pub sensor: usize,
    pub rssi: f64,
    pub truth: Vector3<f64>,
}

/// One trajectory's packets in time order.
#[derive(Clone, Debug)]
pub struct Trajectory {
    pub name: String,
    pub packets: Vec<Packet>,
    /// Lines of its file that were skipped.
    pub skipped: crate::skipped::SkippedLines,
}

impl Trajectory {
    /// Seconds from first to last packet.
    pub fn duration_s(&self) -> f64 {
        self.packets.last().map_or(0.0, |p| p.t)
    }
}

#[derive(Clone, Debug)]
pub struct Dataset {
    pub dir: PathBuf,
    pub sensors: Vec<Sensor>,
    /// Sorted by name.
    pub trajectories: Vec<Trajectory>,
}

/// Why the dataset could not be read.
#[derive(Debug, thiserror::Error)]
pub enum DataError {
    #[error(
        "BLE RSSI dataset not found at {0} (expected cnf/tetam.dev and trk/*{TRACK_SUFFIX}; \
         see shared/datasets/README.md, or set {DIR_ENV})"
    )]
    Missing(PathBuf),
    #[error("reading {path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{path}: {msg}")]
    Devices { path: PathBuf, msg: String },
    #[error("{0}: no trajectory files (*{TRACK_SUFFIX})")]
    NoTracks(PathBuf),
}

/// The dataset's directory: `$OCELLI_BLE_RSSI_DIR`, else `shared/datasets/ble-rssi` beside the
/// repository (as the tests find it).
pub fn default_dir() -> PathBuf {
    std::env::var_os(DIR_ENV).map_or_else(
        || Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/datasets/ble-rssi"),
        PathBuf::from,
    )
}

/// Parse `tetam.dev`'s `Dongles:{MAC: [[x, y, z], colour, alias], …}` line into sensors,
/// sorted by alias. Other lines (`Beacons:`) are ignored.
///
/// # Errors
/// No `Dongles:` line, JSON that does not parse, or a position that is not three finite numbers.
pub fn parse_devices(text: &str) -> Result<Vec<Sensor>, String> {
    let body = text
        .lines()
        .find_map(|l| l.trim().strip_prefix("Dongles:"))
        .ok_or("no `Dongles:` line")?;
    let map: BTreeMap<String, (Vec<f64>, serde_json::Value, String)> =
        serde_json::from_str(body).map_err(|e| format!("Dongles: {e}"))?;
    let mut sensors = Vec::with_capacity(map.len());
    for (mac, (pos, _, alias)) in map {
        let [x, y, z] = pos[..] else {
            return Err(format!("sensor {mac}: position has {} numbers, not 3", pos.len()));
        };
        let pos = Vector3::new(x, y, z);
        if !pos.iter().all(|v| v.is_finite()) {
            return Err(format!("sensor {mac}: position not finite"));
        }
        sensors.push(Sensor { mac, alias, pos });
    }
    if sensors.is_empty() {
        return Err("no sensors in `Dongles:`".into());
    }
    sensors.sort_by(|a, b| a.alias.cmp(&b.alias));
    Ok(sensors)
}

/// One `.mbd` line as a packet (`None` for a blank line), or what is wrong with it. The line is
/// read by `proto::sensor::mbd`, the parser the file radio source uses.
fn parse_packet(line: &str, macs: &[Option<TagId>]) -> Result<Option<Packet>, String> {
    let r = match mbd::parse_line(line) {
        Ok(Some(r)) => r,
        Ok(None) => return Ok(None),
        Err(MbdError::Mac {
            what: "sensor MAC",
            field,
        }) => return Err(format!("unknown sensor MAC {:?}", field.trim())),
        Err(e) => return Err(e.to_string()),
    };
    let sensor = macs
        .iter()
        .position(|m| *m == Some(r.sensor))
        .ok_or_else(|| format!("unknown sensor MAC {:?}", r.sensor.to_string()))?;
    Ok(Some(Packet {
        t: r.time_s,
        sensor,
        rssi: r.dbm,
        truth: Vector3::from(r.position),
    }))
}

/// Parse one `.mbd` file's text into packets sorted by time (the merged files are ordered up to
/// a few sub-millisecond swaps), t relative to the first packet. Blank lines are allowed; a
/// line with a wrong field count, a non-numeric or non-finite number, an RSSI outside
/// `proto::sensor::mbd::BLE_RSSI_DBM` or a sensor MAC not in `sensors` is skipped and counted.
pub fn parse_track(text: &str, sensors: &[Sensor]) -> (Vec<Packet>, crate::skipped::SkippedLines) {
    let macs: Vec<Option<TagId>> = sensors.iter().map(|s| TagId::parse_mac(&s.mac)).collect();
    let mut raw = Vec::new();
    let mut skipped = crate::skipped::SkippedLines::default();
    for (i, line) in text.lines().enumerate() {
        match parse_packet(line, &macs) {
            Ok(Some(p)) => raw.push(p),
            Ok(None) => {}
            Err(problem) => skipped.add(i + 1, problem),
        }
    }
    raw.sort_by(|a, b| a.t.total_cmp(&b.t));
    if let Some(t0) = raw.first().map(|p| p.t) {
        for p in &mut raw {
            p.t -= t0;
        }
    }
    (raw, skipped)
}

fn read(path: &Path) -> Result<String, DataError> {
    std::fs::read_to_string(path).map_err(|source| DataError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Load the sensors and every `trk/*_all_sensors.mbd` trajectory under `dir`.
///
/// # Errors
/// [`DataError::Missing`] when `dir/cnf/tetam.dev` does not exist; otherwise the first file or
/// line that cannot be read or parsed.
pub fn load(dir: &Path) -> Result<Dataset, DataError> {
    let dev = dir.join("cnf/tetam.dev");
    if !dev.is_file() {
        return Err(DataError::Missing(dir.to_path_buf()));
    }
    let sensors = parse_devices(&read(&dev)?).map_err(|msg| DataError::Devices {
        path: dev.clone(),
        msg,
    })?;
    let trk = dir.join("trk");
    let entries = std::fs::read_dir(&trk).map_err(|source| DataError::Io {
        path: trk.clone(),
        source,
    })?;
    let mut paths: Vec<PathBuf> = entries
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.ends_with(TRACK_SUFFIX))
        })
        .collect();
    paths.sort();
    let mut trajectories = Vec::with_capacity(paths.len());
    for path in paths {
        let (packets, skipped) = parse_track(&read(&path)?, &sensors);
        if skipped.count > 0 {
            tracing::warn!(file = %path.display(), "BLE dataset: {skipped}");
        }
        let name = path
            .file_name()
            .and_then(|n| n.to_str())
            .and_then(|n| n.strip_suffix(TRACK_SUFFIX))
            .unwrap_or("?")
            .to_string();
        trajectories.push(Trajectory {
            name,
            packets,
            skipped,
        });
    }
    if trajectories.is_empty() {
        return Err(DataError::NoTracks(trk));
    }
    Ok(Dataset {
        dir: dir.canonicalize().unwrap_or_else(|_| dir.to_path_buf()),
        sensors,
        trajectories,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const DEV: &str = r#"Dongles:{"0000000000aa": [[1.0, 2.0, 1.5], 1, "s1"], "0000000000bb": [[3.0, 4.0, 2.3], 2, "s0"]}
Beacons:{"0000000000cc": [[], 3, "beacon1"] }"#;
    const ORIENT: &str = "1,0,0,0,1,0,0,0,1";

    fn sensors() -> Vec<Sensor> {
        parse_devices(DEV).expect("valid devices")
    }

    #[test]
    fn devices_parse_sorted_by_alias() {
        let s = sensors();
        assert_eq!(s.len(), 2);
        assert_eq!(s[0].alias, "s0");
        assert_eq!(s[0].mac, "0000000000bb");
        assert_eq!(s[1].pos, Vector3::new(1.0, 2.0, 1.5));
    }

    #[test]
    fn devices_reject_a_two_number_position_and_a_missing_line() {
        let e = parse_devices(r#"Dongles:{"aa": [[1.0, 2.0], 1, "s1"]}"#).unwrap_err();
        assert!(e.contains("aa") && e.contains("not 3"), "{e}");
        assert!(parse_devices("Beacons:{}").unwrap_err().contains("Dongles"));
    }

    #[test]
    fn track_parses_sorts_and_rebases_time() {
        let text = format!(
            "10.5,0000000000aa,0000000000cc,-70,1,2,1.8,{ORIENT}\n\n10.0,0000000000bb,0000000000cc,-80,1.5,2,1.8,{ORIENT}\n"
        );
        let (p, skipped) = parse_track(&text, &sensors());
        assert_eq!(skipped.count, 0);
        assert_eq!(p.len(), 2);
        assert_eq!(p[0].t, 0.0);
        assert_eq!(p[0].sensor, 0);
        assert_eq!(p[0].rssi, -80.0);
        assert!((p[1].t - 0.5).abs() < 1e-12);
        assert_eq!(p[1].truth, Vector3::new(1.0, 2.0, 1.8));
    }

    #[test]
    fn track_skips_malformed_and_impossible_lines_naming_line_and_problem() {
        let s = sensors();
        let (a, c) = ("0000000000aa", "0000000000cc");
        let ok = format!("1.0,{a},{c},-70,1,2,1.8,{ORIENT}");
        let cases = [
            (format!("{ok}\n1.0,{a},{c},-70,1,2,1.8"), 2, "fields"),
            (
                format!("{ok}\n1.0,zz,{c},-70,1,2,1.8,{ORIENT}"),
                2,
                "unknown sensor",
            ),
            (
                format!("{ok}\n1.0,0000000000dd,{c},-70,1,2,1.8,{ORIENT}"),
                2,
                "unknown sensor",
            ),
            (format!("1.0,{a},{c},strong,1,2,1.8,{ORIENT}"), 1, "RSSI"),
            (format!("1.0,{a},{c},-70,1,NaN,1.8,{ORIENT}"), 1, "not finite"),
            (format!("1.0,{a},{c},-300,1,2,1.8,{ORIENT}"), 1, "out of range"),
            (
                format!("1.0,{a},{c},-70,1,2,1.8,1,0,0,0,x,0,0,0,1"),
                1,
                "orientation",
            ),
        ];
        for (text, line, what) in cases {
            let text = format!("{text}\n2.0,0000000000bb,{c},-75,1,2,1.8,{ORIENT}\n");
            let (packets, skipped) = parse_track(&text, &s);
            assert_eq!(
                packets.len(),
                if line == 2 { 2 } else { 1 },
                "{what}: the good lines stay"
            );
            assert_eq!(skipped.count, 1, "{what}");
            let (n, msg) = &skipped.first[0];
            assert_eq!(*n, line, "{msg}");
            assert!(msg.contains(what), "{msg} should mention {what}");
        }
    }

    #[test]
    fn a_missing_dataset_is_an_error_naming_the_path() {
        let dir = Path::new("/nonexistent/ble-rssi-for-test");
        let e = load(dir).unwrap_err();
        assert!(matches!(e, DataError::Missing(_)));
        let msg = e.to_string();
        assert!(msg.contains("/nonexistent/ble-rssi-for-test"), "{msg}");
        assert!(msg.contains("not found"), "{msg}");
    }
}
