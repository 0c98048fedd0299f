//! From the scenario to a node's transport: one rule for every role.
//!
//! - iceoryx2 (one host): the scenario's domain, limits sized for its nodes, heartbeats to
//!   every peer at `network.heartbeat-ms` (liveness on one host rests on them).
//! - TCP (between hosts): a node listens at its `listen` address if it has one (heads, the
//!   server); a camera or an acoustic node dials its head and the server, a head dials the
//!   server. Addresses are
//!   `host:port` and may name hosts (resolved once, here); every limit is clamped to at least
//!   1 (ms, frames).

use crate::clock::HostClock;
use crate::transport::{IpcConfig, TcpConfig, TransportConfig};
use proto::scenario::{NodeRole, Scenario, TransportKind};
use proto::{NodeId, Role};
use std::net::{SocketAddr, ToSocketAddrs};
use std::time::Duration;
use thiserror::Error;

/// A transport configuration that cannot be built from the scenario.
#[derive(Debug, Error)]
pub enum ConfigError {
    #[error("node {0} is not in the scenario")]
    NoSuchNode(NodeId),
    #[error("node {node}: address `{addr}` of node {peer}: {problem}")]
    Address {
        node: NodeId,
        peer: NodeId,
        addr: String,
        problem: String,
    },
}

/// The wire role of a scenario role.
pub fn wire_role(role: NodeRole) -> Role {
    match role {
        NodeRole::Camera => Role::Camera,
        NodeRole::Head => Role::Head,
        NodeRole::Server => Role::Server,
        NodeRole::Acoustic => Role::Acoustic,
    }
}

/// Resolve `host:port` (a name or a literal address) to its first socket address.
///
/// # Errors
/// [`ConfigError::Address`] naming both nodes and the address.
pub fn resolve(node: NodeId, peer: NodeId, addr: &str) -> Result<SocketAddr, ConfigError> {
    let bad = |problem: String| ConfigError::Address {
        node,
        peer,
        addr: addr.into(),
        problem,
    };
    addr.to_socket_addrs()
        .map_err(|e| bad(e.to_string()))?
        .next()
        .ok_or_else(|| bad("resolves to no address".into()))
}

/// The nodes `id` dials over TCP: a camera or an acoustic node its head and the server, a head
/// the server.
pub fn dials(scenario: &Scenario, id: NodeId) -> Vec<NodeId> {
    let Some(me) = scenario.node(id.0) else {
        return Vec::new();
    };
    let server = scenario.server().map(|s| NodeId(s.id));
    match me.role {
        NodeRole::Camera | NodeRole::Acoustic => {
            let head = me
                .head
                .or_else(|| scenario.heads().next().map(|h| h.id))
                .map(NodeId);
            head.into_iter().chain(server).collect()
        }
        NodeRole::Head => server.into_iter().collect(),
        NodeRole::Server => Vec::new(),
    }
}

/// Node `id`'s transport of `kind`, its frames stamped by `clock`; `listen` overrides the
/// scenario's listen address (port 0 in tests).
///
/// # Errors
/// The node is not in the scenario, or an address does not resolve.
pub fn transport_config(
    scenario: &Scenario,
    id: NodeId,
    kind: TransportKind,
    clock: &HostClock,
    listen: Option<SocketAddr>,
) -> Result<TransportConfig, ConfigError> {
    let me = scenario.node(id.0).ok_or(ConfigError::NoSuchNode(id))?;
    let role = wire_role(me.role);
    let net = &scenario.network;
    let heartbeat = Duration::from_millis(net.heartbeat_ms.max(1));
    let queue_len = net.queue_len.max(1);
    Ok(match kind {
        TransportKind::Ipc => {
            let mut c = IpcConfig::new(net.domain.clone(), id, role, scenario.nodes.len());
            c.queue_len = queue_len;
            c.heartbeat = Some((heartbeat, clock.for_transport()));
            TransportConfig::Ipc(c)
        }
        TransportKind::Tcp => {
            let mut c = TcpConfig::new(id, role);
            c.listen = match (listen, &me.listen) {
                (Some(a), _) => Some(a),
                (None, Some(a)) => Some(resolve(id, id, a)?),
                (None, None) => None,
            };
            for peer in dials(scenario, id) {
                if let Some(addr) = scenario.node(peer.0).and_then(|n| n.listen.as_deref()) {
                    c.peers.insert(peer, resolve(id, peer, addr)?);
                }
            }
            c.heartbeat = heartbeat;
            c.liveness_timeout = Duration::from_millis(net.liveness_timeout_ms.max(1));
            c.queue_len = queue_len;
            c.clock = clock.for_transport();
            TransportConfig::Tcp(c)
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cameras_dial_head_and_server_heads_the_server() {
        let s = Scenario::default_scenario();
        assert_eq!(dials(&s, NodeId(10)), vec![NodeId(2), NodeId(1)]);
        assert_eq!(dials(&s, NodeId(2)), vec![NodeId(1)]);
        assert!(dials(&s, NodeId(1)).is_empty());
        let clock = HostClock::follower();
        let TransportConfig::Tcp(c) =
            transport_config(&s, NodeId(10), TransportKind::Tcp, &clock, None).unwrap()
        else {
            panic!("tcp")
        };
        assert_eq!(c.peers.len(), 2);
        assert_eq!(c.listen, None);
        let TransportConfig::Tcp(c) =
            transport_config(&s, NodeId(2), TransportKind::Tcp, &clock, None).unwrap()
        else {
            panic!("tcp")
        };
        assert!(c.listen.is_some());
        // Names resolve like literals; a bad address names both nodes.
        let mut named = s.clone();
        named.nodes.iter_mut().find(|n| n.id == 1).unwrap().listen = Some("localhost:7400".into());
        assert!(transport_config(&named, NodeId(10), TransportKind::Tcp, &clock, None).is_ok());
        named.nodes.iter_mut().find(|n| n.id == 1).unwrap().listen = Some("no-such-host.invalid:7400".into());
        let e = transport_config(&named, NodeId(10), TransportKind::Tcp, &clock, None)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("n10") && e.contains("n1") && e.contains("no-such-host.invalid:7400"),
            "{e}"
        );
        assert!(matches!(
            transport_config(&s, NodeId(99), TransportKind::Ipc, &clock, None),
            Err(ConfigError::NoSuchNode(NodeId(99)))
        ));
    }
}
