//! proptest round trips: random valid envelopes of every kind encode, decode and compare equal.

use proptest::prelude::*;
use proto::ids::{NodeId, Role, TagId, TargetId};
use proto::msg::*;
use proto::observation::{
    GroundPerson, HISTOGRAM_BINS, HISTOGRAM_HS_BINS, IldVector, Kinds, MAX_BINS, Observation, PinholePoint,
};
use proto::view::{
    HandoverCause, MAX_VIEW_CONTRIBUTORS, MAX_VIEW_HANDOVERS, MAX_VIEW_PARTS, ViewCounters, ViewHandover,
    ViewNode, ViewTrack,
};
use proto::{
    ClusterTime, Envelope, MAX_CONTRIBUTORS, MAX_MEASURED_DETECTIONS, Message, Mode, decode, encode,
};

fn finite() -> impl Strategy<Value = f64> {
    prop_oneof![
        -1e6..1e6f64,
        -1.0..1.0f64,
        Just(0.0),
        Just(-0.0),
        Just(f64::MAX),
        Just(f64::MIN_POSITIVE)
    ]
}

fn finite32() -> impl Strategy<Value = f32> {
    -1e4..1e4f32
}

fn time() -> impl Strategy<Value = ClusterTime> {
    any::<i64>().prop_map(ClusterTime)
}

fn mode() -> impl Strategy<Value = Mode> {
    prop::sample::select(Mode::ALL.to_vec())
}

fn vec6() -> impl Strategy<Value = Vec6> {
    prop::array::uniform6(finite())
}

/// A random positive semi-definite matrix `A·Aᵀ` (entries of `A` in ±10), rank 0..=6.
fn psd() -> impl Strategy<Value = Mat6> {
    (prop::collection::vec(prop::array::uniform6(-10.0..10.0f64), 0..=6)).prop_map(|cols| {
        let mut m = [[0.0; 6]; 6];
        for c in &cols {
            for i in 0..6 {
                for j in 0..6 {
                    m[i][j] += c[i] * c[j];
                }
            }
        }
        m
    })
}

fn rssi() -> impl Strategy<Value = RssiReading> {
    (any::<u64>(), -200.0..=30.0f64, time()).prop_map(|(tag, dbm, time)| RssiReading {
        tag: TagId(tag),
        dbm,
        time,
    })
}

fn cov2() -> impl Strategy<Value = [f64; 3]> {
    (0.001..10.0f64, -0.99..0.99f64, 0.001..10.0f64)
        .prop_map(|(xx, rho, yy)| [xx, rho * (xx * yy).sqrt(), yy])
}

fn pinhole() -> impl Strategy<Value = Observation> {
    (
        prop::array::uniform2(finite()),
        prop::option::of(prop::array::uniform2(finite())),
        cov2(),
        (
            prop::array::uniform4(finite32()),
            any::<u32>(),
            prop::array::uniform3(finite32()),
        ),
        time(),
    )
        .prop_map(|(point, prev_point, cov, (b, area, c), captured)| {
            Observation::Pinhole(PinholePoint {
                point,
                prev_point,
                cov,
                pixel_box: PixelBox {
                    xmin: b[0].min(b[1]),
                    ymin: b[2].min(b[3]),
                    xmax: b[0].max(b[1]),
                    ymax: b[2].max(b[3]),
                },
                area,
                colour: ColourSignature {
                    hue: c[0],
                    saturation: c[1],
                    intensity: c[2],
                },
                captured,
            })
        })
}

/// A valid quantised histogram: any bytes with each part's fullest at 255.
fn histogram() -> impl Strategy<Value = Vec<u8>> {
    (
        prop::collection::vec(any::<u8>(), HISTOGRAM_BINS),
        0..HISTOGRAM_HS_BINS,
        HISTOGRAM_HS_BINS..HISTOGRAM_BINS,
    )
        .prop_map(|(mut h, a, b)| {
            h[a] = 255;
            h[b] = 255;
            h
        })
}

fn person(local: u32) -> impl Strategy<Value = GroundPerson> {
    (
        prop::option::of(any::<u32>()),
        any::<[i32; 2]>(),
        (1..=u16::MAX, 1..=u16::MAX, -127..=127i8),
        (any::<u16>(), any::<u16>(), any::<u8>()),
        any::<[i16; 2]>(),
        prop::option::of(histogram()),
    )
        .prop_map(
            move |(
                target,
                position_cm,
                (sx, sy, correlation),
                (width_cm, height_cm, confidence),
                ml_offset_cm,
                histogram,
            )| {
                GroundPerson {
                    local,
                    target: target.map(TargetId),
                    position_cm,
                    sigma_mm: [sx, sy],
                    correlation,
                    width_cm,
                    height_cm,
                    confidence,
                    ml_offset_cm,
                    histogram,
                }
            },
        )
}

fn people_frame() -> impl Strategy<Value = Message> {
    (
        time(),
        mode(),
        prop::collection::vec(rssi(), 0..=4),
        prop::collection::btree_set(any::<u32>(), 0..=8),
    )
        .prop_flat_map(|(captured, mode, rssi, locals)| {
            let people: Vec<_> = locals.into_iter().map(person).collect();
            people.prop_map(move |people| {
                Message::PeopleFrame(PeopleFrame {
                    captured,
                    mode,
                    rssi: rssi.clone(),
                    people,
                })
            })
        })
}

fn acoustic() -> impl Strategy<Value = Observation> {
    (
        0.0..20_000.0f32,
        0.1..1000.0f32,
        prop::collection::vec(finite32(), 0..=MAX_BINS),
        time(),
    )
        .prop_map(|(first_hz, step_hz, ild_db, captured)| {
            Observation::Acoustic(IldVector {
                first_hz,
                step_hz,
                ild_db,
                captured,
            })
        })
}

fn observation() -> impl Strategy<Value = Observation> {
    prop_oneof![pinhole(), rssi().prop_map(Observation::Rssi), acoustic()]
}

/// Observations that fit one frame with the rest of a message: at most eight, each small, at
/// most one ground person (a contribution carries no more).
fn observations() -> impl Strategy<Value = Vec<Observation>> {
    prop::collection::vec(observation(), 0..=8)
        .prop_filter("fits a frame", |v| {
            v.iter()
                .map(|o| match o {
                    Observation::Acoustic(a) => a.ild_db.len(),
                    Observation::Ground(_) => HISTOGRAM_BINS,
                    _ => 0,
                })
                .sum::<usize>()
                <= 2 * MAX_BINS
        })
        .prop_filter("one ground person", |v| {
            v.iter().filter(|o| matches!(o, Observation::Ground(_))).count() <= 1
        })
}

fn measurement() -> impl Strategy<Value = Message> {
    (
        (prop::option::of(any::<u32>()), any::<u64>()),
        (prop::array::uniform3(finite()), prop::array::uniform3(finite())),
        mode(),
        observations(),
    )
        .prop_map(|((target, step), (rvec, tvec), mode, observations)| {
            Message::Measurement(Measurement {
                target: target.map(TargetId),
                step,
                pose: PoseWire { rvec, tvec },
                mode,
                observations,
            })
        })
}

fn measured_detection() -> impl Strategy<Value = MeasuredDetection> {
    (
        (
            prop::array::uniform4(finite32()),
            prop::array::uniform4(finite32()),
            any::<u32>(),
            prop::array::uniform3(finite32()),
        ),
        prop::array::uniform2(finite()),
        (0.001..10.0f64, -0.99..0.99f64, 0.001..10.0f64),
    )
        .prop_map(|((cf, b, area, c), point, (xx, rho, yy))| MeasuredDetection {
            centre: [cf[0], cf[1]],
            foot: [cf[2], cf[3]],
            pixel_box: PixelBox {
                xmin: b[0].min(b[1]),
                ymin: b[2].min(b[3]),
                xmax: b[0].max(b[1]),
                ymax: b[2].max(b[3]),
            },
            area,
            colour: ColourSignature {
                hue: c[0],
                saturation: c[1],
                intensity: c[2],
            },
            point,
            cov: [xx, rho * (xx * yy).sqrt(), yy],
        })
}

fn measured_frame() -> impl Strategy<Value = Message> {
    (
        time(),
        prop::collection::vec(rssi(), 0..=8),
        prop::collection::vec(measured_detection(), 0..=MAX_MEASURED_DETECTIONS),
    )
        .prop_map(|(captured, rssi, detections)| {
            Message::MeasuredFrame(MeasuredFrame {
                captured,
                rssi,
                detections,
            })
        })
}

fn contributors() -> impl Strategy<Value = Vec<Contributor>> {
    prop::collection::vec(
        (any::<u32>(), 0..16u8).prop_map(|(n, kinds)| Contributor {
            node: NodeId(n),
            kinds: Kinds(kinds),
        }),
        0..=MAX_CONTRIBUTORS / 4,
    )
}

fn message() -> impl Strategy<Value = Message> {
    prop_oneof![
        (
            prop::sample::select(vec![
                Role::Camera,
                Role::Head,
                Role::Server,
                Role::Tool,
                Role::Viewer
            ]),
            any::<u32>()
        )
            .prop_map(|(role, n)| Message::Hello(Hello {
                version: proto::PROTOCOL_VERSION,
                role,
                node: NodeId(n)
            })),
        (any::<bool>(), "\\PC{0,100}")
            .prop_map(|(accepted, reason)| Message::HelloAck(HelloAck { accepted, reason })),
        Just(Message::Heartbeat),
        measurement(),
        (
            any::<u64>(),
            any::<u16>(),
            time(),
            mode(),
            prop::collection::vec(rssi(), 0..4),
            prop::collection::vec((any::<u32>(), psd(), vec6(), 0..16u8), 0..4)
        )
            .prop_map(|(step, part, captured, mode, rssi, contributions)| {
                Message::Answers(Answers {
                    step,
                    part,
                    captured,
                    mode,
                    rssi,
                    contributions: contributions
                        .into_iter()
                        .map(|(t, matrix, vector, folded)| Contribution {
                            target: TargetId(t),
                            info: Some(Information { matrix, vector }),
                            folded: Kinds(folded),
                            ground: None,
                        })
                        .collect(),
                })
            }),
        (
            mode(),
            any::<[u64; 3]>(),
            any::<[u64; 4]>(),
            any::<i64>(),
            any::<i64>(),
            any::<u64>()
        )
            .prop_map(
                |(mode, time_in_mode_ns, c, sync_offset_ns, sync_error_ns, bytes_sent)| {
                    Message::NodeStatus(NodeStatus {
                        mode,
                        time_in_mode_ns,
                        frames: c[0],
                        detections: c[1],
                        dropped: c[2],
                        rejected: c[3],
                        sync_offset_ns,
                        sync_error_ns,
                        bytes_sent,
                    })
                }
            ),
        (
            any::<u16>(),
            any::<u64>(),
            time(),
            prop::collection::vec((any::<u32>(), vec6(), psd(), any::<bool>()), 1..4)
        )
            .prop_map(|(part, step, deadline, tracks)| {
                // A part within the step's parts, up to MAX_PRIOR_PARTS of them.
                let parts = part % MAX_PRIOR_PARTS + 1;
                Message::Priors(Priors {
                    part: part % parts,
                    parts,
                    tracks: tracks
                        .into_iter()
                        .map(|(t, mean, cov, radio)| Prior {
                            target: TargetId(t),
                            step,
                            mean,
                            cov,
                            deadline,
                            radio,
                        })
                        .collect(),
                })
            }),
        (any::<u32>(), mode()).prop_map(|(n, mode)| Message::Command(Command {
            node: NodeId(n),
            mode
        })),
        (
            (any::<u32>(), prop::option::of(any::<u32>()), any::<u64>(), time()),
            (vec6(), psd(), contributors(), prop::option::of(time())),
            (
                0.0..1e6f64,
                any::<u64>(),
                prop::collection::vec(0.0..1.0f32, 0..=MAX_BINS),
                prop::option::of(grid_posterior())
            )
        )
            .prop_map(
                |(
                    (t, g, step, time),
                    (mean, cov, contributors, captured),
                    (power_mw, late, appearance, grid),
                )| {
                    Message::TrackReport(TrackReport {
                        target: TargetId(t),
                        global: g.map(TargetId),
                        step,
                        time,
                        mean,
                        cov,
                        contributors,
                        power_mw,
                        late,
                        appearance,
                        grid,
                        captured,
                    })
                }
            ),
        (any::<u32>(), any::<u32>()).prop_map(|(n, h)| Message::Assignment(Assignment {
            node: NodeId(n),
            head: NodeId(h)
        })),
        (
            any::<u32>(),
            any::<u32>(),
            prop::option::of(any::<u32>()),
            time(),
            vec6(),
            psd()
        )
            .prop_map(|(g, to, from, time, mean, cov)| Message::Handover(Handover {
                global: TargetId(g),
                to_head: NodeId(to),
                from_head: from.map(NodeId),
                time,
                mean,
                cov,
            })),
        (any::<u32>(), any::<u64>(), time()).prop_map(|(l, round, leader_time)| Message::SyncBeacon(
            SyncBeacon {
                leader: NodeId(l),
                round,
                leader_time
            }
        )),
        (any::<u32>(), any::<bool>()).prop_map(|(n, up)| Message::Liveness(Liveness { node: NodeId(n), up })),
        measured_frame(),
        (any::<u32>(), prop::option::of(any::<u32>())).prop_map(|(n, local)| Message::SampleRequest(
            SampleRequest {
                node: NodeId(n),
                local
            }
        )),
        sample_set(),
        (time(), mode(), any::<u32>()).prop_map(|(captured, mode, detections)| Message::FrameReport(
            FrameReport {
                captured,
                mode,
                detections
            }
        )),
        any::<u32>().prop_map(|period_ms| Message::ViewSubscribe(ViewSubscribe { period_ms })),
        view_update(),
        people_frame(),
        prop::collection::btree_map(
            any::<u64>(),
            (
                -200.0..30.0f32,
                prop::option::of(any::<u32>()),
                finite32(),
                finite32()
            ),
            0..=MAX_TAGS_HEARD
        )
        .prop_map(|tags| {
            Message::TagsHeard(TagsHeard {
                tags: tags
                    .into_iter()
                    .map(|(t, (dbm, track, x, y))| TagHeard {
                        tag: TagId(t),
                        dbm,
                        near: [x, y],
                        track: track.map(TargetId),
                    })
                    .collect(),
            })
        }),
        prop::collection::btree_map(any::<u64>(), (any::<u32>(), any::<bool>()), 0..=MAX_TAGS_HEARD)
            .prop_map(|homes| {
                Message::TagHomes(TagHomes {
                    homes: homes
                        .into_iter()
                        .map(|(t, (h, shared))| TagHome {
                            tag: TagId(t),
                            head: NodeId(h),
                            shared,
                        })
                        .collect(),
                })
            }),
    ]
}

fn view_track() -> impl Strategy<Value = ViewTrack> {
    (
        (any::<u32>(), any::<u32>(), prop::option::of(any::<u32>()), time()),
        (vec6(), prop::array::uniform6(finite()), contributors()),
    )
        .prop_map(
            |((g, owner, local, time), (mean, mut cov_pos, mut contributors))| {
                for i in [0, 3, 5] {
                    cov_pos[i] = cov_pos[i].abs();
                }
                contributors.truncate(MAX_VIEW_CONTRIBUTORS);
                ViewTrack {
                    global: TargetId(g),
                    owner: NodeId(owner),
                    local: local.map(TargetId),
                    time,
                    mean,
                    cov_pos,
                    contributors,
                }
            },
        )
}

fn view_node() -> impl Strategy<Value = ViewNode> {
    (
        (
            any::<u32>(),
            prop::sample::select(vec![Role::Camera, Role::Head, Role::Viewer]),
        ),
        (any::<bool>(), any::<u64>(), prop::option::of(any::<u32>())),
        (prop::option::of(mode()), any::<[u64; 4]>()),
    )
        .prop_map(|((n, role), (up, silent_ms, head), (mode, c))| ViewNode {
            node: NodeId(n),
            role,
            up,
            silent_ms,
            head: head.map(NodeId),
            status: mode.map(|mode| NodeStatus {
                mode,
                time_in_mode_ns: [c[0], c[1], c[2]],
                frames: c[3],
                detections: c[2],
                dropped: c[1],
                rejected: c[0],
                sync_offset_ns: -5,
                sync_error_ns: 7,
                bytes_sent: 0,
            }),
            steps: c[0],
            late: c[1],
            rejected: c[2],
            lost: c[3],
        })
}

fn view_update() -> impl Strategy<Value = Message> {
    let handover = (
        any::<u64>(),
        time(),
        any::<u32>(),
        prop::option::of(any::<u32>()),
        any::<u32>(),
    )
        .prop_map(|(seq, time, g, from, to)| ViewHandover {
            seq,
            time,
            global: TargetId(g),
            from: from.map(NodeId),
            to: NodeId(to),
            cause: HandoverCause::Failover,
        });
    (
        (any::<u64>(), 1..=MAX_VIEW_PARTS, time()),
        prop::collection::vec(view_track(), 0..4),
        prop::collection::vec(view_node(), 0..6),
        prop::collection::vec(handover, 0..=MAX_VIEW_HANDOVERS),
        any::<[u64; 4]>(),
    )
        .prop_map(|((round, parts, time), tracks, nodes, handovers, c)| {
            Message::ViewUpdate(ViewUpdate {
                round,
                part: parts - 1,
                parts,
                time,
                tracks_total: tracks.len() as u32,
                tracks,
                nodes_total: nodes.len() as u32,
                nodes,
                handovers,
                counters: ViewCounters {
                    received: c[0],
                    rejected: c[1],
                    handovers: c[2],
                    undelivered: c[3],
                },
            })
        })
}

fn sample_set() -> impl Strategy<Value = Message> {
    let sample = (prop::array::uniform6(finite32()), 0.0..=1.0f32)
        .prop_map(|(state, weight)| ImageSample { state, weight });
    (
        any::<u32>(),
        time(),
        prop::collection::vec(sample, 0..=MAX_SAMPLES),
    )
        .prop_map(|(local, captured, samples)| {
            Message::SampleSet(SampleSet {
                local,
                captured,
                samples,
            })
        })
}

fn grid_posterior() -> impl Strategy<Value = GridPosterior> {
    (
        1u16..=8,
        1u16..=8,
        -50.0f32..50.0,
        -50.0f32..50.0,
        0.01f32..2.0,
        0.0f32..=1.0,
    )
        .prop_flat_map(|(nx, ny, x, y, cell_m, peak_mass)| {
            prop::collection::vec(any::<u8>(), usize::from(nx) * usize::from(ny)).prop_map(move |cells| {
                GridPosterior {
                    origin: [x, y],
                    cell_m,
                    nx,
                    ny,
                    peak_mass,
                    cells,
                }
            })
        })
}

fn envelope() -> impl Strategy<Value = Envelope> {
    (any::<u32>(), any::<u64>(), time(), message()).prop_map(|(s, seq, time, body)| Envelope {
        source: NodeId(s),
        seq,
        time,
        body,
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn every_kind_round_trips(env in envelope()) {
        let frame = encode(&env).map_err(|e| TestCaseError::fail(format!("{} did not encode: {e}", env.body.kind())))?;
        prop_assert_eq!(decode(&frame).unwrap(), env);
    }

    /// Any prefix of a valid frame is rejected, never accepted or panicking.
    #[test]
    fn every_strict_prefix_is_rejected(env in envelope()) {
        let frame = encode(&env).unwrap();
        for n in 0..frame.len() {
            prop_assert!(decode(&frame[..n]).is_err());
        }
    }

    /// Arbitrary bytes never panic the decoder.
    #[test]
    fn arbitrary_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..600)) {
        let _ = decode(&bytes);
    }
}

/// Every kind appears among the strategy's values (the `prop_oneof!` list is complete).
#[test]
fn strategy_covers_every_kind() {
    use proptest::strategy::ValueTree;
    use proptest::test_runner::TestRunner;
    let mut runner = TestRunner::deterministic();
    let mut seen = std::collections::BTreeSet::new();
    for _ in 0..2000 {
        seen.insert(message().new_tree(&mut runner).unwrap().current().kind());
    }
    assert_eq!(seen.len(), proto::wire::MESSAGE_KINDS.len(), "{seen:?}");
}
