//! Births from ground-plane people: each camera's floor position is already a position, so a
//! group of detections from distinct cameras whose positions agree (pairwise Mahalanobis with
//! the summed covariances within the gate) is fused by inverse-covariance weighting and
//! starts a track at half the measured height (or on `z = plane_z`), if it lies in the world
//! box.

use super::{BIRTH_BOUNDS_MARGIN, Birth, Detection, within};
use crate::init::state_from_position;
use nalgebra::{Matrix2, Matrix3, Vector2, Vector3};

/// Standard deviation of a ground-born track's height, m: the floor position says nothing of it.
pub const GROUND_BIRTH_Z_SIGMA: f64 = 0.5;

fn agree(a: &Detection, b: &Detection, gate: f64) -> bool {
    let d = a.point - b.point;
    (a.cov + b.cov)
        .cholesky()
        .is_some_and(|c| d.dot(&c.solve(&d)) <= gate)
}

/// Inverse-covariance weighted mean of the members' floor positions and its covariance.
fn fuse(dets: &[Detection], members: &[usize]) -> Option<(Vector2<f64>, Matrix2<f64>)> {
    let mut info = Matrix2::zeros();
    let mut vec = Vector2::zeros();
    for &i in members {
        let inv = dets[i].cov.try_inverse()?;
        info += inv;
        vec += inv * dets[i].point;
    }
    let cov = info.try_inverse()?;
    Some((cov * vec, cov))
}

/// Tracks to start from the ground-plane detections among `dets` (the others are ignored):
/// largest agreeing groups first, each with at least `min_cameras` (at least 1) cameras.
pub fn ground_births(
    dets: &[Detection],
    gate: f64,
    min_cameras: usize,
    plane_z: f64,
    bounds: ([f64; 3], [f64; 3]),
) -> Vec<Birth> {
    let mut left: Vec<usize> = (0..dets.len()).filter(|&i| dets[i].ground.is_some()).collect();
    let mut out = Vec::new();
    while !left.is_empty() {
        // The largest group around some seed: the seed plus one agreeing detection per other
        // camera, in order.
        let mut best: Vec<usize> = Vec::new();
        for &seed in &left {
            let mut group = vec![seed];
            for &k in &left {
                if group
                    .iter()
                    .all(|&g| dets[g].slot != dets[k].slot && agree(&dets[g], &dets[k], gate))
                {
                    group.push(k);
                }
            }
            if group.len() > best.len() {
                best = group;
            }
        }
        left.retain(|i| !best.contains(i));
        if best.len() < min_cameras.max(1) {
            continue;
        }
        let Some((p, c)) = fuse(dets, &best) else { continue };
        // The centre is at half the measured height (the members' mean); `plane_z` without one.
        let heights: Vec<f64> = best
            .iter()
            .filter_map(|&i| dets[i].ground)
            .filter(|h| *h > 0.0)
            .collect();
        let z = if heights.is_empty() {
            plane_z
        } else {
            0.5 * heights.iter().sum::<f64>() / heights.len() as f64
        };
        let p3 = Vector3::new(p.x, p.y, z);
        if !within(&p3, bounds, BIRTH_BOUNDS_MARGIN, 2) {
            continue;
        }
        let mut c3 = Matrix3::zeros();
        c3.fixed_view_mut::<2, 2>(0, 0).copy_from(&c);
        c3[(2, 2)] = GROUND_BIRTH_Z_SIGMA.powi(2);
        let (mean, cov) = state_from_position(&p3, &c3);
        out.push(Birth {
            mean,
            cov,
            members: best,
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::association::{associate, births};
    use proto::models::State;
    use proto::{ClusterTime, NodeId};

    const ROOM: ([f64; 3], [f64; 3]) = ([0.0, 0.0, 0.0], [12.0, 8.0, 3.0]);

    fn det(slot: usize, x: f64, y: f64) -> Detection {
        Detection {
            node: NodeId(slot as u32),
            slot,
            point: Vector2::new(x, y),
            cov: Matrix2::identity() * 0.1f64.powi(2),
            prev_point: None,
            hint: None,
            captured: ClusterTime::ZERO,
            ground: Some(1.8),
            appearance: None,
        }
    }

    #[test]
    fn agreeing_floor_positions_of_two_cameras_start_one_track() {
        let dets = vec![det(0, 2.0, 3.0), det(1, 2.1, 3.05), det(1, 6.0, 5.0)];
        let got = ground_births(&dets, 13.8, 2, 0.9, ROOM);
        assert_eq!(got.len(), 1, "the lone far person needs a second camera");
        assert_eq!(got[0].members, vec![0, 1]);
        assert!((got[0].mean[0] - 2.05).abs() < 1e-9 && (got[0].mean[1] - 3.025).abs() < 1e-9);
        assert_eq!(got[0].mean[2], 0.9, "half the measured height");
        // With one camera enough, the far person starts a track too; outside the room none.
        assert_eq!(ground_births(&dets, 13.8, 1, 0.9, ROOM).len(), 2);
        assert!(ground_births(&[det(0, 30.0, 3.0)], 13.8, 1, 0.9, ROOM).is_empty());
        // `births` takes ground detections through the same path, and no rays from them.
        assert_eq!(births(&dets, &[], 13.8, 2, 0.9, ROOM).len(), 1);
    }

    /// Ground detections of one camera associated with tracks standing at `at` (floor
    /// positions, 0.9 m centre height, covariance 0.05 I).
    fn associate_at(at: &[(f64, f64)], dets: &[Detection]) -> Vec<Option<usize>> {
        let cov = nalgebra::Matrix6::identity() * 0.05;
        let tracks: Vec<_> = at
            .iter()
            .map(|&(x, y)| (State::new(x, y, 0.9, 0.0, 0.0, 0.0), cov, ClusterTime::ZERO))
            .collect();
        let cams = vec![crate::init::tests::cam([0.0, 0.0, 2.5], [3.0, 3.0, 0.0])];
        associate(&tracks, dets, &cams, 13.8)
    }

    #[test]
    fn two_people_side_by_side_each_get_their_track() {
        // Person A lies nearer track 0 than person B does, but B gates only track 0:
        // nearest-first gave track 0 person A and left B free (a birth next to a live track).
        let dets = [det(0, 2.4, 3.0), det(0, 1.5, 3.0)];
        assert_eq!(
            associate_at(&[(2.0, 3.0), (2.9, 3.0)], &dets),
            vec![Some(1), Some(0)]
        );
    }

    #[test]
    fn floor_positions_gate_in_the_floor_plane() {
        let dets = [det(0, 6.1, 5.0), det(0, 2.0, 2.9), det(0, 9.0, 1.0)];
        assert_eq!(
            associate_at(&[(2.0, 3.0), (6.0, 5.0)], &dets),
            vec![Some(1), Some(0), None]
        );
    }
}
