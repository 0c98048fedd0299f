use super::*;

#[test]
fn domains_are_checked() {
    assert!(check_domain("ocelli-test_1").is_ok());
    for bad in ["", "a/b", "a b", &"x".repeat(65)] {
        assert!(check_domain(bad).is_err(), "{bad:?} accepted");
    }
}

#[test]
fn limits_grow_with_the_scenario() {
    let small = IpcLimits::for_nodes(3, 8);
    let big = IpcLimits::for_nodes(30, 512);
    assert!(big.max_publishers >= 30 && big.max_nodes > big.max_publishers);
    assert!(small.buffer >= 16 && big.buffer == 512);
    assert!(
        small.max_publishers > 2,
        "iceoryx2's default of 2 publishers is too small"
    );
}

fn shm_files(domain: &str) -> Vec<String> {
    let prefix = file_prefix(domain);
    std::fs::read_dir("/dev/shm")
        .map(|d| {
            d.filter_map(|e| e.ok())
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .filter(|n| n.starts_with(&prefix))
                .collect()
        })
        .unwrap_or_default()
}

use super::super::{Event, Inbox as EventInbox, TransportConfig, open};
use proto::msg::{Message, SyncBeacon};
use proto::node::Outgoing;
use proto::time::ClusterTime;

fn ipc(domain: &str, me: u32) -> TransportConfig {
    TransportConfig::Ipc(IpcConfig::new(domain.to_string(), NodeId(me), Role::Tool, 2))
}

/// The test's message number `round` from node 2.
fn beacon(round: u64) -> Message {
    Message::SyncBeacon(SyncBeacon {
        leader: NodeId(2),
        round,
        leader_time: ClusterTime(0),
    })
}

/// Receive beacons 0 to `n − 1` from node 2, in order, on `inbox`.
async fn receive_beacons(inbox: &mut EventInbox, n: u64) {
    let mut next = 0;
    while next < n {
        let ev = tokio::time::timeout(Duration::from_secs(10), inbox.recv())
            .await
            .unwrap()
            .unwrap();
        match ev {
            Event::Message(m) => {
                assert_eq!((m.from, m.env.body), (NodeId(2), beacon(next)), "out of order");
                next += 1;
            }
            Event::PeerUp(n) => assert_eq!(n, NodeId(2)),
            Event::PeerDown(n) => panic!("PeerDown({n})"),
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn delivers_in_order_rejects_garbage_and_cleans_up() {
    let domain = format!("unit-{}", std::process::id());
    let (_a, mut ia, sa, ha) = open(ipc(&domain, 1)).await.unwrap();
    let (b, _ib, sb, hb) = open(ipc(&domain, 2)).await.unwrap();
    assert!(
        !shm_files(&domain).is_empty(),
        "iceoryx2 files do not carry the domain prefix"
    );
    b.send_raw_frame(NodeId(1), vec![proto::PROTOCOL_VERSION as u8, 0xff, 0xff])
        .await
        .unwrap();
    b.send_raw_frame(NodeId(1), vec![0; MAX_FRAME_BYTES + 1])
        .await
        .unwrap();
    for k in 0..100 {
        b.send(Outgoing::new(NodeId(1), beacon(k)), ClusterTime(k as i64))
            .await
            .unwrap();
    }
    receive_beacons(&mut ia, 100).await;
    let s = sa.snapshot();
    assert_eq!(
        (s.received, s.rejected_malformed, s.rejected_oversized),
        (100, 1, 1),
        "{s:?}"
    );
    assert_eq!(sb.snapshot().sent, 102);
    hb.shutdown().await;
    ha.shutdown().await;
    assert_eq!(shm_files(&domain), Vec::<String>::new(), "files left in /dev/shm");
}

/// Frames sent before the recipient opened its inbox reach it, in order, once it does
/// (a launch starts every process at once); after it read its inbox and stopped, frames
/// to it are dropped and counted at once.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn frames_wait_for_a_recipient_that_has_not_started() {
    use super::super::Delivery;
    let domain = format!("unit-early-{}", std::process::id());
    let (b, _ib, sb, hb) = open(ipc(&domain, 2)).await.unwrap();
    for k in 0..3 {
        let d = b
            .send(Outgoing::new(NodeId(1), beacon(k)), ClusterTime(k as i64))
            .await;
        assert_eq!(
            d.unwrap(),
            Delivery::Queued,
            "frame {k} to a node not started yet"
        );
    }
    let (_a, mut ia, _sa, ha) = open(ipc(&domain, 1)).await.unwrap();
    b.send(Outgoing::new(NodeId(1), beacon(3)), ClusterTime(3))
        .await
        .unwrap();
    receive_beacons(&mut ia, 4).await;
    assert_eq!(sb.snapshot().dropped_undelivered, 0);
    ha.shutdown().await;
    let d = b.send(Outgoing::new(NodeId(1), beacon(4)), ClusterTime(4)).await;
    assert_eq!(d.unwrap(), Delivery::Dropped, "a stopped recipient's frames wait");
    assert_eq!(sb.snapshot().dropped_undelivered, 1);
    hb.shutdown().await;
}
