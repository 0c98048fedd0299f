//! The head process on the in-process transport: it tracks, and keeps stepping and counting
//! when its cameras and then the server vanish.

use crate::sim::{ONE_TARGET, ring_scenario};
use nalgebra::{Matrix6, Vector3};
use node_head::HeadConfig;
use node_head::process::run;
use proto::models::{State, camera_contribution, mat6_to_wire, vec6_to_wire};
use proto::msg::{Answers, Contribution, Handover, Information, Message, Mode, TrackReport};
use proto::node::Outgoing;
use proto::observation::{Kinds, ObservationKind};
use proto::{NodeId, Role, TargetId};
use runtime::HostClock;
use runtime::transport::{Event, InProcessHub, Inbox, TransportConfig, open};
use std::time::Duration;
use tokio_util::sync::CancellationToken;

const WAIT: Duration = Duration::from_secs(20);

fn inproc(hub: &InProcessHub, id: u32, role: Role) -> TransportConfig {
    TransportConfig::InProcess {
        hub: hub.clone(),
        me: NodeId(id),
        role,
        queue_len: 4096,
    }
}

/// Head 2 on its own thread and runtime, as in the `ocelli head` process (`transport::open`'s
/// future is not `Send`).
fn spawn_head(
    cfg: HeadConfig,
    hub: &InProcessHub,
    clock: &HostClock,
    token: &CancellationToken,
) -> std::thread::JoinHandle<Result<node_head::process::Summary, node_head::process::ProcessError>> {
    let (hub, clock, token) = (hub.clone(), clock.clone(), token.clone());
    std::thread::spawn(move || {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap();
        rt.block_on(run(cfg, inproc(&hub, 2, Role::Head), clock, token))
    })
}

async fn next_report(inbox: &mut Inbox) -> TrackReport {
    loop {
        let ev = tokio::time::timeout(WAIT, inbox.recv())
            .await
            .expect("no report in time");
        if let Some(Event::Message(m)) = ev
            && let Message::TrackReport(r) = m.env.body
        {
            return r;
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn head_process_tracks_and_survives_cameras_and_server_vanishing() {
    let mut scenario = ring_scenario(4, "distributed-eif", "all-on", 0.0, ONE_TARGET);
    scenario.method.step_ms = 50;
    scenario.method.deadline_ms = 25;
    scenario.method.track_timeout_ms = 60_000;
    let cfg = HeadConfig::from_scenario(&scenario, 2).unwrap();
    let cams: Vec<_> = cfg.nodes.iter().map(|n| (n.id, n.camera)).collect();
    let hub = InProcessHub::new();
    let token = CancellationToken::new();
    let clock = HostClock::follower();
    let head = spawn_head(cfg, &hub, &clock, &token);
    let (server, mut server_in, _, server_handle) = open(inproc(&hub, 1, Role::Server)).await.unwrap();
    // Wait for the head to be on the hub.
    loop {
        match tokio::time::timeout(WAIT, server_in.recv())
            .await
            .expect("head never came up")
        {
            Some(Event::PeerUp(NodeId(2))) => break,
            Some(_) => {}
            None => panic!("server inbox closed"),
        }
    }
    // Cameras answer every prior with an exact, static target.
    let truth = Vector3::new(4.0, 4.0, 0.2);
    let mut cam_handles = Vec::new();
    for (id, model) in cams {
        let (ep, mut inbox, _, handle) = open(inproc(&hub, id.0, Role::Camera)).await.unwrap();
        let clock = clock.clone();
        tokio::spawn(async move {
            while let Some(ev) = inbox.recv().await {
                let Event::Message(m) = ev else { continue };
                let Message::Priors(priors) = m.env.body else {
                    continue;
                };
                let contributions = priors
                    .tracks
                    .iter()
                    .map(|p| {
                        let mean = proto::models::vec6_from_wire(&p.mean);
                        let point = model.normalized(&truth).0;
                        let cov = model.normalized_covariance(&point, 2.0);
                        let (o, x) = camera_contribution(&model, &point, &cov, &mean).unwrap();
                        Contribution {
                            target: p.target,
                            info: Some(Information {
                                matrix: mat6_to_wire(&o),
                                vector: vec6_to_wire(&x),
                            }),
                            folded: Kinds::of(ObservationKind::Pinhole),
                            ground: None,
                        }
                    })
                    .collect();
                let c = Answers {
                    step: priors.tracks[0].step,
                    part: priors.part,
                    captured: clock.now(),
                    mode: Mode::Active,
                    rssi: Vec::new(),
                    contributions,
                };
                if ep
                    .send(Outgoing::new(m.from, Message::Answers(c)), clock.now())
                    .await
                    .is_err()
                {
                    break;
                }
            }
        });
        cam_handles.push(handle);
    }
    let start = State::new(4.3, 3.8, 0.2, 0.0, 0.0, 0.0);
    let handover = Handover {
        global: TargetId(5),
        to_head: NodeId(2),
        from_head: None,
        time: clock.now(),
        mean: vec6_to_wire(&start),
        cov: mat6_to_wire(&(Matrix6::identity() * 0.25)),
    };
    server
        .send(Outgoing::new(NodeId(2), Message::Handover(handover)), clock.now())
        .await
        .unwrap();
    // Tracking: reports converge on the target.
    let mut last = next_report(&mut server_in).await;
    for _ in 0..15 {
        last = next_report(&mut server_in).await;
    }
    assert_eq!(last.global, Some(TargetId(5)));
    let err = (Vector3::new(last.mean[0], last.mean[1], last.mean[2]) - truth).norm();
    assert!(err < 0.05, "error {err}");
    assert!(!last.contributors.is_empty());
    assert!(
        last.captured.is_some(),
        "a report that fused frames carries their capture time"
    );
    // The cameras vanish: the head keeps reporting, prediction only, uncertainty growing.
    for h in cam_handles {
        h.shutdown().await;
    }
    let mut r = next_report(&mut server_in).await;
    while !r.contributors.is_empty() {
        r = next_report(&mut server_in).await;
    }
    let mut trace = r.cov[0][0] + r.cov[1][1];
    for _ in 0..5 {
        let r = next_report(&mut server_in).await;
        assert!(r.contributors.is_empty());
        assert_eq!(r.captured, None, "a prediction-only report fused no frame");
        let t = r.cov[0][0] + r.cov[1][1];
        assert!(t > trace, "uncertainty did not grow");
        trace = t;
    }
    // The server vanishes too; a camera coming back still gets priors: the head steps on.
    server_handle.shutdown().await;
    drop(server);
    let (_ep, mut cam_in, _, cam_handle) = open(inproc(&hub, 10, Role::Camera)).await.unwrap();
    let priors = tokio::time::timeout(WAIT, async {
        let mut n = 0;
        while let Some(ev) = cam_in.recv().await {
            if let Event::Message(m) = ev
                && matches!(m.env.body, Message::Priors(_))
            {
                n += 1;
                if n == 3 {
                    break;
                }
            }
        }
        n
    })
    .await
    .expect("no priors after the server left");
    assert_eq!(priors, 3);
    token.cancel();
    let joined = tokio::task::spawn_blocking(move || head.join());
    let summary = tokio::time::timeout(WAIT, joined)
        .await
        .expect("head did not stop")
        .unwrap()
        .unwrap()
        .unwrap();
    cam_handle.shutdown().await;
    assert!(summary.counters.steps > 20);
    assert!(summary.counters.applied > 0);
    assert!(summary.run.peers_down >= 4, "{summary:?}");
    assert!(
        summary.run.send_failures > 0,
        "reports to the vanished server should fail: {summary:?}"
    );
}

/// The server's beacons say its clock is 5 ms ahead of this host's: the head's cluster time
/// follows them, and its `NodeStatus` to the server carries the offset and a sync error.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn head_process_syncs_to_the_beacons_and_reports_its_sync_error() {
    #[allow(clippy::disallowed_methods)] // the test plays the server's runtime
    fn host() -> proto::ClusterTime {
        proto::ClusterTime::wall_clock()
    }
    // Far larger than any delivery delay a loaded machine adds, so the test judges the estimator,
    // not the scheduler.
    const AHEAD_NS: i64 = 200_000_000;
    const TOLERANCE_NS: i64 = 40_000_000;
    let scenario = ring_scenario(4, "distributed-eif", "all-on", 0.0, ONE_TARGET);
    let cfg = HeadConfig::from_scenario(&scenario, 2).unwrap();
    let hub = InProcessHub::new();
    let token = CancellationToken::new();
    let clock = HostClock::follower();
    let head = spawn_head(cfg, &hub, &clock, &token);
    let (server, mut server_in, _, server_handle) = open(inproc(&hub, 1, Role::Server)).await.unwrap();
    // Statuses come every second. Three beacons 100 ms apart, then none until the first status:
    // its error is over exactly those three, the first of which found the clock 200 ms off.
    // Then beacons every 100 ms until a status that follows at least ten more, enough to push
    // the first out of the 8-beacon window however the scheduler paces the loop.
    let beacon = async |server: &runtime::transport::Endpoint| {
        let beacon = proto::msg::SyncBeacon {
            leader: NodeId(1),
            round: 0,
            leader_time: proto::ClusterTime(host().0 + AHEAD_NS),
        };
        let _ = server
            .send(Outgoing::new(NodeId(2), Message::SyncBeacon(beacon)), host())
            .await;
    };
    for _ in 0..3 {
        beacon(&server).await;
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    let next_status =
        async |inbox: &mut Inbox, wait: Duration| match tokio::time::timeout(wait, inbox.recv()).await {
            Ok(Some(Event::Message(m))) => match m.env.body {
                Message::NodeStatus(s) if s.sync_error_ns >= 0 => Some(s),
                _ => None,
            },
            _ => None,
        };
    let first = loop {
        if let Some(s) = next_status(&mut server_in, WAIT).await {
            break s;
        }
    };
    let mut sent = 0;
    let later = loop {
        beacon(&server).await;
        sent += 1;
        if let Some(s) = next_status(&mut server_in, Duration::from_millis(100)).await
            && sent >= 10
        {
            break s;
        }
    };
    // In-process delivery takes micro- to (under load) tens of milliseconds, and the drift
    // fitted over a few beacons moves the estimate either way: 200 ms within 40 ms. The first
    // beacons found the host clock 200 ms off; a second later they arrive where the head
    // expects them.
    // The visible error is the RMS over the three beacons' innovations, of which the first
    // (200 ms) dominates: between 200/√3 and 200 ms.
    assert!(
        first.sync_error_ns > AHEAD_NS / 3 && first.sync_error_ns < AHEAD_NS + TOLERANCE_NS,
        "first {first:?}"
    );
    let off = later.sync_offset_ns;
    assert!((off - AHEAD_NS).abs() < TOLERANCE_NS, "offset {off} ns");
    assert!(
        later.sync_error_ns < first.sync_error_ns / 3,
        "sync error {} ns after {} ns",
        later.sync_error_ns,
        first.sync_error_ns
    );
    let ahead = clock.now().0 - host().0;
    assert!(
        (ahead - AHEAD_NS).abs() < TOLERANCE_NS,
        "cluster time {ahead} ns ahead"
    );
    token.cancel();
    head.join().unwrap().unwrap();
    server_handle.shutdown().await;
}
