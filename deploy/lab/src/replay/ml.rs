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
    /// With a plane: how uncertain a view's ground point is beyond its pixel noise.
    pub view_noise: ViewNoise,
}

/// A view's ground error beyond what its pixel noise explains: a detector's reference point
/// is not exactly the person's ground position (a box's bottom centre lies between the feet,
/// wherever the legs are), an error on the ground rather than in the image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ViewNoise {
    /// None: pixel noise alone (exact for detections that are projections).
    Pixel,
    /// The same standard deviation for every view, m (isotropic on the plane). The default,
    /// [`FOOT_POINT_SIGMA_M`], is a box-bottom foot point's.
    Fixed(f64),
    /// Each camera's own, estimated from the detections alone: how far its lifted points
    /// fall from the fusion of the other views of the same person, beyond what their
    /// covariances explain (no ground truth involved). It weighs the views well, but the part
    /// of the error all views of a person share (the feet's spread) does not show between
    /// views, so the fused covariance stays too small.
    Estimated,
}

/// The ground error of a box's bottom centre as a person's foot point, m: measured once
/// against MultiviewX's annotated ground positions (the detector's error model, as a
/// calibration is the camera's; `docs/results-discussion.md`).
pub const FOOT_POINT_SIGMA_M: f64 = 0.08;

impl Default for ViewNoise {
    fn default() -> Self {
        ViewNoise::Fixed(FOOT_POINT_SIGMA_M)
    }
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
            view_noise: ViewNoise::default(),
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

/// One view of a group: its camera (none for a point already fused without a plane), its
/// lifted ground point and the covariance its pixel noise gives it (solver's world).
#[derive(Clone, Copy, Debug)]
struct View {
    camera: Option<usize>,
    point: Vector3<f64>,
    cov: Matrix3<f64>,
}

impl View {
    /// Its covariance with the camera's ground noise (variance, m²) added on the plane.
    fn with_noise(&self, variance: &[f64]) -> (Vector3<f64>, Matrix3<f64>) {
        let mut c = self.cov;
        if let Some(cam) = self.camera {
            c[(0, 0)] += variance[cam];
            c[(1, 1)] += variance[cam];
        }
        (self.point, c)
    }
}

/// The groups of one time stamp: each group's views and the indices of its detections.
struct FrameGroups<'a> {
    frame: &'a [&'a ExternalDetection],
    groups: Vec<(Vec<View>, Vec<usize>)>,
}

/// Fuse every `t` of `detections` (any order) into estimates, sorted by `t`.
pub fn replay_ml(
    detections: &[ExternalDetection],
    cameras: &Cameras,
    options: &MlOptions,
) -> (Vec<Estimate>, Skipped) {
    let models: Vec<_> = cameras.models.values().copied().collect();
    let mut skipped = Skipped::default();
    let mut sorted: Vec<&ExternalDetection> = detections.iter().collect();
    sorted.sort_by(|a, b| a.t.total_cmp(&b.t));
    let frames: Vec<FrameGroups<'_>> = sorted
        .chunk_by(|a, b| a.t == b.t)
        .map(|frame| FrameGroups {
            frame,
            groups: group_frame(frame, cameras, &models, options, &mut skipped),
        })
        .collect();
    let variance = match options.view_noise {
        ViewNoise::Pixel => vec![0.0; models.len()],
        ViewNoise::Fixed(sigma) => vec![sigma * sigma; models.len()],
        ViewNoise::Estimated => estimate_view_noise(&frames, models.len()),
    };
    let mut out = Vec::new();
    for f in &frames {
        for (group, dets) in &f.groups {
            if group.len() < options.min_cameras.max(1) {
                skipped.too_few_cameras += 1;
                continue;
            }
            let points: Vec<_> = group.iter().map(|v| v.with_noise(&variance)).collect();
            let Some((p, c)) = fuse(&points) else {
                skipped.singular += 1;
                continue;
            };
            let (p, c) = (cameras.to_user(&p), cameras.cov_to_user(&c));
            out.push(Estimate {
                t: f.frame[0].t,
                x: p.x,
                y: p.y,
                z: p.z,
                cov: [0, 1, 2].map(|r| [0, 1, 2].map(|k| c[(r, k)])),
                cameras: group.len(),
                track: None,
                rssi: merged_rssi(dets.iter().map(|&i| f.frame[i])),
                rssi_nodes: None,
            });
        }
    }
    (out, skipped)
}

/// One time stamp's detections, undistorted, lifted and grouped per person.
fn group_frame(
    frame: &[&ExternalDetection],
    cameras: &Cameras,
    models: &[proto::camera::CameraModel],
    options: &MlOptions,
    skipped: &mut Skipped,
) -> Vec<(Vec<View>, Vec<usize>)> {
    let t = frame[0].t;
    let mut normalized = Vec::with_capacity(frame.len());
    for (det_idx, det) in frame.iter().enumerate() {
        let Some(camera) = cameras.models.keys().position(|id| *id == det.camera) else {
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
    let Some(h) = options.plane_z else {
        let all = normalized.iter().map(|n| n.det).collect();
        return free_3d(&normalized, models, options, skipped)
            .map(|points| {
                let views = points
                    .into_iter()
                    .map(|(point, cov)| View {
                        camera: None,
                        point,
                        cov,
                    })
                    .collect();
                (views, all)
            })
            .into_iter()
            .collect();
    };
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
            let views = g
                .iter()
                .map(|&i| View {
                    camera: Some(lifted[i].0),
                    point: lifted[i].1,
                    cov: lifted[i].2,
                })
                .collect();
            (views, g.iter().map(|&i| lifted_det[i]).collect())
        })
        .collect()
}

/// The smallest ground variance a camera is given, m² (1 mm²): noise-free detections (exact
/// projections) would otherwise make the fusion singular.
const MIN_VIEW_VARIANCE: f64 = 1e-6;
/// Views a camera needs for its own estimate; fewer take the pooled one.
const MIN_VIEWS_PER_CAMERA: usize = 5;

/// Each camera's ground variance beyond its pixel noise, from the detections alone: a view's
/// residual r from the fusion of the other views of its group has covariance S + σ²I (S: its
/// own pixel covariance plus the others' fused one, on the plane), so a camera's σ² is the one
/// that makes its mean rᵀ(S + σ²I)⁻¹r equal 2, its two degrees of freedom (at least
/// [`MIN_VIEW_VARIANCE`]; cameras with few views take the pooled value). A few fixed-point
/// rounds, as the others' fusion depends on their variances.
fn estimate_view_noise(frames: &[FrameGroups<'_>], cameras: usize) -> Vec<f64> {
    let mut variance = vec![0.05f64.powi(2); cameras];
    for _ in 0..4 {
        let mut residuals: Vec<Vec<(Vector2<f64>, Matrix2<f64>)>> = vec![Vec::new(); cameras];
        for (views, _) in frames
            .iter()
            .flat_map(|f| &f.groups)
            .filter(|(v, _)| v.len() >= 2)
        {
            for (i, v) in views.iter().enumerate() {
                let Some(cam) = v.camera else { continue };
                let others: Vec<_> = views
                    .iter()
                    .enumerate()
                    .filter(|(j, _)| *j != i)
                    .map(|(_, o)| o.with_noise(&variance))
                    .collect();
                let Some((m, cm)) = fuse(&others) else { continue };
                let s = (v.cov + cm).fixed_view::<2, 2>(0, 0).into_owned();
                residuals[cam].push(((v.point - m).xy(), s));
            }
        }
        let all: Vec<_> = residuals.iter().flatten().copied().collect();
        if all.is_empty() {
            return vec![MIN_VIEW_VARIANCE; cameras];
        }
        let pooled = consistent_variance(&all);
        for (c, r) in residuals.iter().enumerate() {
            variance[c] = if r.len() >= MIN_VIEWS_PER_CAMERA {
                consistent_variance(r)
            } else {
                pooled
            };
        }
    }
    tracing::debug!(
        sigma_m = %variance.iter().map(|v| format!("{:.3}", v.sqrt())).collect::<Vec<_>>().join(" "),
        "estimated ground noise per camera"
    );
    variance
}

/// The σ² ≥ [`MIN_VIEW_VARIANCE`] that makes the mean of rᵀ(S + σ²I)⁻¹r over `residuals` equal
/// 2 (the mean falls as σ² grows: bisection on a log scale).
fn consistent_variance(residuals: &[(Vector2<f64>, Matrix2<f64>)]) -> f64 {
    let mean_nis = |v: f64| {
        residuals
            .iter()
            .filter_map(|(r, s)| {
                let m = s + Matrix2::identity() * v;
                m.try_inverse().map(|inv| (r.transpose() * inv * r)[0])
            })
            .sum::<f64>()
            / residuals.len() as f64
    };
    let (mut lo, mut hi) = (MIN_VIEW_VARIANCE.ln(), 1.0f64.ln());
    if mean_nis(MIN_VIEW_VARIANCE) <= 2.0 {
        return MIN_VIEW_VARIANCE;
    }
    for _ in 0..50 {
        let mid = 0.5 * (lo + hi);
        if mean_nis(mid.exp()) > 2.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    (0.5 * (lo + hi)).exp()
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
