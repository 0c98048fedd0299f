//! Every way a frame can be wrong gets its own error variant, and the message names the problem.

use proto::examples::{FLOAT_SLOTS, messages as samples};
use proto::ids::{NodeId, TagId, TargetId};
use proto::msg::*;
use proto::validate::{PSD_TOLERANCE, Validate};
use proto::{
    Envelope, MAX_CONTRIBUTORS, MAX_FRAME_BYTES, MAX_MEASURED_DETECTIONS, Message, PROTOCOL_VERSION,
    WireError, decode, encode,
};

/// Encode without validating, as a faulty or hostile peer would.
fn raw(env: &Envelope) -> Vec<u8> {
    postcard::to_stdvec(&(PROTOCOL_VERSION, env)).unwrap()
}

fn invalid(frame: &[u8]) -> (String, String) {
    match decode(frame) {
        Err(e @ WireError::Invalid(_)) => {
            let WireError::Invalid(v) = &e else { unreachable!() };
            (v.field.to_owned(), e.to_string())
        }
        other => panic!("expected WireError::Invalid, got {other:?}"),
    }
}

fn malformed(frame: &[u8]) -> String {
    match decode(frame) {
        Err(e @ WireError::Malformed(_)) => e.to_string(),
        other => panic!("expected WireError::Malformed, got {other:?}"),
    }
}

#[test]
fn empty_frame() {
    let e = decode(&[]).unwrap_err();
    assert_eq!(e, WireError::Empty);
    assert!(e.to_string().contains("empty"), "{e}");
}

#[test]
fn trailing_bytes() {
    for env in samples() {
        let mut frame = encode(&env).unwrap();
        frame.extend_from_slice(&[0, 0, 7]);
        let e = decode(&frame).unwrap_err();
        assert_eq!(e, WireError::TrailingBytes(3), "{}", env.body.kind());
        assert!(e.to_string().contains("3 trailing bytes"), "{e}");
    }
}

#[test]
fn truncated_frame_names_the_kind() {
    for env in samples() {
        let frame = encode(&env).unwrap();
        let e = malformed(&frame[..frame.len() - 1]);
        assert!(e.contains("truncated"), "{e}");
        if !matches!(env.body, Message::Heartbeat) {
            assert!(e.contains(env.body.kind()), "{}: {e}", env.body.kind());
        }
    }
    let e = malformed(&encode(&samples()[0]).unwrap()[..3]);
    assert!(e.contains("truncated") && e.contains("header"), "{e}");
}

#[test]
fn wrong_version() {
    let mut frame = encode(&samples()[2]).unwrap();
    frame[0] = 1;
    let e = decode(&frame).unwrap_err();
    assert_eq!(
        e,
        WireError::Version {
            got: 1,
            expected: PROTOCOL_VERSION
        }
    );
    assert!(
        e.to_string().contains("protocol version 1 is not supported"),
        "{e}"
    );
    // A version that does not even fit the header type.
    let e = malformed(&[0xff, 0xff, 0xff, 0x7f, 0x07]);
    assert!(e.contains("header"), "{e}");
    // The handshake carries the version too.
    let mut env = samples()[0].clone();
    let Message::Hello(h) = &mut env.body else {
        panic!()
    };
    h.version = PROTOCOL_VERSION + 1;
    let (field, e) = invalid(&raw(&env));
    assert_eq!(field, "hello.version");
    assert!(e.contains("not supported"), "{e}");
}

#[test]
fn oversized_frame() {
    let frame = vec![1u8; MAX_FRAME_BYTES + 1];
    let e = decode(&frame).unwrap_err();
    assert_eq!(
        e,
        WireError::Oversized {
            len: MAX_FRAME_BYTES + 1,
            max: MAX_FRAME_BYTES
        }
    );
    assert!(e.to_string().contains("exceeds the maximum"), "{e}");
}

fn find_all(hay: &[u8], needle: &[u8]) -> Vec<usize> {
    (0..=hay.len().saturating_sub(needle.len()))
        .filter(|&i| &hay[i..i + needle.len()] == needle)
        .collect()
}

/// Every f64 and f32 slot of every kind, replaced in turn by NaN, +∞ and −∞ in the encoded
/// bytes, is rejected by `decode` naming the field of that kind.
#[test]
fn non_finite_numbers_anywhere_are_rejected() {
    for (tag, env) in samples().into_iter().enumerate() {
        let frame = raw(&env);
        let kind = env.body.kind();
        // Find every slot by its bit pattern (sample values are distinct by construction).
        let (want64, want32) = FLOAT_SLOTS[tag];
        let mut slots64 = std::collections::BTreeSet::new();
        let mut slots32 = std::collections::BTreeSet::new();
        for v in sample_f64s(&env.body) {
            slots64.extend(find_all(&frame, &v.to_le_bytes()));
        }
        for v in sample_f32s(&env.body) {
            slots32.extend(find_all(&frame, &v.to_le_bytes()));
        }
        assert_eq!(
            (slots64.len(), slots32.len()),
            (want64, want32),
            "{kind}: float slots found"
        );
        let poisons64 = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY];
        let poisons32 = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY];
        for &at in &slots64 {
            for p in poisons64 {
                let mut bad = frame.clone();
                bad[at..at + 8].copy_from_slice(&p.to_le_bytes());
                let (field, e) = invalid(&bad);
                assert!(field.starts_with(kind), "{kind}: field {field}");
                assert!(e.contains("not a finite number"), "{kind}: {e}");
            }
        }
        for &at in &slots32 {
            for p in poisons32 {
                let mut bad = frame.clone();
                bad[at..at + 4].copy_from_slice(&p.to_le_bytes());
                let (field, e) = invalid(&bad);
                assert!(field.starts_with(kind), "{kind}: field {field}");
                assert!(e.contains("not a finite number"), "{kind}: {e}");
            }
        }
    }
}

/// The f64 values a sample holds (by construction: see `samples`).
fn observation_f64s(o: &Observation) -> Vec<f64> {
    match o {
        Observation::Pinhole(p) => {
            [p.point.to_vec(), p.prev_point.unwrap().to_vec(), p.cov.to_vec()].concat()
        }
        Observation::Rssi(r) => vec![r.dbm],
        Observation::Ground(_) => Vec::new(),
        Observation::Acoustic(_) => Vec::new(),
    }
}

fn observation_f32s(o: &Observation) -> Vec<f32> {
    match o {
        Observation::Pinhole(p) => {
            let b = p.pixel_box;
            vec![
                b.xmin,
                b.ymin,
                b.xmax,
                b.ymax,
                p.colour.hue,
                p.colour.saturation,
                p.colour.intensity,
            ]
        }
        Observation::Rssi(_) | Observation::Ground(_) => Vec::new(),
        Observation::Acoustic(a) => [vec![a.first_hz, a.step_hz], a.ild_db.clone()].concat(),
    }
}

fn sample_f64s(m: &Message) -> Vec<f64> {
    let mat = |m: &Mat6| m.iter().flatten().copied().collect::<Vec<_>>();
    match m {
        Message::Measurement(x) => {
            let mut v = x.pose.rvec.to_vec();
            v.extend(x.pose.tvec);
            v.extend(x.observations.iter().flat_map(observation_f64s));
            v
        }
        Message::Answers(a) => a
            .rssi
            .iter()
            .map(|r| r.dbm)
            .chain(a.contributions.iter().flat_map(|c| {
                c.info
                    .iter()
                    .flat_map(|i| i.matrix.iter().flatten().chain(&i.vector).copied())
            }))
            .collect(),
        Message::Priors(p) => p
            .tracks
            .iter()
            .flat_map(|t| [mat(&t.cov), t.mean.to_vec()].concat())
            .collect(),
        Message::TrackReport(r) => [mat(&r.cov), r.mean.to_vec(), vec![r.power_mw]].concat(),
        Message::Handover(h) => [mat(&h.cov), h.mean.to_vec()].concat(),
        Message::MeasuredFrame(f) => {
            let mut v: Vec<f64> = f.rssi.iter().map(|r| r.dbm).collect();
            for d in &f.detections {
                v.extend(d.point);
                v.extend(d.cov);
            }
            v
        }
        Message::ViewUpdate(u) => u
            .tracks
            .iter()
            .flat_map(|t| t.mean.into_iter().chain(t.cov_pos))
            .collect(),
        Message::PeopleFrame(f) => f.rssi.iter().map(|r| r.dbm).collect(),
        _ => Vec::new(),
    }
}

fn sample_f32s(m: &Message) -> Vec<f32> {
    match m {
        Message::TagsHeard(t) => t
            .tags
            .iter()
            .flat_map(|h| [h.dbm, h.near[0], h.near[1]])
            .collect(),
        Message::Measurement(x) => x.observations.iter().flat_map(observation_f32s).collect(),
        Message::MeasuredFrame(f) => f
            .detections
            .iter()
            .flat_map(|d| {
                let b = d.pixel_box;
                [
                    d.centre[0],
                    d.centre[1],
                    d.foot[0],
                    d.foot[1],
                    b.xmin,
                    b.ymin,
                    b.xmax,
                    b.ymax,
                    d.colour.hue,
                    d.colour.saturation,
                    d.colour.intensity,
                ]
            })
            .collect(),
        Message::TrackReport(r) => r
            .appearance
            .iter()
            .copied()
            .chain(
                r.grid
                    .iter()
                    .flat_map(|g| [g.origin[0], g.origin[1], g.cell_m, g.peak_mass]),
            )
            .collect(),
        Message::SampleSet(s) => s
            .samples
            .iter()
            .flat_map(|x| [x.state.to_vec(), vec![x.weight]].concat())
            .collect(),
        _ => Vec::new(),
    }
}

/// Each 6×6 matrix field, made asymmetric or indefinite beyond `PSD_TOLERANCE`, is rejected
/// naming it; perturbations within the tolerance are accepted.
#[test]
fn asymmetric_or_indefinite_matrices() {
    type Get = fn(&mut Message) -> &mut Mat6;
    let fields: [(usize, &str, Get); 4] = [
        (4, "answers.contributions.info.matrix", |m| match m {
            Message::Answers(a) => &mut a.contributions[0].info.as_mut().unwrap().matrix,
            _ => unreachable!(),
        }),
        (6, "priors.tracks.cov", |m| match m {
            Message::Priors(p) => &mut p.tracks[0].cov,
            _ => unreachable!(),
        }),
        (8, "track_report.cov", |m| match m {
            Message::TrackReport(r) => &mut r.cov,
            _ => unreachable!(),
        }),
        (10, "handover.cov", |m| match m {
            Message::Handover(h) => &mut h.cov,
            _ => unreachable!(),
        }),
    ];
    for (tag, name, get) in fields {
        let base = samples()[tag].clone();
        let scale = get(&mut base.clone().body)
            .iter()
            .flatten()
            .fold(0.0f64, |a, x| a.max(x.abs()));
        let with = |f: &dyn Fn(&mut Mat6)| {
            let mut env = base.clone();
            f(get(&mut env.body));
            env
        };
        // Asymmetric beyond tolerance.
        let env = with(&|m| m[1][4] += 10.0 * PSD_TOLERANCE * scale);
        let (field, e) = invalid(&raw(&env));
        assert_eq!(field, name);
        assert!(e.contains("not symmetric at (1,4)"), "{e}");
        assert!(
            matches!(encode(&env), Err(WireError::Invalid(_))),
            "encode must refuse it too"
        );
        // Asymmetric within tolerance: accepted.
        let env = with(&|m| m[1][4] += 0.1 * PSD_TOLERANCE * scale);
        assert!(decode(&raw(&env)).is_ok(), "{name}: within tolerance");
        // Indefinite: a negative eigenvalue of −1 on a matrix whose entries are ~25.
        let env = with(&|m| *m = negated_diag(5, 1.0, m));
        let (field, e) = invalid(&raw(&env));
        assert_eq!(field, name);
        assert!(e.contains("indefinite"), "{e}");
        // Slightly negative, within tolerance: accepted (rounding of a PSD matrix).
        let env = with(&|m| *m = negated_diag(5, 0.1 * PSD_TOLERANCE * scale, m));
        assert!(decode(&raw(&env)).is_ok(), "{name}: indefinite within tolerance");
    }
}

/// `m` with row/column `k` zeroed and the diagonal entry set to `−eps`: eigenvalue −eps.
fn negated_diag(k: usize, eps: f64, m: &Mat6) -> Mat6 {
    let mut out = *m;
    for i in 0..6 {
        out[i][k] = 0.0;
        out[k][i] = 0.0;
    }
    out[k][k] = -eps;
    out
}

/// A measured frame's limits: detection count, box order, RSSI range and a covariance that is
/// not positive definite are each rejected naming the field; exactly the maximum count is fine.
#[test]
fn measured_frame_checks_name_the_field() {
    let sample = samples()[13].clone();
    let with = |f: &dyn Fn(&mut MeasuredFrame)| {
        let mut env = sample.clone();
        let Message::MeasuredFrame(m) = &mut env.body else {
            panic!("sample 13 is a measured frame")
        };
        f(m);
        env
    };
    let too_many = with(&|m| m.detections = vec![m.detections[0]; MAX_MEASURED_DETECTIONS + 1]);
    let frame = raw(&too_many);
    assert!(
        frame.len() <= MAX_FRAME_BYTES,
        "the size limit must not be what rejects it"
    );
    let (field, e) = invalid(&frame);
    assert_eq!(field, "measured_frame.detections");
    assert!(e.contains("exceed the maximum of 64"), "{e}");
    assert!(matches!(encode(&too_many), Err(WireError::Invalid(_))));
    let most = with(&|m| m.detections = vec![m.detections[0]; MAX_MEASURED_DETECTIONS]);
    assert_eq!(decode(&encode(&most).unwrap()).unwrap(), most);
    let flipped = with(&|m| m.detections[0].pixel_box.ymax = m.detections[0].pixel_box.ymin - 1.0);
    assert_eq!(invalid(&raw(&flipped)).0, "measured_frame.detections.pixel_box");
    let loud = with(&|m| m.rssi[0].dbm = 31.0);
    let (field, e) = invalid(&raw(&loud));
    assert_eq!(field, "measured_frame.rssi");
    assert!(e.contains("outside"), "{e}");
    let singular = with(&|m| m.detections[0].cov = [1.0, 1.0, 1.0]);
    assert_eq!(invalid(&raw(&singular)).0, "measured_frame.detections.cov");
    // No detections and no RSSI: a camera that saw nothing still logs the frame.
    let empty = with(&|m| {
        m.detections.clear();
        m.rssi.clear();
    });
    assert_eq!(decode(&encode(&empty).unwrap()).unwrap(), empty);
}

/// A camera's people frame: every quantised field that could stand for an impossible person,
/// every list and every byte layout problem is rejected naming the field or the kind.
#[test]
fn people_frame_checks_name_the_field() {
    use proto::observation::{HISTOGRAM_BINS, MAX_OBSERVATIONS};
    const TAG: usize = 19;
    let sample = samples()[TAG].clone();
    let with = |f: &dyn Fn(&mut PeopleFrame)| {
        let mut env = sample.clone();
        let Message::PeopleFrame(p) = &mut env.body else {
            panic!("sample 19 is a people frame")
        };
        f(p);
        env
    };
    // (field, problem, the edit that makes it).
    type Case<'a> = (&'a str, &'a str, &'a dyn Fn(&mut PeopleFrame));
    let cases: [Case; 8] = [
        ("people_frame.people: ground.sigma_mm", "0 mm", &|p| {
            p.people[0].sigma_mm[1] = 0
        }),
        ("people_frame.people: ground.correlation", "singular", &|p| {
            p.people[0].correlation = i8::MIN
        }),
        ("people_frame.people: ground.histogram", "109 bins", &|p| {
            p.people[1].histogram.as_mut().unwrap().pop();
        }),
        ("people_frame.people: ground.histogram", "not 255", &|p| {
            let h = p.people[1].histogram.as_mut().unwrap();
            h.iter_mut().skip(100).for_each(|b| *b = (*b).min(254));
        }),
        ("people_frame.people: ground.histogram", "not 255", &|p| {
            p.people[0].histogram = Some(vec![0; HISTOGRAM_BINS])
        }),
        ("people_frame.people", "person 4 twice", &|p| {
            p.people[1].local = 4
        }),
        ("people_frame.rssi", "outside", &|p| p.rssi[0].dbm = 31.0),
        ("people_frame.people", "exceed the maximum of 64", &|p| {
            let one = p.people[0].clone();
            p.people = (0..=MAX_OBSERVATIONS as u32)
                .map(|local| GroundPerson { local, ..one.clone() })
                .collect();
        }),
    ];
    for (want, problem, f) in cases {
        let bad = with(f);
        let (field, e) = invalid(&raw(&bad));
        assert!(
            want.starts_with(&field) && e.contains(&want[field.len()..]),
            "{want}: {e}"
        );
        assert!(e.contains(problem), "{e}");
        assert!(
            matches!(encode(&bad), Err(WireError::Invalid(_))),
            "never sent either"
        );
    }
    let too_many_readings = with(&|p| p.rssi = vec![p.rssi[0]; MAX_OBSERVATIONS + 1]);
    assert_eq!(invalid(&raw(&too_many_readings)).0, "people_frame.rssi");
    // The most people, and none at all, are fine.
    let most = with(&|p| {
        let one = p.people[0].clone();
        p.people = (0..MAX_OBSERVATIONS as u32)
            .map(|local| GroundPerson { local, ..one.clone() })
            .collect();
    });
    assert_eq!(decode(&encode(&most).unwrap()).unwrap(), most);
    let empty = with(&|p| {
        p.people.clear();
        p.rssi.clear();
    });
    assert_eq!(decode(&encode(&empty).unwrap()).unwrap(), empty);
    // Byte-level damage: a bad option tag (the first person's target, right after its local
    // id), a varint that never ends, a frame cut inside the people.
    let frame = encode(&sample).unwrap();
    let header = encode(&with(&|p| {
        p.people.clear();
    }))
    .unwrap();
    // `people` is the last field: its length is the header's last byte, the first person
    // follows (local 4, then the target's option tag).
    let at = header.len() + 1;
    assert_eq!(frame[at - 1], 4, "the first person's local id");
    let mut bad = frame.clone();
    bad[at] = 2;
    let e = malformed(&bad);
    assert!(e.contains("people_frame") && e.contains("option tag"), "{e}");
    let mut bad = frame.clone();
    bad.truncate(at + 2);
    bad.extend([0xff; 12]);
    let e = malformed(&bad);
    assert!(e.contains("people_frame"), "{e}");
    let e = malformed(&frame[..frame.len() - 40]);
    assert!(e.contains("truncated") && e.contains("people_frame"), "{e}");
}

#[test]
fn unknown_enum_tags() {
    // Top-level message tag: `MESSAGE_KINDS.len()` is one past the last kind.
    let mut frame = encode(&samples()[2]).unwrap();
    let past = u8::try_from(proto::wire::MESSAGE_KINDS.len()).unwrap();
    *frame.last_mut().unwrap() = past;
    let e = malformed(&frame);
    assert!(e.contains(&format!("unknown message kind tag {past}")), "{e}");
    // A nested enum: the mode of a command (last byte), tag 3 of 3 modes.
    let mut frame = encode(&samples()[7]).unwrap();
    *frame.last_mut().unwrap() = 3;
    let e = malformed(&frame);
    assert!(
        e.contains("command") && e.contains("unknown enum variant tag"),
        "{e}"
    );
    // The role in a hello: bytes are … tag, version, role, node.
    let mut frame = encode(&samples()[0]).unwrap();
    let n = frame.len();
    frame[n - 2] = 9;
    let e = malformed(&frame);
    assert!(
        e.contains("hello") && e.contains("unknown enum variant tag"),
        "{e}"
    );
    // An option tag that is neither None nor Some: the handover's `from_head`.
    let mut env = samples()[10].clone();
    let Message::Handover(h) = &mut env.body else {
        panic!()
    };
    h.from_head = None;
    let with_none = encode(&env).unwrap();
    let with_some = encode(&samples()[10]).unwrap();
    let at = (0..with_none.len())
        .find(|&i| with_none[i] != with_some[i])
        .unwrap();
    let mut bad = with_some.clone();
    bad[at] = 2;
    let e = malformed(&bad);
    assert!(e.contains("handover") && e.contains("option tag"), "{e}");
}

#[test]
fn too_many_contributors() {
    let mut env = samples()[8].clone();
    let Message::TrackReport(r) = &mut env.body else {
        panic!()
    };
    r.contributors = (0..=MAX_CONTRIBUTORS as u32)
        .map(|i| Contributor {
            node: NodeId(i),
            kinds: proto::observation::Kinds::of(proto::observation::ObservationKind::Pinhole),
        })
        .collect();
    let frame = raw(&env);
    assert!(
        frame.len() <= MAX_FRAME_BYTES,
        "the size limit must not be what rejects it"
    );
    let (field, e) = invalid(&frame);
    assert_eq!(field, "track_report.contributors");
    assert!(
        e.contains(&format!(
            "{} entries exceed the maximum of {MAX_CONTRIBUTORS}",
            MAX_CONTRIBUTORS + 1
        )),
        "{e}"
    );
    assert!(matches!(encode(&env), Err(WireError::Invalid(_))));
    // Exactly the maximum is fine.
    let Message::TrackReport(r) = &mut env.body else {
        panic!()
    };
    r.contributors.pop();
    assert!(decode(&encode(&env).unwrap()).is_ok());
}

#[test]
fn other_range_checks_name_the_field() {
    use proto::observation::Observation;
    let mut env = samples()[3].clone();
    let edit = |env: &mut Envelope, f: &dyn Fn(&mut proto::observation::PinholePoint)| {
        if let Message::Measurement(m) = &mut env.body
            && let Observation::Pinhole(p) = &mut m.observations[0]
        {
            f(p);
        }
    };
    edit(&mut env, &|p| p.cov = [1.0, 2.0, 1.0]);
    let (field, e) = invalid(&raw(&env));
    assert_eq!(field, "measurement.observations");
    assert!(e.contains("pinhole.cov"), "{e}");
    edit(&mut env, &|p| {
        p.cov = [1.0, 0.0, 1.0];
        p.pixel_box.xmax = p.pixel_box.xmin - 1.0;
    });
    let (field, e) = invalid(&raw(&env));
    assert_eq!(field, "measurement.observations");
    assert!(e.contains("pinhole.pixel_box"), "{e}");
    // An acoustic frame with no band step.
    let mut env = samples()[3].clone();
    if let Message::Measurement(m) = &mut env.body {
        m.observations.retain(|o| matches!(o, Observation::Acoustic(_)));
        if let Observation::Acoustic(a) = &mut m.observations[0] {
            a.step_hz = 0.0;
        }
    }
    let (_, e) = invalid(&raw(&env));
    assert!(e.contains("acoustic.bands"), "{e}");
    let mut env = samples()[4].clone();
    if let Message::Answers(a) = &mut env.body {
        a.rssi[0].dbm = 45.0;
    }
    let (field, e) = invalid(&raw(&env));
    assert_eq!(field, "answers.rssi");
    assert!(e.contains("outside"), "{e}");
    // A contribution's ground person is gated to its own track, and a person's quantised
    // numbers are checked there too.
    let ground = proto::examples::observations()
        .into_iter()
        .find_map(|o| match o {
            Observation::Ground(p) => Some(p),
            _ => None,
        })
        .unwrap();
    let answers_with = |edit: &dyn Fn(&mut Answers)| {
        let mut env = samples()[4].clone();
        if let Message::Answers(a) = &mut env.body {
            edit(a);
        }
        env
    };
    let ok = answers_with(&|a| a.contributions[1].ground = Some(ground.clone()));
    assert_eq!(decode(&encode(&ok).unwrap()).unwrap(), ok);
    let other = answers_with(&|a| {
        a.contributions[1].ground = Some(GroundPerson {
            target: Some(TargetId(99)),
            ..ground.clone()
        })
    });
    let (field, e) = invalid(&raw(&other));
    assert_eq!(field, "answers.contributions.ground");
    assert!(e.contains("gated to t99"), "{e}");
    let singular = answers_with(&|a| {
        a.contributions[1].ground = Some(GroundPerson {
            correlation: i8::MIN,
            ..ground.clone()
        })
    });
    let (field, e) = invalid(&raw(&singular));
    assert_eq!(field, "answers.contributions.ground");
    assert!(e.contains("ground.correlation"), "{e}");
    // Each track once, each contribution bringing something, at most MAX_PRIORS of them.
    let twice = answers_with(&|a| a.contributions[1].target = a.contributions[0].target);
    let (field, e) = invalid(&raw(&twice));
    assert_eq!(field, "answers.contributions");
    assert!(e.contains("twice"), "{e}");
    let empty = answers_with(&|a| a.contributions[1].ground = None);
    assert!(invalid(&raw(&empty)).1.contains("brings nothing"));
    let both = answers_with(&|a| a.contributions[1].info = a.contributions[0].info.clone());
    assert!(invalid(&raw(&both)).1.contains("brings both"));
    let many = answers_with(&|a| {
        a.contributions = (0..=proto::msg::MAX_PRIORS as u32)
            .map(|t| Contribution {
                target: TargetId(t),
                ..a.contributions[0].clone()
            })
            .collect()
    });
    assert_eq!(invalid(&raw(&many)).0, "answers.contributions");
    // A step's priors: one step and deadline, each track once, at least one.
    let priors_with = |edit: &dyn Fn(&mut Priors)| {
        let mut env = samples()[6].clone();
        if let Message::Priors(p) = &mut env.body {
            edit(p);
        }
        raw(&env)
    };
    for (edit, want) in [
        (
            &(|p: &mut Priors| p.tracks[1].step += 1) as &dyn Fn(&mut Priors),
            "beside step",
        ),
        (&|p: &mut Priors| p.tracks[1].deadline.0 += 1, "beside step"),
        (&|p: &mut Priors| p.tracks[1].target = p.tracks[0].target, "twice"),
        (&|p: &mut Priors| p.tracks.clear(), "no prior"),
    ] {
        let (field, e) = invalid(&priors_with(edit));
        assert_eq!(field, "priors.tracks");
        assert!(e.contains(want), "{e}");
    }
    for edit in [
        &(|p: &mut Priors| p.parts = 0) as &dyn Fn(&mut Priors),
        &|p: &mut Priors| p.part = p.parts,
        &|p: &mut Priors| p.parts = MAX_PRIOR_PARTS + 1,
    ] {
        assert_eq!(invalid(&priors_with(edit)).0, "priors.part");
    }
    let mut env = samples()[1].clone();
    let Message::HelloAck(a) = &mut env.body else {
        panic!()
    };
    a.reason = "x".repeat(513);
    assert_eq!(invalid(&raw(&env)).0, "hello_ack.reason");
    let mut env = samples()[8].clone();
    let Message::TrackReport(r) = &mut env.body else {
        panic!()
    };
    r.power_mw = -1.0;
    let (field, e) = invalid(&raw(&env));
    assert_eq!(field, "track_report.power_mw");
    assert!(e.contains("negative power"), "{e}");
    // Valid zero information is accepted.
    let mut env = samples()[4].clone();
    let Message::Answers(a) = &mut env.body else {
        panic!()
    };
    a.contributions[0].info.as_mut().unwrap().matrix = [[0.0; 6]; 6];
    assert!(decode(&encode(&env).unwrap()).is_ok());
    // A track the node has nothing for is not listed: 336 bytes of zeros and its id saved.
    let with = encode(&env).unwrap().len();
    let Message::Answers(a) = &mut env.body else {
        panic!()
    };
    a.contributions.remove(0);
    let without = encode(&env).unwrap();
    assert_eq!(with - without.len(), 336 + 4);
    assert_eq!(decode(&without).unwrap(), env);
}

/// Matrices so large that their eigen-decomposition would overflow are still judged: an
/// indefinite one is rejected (not waved through by a NaN comparison), a PSD one accepted.
#[test]
fn huge_matrices_are_judged_correctly() {
    for big in [1e300, f64::MAX] {
        let with = |f: &dyn Fn(usize, usize) -> f64| {
            let mut env = samples()[6].clone();
            let Message::Priors(p) = &mut env.body else {
                panic!()
            };
            for i in 0..6 {
                for j in 0..6 {
                    p.tracks[0].cov[i][j] = f(i, j);
                }
            }
            raw(&env)
        };
        let (field, e) = invalid(&with(&|i, j| if i == j { -big } else { big }));
        assert_eq!(field, "priors.tracks.cov");
        assert!(e.contains("indefinite"), "{e}");
        // Rank one, v vᵀ with v = ±√big: positive semi-definite.
        assert!(
            decode(&with(&|i, j| if (i + j) % 2 == 0 { big } else { -big })).is_ok(),
            "{big:e}"
        );
    }
}

/// A full step part fits in a frame: MAX_PRIORS priors, and MAX_PRIORS contributions of the
/// larger kind (folded information) with the most tag readings, or people with histograms.
#[test]
fn the_largest_priors_and_answers_fit_in_a_frame() {
    let Message::Priors(p) = samples()[6].body.clone() else {
        panic!("sample 6 is priors")
    };
    let mut env = samples()[6].clone();
    env.body = Message::Priors(Priors {
        tracks: (0..MAX_PRIORS as u32)
            .map(|t| Prior {
                target: TargetId(u32::MAX - t),
                step: u64::MAX,
                ..p.tracks[0].clone()
            })
            .collect(),
        ..p
    });
    let frame = encode(&env).unwrap();
    assert!(frame.len() <= MAX_FRAME_BYTES, "{} bytes", frame.len());
    let Message::Answers(a) = samples()[4].body.clone() else {
        panic!("sample 4 is answers")
    };
    let folded = Answers {
        rssi: vec![a.rssi[0]; proto::observation::MAX_OBSERVATIONS],
        contributions: (0..MAX_PRIORS as u32)
            .map(|t| Contribution {
                target: TargetId(u32::MAX - t),
                ..a.contributions[0].clone()
            })
            .collect(),
        step: u64::MAX,
        ..a.clone()
    };
    let mut person = a.contributions[1].ground.clone().unwrap();
    person.histogram = proto::examples::messages()
        .into_iter()
        .find_map(|e| match e.body {
            Message::PeopleFrame(f) => f.people.into_iter().find_map(|p| p.histogram),
            _ => None,
        });
    let people = Answers {
        contributions: (0..MAX_PRIORS as u32)
            .map(|t| Contribution {
                target: TargetId(u32::MAX - t),
                info: None,
                folded: proto::observation::Kinds::NONE,
                ground: Some(GroundPerson {
                    target: None,
                    ..person.clone()
                }),
            })
            .collect(),
        ..folded.clone()
    };
    for answers in [folded, people] {
        env.body = Message::Answers(answers);
        let frame = encode(&env).unwrap();
        assert!(frame.len() <= MAX_FRAME_BYTES, "{} bytes", frame.len());
    }
}

/// A head's tags and the server's homes: a list past its bound, a tag out of order or twice,
/// an impossible loudness are rejected naming the field.
#[test]
fn tag_lists_are_sets_of_plausible_readings() {
    let heard = proto::examples::tags_heard;
    let homes = |tags: &[u64]| {
        Message::TagHomes(TagHomes {
            homes: tags
                .iter()
                .map(|&t| TagHome {
                    tag: TagId(t),
                    head: NodeId(3),
                    shared: false,
                })
                .collect(),
        })
    };
    let field = |m: Message| m.validate().err().map(|e| (e.field, e.problem));
    assert_eq!(field(heard(&[(1, -60.0), (2, -70.0)])), None);
    assert_eq!(field(homes(&[1, 2])), None);
    let (f, p) = field(heard(&[(2, -60.0), (1, -70.0)])).unwrap();
    assert_eq!(f, "tags_heard.tags");
    assert!(p.contains("out of order or named twice"), "{p}");
    let (f, _) = field(heard(&[(1, -60.0), (1, -70.0)])).unwrap();
    assert_eq!(f, "tags_heard.tags");
    let (f, p) = field(heard(&[(1, 35.0)])).unwrap();
    assert_eq!(f, "tags_heard.tags");
    assert!(p.contains("outside"), "{p}");
    let (f, _) = field(homes(&[5, 5])).unwrap();
    assert_eq!(f, "tag_homes.homes");
    let many: Vec<(u64, f32)> = (0..=MAX_TAGS_HEARD as u64).map(|t| (t, -60.0)).collect();
    let (f, p) = field(heard(&many)).unwrap();
    assert_eq!(f, "tags_heard.tags");
    assert!(p.contains("exceed the maximum of 256"), "{p}");
}
