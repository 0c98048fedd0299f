use super::*;
use proto::acoustic::IldSettings;
use proto::msg::Command;

fn cfg() -> AcousticConfig {
    AcousticConfig {
        id: NodeId(40),
        head: Some(NodeId(2)),
        server: Some(NodeId(1)),
        ild: IldSettings {
            sample_rate: 8_000,
            block_len: 256,
            f_min_hz: 50.0,
            f_max_hz: 1_000.0,
            frequencies: 16,
            epsilon: 1e-4,
        },
        frame_ms: 100.0,
        status_period_ms: 1000,
        max_age_ms: 500,
    }
}

fn noise(n: usize, gain: f32, seed: u32) -> Vec<f32> {
    // A deterministic broadband signal.
    let mut x = seed.wrapping_mul(2_654_435_761) | 1;
    (0..n)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            gain * ((x as f32 / u32::MAX as f32) - 0.5)
        })
        .collect()
}

fn frame(left: Vec<f32>, right: Vec<f32>, at: ClusterTime) -> Input<AcousticInput> {
    Input::Sensor(AcousticInput::Frame(AudioFrame {
        sample_rate: 8_000,
        left,
        right,
        captured: at,
    }))
}

#[test]
fn a_good_frame_goes_to_the_head_as_one_ild_observation() {
    let now = ClusterTime::from_millis(1000);
    let mut node = AcousticNode::new(cfg(), now).unwrap();
    let left = noise(800, 0.2, 1);
    let right: Vec<f32> = left.iter().map(|v| 0.5 * v).collect();
    let out = node.handle(now, frame(left, right, now));
    assert_eq!(out.len(), 1);
    assert_eq!(out[0].to, NodeId(2));
    let Message::Measurement(m) = &out[0].body else {
        panic!("{:?}", out[0].body)
    };
    let [Observation::Acoustic(o)] = m.observations.as_slice() else {
        panic!("{:?}", m.observations)
    };
    assert_eq!(o.ild_db.len(), 16);
    assert_eq!(o.captured, now);
    // Left 6 dB louder everywhere: every weighted ILD is positive.
    assert!(o.ild_db.iter().all(|v| *v > 0.0), "{:?}", o.ild_db);
    assert_eq!(node.counters().frames, 1);
}

#[test]
fn bad_frames_are_counted_and_change_nothing() {
    let now = ClusterTime::from_millis(1000);
    let mut node = AcousticNode::new(cfg(), now).unwrap();
    let good = noise(800, 0.2, 2);
    // Silent, clipped, another rate, unequal channels, short, stale.
    assert!(
        node.handle(now, frame(vec![0.0; 800], good.clone(), now))
            .is_empty()
    );
    assert!(
        node.handle(now, frame(vec![1.0; 800], good.clone(), now))
            .is_empty()
    );
    let mut other = AudioFrame {
        sample_rate: 44_100,
        left: good.clone(),
        right: good.clone(),
        captured: now,
    };
    assert!(
        node.handle(now, Input::Sensor(AcousticInput::Frame(other.clone())))
            .is_empty()
    );
    other.sample_rate = 8_000;
    other.right.pop();
    assert!(
        node.handle(now, Input::Sensor(AcousticInput::Frame(other)))
            .is_empty()
    );
    assert!(
        node.handle(now, frame(good[..100].to_vec(), good[..100].to_vec(), now))
            .is_empty()
    );
    let stale = ClusterTime::from_millis(0);
    assert!(
        node.handle(now, frame(good.clone(), good.clone(), stale))
            .is_empty()
    );
    assert!(node.handle(now, Input::Sensor(AcousticInput::Stalled)).is_empty());
    let c = node.counters();
    assert_eq!(
        (c.silent, c.clipped, c.rejected, c.stalls, c.frames),
        (1, 1, 4, 1, 0)
    );
    // Still working.
    assert_eq!(node.handle(now, frame(good.clone(), good, now)).len(), 1);
}

#[test]
fn inactive_nodes_skip_audio_and_every_node_reports_status() {
    let now = ClusterTime::from_millis(1000);
    let mut node = AcousticNode::new(cfg(), now).unwrap();
    let out = node.handle(now, Input::Tick);
    assert_eq!(out.len(), 2, "status to the head and the server");
    assert!(matches!(out[0].body, Message::NodeStatus(_)));
    let cmd = Envelope {
        source: NodeId(2),
        seq: 1,
        time: now,
        body: Message::Command(Command {
            node: NodeId(40),
            mode: Mode::Inactive,
        }),
    };
    node.handle(now, Input::Message(cmd));
    assert!(!node.listening());
    let good = noise(800, 0.2, 3);
    assert!(node.handle(now, frame(good.clone(), good, now)).is_empty());
    assert_eq!(node.counters().skipped, 1);
}
