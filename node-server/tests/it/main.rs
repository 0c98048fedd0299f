//! Integration tests of the server process: the real event loop over the in-process transport,
//! with a recording on disk, stopped and restarted.

use node_server::process::{ProcessConfig, run};
use node_server::recording::read_all;
use node_server::{Decision, Record};
use proto::msg::{Handover, Message, TrackReport};
use proto::node::Outgoing;
use proto::scenario::Scenario;
use proto::{ClusterTime, NodeId, Role, TargetId};
use runtime::transport::{Event, InProcessHub, Inbox, TransportConfig, open};
use std::path::PathBuf;
use std::time::Duration;
use tokio_util::sync::CancellationToken;

const SCENARIO: &str = r#"
name = "server-it"
[world]
min = [0.0, 0.0, 0.0]
max = [12.0, 8.0, 3.0]
[network]
transport = "tcp"
domain = "it"
heartbeat-ms = 100
liveness-timeout-ms = 5000
sync-beacon-ms = 200
queue-len = 64
[[nodes]]
id = 1
role = "server"
[[nodes]]
id = 2
role = "head"
region = [0.0, 0.0, 6.0, 8.0]
[[nodes]]
id = 3
role = "head"
region = [6.0, 0.0, 12.0, 8.0]
"#;

fn config(hub: &InProcessHub, record: PathBuf) -> ProcessConfig {
    ProcessConfig {
        scenario: Scenario::from_toml(SCENARIO, "<it>").unwrap(),
        id: NodeId(1),
        transport: TransportConfig::InProcess {
            hub: hub.clone(),
            me: NodeId(1),
            role: Role::Server,
            queue_len: 256,
        },
        record,
        tick: Duration::from_millis(10),
        sync_every: Duration::from_millis(50),
        origin: None,
    }
}

fn report(local: u32, x: f64, step: u64) -> Message {
    let mut cov = [[0.0; 6]; 6];
    for (i, row) in cov.iter_mut().enumerate() {
        row[i] = 0.04;
    }
    let t = ClusterTime::from_millis(step as i64 * 200);
    Message::TrackReport(TrackReport {
        target: TargetId(local),
        global: None,
        step,
        time: t,
        mean: [x, 4.0, 0.9, 0.0, 0.0, 0.0],
        cov,
        contributors: vec![],
        power_mw: 100.0,
        late: 0,
        appearance: Vec::new(),
        grid: None,
        captured: None,
    })
}

/// The next handover in `inbox` (skipping beacons and other traffic), with a timeout.
async fn next_handover(inbox: &mut Inbox) -> Handover {
    let wait = async {
        loop {
            match inbox.recv().await {
                Some(Event::Message(m)) => {
                    if let Message::Handover(h) = m.env.body {
                        return h;
                    }
                }
                Some(_) => {}
                None => panic!("transport closed"),
            }
        }
    };
    tokio::time::timeout(Duration::from_secs(10), wait)
        .await
        .expect("a handover within 10 s")
}

async fn wait_for_peer(inbox: &mut Inbox, peer: NodeId) {
    let wait = async {
        loop {
            match inbox.recv().await {
                Some(Event::PeerUp(n)) if n == peer => return,
                Some(_) => {}
                None => panic!("transport closed"),
            }
        }
    };
    tokio::time::timeout(Duration::from_secs(10), wait)
        .await
        .expect("peer up within 10 s");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_server_records_stops_and_resumes_where_it_was() {
    // `runtime::transport::open` is not `Send` (the TCP path holds a `&ShutdownHandle` across an
    // await), so the server runs on a local task set, as `ocelli server` runs it in `block_on`.
    tokio::task::LocalSet::new()
        .run_until(records_stops_and_resumes())
        .await;
}

async fn records_stops_and_resumes() {
    let dir = std::env::temp_dir().join(format!("ocelli-server-it-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("server.ocelli");
    let hub = InProcessHub::new();
    let open_node = |id: u32| {
        open(TransportConfig::InProcess {
            hub: hub.clone(),
            me: NodeId(id),
            role: Role::Head,
            queue_len: 256,
        })
    };
    let (h2, mut in2, _, s2) = open_node(2).await.unwrap();
    let (_h3, mut in3, _, s3) = open_node(3).await.unwrap();

    // First run: two tracks of head 2 get global ids (each named back to head 2).
    let stop = CancellationToken::new();
    let server = tokio::task::spawn_local(run(config(&hub, path.clone()), stop.clone()));
    wait_for_peer(&mut in2, NodeId(1)).await;
    h2.send(Outgoing::new(NodeId(1), report(5, 1.0, 1)), ClusterTime::ZERO)
        .await
        .unwrap();
    let g5 = next_handover(&mut in2).await.global;
    h2.send(Outgoing::new(NodeId(1), report(6, 4.0, 1)), ClusterTime::ZERO)
        .await
        .unwrap();
    let g6 = next_handover(&mut in2).await.global;
    assert_ne!(g5, g6);
    stop.cancel();
    let first = server.await.unwrap().unwrap();
    assert!(first.restored.is_none());
    assert!(first.run.received >= 2);

    let back = read_all(&path).unwrap();
    assert!(back.skipped.is_empty());
    assert!(matches!(back.records[0].record, Record::Scenario(_)));
    assert!(back.records.iter().any(|r| matches!(
        &r.record,
        Record::Decision(Decision::NewGlobal { global, .. }) if *global == g6
    )));

    // Second run on the same recording: the state comes back. Head 2's track 6 walks into head
    // 3's region and is handed over under the id it had before the restart.
    while in2.try_recv().is_some() {}
    while in3.try_recv().is_some() {}
    let stop = CancellationToken::new();
    let server = tokio::task::spawn_local(run(config(&hub, path.clone()), stop.clone()));
    wait_for_peer(&mut in2, NodeId(1)).await;
    wait_for_peer(&mut in3, NodeId(1)).await;
    // The server may see head 2's report before head 3's link: report again until it hands over.
    let mut handed = None;
    for step in 2..100 {
        h2.send(Outgoing::new(NodeId(1), report(6, 7.0, step)), ClusterTime::ZERO)
            .await
            .unwrap();
        if let Ok(h) = tokio::time::timeout(Duration::from_millis(100), next_handover(&mut in3)).await {
            handed = Some(h);
            break;
        }
    }
    let h = handed.expect("a handover to head 3");
    assert_eq!(
        (h.global, h.to_head, h.from_head),
        (g6, NodeId(3), Some(NodeId(2)))
    );
    assert_eq!(h.mean[0], 7.0);
    stop.cancel();
    let second = server.await.unwrap().unwrap();
    let restored = second.restored.expect("resumed from the recording");
    assert_eq!(restored.decisions_mismatched, 0);
    assert!(restored.decisions_matched >= 2);
    let back = read_all(&path).unwrap();
    assert!(
        back.records
            .iter()
            .any(|r| matches!(r.record, Record::Decision(Decision::Resumed { .. })))
    );
    s2.shutdown().await;
    s3.shutdown().await;
    let _ = std::fs::remove_dir_all(&dir);
}
