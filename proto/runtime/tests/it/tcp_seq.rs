//! TCP link control frames (handshake, heartbeats) take no data sequence number: after an idle
//! spell of many heartbeats, the next data frame follows the previous one with no gap, so a
//! receiver counting gaps counts lost frames only.

use proto::msg::{Message, SyncBeacon};
use proto::node::Outgoing;
use proto::{ClusterTime, Envelope, NodeId, Role};
use runtime::transport::{ClusterCa, Event, Inbox, Security, TcpConfig, Tls, TransportConfig, open};
use std::time::Duration;

const WAIT: Duration = Duration::from_secs(10);

fn beacon(round: u64) -> Message {
    Message::SyncBeacon(SyncBeacon {
        leader: NodeId(1),
        round,
        leader_time: ClusterTime(0),
    })
}

async fn next_data(inbox: &mut Inbox) -> Envelope {
    loop {
        match tokio::time::timeout(WAIT, inbox.recv()).await {
            Ok(Some(Event::Message(m))) => return m.env,
            Ok(Some(_)) => {}
            Ok(None) => panic!("inbox closed"),
            Err(_) => panic!("no message in time"),
        }
    }
}

#[tokio::test]
async fn heartbeats_between_data_frames_leave_no_sequence_gap() {
    let heartbeat = Duration::from_millis(10);
    // Over mutual TLS, as every link between hosts.
    let ca = ClusterCa::generate("seq").unwrap();
    let tls = |id: u32, role: Role| {
        Security::Tls(Tls::from_pem(ca.cert_pem(), &ca.issue(NodeId(id), role).unwrap()).unwrap())
    };
    let roster: std::collections::BTreeMap<NodeId, Role> =
        [(NodeId(1), Role::Server), (NodeId(2), Role::Camera)].into();
    let mut server = TcpConfig::new(NodeId(1), Role::Server, tls(1, Role::Server));
    server.roster = Some(roster.clone());
    server.listen = Some("127.0.0.1:0".parse().unwrap());
    server.heartbeat = heartbeat;
    let (a, mut ia, sa, ha) = open(TransportConfig::Tcp(server)).await.unwrap();
    let mut camera = TcpConfig::new(NodeId(2), Role::Camera, tls(2, Role::Camera));
    camera.roster = Some(roster);
    camera.peers.insert(NodeId(1), a.local_addr().unwrap());
    camera.heartbeat = heartbeat;
    let (b, mut ib, sb, hb) = open(TransportConfig::Tcp(camera)).await.unwrap();

    let mut seqs = Vec::new();
    let mut back = Vec::new();
    for k in 0..3 {
        b.send(Outgoing::new(NodeId(1), beacon(k)), ClusterTime(0))
            .await
            .unwrap();
        seqs.push(next_data(&mut ia).await.seq);
        a.send(Outgoing::new(NodeId(2), beacon(k)), ClusterTime(0))
            .await
            .unwrap();
        back.push(next_data(&mut ib).await.seq);
        // Idle: about ten heartbeats each way.
        tokio::time::sleep(heartbeat * 10).await;
    }
    let (hs, hr) = (sb.snapshot().heartbeats_sent, sa.snapshot().heartbeats_received);
    assert!(
        hs >= 10 && hr >= 10,
        "heartbeats flowed ({hs} sent, {hr} received)"
    );
    assert_eq!(seqs, vec![seqs[0], seqs[0] + 1, seqs[0] + 2], "camera → server");
    assert_eq!(back, vec![back[0], back[0] + 1, back[0] + 2], "server → camera");
    hb.shutdown().await;
    ha.shutdown().await;
}
