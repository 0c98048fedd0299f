//! Global nearest neighbour association: the optimal assignment of a frame's detections to the
//! tracks over gated costs (squared Mahalanobis distances).
//!
//! A detection paired with a track costs its d²; a detection left free costs the gate (the
//! usual dummy column per detection at the gate cost, so a detection may stay unassigned); a
//! pair outside the gate is forbidden. Each detection goes to at most one track, and each track
//! takes at most one detection *per camera*, so the problem splits into one assignment per
//! camera. Minimising Σ d² + gate · (free detections) is the same as maximising Σ (gate − d²)
//! over the chosen pairs, so each camera's problem is solved as a maximum-weight matching with
//! weights gate − d² ≥ 0: the dummy columns folded into the weights, without enlarging the
//! matrix. The solver is [`crate::matching::max_weight_matching`].

use crate::matching::max_weight_matching;

/// One frame's association problem: rows are detections (each seen by one camera), columns
/// are tracks.
#[derive(Clone, Debug, PartialEq)]
pub struct GatedCosts {
    tracks: usize,
    gate: f64,
    cameras: Vec<usize>,
    /// Row-major d²; `f64::INFINITY` marks a pair outside the gate.
    d2: Vec<f64>,
}

/// Why a cost table was refused.
#[derive(Debug, Clone, PartialEq)]
pub enum AssignError {
    /// The gate is not a finite number > 0.
    Gate(f64),
    /// A detection's row has the wrong number of costs.
    Width {
        detection: usize,
        got: usize,
        tracks: usize,
    },
    /// A squared distance is negative or NaN.
    Cost {
        detection: usize,
        track: usize,
        value: f64,
    },
}

impl std::fmt::Display for AssignError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            AssignError::Gate(g) => write!(f, "gate {g}: expected a finite number > 0"),
            AssignError::Width {
                detection,
                got,
                tracks,
            } => write!(f, "detection {detection}: {got} costs given for {tracks} tracks"),
            AssignError::Cost {
                detection,
                track,
                value,
            } => write!(
                f,
                "detection {detection}, track {track}: squared distance {value} is negative or NaN"
            ),
        }
    }
}

impl std::error::Error for AssignError {}

impl GatedCosts {
    /// An empty table for `tracks` tracks with a gate on d² (e.g. a χ² quantile).
    ///
    /// # Errors
    /// [`AssignError::Gate`] when the gate is not finite and positive.
    pub fn new(tracks: usize, gate: f64) -> Result<Self, AssignError> {
        if !(gate.is_finite() && gate > 0.0) {
            return Err(AssignError::Gate(gate));
        }
        Ok(GatedCosts {
            tracks,
            gate,
            cameras: Vec::new(),
            d2: Vec::new(),
        })
    }

    /// Adds a detection seen by `camera` with its d² to every track (`None` when it could not be
    /// computed); values above the gate, and +∞, are outside it. Returns the detection's row.
    ///
    /// # Errors
    /// [`AssignError::Width`] when `d2` does not have one entry per track, [`AssignError::Cost`]
    /// for a negative or NaN value; the table is unchanged then.
    pub fn push(&mut self, camera: usize, d2: &[Option<f64>]) -> Result<usize, AssignError> {
        let detection = self.cameras.len();
        if d2.len() != self.tracks {
            return Err(AssignError::Width {
                detection,
                got: d2.len(),
                tracks: self.tracks,
            });
        }
        if let Some((track, value)) = d2
            .iter()
            .enumerate()
            .find_map(|(t, v)| v.filter(|x| x.is_nan() || *x < 0.0).map(|x| (t, x)))
        {
            return Err(AssignError::Cost {
                detection,
                track,
                value,
            });
        }
        self.cameras.push(camera);
        self.d2.extend(
            d2.iter()
                .map(|v| v.filter(|x| *x <= self.gate).unwrap_or(f64::INFINITY)),
        );
        Ok(detection)
    }

    pub fn detections(&self) -> usize {
        self.cameras.len()
    }

    pub fn tracks(&self) -> usize {
        self.tracks
    }

    pub fn gate(&self) -> f64 {
        self.gate
    }

    /// The camera of a detection.
    pub fn camera(&self, detection: usize) -> Option<usize> {
        self.cameras.get(detection).copied()
    }

    /// d² of a pair inside the gate; `None` outside it (or out of range).
    pub fn cost(&self, detection: usize, track: usize) -> Option<f64> {
        if detection >= self.detections() || track >= self.tracks {
            return None;
        }
        Some(self.d2[detection * self.tracks + track]).filter(|x| x.is_finite())
    }

    /// Whether a detection has a pair inside the gate with any track.
    pub fn gated(&self, detection: usize) -> bool {
        (0..self.tracks).any(|t| self.cost(detection, t).is_some())
    }

    /// The total cost of an assignment (d² per pair, the gate per free detection), or `None` when
    /// it is not feasible: wrong length, a pair outside the gate, or a track given two detections
    /// of one camera.
    pub fn total_cost(&self, assignment: &[Option<usize>]) -> Option<f64> {
        if assignment.len() != self.detections() {
            return None;
        }
        let mut taken = std::collections::HashSet::new();
        let mut total = 0.0;
        for (det, track) in assignment.iter().enumerate() {
            match track {
                None => total += self.gate,
                Some(t) => {
                    total += self.cost(det, *t)?;
                    if !taken.insert((self.cameras[det], *t)) {
                        return None;
                    }
                }
            }
        }
        Some(total)
    }
}

/// The optimal association: entry `i` is the track of detection `i`, or `None` when it stays
/// free. Never pairs outside the gate; each track gets at most one detection per camera; the
/// total cost (d² per pair, the gate per free detection) is minimal up to 10⁻¹² of the gate per
/// detection.
///
/// Each camera's problem is split further into the connected components of its gated pairs
/// (detections and tracks linked by a pair inside the gate), which are independent: a crowd
/// becomes many small matchings instead of one large, mostly forbidden one.
pub fn assign(costs: &GatedCosts) -> Vec<Option<usize>> {
    let mut out = vec![None; costs.detections()];
    let mut rows: Vec<usize> = (0..costs.detections()).collect();
    rows.sort_by_key(|&i| costs.cameras[i]);
    for group in rows.chunk_by(|a, b| costs.cameras[*a] == costs.cameras[*b]) {
        for (dets, tracks) in components(costs, group) {
            let pairs = max_weight_matching(dets.len(), tracks.len(), costs.gate, false, |r, c| {
                costs.cost(dets[r], tracks[c]).map(|d2| costs.gate - d2)
            });
            for (r, c) in pairs.into_iter().enumerate() {
                out[dets[r]] = c.map(|c| tracks[c]);
            }
        }
    }
    out
}

/// The connected components of the gated pairs among `dets` (one camera's detections) and all
/// tracks, as (detections, tracks) in increasing order; detections and tracks with no pair
/// inside the gate are left out.
fn components(costs: &GatedCosts, dets: &[usize]) -> Vec<(Vec<usize>, Vec<usize>)> {
    fn root(parent: &mut [usize], mut x: usize) -> usize {
        while parent[x] != x {
            parent[x] = parent[parent[x]];
            x = parent[x];
        }
        x
    }
    let n = dets.len();
    // Nodes 0..n are the detections, n..n + tracks the tracks.
    let mut parent: Vec<usize> = (0..n + costs.tracks).collect();
    let mut linked = vec![false; n + costs.tracks];
    for (r, &det) in dets.iter().enumerate() {
        for t in 0..costs.tracks {
            if costs.cost(det, t).is_some() {
                let (a, b) = (root(&mut parent, r), root(&mut parent, n + t));
                parent[a.max(b)] = a.min(b);
                linked[r] = true;
                linked[n + t] = true;
            }
        }
    }
    let mut slot = vec![usize::MAX; n + costs.tracks];
    let mut out: Vec<(Vec<usize>, Vec<usize>)> = Vec::new();
    for node in (0..n + costs.tracks).filter(|&x| linked[x]) {
        let r = root(&mut parent, node);
        if slot[r] == usize::MAX {
            slot[r] = out.len();
            out.push((Vec::new(), Vec::new()));
        }
        let (ds, ts) = &mut out[slot[r]];
        if node < n {
            ds.push(dets[node])
        } else {
            ts.push(node - n)
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn table(gate: f64, rows: &[(usize, &[Option<f64>])]) -> GatedCosts {
        let mut c = GatedCosts::new(rows.first().map_or(0, |r| r.1.len()), gate).unwrap();
        for (camera, d2) in rows {
            c.push(*camera, d2).unwrap();
        }
        c
    }

    /// The least total cost over every feasible assignment, by enumeration.
    fn brute_force(c: &GatedCosts) -> f64 {
        fn go(c: &GatedCosts, det: usize, a: &mut Vec<Option<usize>>, best: &mut f64) {
            if det == c.detections() {
                if let Some(total) = c.total_cost(a) {
                    *best = best.min(total);
                }
                return;
            }
            for choice in std::iter::once(None).chain((0..c.tracks()).map(Some)) {
                a.push(choice);
                go(c, det + 1, a, best);
                a.pop();
            }
        }
        let mut best = f64::INFINITY;
        go(c, 0, &mut Vec::new(), &mut best);
        best
    }

    #[test]
    fn optimal_where_nearest_first_is_wrong() {
        // Greedy nearest-first takes detection 0 → track 0 (d² = 1) and leaves detection 1, which
        // only reaches track 0, free (the gate, 9): total 10. The optimum pairs 0 → 1 and 1 → 0:
        // 3 + 2 = 5.
        let c = table(9.0, &[(0, &[Some(1.0), Some(3.0)]), (0, &[Some(2.0), None])]);
        let a = assign(&c);
        assert_eq!(a, vec![Some(1), Some(0)]);
        assert_eq!(c.total_cost(&a), Some(5.0));
        assert_eq!(c.total_cost(&[Some(0), None]), Some(10.0));
    }

    #[test]
    fn forbidden_pairs_are_never_chosen() {
        // Kuhn–Munkres pairs every row of a square matrix; detection 0 has no allowed pair
        // (`None`: not computable; +∞; above the gate), so it must come back free.
        let c = table(
            9.0,
            &[
                (0, &[None, Some(f64::INFINITY), Some(9.5)]),
                (0, &[None, Some(1.0), None]),
            ],
        );
        assert_eq!(
            (c.cost(0, 1), c.cost(0, 2), c.cost(1, 1)),
            (None, None, Some(1.0))
        );
        assert_eq!(assign(&c), vec![None, Some(1)]);
        assert!(
            !c.gated(0) && c.gated(1) && !c.gated(2),
            "out of range: not gated"
        );
        // A lone pair just outside the gate stays apart; one on the gate may pair (same cost).
        assert_eq!(assign(&table(4.0, &[(0, &[Some(4.000001)])])), vec![None]);
        assert_eq!(table(4.0, &[(0, &[Some(4.0)])]).cost(0, 0), Some(4.0));
    }

    #[test]
    fn one_detection_per_camera_per_track() {
        // Two cameras see the same person: both detections go to track 0. Two detections of
        // one camera compete: the closer one wins and the other stays free.
        let c = table(9.0, &[(3, &[Some(1.0)]), (5, &[Some(2.0)]), (3, &[Some(0.5)])]);
        assert_eq!(assign(&c), vec![None, Some(0), Some(0)]);
        assert!(c.gated(0), "left free, but inside the gate");
    }

    #[test]
    fn empty_problems() {
        assert_eq!(
            assign(&GatedCosts::new(3, 1.0).unwrap()),
            Vec::<Option<usize>>::new()
        );
        assert_eq!(assign(&table(1.0, &[(0, &[]), (1, &[])])), vec![None, None]);
    }

    #[test]
    fn bad_input_is_refused_and_changes_nothing() {
        assert_eq!(GatedCosts::new(2, 0.0), Err(AssignError::Gate(0.0)));
        assert!(matches!(GatedCosts::new(2, f64::NAN), Err(AssignError::Gate(_))));
        let mut c = table(9.0, &[(0, &[Some(1.0), None])]);
        let before = c.clone();
        assert_eq!(
            c.push(0, &[Some(1.0)]),
            Err(AssignError::Width {
                detection: 1,
                got: 1,
                tracks: 2
            })
        );
        let e = c.push(1, &[Some(1.0), Some(-0.5)]).unwrap_err();
        assert_eq!(
            e.to_string(),
            "detection 1, track 1: squared distance -0.5 is negative or NaN"
        );
        assert!(matches!(
            c.push(1, &[Some(f64::NAN), None]),
            Err(AssignError::Cost { track: 0, .. })
        ));
        assert_eq!(c, before);
    }

    /// Up to 6 detections from up to 2 cameras and up to 4 tracks; d² in [0, 12] with gate 9,
    /// each present with probability `density` (sparse tables split into several components).
    fn problem(density: f64) -> impl Strategy<Value = GatedCosts> {
        (0usize..5).prop_flat_map(move |tracks| {
            prop::collection::vec(
                (
                    0usize..2,
                    prop::collection::vec(prop::option::weighted(density, 0.0..12.0f64), tracks),
                ),
                0..7,
            )
            .prop_map(move |rows| {
                let mut c = GatedCosts::new(tracks, 9.0).unwrap();
                for (camera, d2) in rows {
                    c.push(camera, &d2).unwrap();
                }
                c
            })
        })
    }

    proptest! {
        #[test]
        fn matches_brute_force(c in problem(0.8)) {
            check_against_brute_force(&c)?;
        }

        #[test]
        fn matches_brute_force_when_sparse(c in problem(0.3)) {
            check_against_brute_force(&c)?;
        }
    }

    fn check_against_brute_force(c: &GatedCosts) -> Result<(), TestCaseError> {
        let a = assign(c);
        let total = c.total_cost(&a);
        prop_assert!(total.is_some(), "infeasible assignment {:?}", a);
        let best = brute_force(c);
        prop_assert!(
            (total.unwrap() - best).abs() < 1e-9,
            "{:?} costs {:?}, optimum {}",
            a,
            total,
            best
        );
        Ok(())
    }
}
