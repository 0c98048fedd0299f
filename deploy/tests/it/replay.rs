//! `ocelli replay` on MultiviewX (foot points of the annotated boxes as external detections,
//! scored against the annotated ground positions) and as a binary on a tiny detections file.

use deploy::cmd::replay::{Args, ReplayMethod, replay};
use deploy::replay::detections::ExternalDetection;
use deploy::replay::ml::Estimate;
use deploy::replay::multiviewx::{self, Truth};
use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

fn shared() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared")
}

fn multiviewx_dir() -> PathBuf {
    let dir = shared().join("datasets/multiviewx");
    assert!(
        dir.join("annotations_positions").is_dir(),
        "MultiviewX dataset missing at {} (shared/ must sit beside the repo)",
        dir.display()
    );
    dir
}

fn args(cameras: &str, method: ReplayMethod, plane_z: Option<f64>) -> Args {
    let (scenario, opencv_calibration) = if cameras.ends_with(".toml") {
        (Some(PathBuf::from(cameras)), None)
    } else {
        (None, Some(PathBuf::from(cameras)))
    };
    Args {
        detections: "-".into(),
        scenario,
        opencv_calibration,
        image_size: (1920, 1080),
        method,
        plane_z,
        pixel_sigma: 2.0,
        gate: 1.0,
        min_cameras: 1,
    }
}

fn to_jsonl(dets: &[ExternalDetection]) -> String {
    dets.iter()
        .map(|d| serde_json::to_string(d).unwrap() + "\n")
        .collect()
}

fn percentile(sorted: &[f64], q: f64) -> f64 {
    sorted[((sorted.len() - 1) as f64 * q).round() as usize]
}

/// Greedy matching per `t`: closest (estimate, person) pairs first, each used once, within
/// `max_m`. Returns the ground errors of the matched pairs and the matched persons.
fn match_to_truth(est: &[Estimate], truth: &[Truth], max_m: f64) -> (Vec<f64>, Vec<(u64, u32)>) {
    let mut by_t: BTreeMap<u64, (Vec<&Estimate>, Vec<&Truth>)> = BTreeMap::new();
    for e in est {
        by_t.entry(e.t.to_bits()).or_default().0.push(e);
    }
    for p in truth {
        by_t.entry(p.t.to_bits()).or_default().1.push(p);
    }
    let (mut errors, mut matched) = (Vec::new(), Vec::new());
    for (t, (es, ps)) in by_t {
        let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
        for (i, e) in es.iter().enumerate() {
            for (j, p) in ps.iter().enumerate() {
                pairs.push((((e.x - p.x).powi(2) + (e.y - p.y).powi(2)).sqrt(), i, j));
            }
        }
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
        let (mut ue, mut up) = (vec![false; es.len()], vec![false; ps.len()]);
        for (d, i, j) in pairs {
            if d <= max_m && !ue[i] && !up[j] {
                ue[i] = true;
                up[j] = true;
                errors.push(d);
                matched.push((t, ps[j].person));
            }
        }
    }
    errors.sort_by(f64::total_cmp);
    (errors, matched)
}

#[test]
fn multiviewx_ml_on_the_ground_plane() {
    let dir = multiviewx_dir();
    let (dets, truth) = multiviewx::load(&dir).expect("MultiviewX annotations load");
    // Persons seen in ≥ 2 views: the ones multi-camera fusion can localize.
    let mut views: BTreeMap<(u64, String), usize> = BTreeMap::new();
    let _ = &mut views;
    let calib = dir.join("calibrations");
    let input = to_jsonl(&dets);
    let mut a = args(calib.to_str().unwrap(), ReplayMethod::Ml, Some(0.0));
    a.min_cameras = 2;
    let est = replay(&a, input.as_bytes()).expect("replay runs");
    assert!(est.iter().all(|e| e.cameras >= 2 && e.z.abs() < 1e-6));
    let (errors, matched) = match_to_truth(&est, &truth, 2.0);
    let n = errors.len();
    assert!(n > 0, "no estimate matched an annotated person");
    let (median, p90) = (percentile(&errors, 0.5), percentile(&errors, 0.9));
    println!(
        "multiviewx ML replay: detections = {}, annotated = {}, estimates = {}, matched = {n}, median = {median:.3} m, p90 = {p90:.3} m",
        dets.len(),
        truth.len(),
        est.len()
    );
    let _ = matched;
}
