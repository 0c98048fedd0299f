//! ML replay (paper 000 §3, eq. 4–7) of external detections: each detection is undistorted
//! exactly to a normalized point with a covariance from the pixel noise, lifted to a world
//! point, grouped per person across cameras, and each group fused into one estimate.
//!
//! Grouping: with a target plane (`plane_z`), every detection is lifted to the plane and the
//! lifted points of one `t` are clustered by complete linkage on their ground distance — two
//! groups merge while every cross pair is within `gate_m` and they share no camera (one camera
//! sees a person once), closest pair first. Without a plane there is no position before fusion,
//! so all detections of a `t` are taken as one target (at most one per camera; a `t` with more
//! is skipped and counted), lifted at a mean depth and refined by re-lifting each camera at the
//! fused point's depth (a few fixed iterations).

use super::cameras::Cameras;
use super::detections::ExternalDetection;
use nalgebra::{Matrix2, Matrix3, Vector2, Vector3};
use node_head::fusion::ml::{DepthHandling, fuse, lift};
use serde::Serialize;
use std::collections::BTreeMap;

/// Settings of the ML replay.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MlOptions {
    /// Targets move on z = `plane_z` (user world); `None` = free 3-D.
    pub plane_z: Option<f64>,
    /// Thickness of the plane (m): the variance left along z.
    pub plane_sigma: f64,
    /// Pixel noise of a detection (px).
    pub pixel_sigma: f64,
    /// Largest ground distance (m) between two lifted detections of one person.
    pub gate_m: f64,
    /// Groups seen by fewer cameras are not reported.
    pub min_cameras: usize,
    /// Without a plane: the first depth guess (m) along each optical axis.
    pub mean_depth: f64,
}

impl Default for MlOptions {
    fn default() -> Self {
        MlOptions {
            plane_z: None,
            plane_sigma: 0.01,
            pixel_sigma: 2.0,
            gate_m: 1.0,
            min_cameras: 1,
            mean_depth: 5.0,
        }
    }
}

/// One fused estimate, in the user's world.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Estimate {
    pub t: f64,
    pub x: f64,
    pub y: f64,
    pub z: f64,
    /// Position covariance (m²), row-major 3×3.
    pub cov: [[f64; 3]; 3],
    /// Number of cameras fused.
    pub cameras: usize,
    /// Track id (`--method eif` only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub track: Option<u64>,
    /// RSSI readings of the person's tag that came with the group's detections, by node id
    /// (dBm; a node reported by several detections is averaged). ML fusion does not use them;
    /// `--method eif` adds them as range measurements.
    #[serde(skip)]
    pub rssi: BTreeMap<String, f64>,
    /// RSSI readings the tracker used (`--method eif` only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rssi_nodes: Option<usize>,
}

/// The mean reading of each node over the detections `dets`.
fn merged_rssi<'a>(dets: impl Iterator<Item = &'a ExternalDetection>) -> BTreeMap<String, f64> {
    let mut sums: BTreeMap<String, (f64, f64)> = BTreeMap::new();
    for (node, dbm) in dets.filter_map(|d| d.rssi.as_ref()).flatten() {
        let e = sums.entry(node.clone()).or_default();
        e.0 += dbm;
        e.1 += 1.0;
    }
    sums.into_iter().map(|(k, (s, n))| (k, s / n)).collect()
}

/// Detections that could not be used, by reason.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Skipped {
    pub unknown_camera: usize,
    pub undistort_failed: usize,
    /// The ray does not meet the plane in front of the camera.
    pub no_intersection: usize,
    /// Without a plane: detections of a `t` where one camera saw more than one target.
    pub ambiguous: usize,
    /// Groups below `min_cameras`.
    pub too_few_cameras: usize,
    /// Groups whose fusion was numerically singular.
    pub singular: usize,
}

/// A detection ready to lift: camera index, normalized point and its covariance.
struct Normalized {
    /// Index of the detection in its `t`.
    det: usize,
    camera: usize,
    point: Vector2<f64>,
    cov: Matrix2<f64>,
}

/// Fuse every `t` of `detections` (any order) into estimates, sorted by `t`.
pub fn replay_ml(
    detections: &[ExternalDetection],
    cameras: &Cameras,
    options: &MlOptions,
) -> (Vec<Estimate>, Skipped) {
    let ids: Vec<&String> = cameras.models.keys().collect();
    let models: Vec<_> = cameras.models.values().copied().collect();
    let mut skipped = Skipped::default();
    let mut sorted: Vec<&ExternalDetection> = detections.iter().collect();
    sorted.sort_by(|a, b| a.t.total_cmp(&b.t));
    let mut out = Vec::new();
    for frame in sorted.chunk_by(|a, b| a.t == b.t) {
        let t = frame[0].t;
        let mut normalized = Vec::with_capacity(frame.len());
        for (det_idx, det) in frame.iter().enumerate() {
            let Some(camera) = ids.iter().position(|id| **id == det.camera) else {
                tracing::debug!(camera = %det.camera, t, "detection from an unknown camera, skipped");
                skipped.unknown_camera += 1;
                continue;
            };
            let model = &models[camera];
            match model.undistort(&Vector2::new(det.u, det.v)) {
                Ok(point) => normalized.push(Normalized {
                    det: det_idx,
                    camera,
                    point,
                    cov: model.normalized_covariance(&point, options.pixel_sigma),
                }),
                Err(e) => {
                    tracing::debug!(camera = %det.camera, t, error = %e, "detection skipped");
                    skipped.undistort_failed += 1;
                }
            }
        }
        let groups = match options.plane_z {
            Some(h) => {
                let z = cameras.to_solver(&Vector3::new(0.0, 0.0, h)).z;
                let depth = DepthHandling::KnownPlane {
                    z,
                    sigma: options.plane_sigma,
                };
                let mut lifted = Vec::with_capacity(normalized.len());
                let mut lifted_det = Vec::with_capacity(normalized.len());
                for n in &normalized {
                    match lift(&models[n.camera], &n.point, &n.cov, depth) {
                        Some((p, c)) => {
                            lifted.push((n.camera, p, c));
                            lifted_det.push(n.det);
                        }
                        None => skipped.no_intersection += 1,
                    }
                }
                cluster(&lifted, options.gate_m)
                    .into_iter()
                    .map(|g| {
                        let points = g.iter().map(|&i| (lifted[i].1, lifted[i].2)).collect::<Vec<_>>();
                        (points, g.iter().map(|&i| lifted_det[i]).collect::<Vec<_>>())
                    })
                    .collect::<Vec<_>>()
            }
            None => free_3d(&normalized, &models, options, &mut skipped)
                .map(|points| (points, normalized.iter().map(|n| n.det).collect()))
                .into_iter()
                .collect(),
        };
        for (group, dets) in groups {
            if group.len() < options.min_cameras.max(1) {
                skipped.too_few_cameras += 1;
                continue;
            }
            let Some((p, c)) = fuse(&group) else {
                skipped.singular += 1;
                continue;
            };
            let (p, c) = (cameras.to_user(&p), cameras.cov_to_user(&c));
            out.push(Estimate {
                t,
                x: p.x,
                y: p.y,
                z: p.z,
                cov: [0, 1, 2].map(|r| [0, 1, 2].map(|k| c[(r, k)])),
                cameras: group.len(),
                track: None,
                rssi: merged_rssi(dets.iter().map(|&i| frame[i])),
                rssi_nodes: None,
            });
        }
    }
    (out, skipped)
}

/// Without a plane: all detections of one `t` as one target, lifted at the mean depth, then
/// re-lifted twice at the fused point's depth in each camera.
fn free_3d(
    normalized: &[Normalized],
    models: &[proto::camera::CameraModel],
    options: &MlOptions,
    skipped: &mut Skipped,
) -> Option<Vec<(Vector3<f64>, Matrix3<f64>)>> {
    let mut seen = vec![false; models.len()];
    for n in normalized {
        if std::mem::replace(&mut seen[n.camera], true) {
            skipped.ambiguous += normalized.len();
            return None;
        }
    }
    let lift_all = |depth_of: &dyn Fn(usize) -> f64| -> Vec<(Vector3<f64>, Matrix3<f64>)> {
        normalized
            .iter()
            .filter_map(|n| {
                let depth = depth_of(n.camera);
                let handling = DepthHandling::MeanDepth {
                    depth,
                    sigma: depth.max(options.mean_depth),
                };
                lift(&models[n.camera], &n.point, &n.cov, handling)
            })
            .collect()
    };
    let mut points = lift_all(&|_| options.mean_depth);
    for _ in 0..2 {
        let Some((p, _)) = fuse(&points) else { break };
        let refined = lift_all(&|cam| {
            let d = models[cam].pose.world_to_camera(&p).z;
            if d > 0.1 { d } else { options.mean_depth }
        });
        if refined.len() == points.len() {
            points = refined;
        }
    }
    Some(points)
}

/// Complete-linkage grouping of lifted points `(camera, point, cov)` on ground (x, y) distance:
/// merge the closest two groups while their farthest cross pair is within `gate` and they share
/// no camera. Returns index groups.
///
/// Sparse, so its cost grows with the pairs within `gate` rather than with the square of the
/// points: a grid of `gate`-sized cells finds those pairs; merged groups' distances follow the
/// complete-linkage rule d(i∪j, k) = max(d(i, k), d(j, k)), so only pairs within the gate in
/// both groups survive a merge; a heap hands out the closest pair, stale entries are passed
/// over. Ties go to the lowest group indices, so the grouping is the dense algorithm's.
pub fn cluster(points: &[(usize, Vector3<f64>, Matrix3<f64>)], gate: f64) -> Vec<Vec<usize>> {
    use std::cmp::Reverse;
    use std::collections::{BinaryHeap, HashMap};
    let n = points.len();
    // Neighbours within the gate, by group, with the complete-linkage distance.
    let mut near: Vec<BTreeMap<usize, f64>> = vec![BTreeMap::new(); n];
    let cell = |p: &Vector3<f64>| ((p.x / gate).floor() as i64, (p.y / gate).floor() as i64);
    let mut grid: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
    for (i, p) in points.iter().enumerate() {
        grid.entry(cell(&p.1)).or_default().push(i);
    }
    let mut heap = BinaryHeap::new();
    for (i, p) in points.iter().enumerate() {
        let (cx, cy) = cell(&p.1);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for &j in grid.get(&(cx + dx, cy + dy)).into_iter().flatten() {
                    if j <= i || points[j].0 == p.0 {
                        continue;
                    }
                    let d = (p.1.xy() - points[j].1.xy()).norm();
                    if d <= gate {
                        near[i].insert(j, d);
                        near[j].insert(i, d);
                        heap.push(Reverse((Dist(d), i, j)));
                    }
                }
            }
        }
    }
    let mut members: Vec<Vec<usize>> = (0..n).map(|i| vec![i]).collect();
    let mut alive = vec![true; n];
    while let Some(Reverse((Dist(d), i, j))) = heap.pop() {
        // Stale: a group merged away, or the pair's distance grew with a merge.
        if !(alive[i] && alive[j]) || near[i].get(&j) != Some(&d) {
            continue;
        }
        let moved = std::mem::take(&mut members[j]);
        members[i].extend(moved);
        alive[j] = false;
        let from_j = std::mem::take(&mut near[j]);
        let from_i = std::mem::take(&mut near[i]);
        for (&k, &dik) in &from_i {
            near[k].remove(&i);
            if k == j {
                continue;
            }
            // Within the gate of both, or no longer a candidate at all.
            if let Some(&djk) = from_j.get(&k) {
                let m = dik.max(djk);
                near[i].insert(k, m);
                near[k].insert(i, m);
                let (a, b) = if i < k { (i, k) } else { (k, i) };
                heap.push(Reverse((Dist(m), a, b)));
            }
        }
        for &k in from_j.keys() {
            near[k].remove(&j);
        }
    }
    members.into_iter().filter(|m| !m.is_empty()).collect()
}

/// A distance ordered for the heap (never NaN: made from finite points).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Dist(f64);

impl Eq for Dist {}

impl PartialOrd for Dist {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Dist {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&other.0)
    }
}

#[cfg(test)]
mod tests;
