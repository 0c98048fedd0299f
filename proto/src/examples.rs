//! Fixtures: one fixed envelope per message kind, in wire-tag order, and one observation per
//! observation kind — for the golden byte vectors, benchmarks and fuzz corpora. Every
//! floating-point slot holds a distinct, exactly representable value (symmetric matrix entries
//! share theirs), so tests can find each slot in the encoded bytes.

use crate::ids::{NodeId, Role, TagId, TargetId};
use crate::msg::*;
use crate::observation::{GroundPerson, IldVector, PinholePoint};
use crate::{ClusterTime, Envelope, Message, Mode};

/// A symmetric, diagonally dominant (so positive-definite) matrix whose upper-triangle entries
/// are distinct and differ from those of other seeds.
#[allow(clippy::needless_range_loop)] // (i, j) index pairs read clearer than zipped iterators
pub fn spd(seed: u32) -> Mat6 {
    let s = f64::from(seed);
    let mut m = [[0.0; 6]; 6];
    for i in 0..6 {
        for j in i..6 {
            let v = if i == j {
                20.0 + s + i as f64
            } else {
                0.0625 * s + (i * 6 + j) as f64 / 256.0
            };
            m[i][j] = v;
            m[j][i] = v;
        }
    }
    m
}

/// A state-sized fixture vector with distinct entries.
pub fn vec6(seed: u32) -> Vec6 {
    let s = f64::from(seed);
    std::array::from_fn(|i| -s - (i as f64 + 1.0) / 8.0)
}

fn env(body: Message) -> Envelope {
    Envelope {
        source: NodeId(7),
        seq: 42,
        time: ClusterTime(1_500_000_123),
        body,
    }
}

/// The number of f64 and f32 slots of each sample, by tag (what the poison test must find).
pub const FLOAT_SLOTS: [(usize, usize); 22] = [
    (0, 0),   // hello
    (0, 0),   // hello_ack
    (0, 0),   // heartbeat
    (14, 13), // measurement: rvec 3, tvec 3, pin-hole 7, rssi 1; box 4, colour 3, ild 2 + 4
    (43, 0),  // answers: rssi 1; info 36 + 6 (the ground person is integers)
    (0, 0),   // node_status
    (84, 0),  // priors: two tracks of mean 6 + cov 36
    (0, 0),   // command
    (43, 7),  // track_report: mean 6 + cov 36 + power 1; appearance 3; grid origin 2, cell 1, peak 1
    (0, 0),   // assignment
    (42, 0),  // handover
    (0, 0),   // sync_beacon
    (0, 0),   // liveness
    (6, 11),  // measured_frame: rssi 1, point 2, cov 3; centre 2, foot 2, box 4, colour 3
    (0, 0),   // sample_request
    (0, 14),  // sample_set: two samples of state 6 + weight 1
    (0, 0),   // frame_report
    (0, 0),   // view_subscribe
    (12, 0),  // view_update: mean 6 + cov_pos 6
    (1, 0),   // people_frame: rssi 1 (the people are integers)
    (0, 6),   // tags_heard: two tags' dBm and near
    (0, 0),   // tag_homes
];

/// One observation of each kind, in wire-tag order.
pub fn observations() -> Vec<Observation> {
    vec![
        Observation::Pinhole(PinholePoint {
            point: [0.125, -0.375],
            cov: [0.015625, 0.0009765625, 0.0234375],
            prev_point: Some([0.1875, -0.3125]),
            pixel_box: PixelBox {
                xmin: 11.1,
                ymin: 22.2,
                xmax: 33.3,
                ymax: 44.4,
            },
            area: 1234,
            colour: ColourSignature {
                hue: 0.51,
                saturation: 0.62,
                intensity: 0.73,
            },
            captured: ClusterTime(1_499_990_000),
        }),
        Observation::Rssi(RssiReading {
            tag: TagId(0x0200_0000_0001),
            dbm: -61.5,
            time: ClusterTime(1_499_995_000),
        }),
        Observation::Ground(GroundPerson {
            local: 6,
            target: None,
            position_cm: [-410, 655],
            sigma_mm: [301, 287],
            correlation: 12,
            width_cm: 51,
            height_cm: 172,
            confidence: 230,
            ml_offset_cm: [0, 4],
            histogram: None,
        }),
        Observation::Acoustic(IldVector {
            first_hz: 187.3,
            step_hz: 93.7,
            ild_db: vec![1.1, -2.3, 3.7, 0.45],
            captured: ClusterTime(1_499_992_000),
        }),
    ]
}

/// One envelope per message kind, in wire-tag order.
pub fn messages() -> Vec<Envelope> {
    vec![
        env(Message::Hello(Hello {
            version: crate::PROTOCOL_VERSION,
            role: Role::Head,
            node: NodeId(3),
        })),
        env(Message::HelloAck(HelloAck {
            accepted: false,
            reason: "id taken".into(),
        })),
        env(Message::Heartbeat),
        env(Message::Measurement(Measurement {
            target: Some(TargetId(5)),
            step: 300,
            pose: PoseWire {
                rvec: [1.5, -2.5, 0.09375],
                tvec: [3.5, 4.5, -5.5],
            },
            mode: Mode::Active,
            observations: observations(),
        })),
        env(Message::Answers(Answers {
            step: 300,
            part: 1,
            captured: ClusterTime(1_499_990_000),
            mode: Mode::CameraOff,
            rssi: vec![RssiReading {
                tag: TagId(0x0a0b_0c0d_0e0f),
                dbm: -70.25,
                time: ClusterTime(-17),
            }],
            contributions: vec![
                Contribution {
                    target: TargetId(5),
                    info: Some(Information {
                        matrix: spd(1),
                        vector: vec6(1),
                    }),
                    folded: Kinds::of(ObservationKind::Pinhole),
                    ground: None,
                },
                Contribution {
                    target: TargetId(7),
                    info: None,
                    folded: Kinds::NONE,
                    ground: Some(GroundPerson {
                        local: 2,
                        target: Some(TargetId(7)),
                        position_cm: [120, -35],
                        sigma_mm: [210, 198],
                        correlation: 5,
                        width_cm: 49,
                        height_cm: 170,
                        confidence: 201,
                        ml_offset_cm: [3, -1],
                        histogram: None,
                    }),
                },
            ],
        })),
        env(Message::NodeStatus(NodeStatus {
            mode: Mode::Inactive,
            time_in_mode_ns: [1, 300, 70_000],
            frames: 900,
            detections: 850,
            dropped: 2,
            rejected: 1,
            sync_offset_ns: -1500,
            sync_error_ns: 250,
            bytes_sent: 123_456,
        })),
        env(Message::Priors(Priors {
            part: 0,
            parts: 1,
            tracks: vec![
                Prior {
                    target: TargetId(5),
                    step: 301,
                    mean: vec6(2),
                    cov: spd(2),
                    deadline: ClusterTime(1_500_080_000),
                    radio: false,
                },
                Prior {
                    target: TargetId(7),
                    step: 301,
                    mean: vec6(4),
                    cov: spd(4),
                    deadline: ClusterTime(1_500_080_000),
                    radio: true,
                },
            ],
        })),
        env(Message::Command(Command {
            node: NodeId(12),
            mode: Mode::CameraOff,
        })),
        env(Message::TrackReport(TrackReport {
            target: TargetId(5),
            global: Some(TargetId(1005)),
            step: 301,
            time: ClusterTime(1_500_100_000),
            mean: vec6(3),
            cov: spd(3),
            contributors: vec![
                Contributor {
                    node: NodeId(10),
                    kinds: Kinds::of(ObservationKind::Pinhole).union(Kinds::of(ObservationKind::Rssi)),
                },
                Contributor {
                    node: NodeId(300),
                    kinds: Kinds::of(ObservationKind::Rssi),
                },
            ],
            power_mw: 1437.5,
            late: 3,
            appearance: vec![0.625, 0.25, 0.125],
            grid: Some(GridPosterior {
                origin: [0.5, -1.25],
                cell_m: 0.375,
                nx: 3,
                ny: 2,
                peak_mass: 0.0625,
                cells: vec![0, 17, 255, 3, 128, 9],
            }),
            captured: Some(ClusterTime(1_500_020_000)),
        })),
        env(Message::Assignment(Assignment {
            node: NodeId(10),
            head: NodeId(2),
        })),
        env(Message::Handover(Handover {
            global: TargetId(1005),
            to_head: NodeId(3),
            from_head: Some(NodeId(2)),
            time: ClusterTime(1_500_200_000),
            mean: vec6(4),
            cov: spd(4),
        })),
        env(Message::SyncBeacon(SyncBeacon {
            leader: NodeId(1),
            round: 77,
            leader_time: ClusterTime(1_500_300_000),
        })),
        env(Message::Liveness(Liveness {
            node: NodeId(11),
            up: false,
        })),
        env(Message::MeasuredFrame(MeasuredFrame {
            captured: ClusterTime(1_499_990_000),
            rssi: vec![RssiReading {
                tag: TagId(0x0200_0000_0002),
                dbm: -58.75,
                time: ClusterTime(1_499_989_000),
            }],
            detections: vec![MeasuredDetection {
                centre: [101.5, 202.25],
                foot: [103.75, 250.5],
                pixel_box: PixelBox {
                    xmin: 90.5,
                    ymin: 180.25,
                    xmax: 112.75,
                    ymax: 251.5,
                },
                area: 777,
                colour: ColourSignature {
                    hue: 0.21,
                    saturation: 0.32,
                    intensity: 0.43,
                },
                point: [0.40625, -0.59375],
                cov: [0.046875, 0.001953125, 0.0390625],
            }],
        })),
        env(Message::SampleRequest(SampleRequest {
            node: NodeId(10),
            local: Some(4),
        })),
        env(Message::SampleSet(SampleSet {
            local: 4,
            captured: ClusterTime(1_499_991_000),
            samples: vec![
                ImageSample {
                    state: [120.5, 84.25, 1.5, -0.75, 30.5, 90.25],
                    weight: 0.625,
                },
                ImageSample {
                    state: [122.75, 85.5, 2.25, -1.25, 31.75, 88.5],
                    weight: 0.375,
                },
            ],
        })),
        env(Message::FrameReport(FrameReport {
            captured: ClusterTime(1_499_993_000),
            mode: Mode::Active,
            detections: 2,
        })),
        env(Message::ViewSubscribe(ViewSubscribe { period_ms: 200 })),
        env(Message::ViewUpdate(view_update())),
        env(Message::PeopleFrame(PeopleFrame {
            captured: ClusterTime(1_499_994_000),
            mode: Mode::Active,
            rssi: vec![RssiReading {
                tag: TagId(0x0200_0000_0003),
                dbm: -66.125,
                time: ClusterTime(1_499_993_500),
            }],
            people: vec![
                GroundPerson {
                    local: 4,
                    target: Some(TargetId(5)),
                    position_cm: [325, -175],
                    sigma_mm: [250, 265],
                    correlation: -9,
                    width_cm: 55,
                    height_cm: 165,
                    confidence: 217,
                    ml_offset_cm: [7, -3],
                    histogram: None,
                },
                GroundPerson {
                    local: 9,
                    target: None,
                    position_cm: [1210, 40],
                    sigma_mm: [400, 310],
                    correlation: 33,
                    width_cm: 48,
                    height_cm: 181,
                    confidence: 140,
                    ml_offset_cm: [-12, 0],
                    histogram: Some(histogram()),
                },
            ],
        })),
        env(Message::TagsHeard(TagsHeard {
            tags: vec![
                TagHeard {
                    tag: TagId(0x0200_0000_0003),
                    dbm: -58.5,
                    near: [3.25, 1.5],
                    track: Some(TargetId(5)),
                },
                TagHeard {
                    tag: TagId(0x0200_0000_0004),
                    dbm: -77.25,
                    near: [11.0, 7.75],
                    track: None,
                },
            ],
        })),
        env(Message::TagHomes(TagHomes {
            homes: vec![
                TagHome {
                    tag: TagId(0x0200_0000_0003),
                    head: NodeId(3),
                    shared: true,
                },
                TagHome {
                    tag: TagId(0x0200_0000_0004),
                    head: NodeId(4),
                    shared: false,
                },
            ],
        })),
    ]
}

/// A quantised histogram: a few full hue-saturation bins, the value bins' fullest at 255.
fn histogram() -> Vec<u8> {
    let mut h = vec![0u8; crate::observation::HISTOGRAM_BINS];
    h[23] = 255;
    h[24] = 91;
    h[33] = 17;
    h[100 + 6] = 255;
    h[100 + 7] = 120;
    h
}

/// A view update with one track, one camera with its status, one head and one handover.
fn view_update() -> ViewUpdate {
    use crate::view::{HandoverCause, ViewCounters, ViewHandover, ViewNode, ViewTrack};
    ViewUpdate {
        round: 12,
        part: 0,
        parts: 1,
        time: ClusterTime(1_500_400_000),
        tracks: vec![ViewTrack {
            global: TargetId(1005),
            owner: NodeId(3),
            local: Some(TargetId(5)),
            time: ClusterTime(1_500_390_000),
            mean: vec6(5),
            cov_pos: [0.28125, 0.03125, -0.015625, 0.34375, 0.0078125, 0.40625],
            contributors: vec![Contributor {
                node: NodeId(10),
                kinds: Kinds::of(ObservationKind::Pinhole),
            }],
        }],
        tracks_total: 1,
        nodes: vec![
            ViewNode {
                node: NodeId(10),
                role: Role::Camera,
                up: true,
                silent_ms: 120,
                head: Some(NodeId(3)),
                status: Some(NodeStatus {
                    mode: Mode::Active,
                    time_in_mode_ns: [5, 6, 7],
                    frames: 40,
                    detections: 38,
                    dropped: 1,
                    rejected: 0,
                    sync_offset_ns: 900,
                    sync_error_ns: 80,
                    bytes_sent: 0,
                }),
                steps: 0,
                late: 0,
                rejected: 2,
                lost: 3,
            },
            ViewNode {
                node: NodeId(3),
                role: Role::Head,
                up: false,
                silent_ms: 4000,
                head: None,
                status: None,
                steps: 301,
                late: 4,
                rejected: 0,
                lost: 0,
            },
        ],
        nodes_total: 2,
        handovers: vec![ViewHandover {
            seq: 9,
            time: ClusterTime(1_500_350_000),
            global: TargetId(1005),
            from: Some(NodeId(2)),
            to: NodeId(3),
            cause: HandoverCause::Region,
        }],
        counters: ViewCounters {
            received: 5000,
            rejected: 6,
            handovers: 9,
            undelivered: 11,
        },
    }
}

/// A head's word on tags `(tag, dBm)`, each near (1, 1) and bound to its track 1 (tests of the
/// tag homes, at the wire and at the server).
pub fn tags_heard(tags: &[(u64, f32)]) -> Message {
    Message::TagsHeard(TagsHeard {
        tags: claimed_tags(tags),
    })
}

/// The tags of [`tags_heard`]'s word.
pub fn claimed_tags(tags: &[(u64, f32)]) -> Vec<TagHeard> {
    tags.iter()
        .map(|&(t, dbm)| TagHeard {
            tag: TagId(t),
            dbm,
            near: [1.0, 1.0],
            track: Some(TargetId(1)),
        })
        .collect()
}
