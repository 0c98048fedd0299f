//! The camera core in paper 004's mode, on rendered frames of the default scenario.

use super::*;
use nalgebra::Matrix6;
use proto::NodeId;
use proto::models;
use proto::msg::{Prior, Priors, SampleRequest};
use proto::scenario::{CameraTracker, Fusion, Scenario};
use world::render::Renderer;

const CAM: u32 = 10;

fn setup(fusion: Fusion) -> (Scenario, CameraNode, Renderer) {
    let mut s = Scenario::default_scenario();
    s.method.fusion = fusion;
    s.method.camera_tracker = CameraTracker::Particle;
    let cfg = CameraConfig::from_scenario(&s, CAM).unwrap();
    let r = Renderer::for_node(&s, CAM, 3).unwrap();
    (s, CameraNode::new(cfg, ClusterTime::ZERO), r)
}

fn env(body: Message) -> Envelope {
    Envelope {
        source: NodeId(2),
        seq: 1,
        time: ClusterTime::ZERO,
        body,
    }
}

/// Frames from `t0` to `t1` at 5 fps; all outputs.
fn run(node: &mut CameraNode, s: &Scenario, r: &Renderer, t0: f64, t1: f64) -> Vec<Outgoing> {
    run_at(node, s, r, t0, t1, 5.0)
}

/// Frames from `t0` to `t1` at `fps`; all outputs.
fn run_at(node: &mut CameraNode, s: &Scenario, r: &Renderer, t0: f64, t1: f64, fps: f64) -> Vec<Outgoing> {
    let targets = world::targets(s).unwrap();
    let mut out = Vec::new();
    let mut f = Frame::new(0, 0, ClusterTime::ZERO);
    let mut t = t0;
    while t <= t1 + 1e-9 {
        let now = ClusterTime::from_secs_f64(t);
        r.render(&targets, t, now, &mut f);
        out.extend(node.on_frame(now, &f));
        t += 1.0 / fps;
    }
    out
}

/// The people frames among the outputs.
fn frames(out: &[Outgoing]) -> Vec<proto::msg::PeopleFrame> {
    out.iter()
        .filter_map(|o| match &o.body {
            Message::PeopleFrame(f) => Some(f.clone()),
            _ => None,
        })
        .collect()
}

fn truth(s: &Scenario, t: f64) -> proto::models::State {
    world::targets(s).unwrap()[0].truth_at(t)
}

#[test]
fn people_leave_as_ground_points_near_the_robot() {
    let (s, mut node, r) = setup(Fusion::CentralizedEif);
    assert!(node.tracks_people());
    let out = run(&mut node, &s, &r, 0.0, 4.0);
    assert!(
        out.iter().all(|o| !matches!(o.body, Message::Measurement(_))),
        "people go in people frames"
    );
    let grounds: Vec<_> = frames(&out)
        .iter()
        .flat_map(|f| f.people.iter().map(|p| p.point(f.captured)).collect::<Vec<_>>())
        .collect();
    assert!(grounds.len() >= 5, "{} ground points", grounds.len());
    // The node's counters carry its filters'.
    assert!(
        node.counters().particle.tracker.started >= 1,
        "{:?}",
        node.counters().particle
    );
    assert_eq!(node.counters().particle.tracker.frames, node.counters().frames);
    // Of the last frame's people, one is the robot (another may be the first frame's ghost in
    // the background model, where the robot stood).
    let last_t = grounds.last().unwrap().captured;
    let x = truth(&s, last_t.secs_since(ClusterTime::ZERO));
    let err = |g: &proto::observation::GroundPoint| {
        ((g.position[0] - x[0]).powi(2) + (g.position[1] - x[1]).powi(2)).sqrt()
    };
    let last = grounds
        .iter()
        .filter(|g| g.captured == last_t)
        .min_by(|a, b| err(a).total_cmp(&err(b)))
        .unwrap();
    assert!(err(last) < 0.6, "ground point {:?} vs truth {x:?}", last.position);
    assert!(last.cov[0] > 0.0 && last.cov[2] > 0.0 && last.width_m > 0.0 && last.height_m > 0.0);
    // The histogram goes with a person's first point, then only when it changed or is old.
    assert_eq!(grounds[0].histogram.len(), 110);
    assert!(grounds.iter().filter(|g| g.histogram.is_empty()).count() >= grounds.len() / 2);
    // Asked, the camera sends each person's sample set back to the asker.
    let req = SampleRequest {
        node: NodeId(CAM),
        local: None,
    };
    let now = ClusterTime::from_secs_f64(4.0);
    let sets = node.handle(now, Input::Message(env(Message::SampleRequest(req))));
    assert!(!sets.is_empty());
    assert!(
        sets.iter()
            .all(|o| o.to == NodeId(2) && matches!(&o.body, Message::SampleSet(s) if s.samples.len() == 100))
    );
    // Addressed to another camera: refused, counted.
    let rejected = node.counters().rejected;
    let other = SampleRequest {
        node: NodeId(11),
        local: None,
    };
    assert!(
        node.handle(now, Input::Message(env(Message::SampleRequest(other))))
            .is_empty()
    );
    assert_eq!(node.counters().rejected, rejected + 1);
}

#[test]
fn a_prior_is_answered_with_the_ground_information() {
    let (s, mut node, r) = setup(Fusion::DistributedEif);
    run(&mut node, &s, &r, 0.0, 3.0);
    let t = 3.0;
    let prior = |offset: f64| {
        let mut mean = truth(&s, t);
        mean[0] += offset;
        Prior {
            target: TargetId(1),
            step: 7,
            mean: models::vec6_to_wire(&mean),
            cov: models::mat6_to_wire(&(Matrix6::identity() * 0.09)),
            deadline: ClusterTime::from_secs_f64(t + 0.08),
            radio: false,
        }
    };
    let now = ClusterTime::from_secs_f64(t + 0.01);
    let answer = |node: &mut CameraNode, p: Prior| match &node.handle(
        now,
        Input::Message(env(Message::Priors(Priors {
            part: 0,
            parts: 1,
            tracks: vec![p],
        }))),
    )[..]
    {
        [o] => match &o.body {
            Message::Answers(a) => a.contributions.first().cloned(),
            other => panic!("{other:?}"),
        },
        other => panic!("{other:?}"),
    };
    let c = answer(&mut node, prior(0.0)).expect("a contribution");
    // The person gated to it, near the robot, for the head to fold in; nothing folded here.
    let person = c.ground.as_ref().expect("a ground person").position();
    let x = truth(&s, t);
    assert!(
        (person[0] - x[0]).hypot(person[1] - x[1]) < 0.6,
        "{person:?} vs {x}"
    );
    assert!(c.info.is_none() && c.folded.is_empty() && c.camera());
    // A prior metres away gates nothing: the step is answered with nothing for it.
    assert_eq!(answer(&mut node, prior(4.0)), None);
}

#[test]
fn a_fast_camera_sends_its_people_once_per_step_in_one_message() {
    let (s, mut node, r) = setup(Fusion::CentralizedEif);
    // 15 fps against the default 200 ms step: every third frame.
    let out = run_at(&mut node, &s, &r, 0.0, 4.0, 15.0);
    let sent = frames(&out);
    assert!(
        (15..=21).contains(&sent.len()),
        "{} frames sent in 4 s",
        sent.len()
    );
    assert!(
        sent.windows(2)
            .all(|w| w[1].captured.secs_since(w[0].captured) > 0.15),
        "{:?}",
        sent.iter().map(|f| f.captured).collect::<Vec<_>>()
    );
    assert_eq!(node.counters().frames, 61, "every frame is tracked");
    // Each frame's people in one message: ids once, all the tracker's people of that frame.
    let last = sent.last().unwrap();
    let mut locals: Vec<u32> = last.people.iter().map(|p| p.local).collect();
    locals.dedup();
    assert_eq!(locals.len(), last.people.len());
    assert!(last.people.iter().all(|p| p.target.is_none()), "no priors yet");
    assert!(last.rssi.is_empty());
}

#[test]
fn a_distributed_camera_leaves_the_gated_people_to_its_contributions() {
    let (s, mut node, r) = setup(Fusion::DistributedEif);
    let before = frames(&run(&mut node, &s, &r, 0.0, 3.0));
    assert!(!before.is_empty());
    // A prior on the robot: from now on the robot is folded into contributions, not sent.
    // (A prior stays fresh for 500 ms, the default `capture_max_age_ms`.)
    let prior = |t: f64| Prior {
        target: TargetId(1),
        step: 7,
        mean: models::vec6_to_wire(&truth(&s, t)),
        cov: models::mat6_to_wire(&(Matrix6::identity() * 0.09)),
        deadline: ClusterTime::from_secs_f64(t + 0.08),
        radio: false,
    };
    let answer = |node: &mut CameraNode, t: f64| {
        let out = node.handle(
            ClusterTime::from_secs_f64(t),
            Input::Message(env(Message::Priors(Priors {
                part: 0,
                parts: 1,
                tracks: vec![prior(t)],
            }))),
        );
        match &out[..] {
            [o] => match &o.body {
                Message::Answers(a) => a.contributions.iter().any(|c| c.camera()),
                other => panic!("{other:?}"),
            },
            other => panic!("{other:?}"),
        }
    };
    answer(&mut node, 3.0);
    let after = frames(&run(&mut node, &s, &r, 3.2, 3.4));
    assert!(
        answer(&mut node, 3.45),
        "the robot is still tracked, in the contributions"
    );
    let near = |f: &proto::msg::PeopleFrame| {
        f.people.iter().any(|p| {
            let x = truth(&s, f.captured.secs_since(ClusterTime::ZERO));
            let q = p.position();
            (q[0] - x[0]).hypot(q[1] - x[1]) < 0.6
        })
    };
    assert!(
        before.iter().any(near),
        "the robot was sent while no prior gated it"
    );
    assert!(!after.iter().any(near), "{after:?}");
    assert!(after.iter().flat_map(|f| &f.people).all(|p| p.target.is_none()));
}
