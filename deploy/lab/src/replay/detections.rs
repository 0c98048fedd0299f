//! External detections for `ocelli fuse`: JSON Lines, one detection per line,
//! `{"t": <seconds>, "camera": "<id>", "u": <px>, "v": <px>}` with optional
//! `"box": [xmin, ymin, xmax, ymax]` and optional `"rssi": {"<node id>": <dBm>}`.
//! Any detector can feed Ocelli this way.
//!
//! Data from outside is read, not trusted: a line that does not parse, or that holds a value no
//! detector can produce (a time before 0 or centuries ahead, a pixel a million pixels off, an
//! RSSI outside [`RSSI_DBM`]), is skipped and counted with its line number, and reading goes
//! on ([`SkippedLines`]).

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::io::BufRead;
use thiserror::Error;

/// One detection from an external detector.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExternalDetection {
    /// Capture time, seconds.
    pub t: f64,
    /// Camera id as named by the calibration (e.g. `Camera1`) or the scenario node id.
    pub camera: String,
    /// Pixel of the reference point (foot point or centre), distorted sensor coordinates.
    pub u: f64,
    pub v: f64,
    #[serde(default, rename = "box", skip_serializing_if = "Option::is_none")]
    pub pixel_box: Option<[f64; 4]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rssi: Option<BTreeMap<String, f64>>,
}

/// Detections that could not be read at all.
#[derive(Debug, Error)]
pub enum DetectionError {
    #[error("reading detections, line {line}: {source}")]
    Io { line: usize, source: std::io::Error },
}

/// The RSSI a receiver can report, dBm.
pub const RSSI_DBM: std::ops::RangeInclusive<f64> = -130.0..=0.0;
/// The latest time a detection may carry, seconds (Unix time in the year 2286).
pub const MAX_T_S: f64 = 1e10;
/// How far outside any image a pixel may be, px.
pub const MAX_PIXEL: f64 = 1e6;

impl ExternalDetection {
    /// What makes this detection impossible, if anything.
    pub fn problem(&self) -> Option<String> {
        if !(self.t.is_finite() && (0.0..=MAX_T_S).contains(&self.t)) {
            return Some(format!("time {} s is not in [0, {MAX_T_S:e}]", self.t));
        }
        if self.camera.is_empty() {
            return Some("the camera id is empty".into());
        }
        let pixel = |x: f64| x.is_finite() && x.abs() <= MAX_PIXEL;
        if !(pixel(self.u) && pixel(self.v)) {
            return Some(format!(
                "pixel ({}, {}) is not a finite image position",
                self.u, self.v
            ));
        }
        if let Some(b) = self.pixel_box
            && (!b.iter().all(|x| pixel(*x)) || b[2] < b[0] || b[3] < b[1])
        {
            return Some(format!(
                "box [{}, {}, {}, {}] must be finite with xmax ≥ xmin and ymax ≥ ymin",
                b[0], b[1], b[2], b[3]
            ));
        }
        if let Some(r) = &self.rssi
            && let Some((node, dbm)) = r.iter().find(|(_, d)| !RSSI_DBM.contains(*d))
        {
            return Some(format!(
                "RSSI {dbm} dBm of node {node} is not in [{}, {}] dBm",
                RSSI_DBM.start(),
                RSSI_DBM.end()
            ));
        }
        None
    }
}

pub use crate::skipped::SkippedLines;

/// What a reading kept and skipped.
#[derive(Clone, Debug, Default)]
pub struct ReadDetections {
    pub detections: Vec<ExternalDetection>,
    pub skipped: SkippedLines,
}

/// Read every detection; blank lines are passed over, malformed or impossible ones skipped
/// and counted.
///
/// # Errors
/// Only when the input itself cannot be read.
pub fn read_detections(input: impl BufRead) -> Result<ReadDetections, DetectionError> {
    let mut out = ReadDetections::default();
    for (i, line) in input.lines().enumerate() {
        let line = line.map_err(|source| DetectionError::Io { line: i + 1, source })?;
        if line.trim().is_empty() {
            continue;
        }
        match serde_json::from_str::<ExternalDetection>(&line) {
            Err(e) => out.skipped.add(i + 1, e.to_string()),
            Ok(det) => match det.problem() {
                Some(problem) => out.skipped.add(i + 1, problem),
                None => out.detections.push(det),
            },
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_minimal_and_full_lines() {
        let text = r#"{"t": 0.5, "camera": "Camera1", "u": 10.0, "v": 20.0}

{"t": 1, "camera": "7", "u": 1, "v": 2, "box": [0, 0, 4, 5], "rssi": {"12": -61.5}}
"#;
        let read = read_detections(text.as_bytes()).unwrap();
        assert_eq!(read.skipped, SkippedLines::default());
        let d = read.detections;
        assert_eq!(d.len(), 2);
        assert_eq!(d[0].camera, "Camera1");
        assert_eq!(d[1].pixel_box, Some([0.0, 0.0, 4.0, 5.0]));
        assert_eq!(d[1].rssi.as_ref().unwrap()["12"], -61.5);
    }

    #[test]
    fn bad_and_impossible_lines_are_skipped_counted_and_named() {
        let good = r#"{"t": 0, "camera": "a", "u": 1, "v": 2}"#;
        let bad = [
            (r#"{"t": 0, "camera": "a", "u": 1}"#, "missing field `v`"),
            ("not json", "expected"),
            (
                r#"{"t": 0, "camera": "a", "u": 1, "v": 2, "box": [5, 0, 1, 1]}"#,
                "xmax",
            ),
            (
                r#"{"t": 0, "camera": "a", "u": 1, "v": 2, "extra": 1}"#,
                "unknown field",
            ),
            (r#"{"t": -3, "camera": "a", "u": 1, "v": 2}"#, "time -3 s"),
            (r#"{"t": 1e300, "camera": "a", "u": 1, "v": 2}"#, "not in [0"),
            (
                r#"{"t": 0, "camera": "a", "u": 1, "v": 2, "rssi": {"7": 20}}"#,
                "RSSI 20 dBm of node 7",
            ),
            (r#"{"t": 0, "camera": "a", "u": 1e9, "v": 2}"#, "pixel"),
            (r#"{"t": 0, "camera": "", "u": 1, "v": 2}"#, "camera id is empty"),
        ];
        for (line, want) in bad {
            let text = format!("{good}\n{line}\n{good}\n");
            let read = read_detections(text.as_bytes()).unwrap();
            assert_eq!(read.detections.len(), 2, "{line}");
            assert_eq!(read.skipped.count, 1, "{line}");
            let said = read.skipped.to_string();
            assert!(said.starts_with("1 line(s) skipped (first: line 2: "), "{said}");
            assert!(said.contains(want), "{said:?} should mention {want:?}");
        }
        let many: String = (0..10).map(|_| "x\n").collect();
        let read = read_detections(many.as_bytes()).unwrap();
        assert_eq!(read.skipped.count, 10);
        assert_eq!(
            read.skipped.first.iter().map(|(l, _)| *l).collect::<Vec<_>>(),
            [1, 2, 3]
        );
    }
}
