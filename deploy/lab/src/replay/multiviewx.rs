//! MultiviewX annotations as external detections and ground truth: each annotated box's foot
//! point (bottom centre) in every view becomes one detection; the annotated ground position is
//! the truth it is scored against. Camera ids are `Camera<view + 1>`, as in `calibrations/`.

use super::detections::ExternalDetection;
use serde::Deserialize;
use std::path::Path;
use thiserror::Error;

/// Seconds between annotated frames (MultiviewX follows WILDTRACK's 2 fps annotation rate).
pub const FRAME_PERIOD_S: f64 = 0.5;

#[derive(Debug, Deserialize)]
#[serde(rename_all = "camelCase")]
struct AnnotatedPerson {
    #[serde(rename = "personID")]
    person_id: u32,
    #[serde(rename = "positionID")]
    position_id: u64,
    views: Vec<View>,
}

#[derive(Debug, Deserialize)]
#[serde(rename_all = "camelCase")]
struct View {
    view_num: u32,
    xmin: f64,
    ymin: f64,
    xmax: f64,
    ymax: f64,
}

/// A person's true ground position at one annotated frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Truth {
    pub t: f64,
    pub person: u32,
    pub x: f64,
    pub y: f64,
    /// Views in which the person has a usable box (= detections made of it).
    pub views: usize,
}

#[derive(Debug, Error)]
pub enum MultiviewxError {
    #[error("cannot read {path}: {source}")]
    Io { path: String, source: std::io::Error },
    #[error("{path}: {problem}")]
    Format { path: String, problem: String },
}

/// Ground position of a MultiviewX grid cell (`unitConversion.py`): 2.5 cm cells, 1000 per row.
pub fn ground_of(position_id: u64) -> (f64, f64) {
    (
        (position_id % 1000) as f64 / 40.0,
        (position_id / 1000) as f64 / 40.0,
    )
}

/// Read `annotations_positions/*.json` under `dataset`: detections (foot points of every visible
/// box) and the truth, frame `N` at `t = N · FRAME_PERIOD_S`.
///
/// # Errors
/// Unreadable directory or a file that is not MultiviewX annotation JSON, naming the file.
pub fn load(dataset: &Path) -> Result<(Vec<ExternalDetection>, Vec<Truth>), MultiviewxError> {
    let dir = dataset.join("annotations_positions");
    let io = |source| MultiviewxError::Io {
        path: dir.display().to_string(),
        source,
    };
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .map_err(io)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "json"))
        .collect();
    files.sort();
    let (mut dets, mut truth) = (Vec::new(), Vec::new());
    for path in files {
        let name = path.display().to_string();
        let frame: u64 = path
            .file_stem()
            .and_then(|s| s.to_str())
            .and_then(|s| s.parse().ok())
            .ok_or_else(|| MultiviewxError::Format {
                path: name.clone(),
                problem: "file name is not a frame number".into(),
            })?;
        let text = std::fs::read_to_string(&path).map_err(|source| MultiviewxError::Io {
            path: name.clone(),
            source,
        })?;
        let people: Vec<AnnotatedPerson> =
            serde_json::from_str(&text).map_err(|e| MultiviewxError::Format {
                path: name.clone(),
                problem: e.to_string(),
            })?;
        let t = frame as f64 * FRAME_PERIOD_S;
        for p in people {
            let (x, y) = ground_of(p.position_id);
            let visible: Vec<&View> = p
                .views
                .iter()
                .filter(|v| v.xmin >= 0.0 && v.xmax > v.xmin && v.ymax > v.ymin)
                .collect();
            truth.push(Truth {
                t,
                person: p.person_id,
                x,
                y,
                views: visible.len(),
            });
            for v in visible {
                dets.push(ExternalDetection {
                    t,
                    camera: format!("Camera{}", v.view_num + 1),
                    u: 0.5 * (v.xmin + v.xmax),
                    v: v.ymax,
                    pixel_box: Some([v.xmin, v.ymin, v.xmax, v.ymax]),
                    rssi: None,
                });
            }
        }
    }
    Ok((dets, truth))
}
