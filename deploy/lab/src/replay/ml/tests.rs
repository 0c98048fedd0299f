use super::*;
use crate::replay::cameras::Cameras;
use proto::camera::{CameraModel, Distortion, Intrinsics, Pose};
use std::collections::BTreeMap;

fn cam(pos: [f64; 3], at: [f64; 3]) -> CameraModel {
    CameraModel {
        intrinsics: Intrinsics {
            fx: 800.0,
            fy: 800.0,
            cx: 640.0,
            cy: 360.0,
            width: 1280,
            height: 720,
        },
        distortion: Distortion {
            k1: -0.1,
            k2: 0.01,
            p1: 0.001,
            p2: -0.001,
            k3: 0.0,
        },
        pose: Pose::look_at(Vector3::from(pos), Vector3::from(at), Vector3::z()).unwrap(),
    }
}

fn three_cameras() -> Cameras {
    let mut models = BTreeMap::new();
    models.insert("a".into(), cam([0.0, 0.0, 3.0], [4.0, 4.0, 0.0]));
    models.insert("b".into(), cam([8.0, 0.0, 3.0], [4.0, 4.0, 0.0]));
    models.insert("c".into(), cam([4.0, 9.0, 3.0], [4.0, 4.0, 0.0]));
    Cameras { models, mirror: None }
}

fn detect(cams: &Cameras, t: f64, p: Vector3<f64>) -> Vec<ExternalDetection> {
    cams.models
        .iter()
        .map(|(id, c)| {
            let px = c.project(&p).unwrap();
            ExternalDetection {
                t,
                camera: id.clone(),
                u: px.x,
                v: px.y,
                pixel_box: None,
                rssi: None,
            }
        })
        .collect()
}

#[test]
fn two_people_on_the_floor_are_grouped_apart_and_fused_exactly() {
    let cams = three_cameras();
    let (p, q) = (Vector3::new(3.0, 4.0, 0.0), Vector3::new(4.5, 4.2, 0.0));
    let mut dets = detect(&cams, 1.0, p);
    dets.extend(detect(&cams, 1.0, q));
    dets.reverse();
    let opts = MlOptions {
        plane_z: Some(0.0),
        ..MlOptions::default()
    };
    let (est, skipped) = replay_ml(&dets, &cams, &opts);
    assert_eq!(skipped, Skipped::default());
    assert_eq!(est.len(), 2);
    for truth in [p, q] {
        let e = est
            .iter()
            .find(|e| (Vector3::new(e.x, e.y, e.z) - truth).norm() < 1e-6)
            .unwrap_or_else(|| panic!("no estimate at {truth}: {est:?}"));
        assert_eq!(e.cameras, 3);
        assert!(e.cov[0][0] > 0.0 && e.cov[1][1] > 0.0);
    }
}

#[test]
fn a_gate_smaller_than_the_noise_splits_and_unknown_cameras_are_counted() {
    let cams = three_cameras();
    let mut dets = detect(&cams, 0.0, Vector3::new(4.0, 4.0, 0.0));
    dets[0].u += 40.0;
    dets.push(ExternalDetection {
        camera: "nope".into(),
        ..dets[1].clone()
    });
    let tight = MlOptions {
        plane_z: Some(0.0),
        gate_m: 0.01,
        ..MlOptions::default()
    };
    let (est, skipped) = replay_ml(&dets, &cams, &tight);
    assert_eq!(skipped.unknown_camera, 1);
    assert_eq!(est.len(), 2, "the displaced view stands alone: {est:?}");
    let (est, _) = replay_ml(
        &dets,
        &cams,
        &MlOptions {
            min_cameras: 2,
            ..tight
        },
    );
    assert_eq!(est.len(), 1);
    assert_eq!(est[0].cameras, 2);
}

#[test]
fn without_a_plane_one_target_is_triangulated() {
    let cams = three_cameras();
    let p = Vector3::new(3.5, 4.5, 1.2);
    let (est, skipped) = replay_ml(&detect(&cams, 2.0, p), &cams, &MlOptions::default());
    assert_eq!(skipped, Skipped::default());
    assert_eq!(est.len(), 1);
    let e = Vector3::new(est[0].x, est[0].y, est[0].z);
    assert!((e - p).norm() < 0.05, "{e} vs {p}");
    // Two targets in one camera cannot be told apart without a plane.
    let mut two = detect(&cams, 2.0, p);
    two.extend(detect(&cams, 2.0, Vector3::new(5.0, 3.0, 1.0)));
    let (est, skipped) = replay_ml(&two, &cams, &MlOptions::default());
    assert!(est.is_empty());
    assert_eq!(skipped.ambiguous, 6);
}

#[test]
fn a_mirrored_world_is_reported_back_in_the_users_coordinates() {
    let mut cams = three_cameras();
    let user = Vector3::new(3.0, -4.0, 0.0);
    cams.mirror = Some(proto::opencv::MirrorAxis::Y);
    // Detections are made in the solver's (mirrored) world: the user's point (3, −4) is (3, 4).
    let dets = detect(&cams, 0.0, cams.to_solver(&user));
    let opts = MlOptions {
        plane_z: Some(0.0),
        ..MlOptions::default()
    };
    let (est, _) = replay_ml(&dets, &cams, &opts);
    assert_eq!(est.len(), 1);
    assert!((Vector3::new(est[0].x, est[0].y, est[0].z) - user).norm() < 1e-6);
}

/// The grouping before it was made sparse: every pair's distance in an n × n matrix.
fn dense_cluster(points: &[(usize, Vector3<f64>, Matrix3<f64>)], gate: f64) -> Vec<Vec<usize>> {
    let n = points.len();
    let mut members: Vec<Vec<usize>> = (0..n).map(|i| vec![i]).collect();
    let mut alive = vec![true; n];
    let mut d = vec![f64::INFINITY; n * n];
    for i in 0..n {
        for j in 0..n {
            if i != j && points[i].0 != points[j].0 {
                d[i * n + j] = (points[i].1.xy() - points[j].1.xy()).norm();
            }
        }
    }
    loop {
        let mut best = (f64::INFINITY, 0, 0);
        for i in (0..n).filter(|&i| alive[i]) {
            for j in (i + 1..n).filter(|&j| alive[j]) {
                if d[i * n + j] < best.0 {
                    best = (d[i * n + j], i, j);
                }
            }
        }
        let (dist, i, j) = best;
        if dist > gate {
            break;
        }
        let moved = std::mem::take(&mut members[j]);
        members[i].extend(moved);
        alive[j] = false;
        for k in 0..n {
            let m = d[i * n + k].max(d[j * n + k]);
            d[i * n + k] = m;
            d[k * n + i] = m;
        }
    }
    members.into_iter().filter(|m| !m.is_empty()).collect()
}

/// The sparse grouping is the dense one, on crowds of every density.
#[test]
fn sparse_grouping_equals_the_dense_one() {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    for case in 0..60 {
        let n = rng.random_range(0..120);
        let side = rng.random_range(0.5..20.0);
        let cameras = rng.random_range(1..7);
        let gate = rng.random_range(0.2..2.0);
        let points: Vec<_> = (0..n)
            .map(|_| {
                // Coarse coordinates make equal distances (ties) common.
                let q = |x: f64| (x * 4.0).round() / 4.0;
                let p = Vector3::new(
                    q(rng.random_range(0.0..side)),
                    q(rng.random_range(0.0..side)),
                    0.0,
                );
                (rng.random_range(0..cameras), p, Matrix3::identity())
            })
            .collect();
        assert_eq!(
            cluster(&points, gate),
            dense_cluster(&points, gate),
            "case {case}"
        );
    }
}
