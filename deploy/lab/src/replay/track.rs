//! `--method eif`: the ML estimates of each `t` fed as position measurements to one Extended
//! Information Filter per target (the heads' constant-velocity EIF, [`node_head::eif`]), with
//! greedy nearest-neighbour association on the Mahalanobis distance of the position innovation.
//! An estimate no track accepts starts a new track; a track not updated for `timeout_s` ends.
//!
//! RSSI: the readings that came with an estimate's detections (`"rssi": {"<node>": dBm}`) are
//! added to the same update as range measurements of the nodes ([`RssiNodes`]: positions and
//! the scenario's default model, paper 002 eq. 2), each linearized at the predicted mean with
//! `proto::models::rssi_contribution`, as a head does. Where cameras are sparse — one camera
//! and no plane leaves the depth along its ray almost unknown — they are what fixes the
//! position.

use super::ml::Estimate;
use nalgebra::{Matrix3, Matrix6, Vector3, Vector6};
use node_head::eif::{Accumulator, Eif};
use proto::models::{MotionModel, POS, RssiModel, State, VEL};
use std::collections::BTreeMap;

/// The nodes whose RSSI readings a tracker can use: positions (the user's world) by node id,
/// and the range model of every node.
#[derive(Clone, Debug, Default)]
pub struct RssiNodes {
    pub positions: BTreeMap<String, Vector3<f64>>,
    pub model: RssiModel,
}

/// What the tracker did not use.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TrackCounts {
    /// Estimates dropped (covariance not positive definite, or a failed update).
    pub dropped: usize,
    /// RSSI readings folded into updates.
    pub rssi_used: usize,
    /// RSSI readings from nodes without a known position.
    pub rssi_unknown_node: usize,
}

/// The information of an estimate's RSSI readings linearized at `mean`.
fn rssi_info(
    e: &Estimate,
    nodes: &RssiNodes,
    mean: &State,
    acc: &mut Accumulator,
    counts: &mut TrackCounts,
) -> usize {
    let mut used = 0;
    for (node, &dbm) in &e.rssi {
        let Some(pos) = nodes.positions.get(node) else {
            counts.rssi_unknown_node += 1;
            continue;
        };
        if let Some((omega, xi)) = proto::models::rssi_contribution(&nodes.model, pos, dbm, mean) {
            acc.add(&omega, &xi);
            used += 1;
        }
    }
    counts.rssi_used += used;
    used
}

/// Settings of the tracker.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrackOptions {
    pub motion: MotionModel,
    /// Gate on the squared Mahalanobis distance (3 dof; 11.34 is the 99 % quantile).
    pub gate_chi2: f64,
    /// Initial velocity standard deviation (m/s) of a new track.
    pub initial_speed_sigma: f64,
    /// A track not updated for this long (s) ends.
    pub timeout_s: f64,
}

impl Default for TrackOptions {
    fn default() -> Self {
        TrackOptions {
            motion: MotionModel::default(),
            gate_chi2: 11.34,
            initial_speed_sigma: 1.5,
            timeout_s: 2.0,
        }
    }
}

struct Track {
    id: u64,
    filter: Eif,
    last_t: f64,
}

fn position_cov(e: &Estimate) -> Matrix3<f64> {
    Matrix3::from_fn(|r, c| e.cov[r][c])
}

/// Track ML estimates (sorted by `t`): one output per estimate a track absorbed or started,
/// carrying the filtered position, covariance and track id. Estimates whose covariance is not
/// positive definite are dropped (counted in the returned number).
pub fn track(estimates: &[Estimate], options: &TrackOptions) -> (Vec<Estimate>, usize) {
    let nodes = RssiNodes::default();
    let (out, counts) = track_with_rssi(estimates, options, &nodes);
    (out, counts.dropped)
}

/// As [`track`], adding each estimate's RSSI readings from `nodes` to its update.
pub fn track_with_rssi(
    estimates: &[Estimate],
    options: &TrackOptions,
    nodes: &RssiNodes,
) -> (Vec<Estimate>, TrackCounts) {
    let mut counts = TrackCounts::default();
    let mut tracks: Vec<Track> = Vec::new();
    let mut next_id = 1;
    let mut out = Vec::new();
    let mut dropped = 0;
    for frame in estimates.chunk_by(|a, b| a.t == b.t) {
        let t = frame[0].t;
        tracks.retain(|tr| t - tr.last_t <= options.timeout_s);
        let predicted: Vec<Option<Eif>> = tracks
            .iter()
            .map(|tr| tr.filter.predicted(&options.motion, t - tr.last_t).ok())
            .collect();
        // All gated (distance, track, estimate) pairs, closest first.
        let mut pairs = Vec::new();
        for (k, pred) in predicted.iter().enumerate() {
            let Some(pred) = pred else { continue };
            let mean = pred.mean().fixed_rows::<3>(POS).into_owned();
            let p_cov = pred.cov().fixed_view::<3, 3>(POS, POS).into_owned();
            for (e_idx, e) in frame.iter().enumerate() {
                let innov = Vector3::new(e.x, e.y, e.z) - mean;
                if let Some(s) = (p_cov + position_cov(e)).cholesky() {
                    let d2 = innov.dot(&s.solve(&innov));
                    if d2 <= options.gate_chi2 {
                        pairs.push((d2, k, e_idx));
                    }
                }
            }
        }
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut track_used = vec![false; tracks.len()];
        let mut est_used = vec![false; frame.len()];
        let mut assigned: Vec<(usize, usize)> = Vec::new();
        for (_, k, e_idx) in pairs {
            if !track_used[k] && !est_used[e_idx] {
                track_used[k] = true;
                est_used[e_idx] = true;
                assigned.push((k, e_idx));
            }
        }
        for (k, e_idx) in assigned {
            let e = &frame[e_idx];
            let Some(info) = position_cov(e).cholesky().map(|c| c.inverse()) else {
                dropped += 1;
                continue;
            };
            let z = Vector3::new(e.x, e.y, e.z);
            let mut omega = Matrix6::zeros();
            omega.fixed_view_mut::<3, 3>(POS, POS).copy_from(&info);
            let mut xi = Vector6::zeros();
            xi.fixed_rows_mut::<3>(POS).copy_from(&(info * z));
            let mut acc = Accumulator::default();
            acc.add(&omega, &xi);
            let Some(mut filter) = predicted[k].clone() else {
                continue;
            };
            let rssi = rssi_info(e, nodes, filter.mean(), &mut acc, &mut counts);
            if filter.update(&acc).is_err() {
                dropped += 1;
                continue;
            }
            let tr = &mut tracks[k];
            tr.filter = filter;
            tr.last_t = t;
            out.push(output(e, tr, rssi));
        }
        for (e_idx, e) in frame.iter().enumerate().filter(|(i, _)| !est_used[*i]) {
            let mut cov = Matrix6::zeros();
            cov.fixed_view_mut::<3, 3>(POS, POS).copy_from(&position_cov(e));
            let v = options.initial_speed_sigma.powi(2);
            cov.fixed_view_mut::<3, 3>(VEL, VEL)
                .copy_from(&Matrix3::from_diagonal_element(v));
            let mut mean = Vector6::zeros();
            mean.fixed_rows_mut::<3>(POS)
                .copy_from(&Vector3::new(e.x, e.y, e.z));
            let born = Eif::from_gaussian(mean, cov).and_then(|mut filter| {
                let mut acc = Accumulator::default();
                let used = rssi_info(e, nodes, filter.mean(), &mut acc, &mut counts);
                if used > 0 {
                    filter.update(&acc)?;
                }
                Ok((filter, used))
            });
            match born {
                Ok((filter, rssi)) => {
                    let tr = Track {
                        id: next_id,
                        filter,
                        last_t: t,
                    };
                    next_id += 1;
                    out.push(output(e, &tr, rssi));
                    tracks.push(tr);
                }
                Err(err) => {
                    tracing::warn!(t, error = %err, estimate = e_idx, "estimate cannot start a track");
                    dropped += 1;
                }
            }
        }
    }
    counts.dropped = dropped;
    (out, counts)
}

fn output(e: &Estimate, tr: &Track, rssi: usize) -> Estimate {
    let m = tr.filter.mean();
    let c = tr.filter.cov();
    Estimate {
        t: e.t,
        x: m[POS],
        y: m[POS + 1],
        z: m[POS + 2],
        cov: [0, 1, 2].map(|r| [0, 1, 2].map(|k| c[(POS + r, POS + k)])),
        cameras: e.cameras,
        track: Some(tr.id),
        rssi: BTreeMap::new(),
        rssi_nodes: Some(rssi),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn est(t: f64, x: f64, y: f64) -> Estimate {
        let s2 = 0.05_f64.powi(2);
        Estimate {
            t,
            x,
            y,
            z: 0.0,
            cov: [[s2, 0.0, 0.0], [0.0, s2, 0.0], [0.0, 0.0, 1e-4]],
            cameras: 2,
            track: None,
            rssi: BTreeMap::new(),
            rssi_nodes: None,
        }
    }

    #[test]
    fn two_walkers_keep_their_ids_and_a_timeout_ends_a_track() {
        // Two people 3 m apart walking parallel at 1.2 m/s, sampled every 0.5 s.
        let mut input = Vec::new();
        for k in 0..8 {
            let t = f64::from(k) * 0.5;
            input.push(est(t, 1.2 * t, 0.0));
            input.push(est(t, 1.2 * t, 3.0));
        }
        let (out, dropped) = track(&input, &TrackOptions::default());
        assert_eq!(dropped, 0);
        assert_eq!(out.len(), input.len());
        for e in &out {
            let want = if e.y < 1.5 { 1 } else { 2 };
            assert_eq!(e.track, Some(want), "{e:?}");
        }
        // The filter has learnt the velocity: the last estimate is close to the measurement.
        let last = out.last().unwrap();
        assert!((last.x - 4.2).abs() < 0.1, "{last:?}");
        // A gap longer than the timeout starts a new track.
        let later = [est(10.0, 12.0, 0.0)];
        let mut all = input.clone();
        all.extend(later);
        let (out, _) = track(&all, &TrackOptions::default());
        assert_eq!(out.last().unwrap().track, Some(3));
    }

    #[test]
    fn rssi_of_unknown_nodes_is_counted_and_not_used() {
        let mut input: Vec<Estimate> = (0..4).map(|k| est(f64::from(k) * 0.5, 1.0, 1.0)).collect();
        for e in &mut input {
            e.rssi.insert("7".into(), -60.0);
            e.rssi.insert("99".into(), -50.0);
        }
        let nodes = RssiNodes {
            positions: [("7".to_string(), Vector3::new(4.0, 1.0, 2.0))]
                .into_iter()
                .collect(),
            model: RssiModel::default(),
        };
        let (out, counts) = track_with_rssi(&input, &TrackOptions::default(), &nodes);
        assert_eq!(counts.rssi_used, 4);
        assert_eq!(counts.rssi_unknown_node, 4);
        assert!(out.iter().all(|e| e.rssi_nodes == Some(1)));
        let (plain, _) = track(&input, &TrackOptions::default());
        assert!(plain.iter().all(|e| e.rssi_nodes == Some(0)));
        assert_ne!(
            plain.last().unwrap().x,
            out.last().unwrap().x,
            "the reading was used"
        );
    }
}
