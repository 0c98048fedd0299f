//! Tests of who may connect and what a connection may cost, on loopback: certificates bind ids
//! and roles, the roster admits the scenario's nodes only, one live link per id, handshake
//! limits and timeouts, a flooding peer read at its budget while the others go on, and links
//! dialed when first needed.

use super::super::{Event, Inbox, TransportConfig, open};
use super::*;
use crate::transport::inproc::tests::measurement;
use crate::transport::{ClusterCa, Incoming, Opened};
use proto::msg::SyncBeacon;
use proto::node::Outgoing;
use proto::time::ClusterTime;
use tokio::io::AsyncReadExt;
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

fn roster() -> BTreeMap<NodeId, Role> {
    [
        (NodeId(2), Role::Head),
        (NodeId(10), Role::Camera),
        (NodeId(11), Role::Camera),
    ]
    .into()
}

fn tls(ca: &ClusterCa, id: u32, role: Role) -> Security {
    Security::Tls(Tls::from_pem(ca.cert_pem(), &ca.issue(NodeId(id), role).unwrap()).unwrap())
}

fn head(security: Security) -> TcpConfig {
    let mut c = TcpConfig::new(NodeId(2), Role::Head, security);
    c.listen = Some("127.0.0.1:0".parse().unwrap());
    c.roster = Some(roster());
    c.heartbeat = Duration::from_millis(50);
    c.liveness_timeout = Duration::from_millis(400);
    c
}

/// A camera claiming `me` that dials the head at `addr`.
fn camera(me: u32, security: Security, addr: SocketAddr) -> TcpConfig {
    let mut c = TcpConfig::new(NodeId(me), Role::Camera, security);
    c.peers.insert(NodeId(2), addr);
    c.roster = Some(roster());
    c.heartbeat = Duration::from_millis(50);
    c.liveness_timeout = Duration::from_millis(400);
    c.backoff = Backoff::new(Duration::from_millis(10), Duration::from_millis(50), 2.0, 0.3);
    c
}

async fn next_event(inbox: &mut Inbox) -> Event {
    timeout(WAIT, inbox.recv())
        .await
        .expect("no event in time")
        .expect("inbox closed")
}

async fn wait_for(inbox: &mut Inbox, want: Event) {
    loop {
        if next_event(inbox).await == want {
            return;
        }
    }
}

async fn next_message(inbox: &mut Inbox) -> Incoming {
    loop {
        if let Event::Message(m) = next_event(inbox).await {
            return m;
        }
    }
}

async fn open_tcp(c: TcpConfig) -> Opened {
    open(TransportConfig::Tcp(c)).await.unwrap()
}

/// Wait until `cond` holds on the stats (checked every 10 ms, at most [`WAIT`]).
async fn until(stats: &TransportStats, what: &str, cond: impl Fn(&super::super::StatsSnapshot) -> bool) {
    let deadline = Instant::now() + WAIT;
    loop {
        let s = stats.snapshot();
        if cond(&s) {
            return;
        }
        assert!(Instant::now() < deadline, "{what}: {s:?}");
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
}

use tokio::time::Instant;

#[tokio::test]
async fn a_camera_with_its_own_certificate_talks_over_tls() {
    let ca = ClusterCa::generate("t").unwrap();
    let (h, mut ih, _sh, _hh) = open_tcp(head(tls(&ca, 2, Role::Head))).await;
    let addr = h.local_addr().unwrap();
    let (c, mut ic, _sc, _hc) = open_tcp(camera(10, tls(&ca, 10, Role::Camera), addr)).await;
    c.send(Outgoing::new(NodeId(2), beacon(7)), ClusterTime(0))
        .await
        .unwrap();
    wait_for(&mut ih, Event::PeerUp(NodeId(10))).await;
    let m = next_message(&mut ih).await;
    assert_eq!((m.from, m.env.body), (NodeId(10), beacon(7)));
    h.send(Outgoing::new(NodeId(10), beacon(8)), ClusterTime(0))
        .await
        .unwrap();
    assert_eq!(next_message(&mut ic).await.env.body, beacon(8));
}

#[tokio::test]
async fn certificates_of_another_ca_and_claims_they_do_not_prove_are_refused() {
    let ca = ClusterCa::generate("t").unwrap();
    let other = ClusterCa::generate("t").unwrap();
    let (h, mut ih, sh, _hh) = open_tcp(head(tls(&ca, 2, Role::Head))).await;
    let addr = h.local_addr().unwrap();
    // Another cluster's CA: the chain does not verify (each end refuses the other).
    let (_c1, _i1, s1, _h1) = open_tcp(camera(10, tls(&other, 10, Role::Camera), addr)).await;
    until(&s1, "the dialer refused the head's certificate", |s| {
        s.rejected_identity >= 1
    })
    .await;
    // Camera 11's certificate claiming to be camera 10.
    let (_c2, _i2, _s2, _h2) = open_tcp(camera(10, tls(&ca, 11, Role::Camera), addr)).await;
    // An id the scenario does not have, with a valid certificate for it.
    let (_c3, _i3, _s3, _h3) = open_tcp(camera(99, tls(&ca, 99, Role::Camera), addr)).await;
    until(&sh, "the head refused both claims", |s| s.rejected_identity >= 2).await;
    // A head's certificate cannot pose as camera 10, nor camera 10's as a head.
    let mut as_head = camera(10, tls(&ca, 10, Role::Head), addr);
    as_head.role = Role::Head;
    let (_c4, _i4, _s4, _h4) = open_tcp(as_head).await;
    until(&sh, "the head refused the role the scenario does not give", |s| {
        s.rejected_identity >= 3
    })
    .await;
    assert_eq!(sh.snapshot().peers_up, 0, "no impostor got a link");
    assert!(ih.try_recv().is_none());
}

#[tokio::test]
async fn a_second_connection_for_a_live_id_is_refused_and_a_reconnect_after_it_is_gone_works() {
    let ca = ClusterCa::generate("t").unwrap();
    let cert = ca.issue(NodeId(10), Role::Camera).unwrap();
    let same = || Security::Tls(Tls::from_pem(ca.cert_pem(), &cert).unwrap());
    let (h, mut ih, sh, _hh) = open_tcp(head(tls(&ca, 2, Role::Head))).await;
    let addr = h.local_addr().unwrap();
    let (first, _if, _sf, hf) = open_tcp(camera(10, same(), addr)).await;
    wait_for(&mut ih, Event::PeerUp(NodeId(10))).await;
    let (second, _is, ss, _hs) = open_tcp(camera(10, same(), addr)).await;
    until(&sh, "the second connection was refused", |s| {
        s.rejected_duplicate >= 2
    })
    .await;
    // The dialer learns of each refusal after the head counted it: wait for it too.
    until(&ss, "the second dialer saw its handshakes refused", |s| {
        s.rejected_handshake >= 2
    })
    .await;
    // The first is undisturbed.
    first
        .send(Outgoing::new(NodeId(2), beacon(1)), ClusterTime(0))
        .await
        .unwrap();
    assert_eq!(next_message(&mut ih).await.env.body, beacon(1));
    // Once it is really gone, the second gets in.
    hf.shutdown().await;
    drop(first);
    wait_for(&mut ih, Event::PeerDown(NodeId(10))).await;
    wait_for(&mut ih, Event::PeerUp(NodeId(10))).await;
    second
        .send(Outgoing::new(NodeId(2), beacon(2)), ClusterTime(0))
        .await
        .unwrap();
    assert_eq!(next_message(&mut ih).await.env.body, beacon(2));
}

#[tokio::test]
async fn connections_that_never_handshake_are_closed_and_too_many_at_once_are_refused() {
    let mut cfg = head(Security::Insecure);
    cfg.handshake_timeout = Duration::from_millis(300);
    cfg.max_handshakes_per_ip = 2;
    let (h, _ih, sh, _hh) = open_tcp(cfg).await;
    let addr = h.local_addr().unwrap();
    let mut silent = Vec::new();
    for _ in 0..4 {
        silent.push(TcpStream::connect(addr).await.unwrap());
    }
    // Two are over the per-address limit: closed at once. The other two are closed when the
    // handshake timeout passes.
    for s in &mut silent {
        let mut buf = [0u8; 8];
        let n = timeout(WAIT, s.read(&mut buf)).await.expect("never closed");
        assert!(matches!(n, Ok(0) | Err(_)), "{n:?}");
    }
    until(&sh, "limits counted", |s| s.rejected_connections == 4).await;
    // The listener still serves a real node afterwards.
    let (c, _ic, sc, _hc) = open_tcp(camera(10, Security::Insecure, addr)).await;
    until(&sc, "link up after the flood", |s| s.peers_up == 1).await;
    drop(c);
}

/// A peer flooding droppable messages is read at its budget; a well-behaved peer's messages
/// all get through, although the receiver consumes slower than the flood could arrive.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_flooding_peer_cannot_starve_the_others() {
    let mut cfg = head(Security::Insecure);
    cfg.max_frames_per_sec = 100;
    cfg.queue_len = 64;
    let (h, mut ih, sh, _hh) = open_tcp(cfg).await;
    let addr = h.local_addr().unwrap();
    let (flooder, _if, sf, _hf) = open_tcp(camera(10, Security::Insecure, addr)).await;
    let (good, _ig, _sg, _hg) = open_tcp(camera(11, Security::Insecure, addr)).await;
    until(&sh, "both cameras up", |s| s.peers_up == 2).await;
    let stop = tokio_util::sync::CancellationToken::new();
    let flooding = stop.clone();
    let flood = tokio::spawn(async move {
        let m = measurement();
        while !flooding.is_cancelled() {
            let _ = flooder
                .send(Outgoing::new(NodeId(2), m.clone()), ClusterTime(0))
                .await;
            tokio::task::yield_now().await;
        }
    });
    let sender = tokio::spawn(async move {
        for _ in 0..50 {
            good.send(Outgoing::new(NodeId(2), measurement()), ClusterTime(0))
                .await
                .unwrap();
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    });
    // A receiver of a few hundred messages a second: far less than the flood could send.
    let deadline = Instant::now() + Duration::from_secs(30);
    let (mut from_good, mut from_flooder) = (0, 0);
    while from_good < 50 && Instant::now() < deadline {
        if let Ok(Some(Event::Message(m))) = timeout(Duration::from_millis(100), ih.recv()).await {
            if m.from == NodeId(11) {
                from_good += 1;
            } else {
                from_flooder += 1;
            }
            tokio::time::sleep(Duration::from_millis(2)).await;
        }
    }
    stop.cancel();
    flood.await.unwrap();
    sender.await.unwrap();
    let s = sh.snapshot();
    assert_eq!(from_good, 50, "the well-behaved camera was starved: {s:?}");
    assert_eq!(s.dropped_inbox_full, 0, "{s:?}");
    assert!(s.throttled >= 1 && from_flooder > 0, "{s:?}");
    // The flooder offered far more than it was read.
    assert!(
        sf.snapshot().sent + sf.snapshot().dropped_queue_full > 10 * from_flooder,
        "{:?}",
        sf.snapshot()
    );
    assert_eq!(s.peers_lost, 0, "{s:?}");
}

#[tokio::test]
async fn a_directory_peer_is_dialed_when_first_needed() {
    let ca = ClusterCa::generate("t").unwrap();
    let (h, mut ih, _sh, _hh) = open_tcp(head(tls(&ca, 2, Role::Head))).await;
    let mut c = camera(10, tls(&ca, 10, Role::Camera), h.local_addr().unwrap());
    c.directory = std::mem::take(&mut c.peers);
    let (cam, mut ic, _sc, _hc) = open_tcp(c).await;
    assert!(!cam.ensure_link(NodeId(3)), "no address for head 3");
    tokio::time::sleep(Duration::from_millis(200)).await;
    assert!(ih.try_recv().is_none(), "nothing dialed before it was needed");
    assert!(cam.ensure_link(NodeId(2)));
    wait_for(&mut ih, Event::PeerUp(NodeId(10))).await;
    wait_for(&mut ic, Event::PeerUp(NodeId(2))).await;
    h.send(Outgoing::new(NodeId(10), beacon(3)), ClusterTime(0))
        .await
        .unwrap();
    assert_eq!(next_message(&mut ic).await.env.body, beacon(3));
}
