//! The camera process over the in-process transport: it runs with its head away (counting
//! what it cannot deliver), answers a head that appears, and stops cleanly when told.

use node_camera::process::{ProcessConfig, run};
use proto::msg::{Message, Prior, Priors};
use proto::node::Outgoing;
use proto::scenario::Scenario;
use proto::sensor::{FrameSource, ReferencePoint};
use proto::{ClusterTime, NodeId, Role, TargetId, models};
use runtime::HostClock;
use runtime::transport::{Event, InProcessHub, TransportConfig, open};
use std::time::Duration;
use tokio_util::sync::CancellationToken;
use world::sources::{SyntheticFrames, SyntheticRadio};

/// Camera 10 of `scenario` on the hub, fed the simulated world (seed 1) from now on.
fn camera_10(
    scenario: &Scenario,
    hub: &InProcessHub,
    clock: &HostClock,
    record_measurements: bool,
) -> ProcessConfig {
    let epoch = clock.now();
    let frames = SyntheticFrames::new(scenario, 10, 1, epoch).unwrap();
    let radio = SyntheticRadio::new(scenario, 10, 1, epoch).unwrap();
    let transport = TransportConfig::InProcess {
        hub: hub.clone(),
        me: NodeId(10),
        role: Role::Camera,
        queue_len: 64,
    };
    ProcessConfig {
        scenario: scenario.clone(),
        id: 10,
        process: runtime::ProcessConfig::new(transport, Some(NodeId(1)), Duration::from_millis(100)),
        frames: Box::new(move || Ok(Box::new(frames) as Box<dyn FrameSource>)),
        radio: Some(Box::new(radio)),
        reference: ReferencePoint::Centre,
        record_measurements,
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn runs_without_its_head_answers_when_it_comes_and_stops_cleanly() {
    let scenario = Scenario::default_scenario();
    let hub = InProcessHub::new();
    let clock = HostClock::follower();
    let cfg = camera_10(&scenario, &hub, &clock, false);
    let stop = CancellationToken::new();
    // The camera's future is driven on this task: `runtime::transport::open`'s future holds a
    // `&ShutdownHandle` (not `Sync`) across an await, so `run` cannot be `tokio::spawn`ed.
    // The driver plays the absent, then present,
    // head alongside it.
    let camera = run(cfg, clock.clone(), stop.clone());
    let driver = async {
        // Head (node 2) and server (node 1) away for a while: the camera keeps going.
        tokio::time::sleep(Duration::from_millis(1500)).await;
        let (head, mut inbox, _stats, handle) = open(TransportConfig::InProcess {
            hub: hub.clone(),
            me: NodeId(2),
            role: Role::Head,
            queue_len: 256,
        })
        .await
        .unwrap();
        let prior = Prior {
            target: TargetId(1),
            step: 77,
            mean: models::vec6_to_wire(&world::targets(&scenario).unwrap()[0].truth_at(0.0)),
            cov: models::mat6_to_wire(&(nalgebra::Matrix6::identity() * 0.04)),
            deadline: ClusterTime::ZERO,
            radio: false,
        };
        let mut answered = false;
        for _ in 0..30 {
            head.send(
                Outgoing::new(
                    NodeId(10),
                    Message::Priors(Priors {
                        part: 0,
                        parts: 1,
                        tracks: vec![prior.clone()],
                    }),
                ),
                clock.now(),
            )
            .await
            .unwrap();
            let wait = tokio::time::sleep(Duration::from_millis(300));
            tokio::pin!(wait);
            loop {
                tokio::select! {
                    _ = &mut wait => break,
                    ev = inbox.recv() => match ev {
                        Some(Event::Message(m)) => {
                            if let Message::Answers(a) = m.env.body {
                                assert_eq!(m.from, NodeId(10));
                                assert_eq!((a.step, a.part), (77, 0));
                                answered = true;
                                break;
                            }
                        }
                        Some(_) => {}
                        None => break,
                    },
                }
            }
            if answered {
                break;
            }
        }
        stop.cancel();
        (answered, handle)
    };
    let (summary, (answered, handle)) =
        tokio::time::timeout(Duration::from_secs(30), async { tokio::join!(camera, driver) })
            .await
            .expect("the camera answers and stops when told");
    assert!(answered, "no contribution from the camera");
    let summary = summary.unwrap();
    assert!(summary.counters.frames > 0, "{summary:?}");
    assert!(
        summary.counters.dropped > 0,
        "messages to the absent head and server were counted: {summary:?}"
    );
    assert!(summary.counters.contributions >= 1);
    handle.shutdown().await;
}

/// A logging run: switched Inactive by its head, the camera still captures and measures every
/// frame and sends each to the server as a `MeasuredFrame`, while its core stays asleep.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_logging_camera_sends_every_frame_to_the_server_whatever_its_mode() {
    let scenario = Scenario::default_scenario();
    let hub = InProcessHub::new();
    let clock = HostClock::follower();
    let (server, mut inbox, _stats, server_handle) = open(TransportConfig::InProcess {
        hub: hub.clone(),
        me: NodeId(1),
        role: Role::Server,
        queue_len: 256,
    })
    .await
    .unwrap();
    let cfg = camera_10(&scenario, &hub, &clock, true);
    let stop = CancellationToken::new();
    let camera = run(cfg, clock.clone(), stop.clone());
    let driver = async {
        // The server's stand-in sends the command a head would (the camera takes commands
        // from anyone addressed to it), then counts the frames that keep coming.
        let sleep = proto::msg::Command {
            node: NodeId(10),
            mode: proto::Mode::Inactive,
        };
        let mut frames = 0u32;
        let deadline = tokio::time::Instant::now() + Duration::from_secs(20);
        let mut commanded = false;
        while frames < 5 && tokio::time::Instant::now() < deadline {
            if !commanded {
                commanded = server
                    .send(
                        Outgoing::new(NodeId(10), Message::Command(sleep.clone())),
                        clock.now(),
                    )
                    .await
                    .is_ok();
            }
            tokio::select! {
                () = tokio::time::sleep(Duration::from_millis(200)) => {}
                ev = inbox.recv() => if let Some(Event::Message(m)) = ev
                    && let Message::MeasuredFrame(f) = m.env.body
                {
                    assert_eq!(m.from, NodeId(10));
                    assert!(f.detections.len() <= proto::MAX_MEASURED_DETECTIONS);
                    frames += commanded as u32;
                },
            }
        }
        stop.cancel();
        frames
    };
    let (summary, frames) =
        tokio::time::timeout(Duration::from_secs(30), async { tokio::join!(camera, driver) })
            .await
            .expect("the camera logs frames and stops when told");
    assert!(
        frames >= 5,
        "only {frames} measured frames after the camera went inactive"
    );
    let summary = summary.unwrap();
    assert!(summary.logged.frames >= 5, "{summary:?}");
    assert!(
        summary.counters.frames_skipped > 0,
        "the sleeping core still used frames: {summary:?}"
    );
    server_handle.shutdown().await;
}
