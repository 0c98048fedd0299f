//! External detections for `ocelli replay`: JSON Lines, one detection per line,
//! `{"t": <seconds>, "camera": "<id>", "u": <px>, "v": <px>}` with optional
//! `"box": [xmin, ymin, xmax, ymax]` and optional `"rssi": {"<node id>": <dBm>}`.
//! Any detector can feed Ocelli this way.

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

/// A line that is not a valid detection.
#[derive(Debug, Error)]
pub enum DetectionError {
    #[error("line {line}: {problem}")]
    Line { line: usize, problem: String },
    #[error("reading detections: {0}")]
    Io(#[from] std::io::Error),
}

impl ExternalDetection {
    fn check(&self) -> Result<(), String> {
        if !(self.t.is_finite() && self.u.is_finite() && self.v.is_finite()) {
            return Err("t, u and v must be finite numbers".into());
        }
        if let Some(b) = self.pixel_box
            && (b.iter().any(|x| !x.is_finite()) || b[2] < b[0] || b[3] < b[1])
        {
            return Err(format!(
                "box {b:?} must be finite with xmax ≥ xmin and ymax ≥ ymin"
            ));
        }
        if let Some(r) = &self.rssi
            && let Some((node, dbm)) = r.iter().find(|(_, d)| !d.is_finite())
        {
            return Err(format!("rssi of node {node} is not finite ({dbm})"));
        }
        Ok(())
    }
}

/// Read every detection; blank lines are skipped, the first bad line is an error naming it.
///
/// # Errors
/// IO errors, or the first malformed line with its 1-based number.
pub fn read_detections(input: impl BufRead) -> Result<Vec<ExternalDetection>, DetectionError> {
    let mut out = Vec::new();
    for (i, line) in input.lines().enumerate() {
        let line = line?;
        if line.trim().is_empty() {
            continue;
        }
        let det: ExternalDetection = serde_json::from_str(&line).map_err(|e| DetectionError::Line {
            line: i + 1,
            problem: e.to_string(),
        })?;
        det.check()
            .map_err(|problem| DetectionError::Line { line: i + 1, problem })?;
        out.push(det);
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
        let d = read_detections(text.as_bytes()).unwrap();
        assert_eq!(d.len(), 2);
        assert_eq!(d[0].camera, "Camera1");
        assert_eq!(d[1].pixel_box, Some([0.0, 0.0, 4.0, 5.0]));
        assert_eq!(d[1].rssi.as_ref().unwrap()["12"], -61.5);
    }

    #[test]
    fn bad_lines_are_named() {
        for (text, want) in [
            ("{\"t\": 0, \"camera\": \"a\", \"u\": 1}\n", "line 1"),
            (
                "{\"t\": 0, \"camera\": \"a\", \"u\": 1, \"v\": 2}\nnot json\n",
                "line 2",
            ),
            (
                "{\"t\": 0, \"camera\": \"a\", \"u\": 1, \"v\": 2, \"box\": [5, 0, 1, 1]}\n",
                "xmax",
            ),
            (
                "{\"t\": 0, \"camera\": \"a\", \"u\": 1, \"v\": 2, \"extra\": 1}\n",
                "unknown field",
            ),
        ] {
            let e = read_detections(text.as_bytes()).unwrap_err().to_string();
            assert!(e.contains(want), "{e:?} should mention {want:?}");
        }
    }
}
