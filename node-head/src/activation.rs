//! Greedy sensor activation (paper 000 §5, paper 002 §V, Algorithm 2): at most one action per
//! step, the one whose expected information gain most exceeds its energy cost.
//!
//! Reward of an action: ½ log(|Ω^a| / |Ω|) where Ω is the predicted information of the next
//! step with the expected contributions of the sensors as they are, and Ω^a the same after the
//! action. Adding or removing a sensor's rows H (Q their noise) changes Ω by ±HᵀQ⁻¹H, so by the
//! matrix determinant lemma the ratio is |Q ± H Σ Hᵀ| / |Q| with Σ = Ω⁻¹: a determinant of at
//! most 3×3 per candidate and track, which keeps the decision linear in the number of nodes.
//! Cost: `energy_weight × cost_factor × (P(to) − P(from))` from the node's power figures (the
//! head passes the scenario's weight, nats per mJ, times the step in seconds: the cost is the
//! energy difference over the step whose information gain is the reward), so c1
//! is the node's active-minus-low-power draw and c2 its camera's (paper 002 Fig. 3); savings are
//! negative costs.
//!
//! Lost cameras (opt-in, [`Planner::watching_deliveries`]): paper 000's Ω counts "the sensors
//! currently used". A camera that is on, expected to see a track, but delivered nothing since
//! the last decision (paper 000 §6.2 loses cameras 2 and 3's measurements for 15 s; the head
//! cannot know why) is not counted in Ω, and no action is taken on it: switching it off and on
//! again would spend the one action per step on a camera whose worth nothing measures. The
//! camera the last decision switched on counts before its first frame. A plain planner counts
//! every camera on, as its mode says (paper 002's planners).

use nalgebra::{Matrix2, Matrix3, Matrix6, SMatrix, Vector3};
use proto::Mode;
use proto::NodeId;
use proto::camera::CameraModel;
use proto::models::{Info, RssiModel, State, pinhole};
use proto::scenario::{PowerFigures, Wall};

/// Which actions are available and which measurements a mode yields.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Variant {
    /// Paper 002 Method2 / paper 000 §5: cameras on or off, camera measurements only.
    CameraOnly,
    /// Paper 002 §V-A: Active (camera + RSSI) or Inactive.
    FullNode,
    /// Paper 002 §V-B: Active, CameraOff (RSSI only) or Inactive.
    ThreeMode,
}

impl Variant {
    fn yields(self, mode: Mode) -> (bool, bool) {
        match (self, mode) {
            (_, Mode::Inactive) => (false, false),
            (Variant::CameraOnly, Mode::Active) => (true, false),
            (Variant::CameraOnly, Mode::CameraOff) => (false, false),
            (_, Mode::Active) => (true, true),
            (_, Mode::CameraOff) => (false, true),
        }
    }

    fn targets(self, from: Mode) -> &'static [Mode] {
        match (self, from) {
            (Variant::ThreeMode, Mode::Active) => &[Mode::CameraOff, Mode::Inactive],
            (Variant::ThreeMode, Mode::CameraOff) => &[Mode::Active, Mode::Inactive],
            (Variant::ThreeMode, Mode::Inactive) => &[Mode::Active, Mode::CameraOff],
            (_, Mode::Active) => &[Mode::Inactive],
            (_, _) => &[Mode::Active],
        }
    }
}

/// What a node is expected to measure of one track next step.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Expected {
    /// Pin-hole Jacobian and normalized-point covariance, when the track is in view.
    pub camera: Option<(SMatrix<f64, 2, 6>, Matrix2<f64>)>,
    /// RSSI Jacobian and variance.
    pub rssi: Option<(SMatrix<f64, 1, 6>, f64)>,
}

impl Expected {
    /// Expected measurements of a node at the predicted `mean`: the camera's only when the
    /// point projects inside the image in front of it and no wall of `walls` stands between the
    /// camera and the point (paper 002 §VI-B: an occluded camera contributes nothing, while its
    /// radio still hears the tag).
    pub fn at(
        camera: Option<&CameraModel>,
        walls: &[Wall],
        pixel_sigma: f64,
        rssi: Option<(&RssiModel, &Vector3<f64>)>,
        mean: &State,
    ) -> Self {
        let camera = camera.and_then(|cam| {
            let world = mean.fixed_rows::<3>(0).into_owned();
            let px = cam.project(&world)?;
            let k = &cam.intrinsics;
            if !(px.x >= 0.0 && px.y >= 0.0 && px.x < k.width as f64 && px.y < k.height as f64) {
                return None;
            }
            let centre = cam.pose.centre();
            if walls.iter().any(|w| w.crosses(&centre, &world)) {
                return None;
            }
            let (h, jac) = pinhole(cam, mean)?;
            Some((jac, cam.normalized_covariance(&h, pixel_sigma)))
        });
        let rssi = rssi.map(|(model, node)| {
            let (_, jac) = model.measurement(node, mean);
            (jac, model.variance())
        });
        Expected { camera, rssi }
    }

    fn info(&self, cam: bool, rssi: bool) -> Info {
        let mut o = Matrix6::zeros();
        if cam
            && let Some((h, q)) = &self.camera
            && let Some(qi) = q.try_inverse()
        {
            o += h.transpose() * qi * h;
        }
        if rssi && let Some((h, v)) = &self.rssi {
            o += h.transpose() * h / *v;
        }
        o
    }
}

/// A node the planner may act on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Candidate {
    pub node: NodeId,
    pub mode: Mode,
    pub power: PowerFigures,
    pub cost_factor: f64,
}

/// The chosen action.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Decision {
    pub node: NodeId,
    pub from: Mode,
    pub to: Mode,
    /// Expected information gain, nats (negative for a loss).
    pub reward: f64,
    /// Energy cost in nats (negative for a saving).
    pub cost: f64,
}

/// ½ log(|Q + s H Σ Hᵀ| / |Q|) for the rows selected; −∞ when a removal would leave the
/// information singular.
fn gain(e: &Expected, cam: bool, rssi: bool, sigma: &Matrix6<f64>, sign: f64) -> f64 {
    let cam = if cam { e.camera.as_ref() } else { None };
    let rssi = if rssi { e.rssi.as_ref() } else { None };
    let ratio = match (cam, rssi) {
        (None, None) => return 0.0,
        (Some((h, q)), None) => {
            let s = q + h * sigma * h.transpose() * sign;
            s.determinant() / q.determinant()
        }
        (None, Some((h, v))) => 1.0 + sign * (h * sigma * h.transpose())[(0, 0)] / v,
        (Some((hc, q)), Some((hr, v))) => {
            let mut h = SMatrix::<f64, 3, 6>::zeros();
            h.fixed_rows_mut::<2>(0).copy_from(hc);
            h.fixed_rows_mut::<1>(2).copy_from(hr);
            let mut qq = Matrix3::zeros();
            qq.fixed_view_mut::<2, 2>(0, 0).copy_from(q);
            qq[(2, 2)] = *v;
            let s = qq + h * sigma * h.transpose() * sign;
            s.determinant() / qq.determinant()
        }
    };
    if ratio > 0.0 && ratio.is_finite() {
        0.5 * ratio.ln()
    } else {
        f64::NEG_INFINITY
    }
}

/// The planner. Reuses its scratch space, so a decision allocates nothing once warmed up.
#[derive(Debug, Default)]
pub struct Planner {
    expected: Vec<Expected>,
    sigmas: Vec<Matrix6<f64>>,
    /// Nodes whose camera delivered a measurement since the last decision, when deliveries are
    /// watched (`None`: every camera on counts, as its mode says).
    delivered: Option<Vec<NodeId>>,
    /// The node the last decision switched a camera on at: it has had no frame to deliver yet.
    switched_on: Option<NodeId>,
}

impl Planner {
    /// A planner that counts a camera that is on only while it delivers (see
    /// [`Planner::camera_delivered`]).
    pub fn watching_deliveries() -> Self {
        Planner {
            delivered: Some(Vec::new()),
            ..Planner::default()
        }
    }

    /// Node `node`'s camera delivered a measurement this step.
    pub fn camera_delivered(&mut self, node: NodeId) {
        if let Some(d) = &mut self.delivered
            && !d.contains(&node)
        {
            d.push(node);
        }
    }

    /// Whether a camera that is on is one of "the sensors currently used" (paper 000 §5): it
    /// delivered since the last decision, or that decision just switched it on.
    fn in_use(&self, node: NodeId) -> bool {
        self.delivered
            .as_ref()
            .is_none_or(|d| d.contains(&node) || self.switched_on == Some(node))
    }

    /// Whether candidate `n` (of `nt` tracks' expectations) has its camera on and expected to
    /// see a track, yet delivered nothing: its measurements are lost.
    fn lost(&self, variant: Variant, n: usize, c: &Candidate, nt: usize) -> bool {
        variant.yields(c.mode).0
            && !self.in_use(c.node)
            && self.expected[n * nt..(n + 1) * nt]
                .iter()
                .any(|e| e.camera.is_some())
    }

    /// The decision, remembering what it switched on and forgetting this step's deliveries.
    fn decided(&mut self, variant: Variant, d: Option<Decision>) -> Option<Decision> {
        if let Some(v) = &mut self.delivered {
            v.clear();
        }
        self.switched_on = d
            .filter(|d| variant.yields(d.to).0 && !variant.yields(d.from).0)
            .map(|d| d.node);
        d
    }

    /// Algorithm 2 over `nodes` for tracks with predicted information `predicted[t]` (Ω̄ of the
    /// next step). `expect(n, t)` gives node `n`'s expected measurements of track `t`.
    /// `None` when no action's reward exceeds its cost.
    pub fn decide(
        &mut self,
        variant: Variant,
        energy_weight: f64,
        nodes: &[Candidate],
        predicted: &[Info],
        mut expect: impl FnMut(usize, usize) -> Expected,
    ) -> Option<Decision> {
        let d = self.choose(variant, energy_weight, nodes, predicted, &mut expect);
        self.decided(variant, d)
    }

    fn choose(
        &mut self,
        variant: Variant,
        energy_weight: f64,
        nodes: &[Candidate],
        predicted: &[Info],
        expect: &mut impl FnMut(usize, usize) -> Expected,
    ) -> Option<Decision> {
        let nt = predicted.len();
        if nt == 0 {
            return None;
        }
        self.expected.clear();
        self.sigmas.clear();
        for n in 0..nodes.len() {
            for t in 0..nt {
                self.expected.push(expect(n, t));
            }
        }
        for (t, omega_bar) in predicted.iter().enumerate() {
            let mut omega = *omega_bar;
            for (n, c) in nodes.iter().enumerate() {
                let (cam, rssi) = variant.yields(c.mode);
                let cam = cam && !self.lost(variant, n, c, nt);
                omega += self.expected[n * nt + t].info(cam, rssi);
            }
            let sigma = crate::eif::spd_inverse(&omega, "expected information").ok()?;
            self.sigmas.push(sigma);
        }
        let mut best: Option<Decision> = None;
        for (n, c) in nodes.iter().enumerate() {
            if self.lost(variant, n, c, nt) {
                // On, but its measurements are lost: worth nothing now, and nothing tells what
                // switching it would change.
                continue;
            }
            let (cam0, rssi0) = variant.yields(c.mode);
            for &to in variant.targets(c.mode) {
                let (cam1, rssi1) = variant.yields(to);
                let adding = (cam1 && !cam0) || (rssi1 && !rssi0);
                let (dc, dr, sign) = if adding {
                    (cam1 && !cam0, rssi1 && !rssi0, 1.0)
                } else {
                    (cam0 && !cam1, rssi0 && !rssi1, -1.0)
                };
                let reward: f64 = (0..nt)
                    .map(|t| gain(&self.expected[n * nt + t], dc, dr, &self.sigmas[t], sign))
                    .sum();
                if !reward.is_finite() {
                    continue;
                }
                let cost = energy_weight * c.cost_factor * (c.power.in_mode(to) - c.power.in_mode(c.mode));
                let net = reward - cost;
                if net > 0.0 && best.is_none_or(|b| net > b.reward - b.cost) {
                    best = Some(Decision {
                        node: c.node,
                        from: c.mode,
                        to,
                        reward,
                        cost,
                    });
                }
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eif::log_det_spd;

    use crate::init::tests::cam;

    fn setup() -> (Vec<CameraModel>, State, Info) {
        let cams = vec![
            cam([0.0, 0.0, 2.5], [3.0, 3.0, 0.0]),
            cam([6.0, 0.0, 2.5], [3.0, 3.0, 0.0]),
            cam([3.0, 6.0, 2.5], [3.0, 3.0, 0.0]),
        ];
        let mean = State::new(3.0, 3.0, 0.2, 0.2, 0.0, 0.0);
        (cams, mean, Matrix6::identity() * 4.0)
    }

    #[test]
    fn determinant_lemma_matches_direct_log_det() {
        let (cams, mean, omega) = setup();
        let e = Expected::at(
            Some(&cams[0]),
            &[],
            18.0,
            Some((&RssiModel::default(), &Vector3::zeros())),
            &mean,
        );
        assert!(e.camera.is_some());
        let sigma = crate::eif::spd_inverse(&omega, "t").unwrap();
        let direct =
            0.5 * (log_det_spd(&(omega + e.info(true, true))).unwrap() - log_det_spd(&omega).unwrap());
        assert!((gain(&e, true, true, &sigma, 1.0) - direct).abs() < 1e-9);
        let with = omega + e.info(true, false);
        let sigma_with = crate::eif::spd_inverse(&with, "t").unwrap();
        let removal = 0.5 * (log_det_spd(&omega).unwrap() - log_det_spd(&with).unwrap());
        assert!((gain(&e, true, false, &sigma_with, -1.0) - removal).abs() < 1e-9);
    }

    #[test]
    fn activates_a_useful_camera_when_cheap_and_not_when_dear() {
        let (cams, mean, omega) = setup();
        let nodes = all(Mode::Inactive);
        let mut p = Planner::default();
        let expect = |n: usize, _t: usize| Expected::at(Some(&cams[n]), &[], 18.0, None, &mean);
        let d = p
            .decide(Variant::CameraOnly, 1e-3, &nodes, &[omega], expect)
            .unwrap();
        assert_eq!((d.from, d.to), (Mode::Inactive, Mode::Active));
        assert!(d.reward > d.cost);
        assert!(
            p.decide(Variant::CameraOnly, 1.0, &nodes, &[omega], expect)
                .is_none()
        );
    }

    fn all(mode: Mode) -> Vec<Candidate> {
        (0..3)
            .map(|i| Candidate {
                node: NodeId(10 + i),
                mode,
                power: PowerFigures::default(),
                cost_factor: 1.0,
            })
            .collect()
    }

    #[test]
    fn a_lost_camera_is_neither_counted_nor_switched_when_deliveries_are_watched() {
        let (cams, mean, omega) = setup();
        let expect = |n: usize, _t: usize| Expected::at(Some(&cams[n]), &[], 18.0, None, &mean);
        // Camera 10 on, 11 and 12 off; a price at which one camera is worth keeping but a
        // second is not worth adding next to it.
        let mut nodes = all(Mode::Inactive);
        nodes[0].mode = Mode::Active;
        let sigma_one = crate::eif::spd_inverse(&(omega + expect(0, 0).info(true, false)), "t").unwrap();
        let second = gain(&expect(1, 0), true, false, &sigma_one, 1.0).max(gain(
            &expect(2, 0),
            true,
            false,
            &sigma_one,
            1.0,
        ));
        let keep = -gain(&expect(0, 0), true, false, &sigma_one, -1.0);
        assert!(second < keep, "{second} {keep}");
        let w = (second + keep)
            / 2.0
            / (PowerFigures::default().in_mode(Mode::Active)
                - PowerFigures::default().in_mode(Mode::Inactive));
        // A plain planner counts camera 10 and leaves everything as it is.
        let mut plain = Planner::default();
        assert!(
            plain
                .decide(Variant::CameraOnly, w, &nodes, &[omega], expect)
                .is_none()
        );
        // Watching deliveries: while 10 delivers, the same.
        let mut p = Planner::watching_deliveries();
        p.camera_delivered(NodeId(10));
        assert!(
            p.decide(Variant::CameraOnly, w, &nodes, &[omega], expect)
                .is_none()
        );
        // 10 delivers nothing: it is not counted, so another camera is switched on, and 10 is
        // left alone.
        let d = p
            .decide(Variant::CameraOnly, w, &nodes, &[omega], expect)
            .unwrap();
        assert_ne!(d.node, NodeId(10));
        assert_eq!(d.to, Mode::Active);
        // The camera just switched on counts before its first frame: with it on (and 10 still
        // silent) nothing more is worth doing.
        let on = nodes.iter().position(|c| c.node == d.node).unwrap();
        nodes[on].mode = Mode::Active;
        assert!(
            p.decide(Variant::CameraOnly, w, &nodes, &[omega], expect)
                .is_none()
        );
    }

    #[test]
    fn a_silent_camera_expected_to_see_nothing_is_switched_off_as_before() {
        let (cams, _, omega) = setup();
        // A target behind every camera: none expects to see it.
        let far = State::new(3.0, 3.0, 40.0, 0.0, 0.0, 0.0);
        let expect = |n: usize, _t: usize| Expected::at(Some(&cams[n]), &[], 18.0, None, &far);
        assert!(expect(0, 0).camera.is_none());
        let nodes = all(Mode::Active);
        let mut p = Planner::watching_deliveries();
        let d = p
            .decide(Variant::CameraOnly, 1e-3, &nodes, &[omega], expect)
            .unwrap();
        assert_eq!(d.to, Mode::Inactive);
        assert_eq!(d.reward, 0.0);
    }

    #[test]
    fn three_mode_turns_a_camera_off_when_rssi_suffices_and_energy_is_dear() {
        let (cams, mean, omega) = setup();
        let mut nodes = all(Mode::Active);
        nodes[2].cost_factor = 5.0;
        let model = RssiModel::Linear {
            a: -10.0,
            b: -40.0,
            variance: 0.25,
        };
        let pos: Vec<_> = cams.iter().map(|c| c.pose.centre()).collect();
        let expect =
            |n: usize, _t: usize| Expected::at(Some(&cams[n]), &[], 18.0, Some((&model, &pos[n])), &mean);
        let mut p = Planner::default();
        let d = p
            .decide(Variant::ThreeMode, 5e-4, &nodes, &[omega], expect)
            .unwrap();
        // The low-battery node (cost factor 5) saves the most by switching its camera off.
        assert_eq!(d.node, NodeId(12));
        assert_eq!(d.to, Mode::CameraOff);
        assert!(d.cost < 0.0 && d.reward < 0.0);
    }

    #[test]
    fn a_camera_behind_a_wall_expects_no_view_but_its_radio_still_counts() {
        let (cams, mean, omega) = setup();
        let model = RssiModel::Linear {
            a: -10.0,
            b: -40.0,
            variance: 0.25,
        };
        let pos: Vec<_> = cams.iter().map(|c| c.pose.centre()).collect();
        // A wall across the room between camera 0 (at the origin) and the target at (3, 3);
        // cameras 1 and 2 look past its ends.
        let walls = [Wall {
            from: [0.5, 2.0],
            to: [2.5, 0.5],
            height: 3.0,
            attenuation_db: 0.0,
        }];
        let e = |n: usize| Expected::at(Some(&cams[n]), &walls, 18.0, Some((&model, &pos[n])), &mean);
        assert!(e(0).camera.is_none(), "seen through the wall");
        assert!(e(0).rssi.is_some(), "the radio is not a camera");
        assert!(e(1).camera.is_some() && e(2).camera.is_some());
        // Three-mode, all Inactive, energy cheap: the hidden node is worth only its radio, so
        // the planner wakes a camera that can see, and never wakes the hidden one's camera.
        let nodes = all(Mode::Inactive);
        let mut p = Planner::default();
        let d = p
            .decide(Variant::ThreeMode, 1e-4, &nodes, &[omega], |n, _| e(n))
            .unwrap();
        assert_ne!(d.node, NodeId(10));
        // Only the hidden node left to act on: RSSI only, not Active (its camera adds
        // nothing but cost).
        let d = p
            .decide(Variant::ThreeMode, 1e-4, &nodes[..1], &[omega], |n, _| e(n))
            .unwrap();
        assert_eq!((d.node, d.to), (NodeId(10), Mode::CameraOff));
    }
}
