//! Radio tracks: a radio-only cluster's tags, and with `unseen-tags` the radio tracks of a
//! cluster with cameras (`crate::unseen`).
use super::*;

/// A radio-only cluster gives each tag it hears a radio track of its own: the search track
/// takes the first, a new track the second, and each takes only its own tag's readings.
#[test]
fn a_radio_only_cluster_tracks_each_tag_on_its_own_track() {
    let mut s = Scenario::default_scenario();
    s.method.activation = Activation::ThreeMode;
    let ids: Vec<u32> = s.cameras().filter(|n| n.head == Some(2)).map(|n| n.id).collect();
    for id in ids {
        let c = s.camera_model(id).unwrap().pose.centre();
        let n = s.nodes.iter_mut().find(|n| n.id == id).unwrap();
        n.position = Some([c.x, c.y, c.z]);
        n.camera = None;
    }
    let cfg = HeadConfig::from_scenario(&s, 2).unwrap();
    let mut h = HeadNode::new(cfg.clone()).with_nodes_heard();
    let t0 = ClusterTime::ZERO;
    let priors = h.tick(t0);
    assert_eq!(h.tracks().len(), 1, "the search track");
    let prior = first_prior(&priors).expect("a prior for the search track");
    let node = cfg
        .nodes
        .iter()
        .find(|n| n.member && n.rssi)
        .expect("a radio node");
    let (a, b) = (proto::TagId(0xa), proto::TagId(0xb));
    let mut c = answers_to(&prior, false, t0, Mode::CameraOff, None);
    for (tag, dbm) in [(a, -55.0), (b, -70.0)] {
        c.rssi.push(proto::msg::RssiReading { tag, dbm, time: t0 });
    }
    h.on_message(t0, env(node.id.0, Message::Answers(c)));
    h.tick(ClusterTime::from_millis(81));
    assert_eq!(h.tracks().len(), 2, "one radio track per tag");
    let (first, second) = (h.tracks()[0].local, h.tracks()[1].local);
    assert_eq!(
        h.tags.track_of(a),
        Some(first),
        "the search track took the first tag"
    );
    assert_eq!(h.tags.track_of(b), Some(second));
    let dbm = |t: &Track| t.rssi.iter().map(|r| r.1).collect::<Vec<_>>();
    assert_eq!(dbm(&h.tracks()[0]), vec![-55.0]);
    assert_eq!(dbm(&h.tracks()[1]), vec![-70.0]);
}

/// Every member radio node answers `prior`'s step at `t` with a noise-free reading of `tag`
/// at `at` (the method's default model); what the head sent meanwhile.
fn answer_tag(
    h: &mut HeadNode,
    cfg: &HeadConfig,
    prior: &Prior,
    tag: proto::TagId,
    at: nalgebra::Vector3<f64>,
    t: ClusterTime,
) -> Vec<Outgoing> {
    let mut out = Vec::new();
    for n in cfg.nodes.iter().filter(|n| n.member && n.rssi) {
        let rssi = proto::msg::RssiReading {
            tag,
            dbm: cfg.method.rssi_default.predict((at - n.position).norm()),
            time: t,
        };
        let answers = answers_to(prior, false, t, Mode::CameraOff, Some(rssi));
        out.extend(h.on_message(t, env(n.id.0, Message::Answers(answers))));
    }
    out
}

/// Step head `h` from `from_ms` for `steps` steps of 200 ms: every up member radio node
/// answers each step's priors with a noise-free reading of `tag` at `at` (the method's
/// default model); returns the last step's priors.
fn answer_with_tag(
    h: &mut HeadNode,
    cfg: &HeadConfig,
    tag: proto::TagId,
    at: nalgebra::Vector3<f64>,
    from_ms: i64,
    steps: i64,
) -> Vec<Prior> {
    let mut last = Vec::new();
    for k in 0..steps {
        let t = ClusterTime::from_millis(from_ms + 200 * k);
        let out = h.tick(t);
        let priors: Vec<Prior> = out
            .iter()
            .find_map(|o| match &o.body {
                Message::Priors(p) => Some(p.tracks.clone()),
                _ => None,
            })
            .unwrap_or_default();
        if let Some(prior) = priors.first() {
            answer_tag(h, cfg, prior, tag, at, t);
        }
        h.tick(ClusterTime::from_millis(from_ms + 200 * k + 81));
        last = priors;
    }
    last
}

/// With `unseen-tags`, a cluster with cameras that holds no track keeps a radio search track
/// whose priors ask its nodes for the tags they hear (never reported; cameras pair nothing
/// with it); a tag heard, unbound and unclaimed for the wait gets a radio track at its RSSI fix,
/// bound to it, whose prior tells cameras to leave it alone. Without the option, nothing.
#[test]
fn an_unseen_tag_gets_a_radio_track_at_its_fix_with_unseen_tags_on() {
    let tag = proto::TagId::simulated(5);
    let at = nalgebra::Vector3::new(3.0, 4.5, 0.5);
    // A camera cluster holding a track 3 m from the tag (kept alive by a long timeout): its
    // priors bring the readings. Only with the option does the tag get a radio track.
    let radio_tracks = |unseen: bool| {
        let mut s = Scenario::default_scenario();
        s.method.activation = Activation::ThreeMode;
        s.method.unseen_tags = unseen;
        s.method.track_timeout_ms = 30_000;
        let (cfg, mut h) = head_with_a_track(&s, State::new(1.0, 2.0, 0.5, 0.0, 0.0, 0.0));
        answer_with_tag(&mut h, &cfg, tag, at, 200, 25);
        h.tracks()
            .iter()
            .filter(|t| t.radio == Some(crate::track::Radio::Tag))
            .count()
    };
    assert_eq!(radio_tracks(false), 0, "a radio track without the option");
    assert_eq!(radio_tracks(true), 1);

    let mut s = Scenario::default_scenario();
    s.method.activation = Activation::ThreeMode;
    s.method.unseen_tags = true;
    let cfg = HeadConfig::from_scenario(&s, 2).unwrap();
    let mut h = HeadNode::new(cfg.clone()).with_nodes_heard();
    let reports = |out: &[Outgoing]| {
        out.iter()
            .filter(|o| matches!(o.body, Message::TrackReport(_)))
            .count()
    };
    // The first step: a search track, its prior marked radio, nothing reported.
    let out = h.tick(ClusterTime::ZERO);
    assert_eq!(h.tracks().len(), 1);
    assert_eq!(h.tracks()[0].radio, Some(crate::track::Radio::Search));
    assert!(
        first_prior(&out).is_some_and(|p| p.radio),
        "the search prior is a radio prior"
    );
    assert_eq!(reports(&h.tick(ClusterTime::from_millis(81))), 0);
    // Before the wait is over the tag has no track of its own.
    answer_with_tag(&mut h, &cfg, tag, at, 200, 10);
    assert!(
        h.tracks()
            .iter()
            .all(|t| t.radio != Some(crate::track::Radio::Tag))
    );
    let priors = answer_with_tag(&mut h, &cfg, tag, at, 2200, 10);
    let radio: Vec<&Track> = h
        .tracks()
        .iter()
        .filter(|t| t.radio == Some(crate::track::Radio::Tag))
        .collect();
    assert_eq!(radio.len(), 1, "one radio track for the tag");
    let track = radio[0];
    assert_eq!(h.tags.track_of(tag), Some(track.local));
    let off = (track.position() - at).xy().norm();
    assert!(off < 0.6, "the radio track is {off:.2} m from the tag");
    assert!(
        priors.iter().any(|p| p.target == track.local && p.radio),
        "cameras are told to leave it alone: {priors:?}"
    );
    // The search track went when the radio track came; the radio track is reported (its tag
    // is heard).
    assert!(
        h.tracks()
            .iter()
            .all(|t| t.radio != Some(crate::track::Radio::Search))
    );
    let t = ClusterTime::from_millis(4200);
    let prior = first_prior(&h.tick(t)).expect("the radio track's prior");
    let mut out = answer_tag(&mut h, &cfg, &prior, tag, at, t);
    out.extend(h.tick(ClusterTime::from_millis(4281)));
    assert_eq!(reports(&out), 1);
    // With only a radio track, no camera sleeps: none looks for it, all look for newcomers.
    let cameras: Vec<NodeId> = cfg
        .nodes
        .iter()
        .filter(|n| n.member && !n.radio_only)
        .map(|n| n.id)
        .collect();
    assert!(
        cameras.iter().all(|&c| h.mode_of(c) == Some(Mode::Active)),
        "{:?}",
        cameras.iter().map(|&c| h.mode_of(c)).collect::<Vec<_>>()
    );
    // The server names it (a handover from no head, its own report's posterior): it takes the
    // global id, and no second track starts.
    let radio_local = h.tracks()[0].local;
    let report = first_report(&out).unwrap();
    let naming = Message::Handover(Handover {
        global: TargetId(42),
        to_head: NodeId(2),
        from_head: None,
        time: report.time,
        mean: report.mean,
        cov: report.cov,
    });
    h.on_message(ClusterTime::from_millis(4300), env(1, naming));
    assert_eq!(h.tracks().len(), 1, "a twin of the radio track");
    assert_eq!(
        (h.tracks()[0].local, h.tracks()[0].global),
        (radio_local, Some(TargetId(42)))
    );
}

/// A radio track whose tag a camera track claims (its evidence reaches `UNSEEN_LLR`: the
/// person is seen after all) is dropped, and never merged with that track on the way.
#[test]
fn a_radio_track_whose_tag_a_camera_track_claims_is_dropped() {
    let mut s = Scenario::default_scenario();
    s.method.activation = Activation::ThreeMode;
    s.method.unseen_tags = true;
    let at = State::new(3.0, 4.0, 0.5, 0.0, 0.0, 0.0);
    let (cfg, mut h) = head_with_a_track(&s, at);
    let tag = proto::TagId::simulated(9);
    // A radio track for the tag 1.5 m off, as wide as a fix.
    let radio_at = State::new(3.0, 5.5, 0.5, 0.0, 0.0, 0.0);
    let mut cov = Matrix6::identity() * 0.01;
    cov[(0, 0)] = 1.0;
    cov[(1, 1)] = 1.0;
    let local = h.alloc_local();
    let mut t = h
        .new_track(local, None, radio_at, cov, ClusterTime::ZERO)
        .unwrap();
    t.confirm();
    t.radio = Some(crate::track::Radio::Tag);
    h.tracks.push(t);
    h.tags.offer(
        0,
        proto::msg::RssiReading {
            tag,
            dbm: -60.0,
            time: ClusterTime::ZERO,
        },
        ClusterTime::ZERO,
    );
    h.tags.give(tag, local);
    // (The first tick made a search track; the handover started a track of its own.)
    let camera_track = h
        .tracks()
        .iter()
        .find(|t| t.global == Some(TargetId(7)))
        .unwrap()
        .local;
    let model = cfg.method.rssi_default;
    let pos = nalgebra::Vector3::new(3.0, 4.0, 0.5);
    let mut dropped_at = None;
    for k in 1..=40 {
        let t = ClusterTime::from_millis(200 * k);
        let out = h.tick(t);
        let Some(parts) = out.iter().find_map(|o| match &o.body {
            Message::Priors(p) => Some(p.tracks.clone()),
            _ => None,
        }) else {
            continue;
        };
        let camera_prior = parts
            .iter()
            .find(|p| p.target == camera_track)
            .expect("its prior");
        for n in cfg.nodes.iter().filter(|n| n.member && n.rssi) {
            let rssi = proto::msg::RssiReading {
                tag,
                dbm: model.predict((pos - n.position).norm()),
                time: t,
            };
            let answers = answers_to(camera_prior, true, t, Mode::Active, Some(rssi));
            h.on_message(t, env(n.id.0, Message::Answers(answers)));
        }
        h.tick(ClusterTime::from_millis(200 * k + 81));
        if !h.tracks().iter().any(|t| t.local == local) {
            // By the claim, before binding's rules moved the tag (they ask for twice the
            // evidence and a lead).
            assert_ne!(h.tags.track_of(tag), Some(camera_track), "the tag moved first");
            dropped_at = Some(k);
            break;
        }
    }
    assert!(
        dropped_at.is_some(),
        "the radio track outlived the camera track's claim"
    );
    assert!(h.tags.evidence(tag, camera_track) >= crate::unseen::UNSEEN_LLR);
    assert_eq!(h.counters().merges, 0, "dropped, not merged");
    assert!(h.tracks().iter().any(|t| t.local == camera_track));
}
