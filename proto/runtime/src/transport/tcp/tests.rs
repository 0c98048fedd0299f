//! Tests of the TCP transport on loopback: delivery both ways, reconnect, liveness, queue
//! drop accounting, garbage and handshake rejection (plain TCP); identity, duplicates,
//! limits and floods in `tests_tls`.

use super::super::{Delivery, Event, Inbox, TcpConfig, TransportConfig, open};
use super::*;
use crate::transport::codec::Frame;
use crate::transport::{Backoff, SendError};
use futures_util::{FutureExt, SinkExt, StreamExt};
use proto::PROTOCOL_VERSION;
use proto::msg::{Command, Hello, Mode, SyncBeacon};
use proto::node::Outgoing;
use proto::time::ClusterTime;
use proto::wire::decode;
use tokio::net::TcpStream;
use tokio::time::timeout;

const WAIT: Duration = Duration::from_secs(10);

fn beacon(round: u64) -> Message {
    Message::SyncBeacon(SyncBeacon {
        leader: NodeId(1),
        round,
        leader_time: ClusterTime(0),
    })
}

fn listener_cfg(me: u32) -> TcpConfig {
    let mut c = TcpConfig::new(NodeId(me), Role::Head, Security::Insecure);
    c.listen = Some("127.0.0.1:0".parse().unwrap());
    c.heartbeat = Duration::from_millis(50);
    c.liveness_timeout = Duration::from_millis(400);
    c
}

fn dialer_cfg(me: u32, peer: u32, addr: SocketAddr) -> TcpConfig {
    let mut c = TcpConfig::new(NodeId(me), Role::Camera, Security::Insecure);
    c.peers.insert(NodeId(peer), addr);
    c.heartbeat = Duration::from_millis(50);
    c.liveness_timeout = Duration::from_millis(400);
    c.backoff = Backoff::new(Duration::from_millis(10), Duration::from_millis(100), 2.0, 0.3);
    c
}

async fn next_event(inbox: &mut Inbox) -> Event {
    timeout(WAIT, inbox.recv())
        .await
        .expect("no event in time")
        .expect("inbox closed")
}

async fn next_message(inbox: &mut Inbox) -> super::super::Incoming {
    loop {
        if let Event::Message(m) = next_event(inbox).await {
            return m;
        }
    }
}

async fn wait_for(inbox: &mut Inbox, want: Event) {
    loop {
        if next_event(inbox).await == want {
            return;
        }
    }
}

#[tokio::test]
async fn messages_flow_both_ways_in_order() {
    let (a, mut ia, sa, ha) = open(TransportConfig::Tcp(listener_cfg(1))).await.unwrap();
    let addr = a.local_addr().unwrap();
    let (b, mut ib, sb, hb) = open(TransportConfig::Tcp(dialer_cfg(2, 1, addr))).await.unwrap();
    for k in 0..50 {
        b.send(Outgoing::new(NodeId(1), beacon(k)), ClusterTime(k as i64))
            .await
            .unwrap();
    }
    wait_for(&mut ia, Event::PeerUp(NodeId(2))).await;
    for k in 0..50 {
        let m = next_message(&mut ia).await;
        assert_eq!((m.from, m.env.body.clone()), (NodeId(2), beacon(k)));
        assert_eq!(m.env.time, ClusterTime(k as i64));
    }
    // The listener answers over the accepted connection.
    a.send(Outgoing::new(NodeId(2), beacon(99)), ClusterTime(0))
        .await
        .unwrap();
    assert_eq!(next_message(&mut ib).await.env.body, beacon(99));
    assert_eq!(sb.snapshot().sent, 50);
    assert_eq!(sa.snapshot().received, 50);
    hb.shutdown().await;
    wait_for(&mut ia, Event::PeerDown(NodeId(2))).await;
    ha.shutdown().await;
}

#[tokio::test]
async fn dialer_survives_a_listener_restart() {
    let (a, mut ia, _sa, ha) = open(TransportConfig::Tcp(listener_cfg(1))).await.unwrap();
    let addr = a.local_addr().unwrap();
    let (b, mut ib, sb, _hb) = open(TransportConfig::Tcp(dialer_cfg(2, 1, addr))).await.unwrap();
    b.send(Outgoing::new(NodeId(1), beacon(0)), ClusterTime(0))
        .await
        .unwrap();
    assert_eq!(next_message(&mut ia).await.env.body, beacon(0));
    ha.shutdown().await;
    drop((a, ia));
    wait_for(&mut ib, Event::PeerDown(NodeId(1))).await;
    let mut cfg = listener_cfg(1);
    cfg.listen = Some(addr);
    let (_a2, mut ia2, _sa2, _ha2) = open(TransportConfig::Tcp(cfg)).await.unwrap();
    wait_for(&mut ib, Event::PeerUp(NodeId(1))).await;
    b.send(Outgoing::new(NodeId(1), beacon(1)), ClusterTime(0))
        .await
        .unwrap();
    assert_eq!(next_message(&mut ia2).await.env.body, beacon(1));
    let s = sb.snapshot();
    assert!(s.reconnects >= 1 && s.peers_lost == 1 && s.peers_up == 2, "{s:?}");
}

#[tokio::test]
async fn full_queue_drops_measurements_counts_them_and_holds_commands() {
    // Nobody listens there: the link never comes up and the queue fills.
    let dead: SocketAddr = {
        let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        l.local_addr().unwrap()
    };
    let mut cfg = dialer_cfg(2, 1, dead);
    cfg.queue_len = 4;
    let (b, _ib, sb, _hb) = open(TransportConfig::Tcp(cfg)).await.unwrap();
    let m = super::super::inproc::tests::measurement();
    let mut outcomes = Vec::new();
    for _ in 0..10 {
        outcomes.push(
            b.send(Outgoing::new(NodeId(1), m.clone()), ClusterTime(0))
                .await
                .unwrap(),
        );
    }
    assert_eq!(outcomes.iter().filter(|d| **d == Delivery::Dropped).count(), 6);
    assert_eq!(sb.snapshot().dropped_queue_full, 6);
    let cmd = Message::Command(Command {
        node: NodeId(2),
        mode: Mode::Inactive,
    });
    let pending = b
        .send(Outgoing::new(NodeId(1), cmd), ClusterTime(0))
        .now_or_never();
    assert!(
        pending.is_none(),
        "a command on a full queue must wait, not be dropped"
    );
    assert_eq!(sb.snapshot().dropped_queue_full, 6);
    assert_eq!(
        b.send(Outgoing::new(NodeId(9), beacon(0)), ClusterTime(0)).await,
        Err(SendError::UnknownPeer(NodeId(9)))
    );
}

/// Handshake by hand, returning the connection.
async fn raw_client(addr: SocketAddr, me: u32) -> Conn {
    let stream = TcpStream::connect(addr).await.unwrap();
    let mut conn = framed(Box::new(stream));
    let env = Envelope {
        source: NodeId(me),
        seq: 0,
        time: ClusterTime(0),
        body: Message::Hello(Hello {
            version: PROTOCOL_VERSION,
            role: Role::Tool,
            node: NodeId(me),
        }),
    };
    conn.send(Bytes::from(encode(&env).unwrap())).await.unwrap();
    match timeout(WAIT, conn.next()).await.unwrap().unwrap().unwrap() {
        Frame::Data(b) => match decode(&b).unwrap().body {
            Message::HelloAck(a) => assert!(a.accepted, "{}", a.reason),
            other => panic!("expected hello_ack, got {other:?}"),
        },
        Frame::Oversized { .. } => panic!("oversized ack"),
    }
    conn
}

#[tokio::test]
async fn garbage_and_oversized_frames_are_counted_and_the_link_stays_up() {
    let (a, mut ia, sa, _ha) = open(TransportConfig::Tcp(listener_cfg(1))).await.unwrap();
    let mut conn = raw_client(a.local_addr().unwrap(), 5).await;
    wait_for(&mut ia, Event::PeerUp(NodeId(5))).await;
    conn.send(Bytes::from(vec![PROTOCOL_VERSION as u8, 0xff, 0xff, 0xff]))
        .await
        .unwrap();
    conn.send(Bytes::from(vec![0u8; MAX_FRAME_BYTES + 1]))
        .await
        .unwrap();
    // A frame of a protocol version this build does not speak.
    conn.send(Bytes::from(vec![PROTOCOL_VERSION as u8 + 1, 0]))
        .await
        .unwrap();
    let spoofed = Envelope {
        source: NodeId(6),
        seq: 1,
        time: ClusterTime(0),
        body: beacon(0),
    };
    conn.send(Bytes::from(encode(&spoofed).unwrap())).await.unwrap();
    let good = Envelope {
        source: NodeId(5),
        seq: 2,
        time: ClusterTime(0),
        body: beacon(3),
    };
    conn.send(Bytes::from(encode(&good).unwrap())).await.unwrap();
    let m = next_message(&mut ia).await;
    assert_eq!((m.from, m.env.body), (NodeId(5), beacon(3)));
    let s = sa.snapshot();
    assert_eq!(
        (
            s.rejected_malformed,
            s.rejected_oversized,
            s.rejected_version,
            s.rejected_invalid
        ),
        (1, 1, 1, 1),
        "{s:?}"
    );
}

#[tokio::test]
async fn a_silent_peer_is_declared_down() {
    let (a, mut ia, sa, _ha) = open(TransportConfig::Tcp(listener_cfg(1))).await.unwrap();
    let _conn = raw_client(a.local_addr().unwrap(), 5).await;
    wait_for(&mut ia, Event::PeerUp(NodeId(5))).await;
    // The raw client never sends a heartbeat.
    wait_for(&mut ia, Event::PeerDown(NodeId(5))).await;
    assert_eq!(sa.snapshot().peers_lost, 1);
    assert!(sa.snapshot().heartbeats_sent >= 1);
}

#[tokio::test]
async fn wrong_version_hello_is_refused_with_a_reason() {
    let (a, _ia, sa, _ha) = open(TransportConfig::Tcp(listener_cfg(1))).await.unwrap();
    let stream = TcpStream::connect(a.local_addr().unwrap()).await.unwrap();
    let mut conn = framed(Box::new(stream));
    // The next version's header, then anything.
    conn.send(Bytes::from(vec![PROTOCOL_VERSION as u8 + 1, 0, 0]))
        .await
        .unwrap();
    match timeout(WAIT, conn.next()).await.unwrap().unwrap().unwrap() {
        Frame::Data(b) => match decode(&b).unwrap().body {
            Message::HelloAck(ack) => {
                assert!(!ack.accepted);
                assert!(
                    ack.reason.contains(&format!("version {}", PROTOCOL_VERSION + 1)),
                    "{}",
                    ack.reason
                );
            }
            other => panic!("expected hello_ack, got {other:?}"),
        },
        Frame::Oversized { .. } => panic!("oversized ack"),
    }
    let s = sa.snapshot();
    assert_eq!((s.rejected_version, s.rejected_handshake), (1, 1));
}
