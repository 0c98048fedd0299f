//! Unit tests of the head core: strangers, handover, assignment.
use super::*;
use proto::observation::{Kinds, Observation, PinholePoint};
use proto::scenario::{Fusion, Scenario};

mod membership;
mod parts;
mod radio;

/// The first prior among a head's outgoing messages.
fn first_prior(out: &[Outgoing]) -> Option<Prior> {
    out.iter().find_map(|o| match &o.body {
        Message::Priors(p) => p.tracks.first().cloned(),
        _ => None,
    })
}

/// The first track report among a head's outgoing messages.
fn first_report(out: &[Outgoing]) -> Option<proto::msg::TrackReport> {
    out.iter().find_map(|o| match &o.body {
        Message::TrackReport(r) => Some(r.clone()),
        _ => None,
    })
}

/// Information that changes nothing (Ω_i = 0, ξ_i = 0), folded from a pin-hole point.
fn zero_information() -> Option<proto::msg::Information> {
    Some(proto::msg::Information {
        matrix: [[0.0; 6]; 6],
        vector: [0.0; 6],
    })
}

fn env(source: u32, body: Message) -> Envelope {
    Envelope {
        source: NodeId(source),
        seq: 0,
        time: ClusterTime::ZERO,
        body,
    }
}

#[test]
fn a_step_without_tracks_sends_nothing_and_strangers_are_rejected() {
    let s = Scenario::default_scenario();
    let mut h = HeadNode::new(HeadConfig::from_scenario(&s, 2).unwrap()).with_nodes_heard();
    let out = h.tick(ClusterTime::ZERO);
    // Nothing but its status to the server.
    assert!(
        out.iter()
            .all(|o| o.to == NodeId(1) && matches!(o.body, Message::NodeStatus(_))),
        "{out:?}"
    );
    assert!(h.step_open());
    // Node 13 belongs to head 3.
    let c = Answers {
        step: 1,
        part: 0,
        captured: ClusterTime::ZERO,
        mode: Mode::Active,
        rssi: Vec::new(),
        contributions: vec![Contribution {
            target: TargetId(1),
            info: zero_information(),
            folded: Kinds::of(ObservationKind::Pinhole),
            ground: None,
        }],
    };
    h.on_message(ClusterTime::ZERO, env(13, Message::Answers(c.clone())));
    assert_eq!(h.counters().rejected, 1);
    // A member's answers to a part this step never had (it has no tracks): confused, and
    // nothing of it is applied.
    h.on_message(ClusterTime::ZERO, env(10, Message::Answers(c)));
    let counters = h.counters();
    assert_eq!((counters.future, counters.applied), (1, 0), "{counters:?}");
    // Liveness only from the server.
    h.on_message(
        ClusterTime::ZERO,
        env(
            10,
            Message::Liveness(proto::msg::Liveness {
                node: NodeId(11),
                up: false,
            }),
        ),
    );
    assert_eq!(h.counters().rejected, 2);
    assert_eq!(h.mode_of(NodeId(11)), Some(Mode::Active));
}

fn handover(global: u32, to: u32, from: Option<u32>, x: f64) -> Message {
    let mean = State::new(x, 4.0, 0.2, 0.0, 0.0, 0.0);
    Message::Handover(Handover {
        global: TargetId(global),
        to_head: NodeId(to),
        from_head: from.map(NodeId),
        time: ClusterTime::ZERO,
        mean: vec6_to_wire(&mean),
        cov: mat6_to_wire(&(Matrix6::identity() * 0.04)),
    })
}

/// Head 2 of the default scenario, every node heard, stepped once, with global 7 handed to it
/// at x = 3 m.
fn head_2_with_global_7() -> HeadNode {
    let s = Scenario::default_scenario();
    let mut h = HeadNode::new(HeadConfig::from_scenario(&s, 2).unwrap()).with_nodes_heard();
    h.tick(ClusterTime::ZERO);
    h.on_message(ClusterTime::ZERO, env(1, handover(7, 2, None, 3.0)));
    h
}

#[test]
fn handover_starts_a_track_that_reports_its_global_id_and_leaves_again() {
    let s = Scenario::default_scenario();
    let mut h = HeadNode::new(HeadConfig::from_scenario(&s, 2).unwrap()).with_nodes_heard();
    h.tick(ClusterTime::ZERO);
    h.on_message(ClusterTime::ZERO, env(1, handover(7, 2, Some(3), 3.0)));
    assert_eq!(h.tracks().len(), 1);
    assert_eq!(h.counters().handovers, 1);
    // The same global again does not make a second track; a forged sender is rejected.
    h.on_message(ClusterTime::ZERO, env(1, handover(7, 2, Some(3), 3.0)));
    h.on_message(ClusterTime::ZERO, env(10, handover(8, 2, None, 1.0)));
    assert_eq!(h.tracks().len(), 1);
    assert_eq!(h.counters().rejected, 1);
    // Next step: a prior to every member camera, a report with the global id at the close.
    let t1 = ClusterTime::from_millis(200);
    let out = h.tick(t1);
    let priors = out
        .iter()
        .filter(|o| matches!(o.body, Message::Priors(_)))
        .count();
    let awake = s.clusters()[&NodeId(2)]
        .iter()
        .filter(|&&n| h.mode_of(n) != Some(Mode::Inactive))
        .count();
    assert!(awake > 0);
    assert_eq!(priors, awake);
    let out = h.tick(ClusterTime::from_millis(281));
    let report = first_report(&out).unwrap();
    assert_eq!(report.global, Some(TargetId(7)));
    assert_eq!(h.last_step().prediction_only, 1);
    assert!(!h.last_step().complete);
    // The server moves it on to head 3: the track leaves.
    h.on_message(t1, env(1, handover(7, 3, Some(2), 3.0)));
    assert!(h.tracks().is_empty());
}

#[test]
fn a_naming_handover_names_the_nearest_unnamed_track() {
    let s = Scenario::default_scenario();
    let mut h = HeadNode::new(HeadConfig::from_scenario(&s, 2).unwrap()).with_nodes_heard();
    h.tick(ClusterTime::ZERO);
    // Two people of ours, 0.5 m apart, neither named yet; the server names the second.
    for x in [3.0, 3.5] {
        let local = h.alloc_local();
        let mean = State::new(x, 4.0, 0.2, 0.0, 0.0, 0.0);
        let t = h
            .new_track(local, None, mean, Matrix6::identity() * 0.04, ClusterTime::ZERO)
            .unwrap();
        h.tracks.push(t);
    }
    h.on_message(ClusterTime::ZERO, env(1, handover(7, 2, None, 3.5)));
    let named: Vec<_> = h.tracks().iter().map(|t| t.global).collect();
    assert_eq!(
        named,
        vec![None, Some(TargetId(7))],
        "no new track, the nearer one named"
    );
}

/// A track that strays more than `OUTSIDE_MARGIN_M` outside the world's box is dropped.
#[test]
fn a_track_that_leaves_the_world_is_dropped() {
    let s = Scenario::default_scenario();
    let edge = s.world.max[0] + 0.9;
    let (_, mut h) = head_with_a_track(&s, State::new(edge, 4.0, 0.25, 5.0, 0.0, 0.0));
    assert_eq!(h.tracks().len(), 1);
    // The next step opens with it still there (kept) and predicts it 1.9 m out (5 m/s for
    // 0.2 s); the step after that drops it.
    h.tick(ClusterTime::from_millis(200));
    h.tick(ClusterTime::from_millis(281));
    assert_eq!(h.tracks().len(), 1, "0.9 m outside is within the margin");
    h.tick(ClusterTime::from_millis(400));
    assert!(
        h.tracks().is_empty(),
        "{:?}",
        h.tracks().first().map(|t| t.position())
    );
    assert_eq!((h.counters().deaths, h.counters().left_world), (1, 1));
}

#[test]
fn duplicate_tracks_on_one_target_are_merged() {
    let mut h = head_2_with_global_7();
    h.on_message(ClusterTime::ZERO, env(1, handover(8, 2, None, 3.05)));
    h.on_message(ClusterTime::ZERO, env(1, handover(9, 2, None, 5.0)));
    assert_eq!(h.tracks().len(), 3);
    h.tick(ClusterTime::from_millis(200));
    h.tick(ClusterTime::from_millis(281));
    assert_eq!(h.counters().merges, 1);
    let globals: Vec<_> = h.tracks().iter().map(|t| t.global).collect();
    assert_eq!(globals, vec![Some(TargetId(7)), Some(TargetId(9))]);
}

/// Paper 002 §V: the cost is an energy, over the step whose information the reward counts.
#[test]
fn activation_cost_is_the_energy_of_one_step() {
    let s = Scenario::default_scenario();
    let mut h = HeadNode::new(HeadConfig::from_scenario(&s, 2).unwrap()).with_nodes_heard();
    h.tick(ClusterTime::ZERO);
    h.on_message(ClusterTime::ZERO, env(1, handover(7, 2, Some(3), 3.0)));
    h.tick(ClusterTime::from_millis(200));
    h.tick(ClusterTime::from_millis(281));
    let d = h
        .last_step()
        .decision
        .expect("a camera far from the target is switched off");
    let power = s.power_of(d.node.0);
    let step_s = s.method.step_ms as f64 * 1e-3;
    let want = s.method.energy_weight * (power.in_mode(d.to) - power.in_mode(d.from)) * step_s;
    assert!((d.cost - want).abs() < 1e-12, "cost {} vs {want}", d.cost);
}

/// Twelve steps of a head on the default scenario with the camera-only planner, energy so dear
/// that no camera is worth keeping, and a still track handed over at (3, 4): every member
/// camera that is on sends its (empty) camera contribution when `deliver`. Returns the config,
/// the track's predicted mean and each step's decision.
fn camera_only_steps(
    drop_lost: bool,
    deliver: bool,
) -> (HeadConfig, State, Vec<crate::activation::Decision>) {
    let mut s = Scenario::default_scenario();
    s.method.activation = Activation::CameraEntropy;
    s.method.drop_lost_cameras = drop_lost;
    s.method.energy_weight = 1.0;
    let cfg = HeadConfig::from_scenario(&s, 2).unwrap();
    let mut h = HeadNode::new(cfg.clone()).with_nodes_heard();
    h.tick(ClusterTime::ZERO);
    h.on_message(ClusterTime::ZERO, env(1, handover(7, 2, Some(3), 3.0)));
    let mut mean = State::zeros();
    let mut decisions = Vec::new();
    for k in 1..=12 {
        let t = ClusterTime::from_millis(200 * k);
        let out = h.tick(t);
        // A prior goes to the cameras that are on (none once all are off).
        let prior = first_prior(&out);
        if let Some(p) = &prior {
            mean = vec6_from_wire(&p.mean);
        }
        if let Some(prior) = prior.filter(|_| deliver) {
            for n in cfg.nodes.iter().filter(|n| n.member) {
                if h.mode_of(n.id) != Some(Mode::Active) {
                    continue;
                }
                let c = answers_to(&prior, true, t, Mode::Active, None);
                h.on_message(t, env(n.id.0, Message::Answers(c)));
            }
        }
        h.tick(ClusterTime::from_millis(200 * k + 81));
        decisions.extend(h.last_step().decision);
    }
    (cfg, mean, decisions)
}

/// Paper 000 §6.2 (`drop-lost-cameras`): while every camera delivers, the head decides as a
/// plain one; a camera that should see the track but sends nothing is left alone.
#[test]
fn lost_cameras_are_left_alone_and_delivering_ones_count_as_before() {
    let (_, _, plain) = camera_only_steps(false, true);
    let (_, _, watched) = camera_only_steps(true, true);
    assert!(!plain.is_empty());
    assert_eq!(plain, watched);
    let sees = |cfg: &HeadConfig, mean: &State, node: NodeId| {
        let info = cfg.nodes.iter().find(|n| n.id == node).unwrap();
        crate::activation::Expected::at(Some(&info.camera), &[], cfg.method.pixel_sigma, None, mean)
            .camera
            .is_some()
    };
    // Nobody delivers: the plain head switches off cameras that see the track too, one a step;
    // the watching one counts them lost and switches none of those.
    let (cfg, mean, d) = camera_only_steps(false, false);
    assert!(d.iter().any(|d| sees(&cfg, &mean, d.node)), "{d:?}");
    let (cfg, mean, d) = camera_only_steps(true, false);
    assert!(d.iter().all(|d| !sees(&cfg, &mean, d.node)), "{d:?}");
}

/// Centralized fusion takes a frame at its capture time: a track moving at 1 m/s, predicted to
/// the step's time, and a measurement of where the target was 0.1 s before it, leave the
/// track where it is (as current, the frame would drag it 0.1 m back).
#[test]
fn centralized_fusion_takes_a_frame_at_its_capture_time() {
    let (cfg, mut h, t1) = centralized_head_stepped_once();
    let predicted = *h.tracks()[0].filter.mean();
    assert!((predicted[0] - 3.2).abs() < 1e-9, "{predicted}");
    let was = nalgebra::Vector3::new(3.1, 4.0, 0.25);
    let node = cfg
        .nodes
        .iter()
        .filter(|n| n.member)
        .find(|n| {
            let k = n.camera.intrinsics;
            n.camera.project(&was).is_some_and(|p| {
                p.x > 0.0 && p.y > 0.0 && p.x < f64::from(k.width) && p.y < f64::from(k.height)
            })
        })
        .expect("a member camera sees (3.1, 4)");
    let m = measurement_of(node, &was, ClusterTime::from_millis(100));
    h.on_message(t1, env(node.id.0, Message::Measurement(m)));
    h.tick(ClusterTime::from_millis(281));
    assert_eq!(h.last_step().prediction_only, 0, "the measurement was fused");
    let after = h.tracks()[0].filter.mean();
    assert!((after[0] - 3.2).abs() < 0.01, "x {} (3.2 expected)", after[0]);
}

/// A centralized measurement of `node` seeing `world`, captured at `captured`, 2 px noise.
fn measurement_of(
    node: &crate::config::NodeInfo,
    world: &nalgebra::Vector3<f64>,
    captured: ClusterTime,
) -> Measurement {
    let point = node.camera.normalized(world).0;
    let sd = 2.0 / node.camera.intrinsics.fx;
    Measurement {
        target: Some(TargetId(1)),
        step: 1,
        pose: node.camera.pose.to_wire(),
        mode: Mode::Active,
        observations: vec![Observation::Pinhole(PinholePoint {
            point: [point.x, point.y],
            cov: [sd * sd, 0.0, sd * sd],
            prev_point: None,
            pixel_box: proto::msg::PixelBox {
                xmin: 0.0,
                ymin: 0.0,
                xmax: 1.0,
                ymax: 1.0,
            },
            area: 100,
            colour: proto::msg::ColourSignature {
                hue: 0.0,
                saturation: 1.0,
                intensity: 0.5,
            },
            captured,
        })],
    }
}

/// A measurement stamped seconds away from the head's time (a camera clock that is off) is
/// refused and counted, in either direction, and changes nothing.
#[test]
fn a_measurement_captured_far_from_now_is_refused() {
    let mut s = Scenario::default_scenario();
    s.method.fusion = Fusion::CentralizedEif;
    let cfg = HeadConfig::from_scenario(&s, 2).unwrap();
    let mut h = HeadNode::new(cfg.clone()).with_nodes_heard();
    h.tick(ClusterTime::ZERO);
    let node = cfg.nodes.iter().find(|n| n.member).unwrap();
    let seen = nalgebra::Vector3::new(3.0, 4.0, 0.25);
    let now = ClusterTime::from_secs_f64(20.0);
    for captured in [ClusterTime::from_secs_f64(10.0), ClusterTime::from_secs_f64(30.0)] {
        h.on_message(
            now,
            env(
                node.id.0,
                Message::Measurement(measurement_of(node, &seen, captured)),
            ),
        );
    }
    assert_eq!(h.counters().stale_measurements, 2);
    assert!(h.detections.is_empty());
    h.on_message(
        now,
        env(
            node.id.0,
            Message::Measurement(measurement_of(node, &seen, now + -100_000_000)),
        ),
    );
    assert_eq!(h.counters().stale_measurements, 2);
    assert_eq!(h.detections.len(), 1);
}

/// The head reads an RSSI packet as the range to where the track was when it came: a track
/// moving at 1 m/s, and a packet 0.1 s old that agrees with the track then, leave it in place.
#[test]
fn rssi_is_fused_at_the_packet_time() {
    let h = head_after_one_rssi_packet(ClusterTime::from_millis(100), false, true).1;
    assert_eq!(h.last_step().rssi_nodes, 1, "the packet was fused");
    let after = h.tracks()[0].filter.mean();
    assert!((after[0] - 3.2).abs() < 1e-3, "x {} (3.2 expected)", after[0]);
}

/// Algorithm 1 pairs a packet with where the camera-only filter puts the target when the packet
/// came: 0.1 s before the step, x = 3.1, not the step's x = 3.2.
#[test]
fn algorithm_1_pairs_a_packet_with_the_position_at_its_time() {
    let (slot, h) = head_after_one_rssi_packet(ClusterTime::from_millis(100), true, true);
    let node = h.nodes[slot].info.position;
    let (d, _) = h.tracks()[0].trainers[slot].last_pair().expect("a pair");
    let then = (nalgebra::Vector3::new(3.1, 4.0, 0.25) - node).norm();
    let now = (nalgebra::Vector3::new(3.2, 4.0, 0.25) - node).norm();
    assert!((then - now).abs() > 1e-3, "the node cannot tell the two apart");
    assert!(
        (d - then).abs() < 1e-6,
        "paired at {d}, the position then is at {then}, now {now}"
    );
}

/// An RSSI packet stamped 10 s from the head's time (a clock that is off) is refused and
/// counted, not carried along the track.
#[test]
fn an_rssi_packet_stamped_far_from_now_is_refused() {
    let h = head_after_one_rssi_packet(ClusterTime::from_secs_f64(-9.8), false, true).1;
    assert_eq!(h.last_step().rssi_nodes, 0);
    assert_eq!(h.counters().stale_measurements, 1);
}

/// Head 2 with a track at x = 3 moving at 1 m/s (`head_with_a_moving_track`), after one step
/// at 200 ms in which a radio node sent, as its only contribution, a packet received at `time`
/// that agrees with where the track was at 100 ms; with `camera`, the contribution also carries
/// camera information that confirms the prior (so the camera-only filter trains Algorithm 1
/// without moving); with `bound`, the tag is bound to the track. Also returns the node's slot.
fn head_after_one_rssi_packet(time: ClusterTime, camera: bool, bound: bool) -> (usize, HeadNode) {
    let mut s = Scenario::default_scenario();
    s.method.activation = Activation::ThreeMode;
    let model = proto::models::RssiModel::LogDistance {
        a: -25.0,
        b: -48.0,
        variance: 0.01,
    };
    s.method.rssi_default = model;
    // The track's own height: the height prior (`observe::height_prior`) leaves it in place.
    s.method.target_plane_z = Some(0.25);
    let (cfg, mut h) = head_with_a_moving_track(&s);
    let t1 = ClusterTime::from_millis(200);
    let prior = first_prior(&h.tick(t1)).expect("a prior");
    let slot = cfg
        .nodes
        .iter()
        .position(|n| n.member && n.rssi)
        .expect("a radio node");
    let node = &cfg.nodes[slot];
    let was = nalgebra::Vector3::new(3.1, 4.0, 0.25);
    let rssi = proto::msg::RssiReading {
        tag: proto::TagId::simulated(1),
        dbm: model.predict((was - node.position).norm()),
        time,
    };
    let mut c = answers_to(&prior, camera, t1, Mode::CameraOff, Some(rssi));
    if camera {
        // Ω_i on the position, ξ_i = Ω_i μ̄: information that leaves the mean where it is.
        let omega = Matrix6::from_diagonal(&State::new(100.0, 100.0, 100.0, 0.0, 0.0, 0.0));
        c.contributions[0].info = Some(proto::msg::Information {
            matrix: proto::models::mat6_to_wire(&omega),
            vector: vec6_to_wire(&(omega * proto::models::vec6_from_wire(&prior.mean))),
        });
        c.mode = Mode::Active;
    }
    h.on_message(t1, env(node.id.0, Message::Answers(c)));
    // With `bound`, the tag is taken as the track's: binding by evidence is `crate::tags`' to
    // test.
    if bound {
        let local = h.tracks()[0].local;
        h.tags.bind(rssi.tag, local);
    }
    h.tick(ClusterTime::from_millis(281));
    (slot, h)
}

/// Head 2 of `s` with one track handed over at t = 0: at (3, 4, 0.25) moving at 1 m/s along x,
/// σ 0.1 in every component.
fn head_with_a_moving_track(s: &Scenario) -> (HeadConfig, HeadNode) {
    head_with_a_track(s, State::new(3.0, 4.0, 0.25, 1.0, 0.0, 0.0))
}

/// A centralized head, every camera on, whose moving track has been stepped to 200 ms (that
/// time is returned too).
fn centralized_head_stepped_once() -> (HeadConfig, HeadNode, ClusterTime) {
    let mut s = Scenario::default_scenario();
    s.method.fusion = Fusion::CentralizedEif;
    s.method.activation = Activation::AllOn;
    let (cfg, mut h) = head_with_a_moving_track(&s);
    let t1 = ClusterTime::from_millis(200);
    h.tick(t1);
    (cfg, h, t1)
}

/// Head 2 of `s` with one track handed over at t = 0 at `mean`, σ 0.1 in every component.
fn head_with_a_track(s: &Scenario, mean: State) -> (HeadConfig, HeadNode) {
    let cfg = HeadConfig::from_scenario(s, 2).unwrap();
    let mut h = HeadNode::new(cfg.clone()).with_nodes_heard();
    h.tick(ClusterTime::ZERO);
    h.on_message(
        ClusterTime::ZERO,
        env(
            1,
            Message::Handover(Handover {
                global: TargetId(7),
                to_head: NodeId(2),
                from_head: None,
                time: ClusterTime::ZERO,
                mean: vec6_to_wire(&mean),
                cov: mat6_to_wire(&(Matrix6::identity() * 0.01)),
            }),
        ),
    );
    (cfg, h)
}

/// The answers of a node to `prior`'s step (part 0): with `camera`, a pin-hole contribution
/// that changes nothing (Ω_i, ξ_i zero); the tag reading `rssi`, if any.
fn answers_to(
    prior: &Prior,
    camera: bool,
    captured: ClusterTime,
    mode: Mode,
    rssi: Option<proto::msg::RssiReading>,
) -> Answers {
    Answers {
        step: prior.step,
        part: 0,
        captured,
        mode,
        rssi: rssi.into_iter().collect(),
        contributions: camera
            .then(|| Contribution {
                target: prior.target,
                info: zero_information(),
                folded: Kinds::of(ObservationKind::Pinhole),
                ground: None,
            })
            .into_iter()
            .collect(),
    }
}

/// A people frame of `node` captured at `captured`: a person at `at` (floor, m) gated to
/// `target`, σ 0.1 m, 1.6 m tall.
fn people_frame(at: [f64; 2], target: Option<TargetId>, captured: ClusterTime) -> proto::msg::PeopleFrame {
    let point = proto::observation::GroundPoint {
        local: 3,
        position: at,
        cov: [0.01, 0.0, 0.01],
        width_m: 0.5,
        height_m: 1.6,
        confidence: 0.9,
        histogram: Vec::new(),
        captured,
        ml_position: at,
    };
    proto::msg::PeopleFrame {
        captured,
        mode: Mode::Active,
        rssi: Vec::new(),
        people: vec![proto::observation::GroundPerson::quantise(&point, target, false).unwrap()],
    }
}

/// Each person of a people frame is a floor detection with the frame's capture time, the
/// measured height and the colours the camera sent; the frame's tag readings go to the head's
/// tag book; a centralized head fuses the person at its capture time, and its track takes the
/// person's colours (its appearance for the server).
#[test]
fn a_people_frame_gives_one_floor_detection_per_person() {
    let (cfg, mut h, t1) = centralized_head_stepped_once();
    let node = cfg.nodes.iter().find(|n| n.member).unwrap();
    let local = h.tracks()[0].local;
    let captured = ClusterTime::from_millis(100);
    let mut f = people_frame([3.1, 4.0], Some(local), captured);
    let mut colours = vec![0.0f32; proto::observation::HISTOGRAM_BINS];
    colours[7] = 1.0;
    colours[proto::observation::HISTOGRAM_HS_BINS + 2] = 1.0;
    f.people[0].histogram = proto::observation::quantise_histogram(&colours);
    let mut far = people_frame([9.0, 1.0], None, captured).people.remove(0);
    far.local = 4;
    f.people.push(far);
    f.rssi.push(proto::msg::RssiReading {
        tag: proto::TagId::simulated(1),
        dbm: -60.0,
        time: captured,
    });
    h.on_message(t1, env(node.id.0, Message::PeopleFrame(f)));
    assert_eq!(h.detections.len(), 2);
    let (gated, free) = (&h.detections[0], &h.detections[1]);
    assert_eq!((gated.hint, free.hint), (Some(local), None));
    assert_eq!(
        h.tags.queued().len(),
        1,
        "the frame's tag reading, for the tag book"
    );
    assert_eq!(gated.ground, Some(1.6));
    assert!(gated.appearance.is_some() && free.appearance.is_none());
    assert!(
        h.tracks()[0].appearance.is_empty(),
        "none before the step fuses it"
    );
    assert_eq!(gated.captured, captured);
    assert!((gated.point - Vector2::new(3.1, 4.0)).norm() < 1e-9);
    assert!((gated.cov[(0, 0)] - 0.01).abs() < 1e-9 && gated.cov[(0, 1)] == 0.0);
    h.tick(ClusterTime::from_millis(281));
    assert_eq!(h.last_step().prediction_only, 0, "the person was fused");
    let after = h.tracks()[0].filter.mean();
    assert!((after[0] - 3.2).abs() < 0.01, "x {} (3.2 expected)", after[0]);
    let appearance = &h.tracks()[0].appearance;
    assert_eq!(appearance.len(), proto::observation::HISTOGRAM_BINS);
    assert!(appearance[7] > 0.5 && appearance[8] < 0.1, "{appearance:?}");
}

/// A people frame stamped seconds from the head's time is refused and counted; one from a node
/// of another cluster is rejected.
#[test]
fn a_stale_or_foreign_people_frame_changes_nothing() {
    let s = Scenario::default_scenario();
    let cfg = HeadConfig::from_scenario(&s, 2).unwrap();
    let mut h = HeadNode::new(cfg.clone()).with_nodes_heard();
    h.tick(ClusterTime::ZERO);
    let node = cfg.nodes.iter().find(|n| n.member).unwrap();
    let now = ClusterTime::from_secs_f64(20.0);
    let stale = people_frame([3.0, 4.0], None, ClusterTime::from_secs_f64(10.0));
    h.on_message(now, env(node.id.0, Message::PeopleFrame(stale)));
    assert_eq!(h.counters().stale_measurements, 1);
    // Node 13 belongs to head 3.
    let fresh = people_frame([3.0, 4.0], None, now);
    h.on_message(now, env(13, Message::PeopleFrame(fresh.clone())));
    assert_eq!(h.counters().rejected, 1);
    assert!(h.detections.is_empty());
    h.on_message(now, env(node.id.0, Message::PeopleFrame(fresh)));
    assert_eq!(h.detections.len(), 1);
}

/// A ground-plane person a camera gated to a prior comes in its contribution as itself; the
/// head folds it in at the capture time and moves the track exactly as the Ω_i, ξ_i the camera
/// would have folded (the model is linear), counting the node as a ground contributor.
#[test]
fn a_contribution_with_a_ground_person_is_folded_in_at_the_head() {
    let mut s = Scenario::default_scenario();
    s.method.activation = Activation::AllOn;
    let run = |carried: bool| {
        let (cfg, mut h) = head_with_a_moving_track(&s);
        let t1 = ClusterTime::from_millis(200);
        let out = h.tick(t1);
        let node = cfg.nodes.iter().find(|n| n.member).unwrap().id;
        let prior = out
            .iter()
            .find_map(|o| match &o.body {
                Message::Priors(p) if o.to == node => p.tracks.first().cloned(),
                _ => None,
            })
            .expect("a prior");
        let captured = ClusterTime::from_millis(100);
        let frame = people_frame([3.1, 4.0], None, captured);
        let person = frame.people[0].clone();
        let mut c = answers_to(&prior, true, captured, Mode::Active, None);
        if carried {
            c.contributions[0] = Contribution {
                target: prior.target,
                info: None,
                folded: Kinds::NONE,
                ground: Some(person),
            };
        } else {
            // What the camera folded before: the same model at the prior's mean.
            let back = person.point(captured);
            let mean = proto::models::vec6_from_wire(&prior.mean);
            let age = t1.secs_since(captured);
            let pos = Vector2::from(back.position);
            let cov = Matrix2::new(back.cov[0], back.cov[1], back.cov[1], back.cov[2]);
            let (mut o, mut x) = proto::models::ground_contribution_aged(&pos, &cov, &mean, age).unwrap();
            let (oh, xh) = proto::models::ground_height_contribution(back.height_m, &mean).unwrap();
            o += oh;
            x += xh;
            c.contributions[0].info = Some(proto::msg::Information {
                matrix: proto::models::mat6_to_wire(&o),
                vector: vec6_to_wire(&x),
            });
            c.contributions[0].folded = Kinds::of(ObservationKind::Ground);
        }
        h.on_message(t1, env(node.0, Message::Answers(c)));
        let out = h.tick(ClusterTime::from_millis(281));
        let report = first_report(&out).expect("a report");
        (*h.tracks()[0].filter.mean(), report.contributors)
    };
    let (carried, who) = run(true);
    let (folded, _) = run(false);
    assert!((carried - folded).norm() < 1e-9, "{carried} vs {folded}");
    assert!((carried[0] - 3.2).abs() < 0.01, "x {}", carried[0]);
    assert!(
        who.iter().any(|c| c.kinds.contains(ObservationKind::Ground)),
        "{who:?}"
    );
}

/// A tag's reading is fused only into the track the tag is bound to: the same packet as in
/// `rssi_is_fused_at_the_packet_time`, with the tag bound to no track, moves nothing.
#[test]
fn an_unbound_tags_reading_is_not_fused() {
    let h = head_after_one_rssi_packet(ClusterTime::from_millis(100), false, false).1;
    assert_eq!(h.last_step().rssi_nodes, 0, "the reading was fused");
    assert!(h.tracks()[0].rssi.is_empty());
    assert_eq!(h.tags.queued().len(), 0, "the reading was weighed with the step");
}

/// Two tracks over one floor point at two heights (a duplicate whose height drifted under
/// steep views) are one target and are merged; the three-dimensional test kept them apart
/// (1.25 m in height against σ 0.1 m).
#[test]
fn two_tracks_over_one_floor_point_at_two_heights_are_merged() {
    let s = Scenario::default_scenario();
    let (_, mut h) = head_with_a_moving_track(&s);
    h.on_message(
        ClusterTime::ZERO,
        env(
            1,
            Message::Handover(Handover {
                global: TargetId(8),
                to_head: NodeId(2),
                from_head: None,
                time: ClusterTime::ZERO,
                mean: vec6_to_wire(&State::new(3.0, 4.0, 1.5, 1.0, 0.0, 0.0)),
                cov: mat6_to_wire(&(Matrix6::identity() * 0.01)),
            }),
        ),
    );
    assert_eq!(h.tracks().len(), 2);
    h.tick(ClusterTime::from_millis(200));
    h.tick(ClusterTime::from_millis(281));
    assert_eq!(
        h.tracks().len(),
        1,
        "the duplicate above the same floor point was kept"
    );
    assert_eq!(h.counters().merges, 1);
}

/// People that `birth_min_cameras` member cameras agree on start a track in the head's region
/// (or within `BIRTH_REGION_MARGIN_M` of it); beyond that, on a live head's region, they are
/// that head's: refused and counted. Floor no region covers is anybody's, and so is a head's
/// while the server says it is down, until it gets cameras again.
#[test]
fn a_head_starts_tracks_only_near_its_region() {
    let s = Scenario::default_scenario();
    let server = s.server().unwrap().id;
    // Head 2 covers x 0–6 of the 12 × 8 m floor, head 3 x 6–12 but (here) only y 0–5.
    let cfg = {
        let mut cfg = HeadConfig::from_scenario(&s, 2).unwrap();
        assert_eq!(cfg.region, Some([0.0, 0.0, 6.0, 8.0]));
        assert_eq!(cfg.other_regions, vec![(NodeId(3), [6.0, 0.0, 12.0, 8.0])]);
        cfg.other_regions = vec![(NodeId(3), [6.0, 0.0, 12.0, 5.0])];
        cfg
    };
    // The births one step makes of a person at `at` that the cluster's cameras agree on, after
    // the server's `news`.
    let births_at = |at: [f64; 2], news: &[Message]| {
        let mut h = HeadNode::new(cfg.clone()).with_nodes_heard();
        let now = ClusterTime::from_millis(100);
        for m in news {
            h.on_message(now, env(server, m.clone()));
        }
        h.tick(now);
        let members: Vec<u32> = cfg.nodes.iter().filter(|n| n.member).map(|n| n.id.0).collect();
        for &id in members.iter().take(cfg.birth_min_cameras.max(2)) {
            h.on_message(now, env(id, Message::PeopleFrame(people_frame(at, None, now))));
        }
        h.tick(ClusterTime::from_millis(400));
        (h.tracks().len(), h.counters().births_elsewhere)
    };
    let head3_down = Message::Liveness(proto::msg::Liveness {
        node: NodeId(3),
        up: false,
    });
    // Head 3 back: the server gives it a camera.
    let camera_to_head3 = Message::Assignment(proto::msg::Assignment {
        node: NodeId(cfg.nodes.iter().find(|n| !n.member).unwrap().id.0),
        head: NodeId(3),
    });
    assert_eq!(births_at([5.5, 4.0], &[]), (1, 0), "inside the region");
    assert_eq!(births_at([6.9, 4.0], &[]), (1, 0), "within the margin");
    assert_eq!(births_at([7.1, 4.0], &[]), (0, 1), "past the margin");
    assert_eq!(births_at([9.0, 4.0], &[]), (0, 1), "head 3's floor");
    assert_eq!(
        births_at([9.0, 5.4], &[]),
        (0, 1),
        "within the slack around head 3's floor"
    );
    assert_eq!(births_at([9.0, 6.5], &[]), (1, 0), "nobody's floor");
    assert_eq!(
        births_at([9.0, 4.0], std::slice::from_ref(&head3_down)),
        (1, 0),
        "head 3 is down"
    );
    assert_eq!(
        births_at([9.0, 4.0], &[head3_down, camera_to_head3]),
        (0, 1),
        "head 3 is back"
    );
}
