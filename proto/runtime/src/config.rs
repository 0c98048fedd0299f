//! From the scenario to a node's transport: one rule for every role.
//!
//! - iceoryx2 (one host): the scenario's domain, limits sized for its nodes, heartbeats to
//!   every peer at `network.heartbeat-ms` (liveness on one host rests on them).
//! - TCP (between hosts): a node listens at its `listen` address if it has one (heads, the
//!   server); a camera or an acoustic node dials its head and the server, a head dials the
//!   server, and a camera knows every head's address so it can dial the one it is assigned to
//!   later. Only the scenario's nodes, in their roles, may connect (the roster). Links are
//!   mutual TLS with the node's certificate from a directory ([`LinkSecurity`]); plain TCP only
//!   when the scenario says `insecure = true` or the caller insists. Addresses are `host:port`
//!   and may name hosts (resolved once, here); every limit is clamped to at least 1 (ms, frames).

use crate::clock::HostClock;
use crate::transport::{IpcConfig, Security, TcpConfig, Tls, TlsError, TransportConfig};
use proto::scenario::{NodeRole, Scenario, TransportKind};
use proto::{NodeId, Role};
use std::collections::BTreeMap;
use std::net::{SocketAddr, ToSocketAddrs};
use std::path::PathBuf;
use std::time::Duration;
use thiserror::Error;

/// A transport configuration that cannot be built from the scenario.
#[derive(Debug, Error)]
pub enum ConfigError {
    #[error("node {0} is not in the scenario")]
    NoSuchNode(NodeId),
    #[error("node {0} is the scenario's; a client needs an id the scenario does not use")]
    Declared(NodeId),
    #[error("the scenario's server has no listen address to dial")]
    NoServer,
    #[error("node {node}: address `{addr}` of node {peer}: {problem}")]
    Address {
        node: NodeId,
        peer: NodeId,
        addr: String,
        problem: String,
    },
    #[error(
        "node {0}: TCP links need TLS: pass the directory of the cluster's certificates (`--tls-dir`, written by `ocelli deploy`) or, knowing anyone on the network can then pose as any node, set `[network] insecure = true` / `--insecure`"
    )]
    NoTls(NodeId),
    #[error("node {node}: {error}")]
    Tls { node: NodeId, error: TlsError },
}

/// How a node's TCP links are secured.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LinkSecurity {
    /// Directory with `ca.pem`, `node-{id}.pem` and `node-{id}.key`.
    pub tls_dir: Option<PathBuf>,
    /// Plain TCP even if the scenario does not say `insecure = true`.
    pub insecure: bool,
}

impl LinkSecurity {
    /// Node `id`'s security under `scenario`: plain TCP if either side says insecure, else TLS
    /// from the directory.
    ///
    /// # Errors
    /// [`ConfigError::NoTls`] without a directory, [`ConfigError::Tls`] if its files do not
    /// load.
    pub fn resolve(&self, scenario: &Scenario, id: NodeId) -> Result<Security, ConfigError> {
        if self.insecure || scenario.network.insecure {
            return Ok(Security::Insecure);
        }
        let dir = self.tls_dir.as_ref().ok_or(ConfigError::NoTls(id))?;
        Tls::load(dir, id)
            .map(Security::Tls)
            .map_err(|error| ConfigError::Tls { node: id, error })
    }
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

/// The nodes `id` may dial later: a camera every head (it is assigned to one of them by the
/// server), besides what [`dials`] names from the start.
pub fn may_dial(scenario: &Scenario, id: NodeId) -> Vec<NodeId> {
    match scenario.node(id.0).map(|n| n.role) {
        Some(NodeRole::Camera) => scenario.heads().map(|h| NodeId(h.id)).collect(),
        _ => Vec::new(),
    }
}

/// Every node of the scenario and its wire role: who may connect, as what.
pub fn roster(scenario: &Scenario) -> BTreeMap<NodeId, Role> {
    scenario
        .nodes
        .iter()
        .map(|n| (NodeId(n.id), wire_role(n.role)))
        .collect()
}

/// Node `id`'s transport of `kind`, its frames stamped by `clock`; `listen` overrides the
/// scenario's listen address (port 0 in tests); `security` says how TCP links are secured.
///
/// # Errors
/// The node is not in the scenario, an address does not resolve, or TCP's TLS files are
/// missing (see [`LinkSecurity::resolve`]).
pub fn transport_config(
    scenario: &Scenario,
    id: NodeId,
    kind: TransportKind,
    clock: &HostClock,
    listen: Option<SocketAddr>,
    security: &LinkSecurity,
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
            c.liveness_timeout = Some(Duration::from_millis(net.liveness_timeout_ms.max(1)));
            TransportConfig::Ipc(c)
        }
        TransportKind::Tcp => {
            let mut c = TcpConfig::new(id, role, security.resolve(scenario, id)?);
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
            for peer in may_dial(scenario, id) {
                if let Some(addr) = scenario.node(peer.0).and_then(|n| n.listen.as_deref()) {
                    c.directory.insert(peer, resolve(id, peer, addr)?);
                }
            }
            c.roster = Some(roster(scenario));
            c.heartbeat = heartbeat;
            c.liveness_timeout = Duration::from_millis(net.liveness_timeout_ms.max(1));
            c.queue_len = queue_len;
            c.clock = clock.for_transport();
            TransportConfig::Tcp(c)
        }
    })
}

/// The transport of a client the scenario does not declare (a viewer, a tool) with id `id` and
/// wire role `role`: over iceoryx2 the scenario's domain with its limits and heartbeats; over
/// TCP it dials the server's listen address.
///
/// # Errors
/// [`ConfigError::Declared`] if the scenario gives `id` to one of its nodes; over TCP, a
/// server without a listen address or one that does not resolve.
pub fn client_transport_config(
    scenario: &Scenario,
    id: NodeId,
    role: Role,
    kind: TransportKind,
    clock: &HostClock,
    security: &LinkSecurity,
) -> Result<TransportConfig, ConfigError> {
    if scenario.node(id.0).is_some() {
        return Err(ConfigError::Declared(id));
    }
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
            let server = scenario.server().ok_or(ConfigError::NoServer)?;
            let addr = server.listen.as_deref().ok_or(ConfigError::NoServer)?;
            let mut c = TcpConfig::new(id, role, security.resolve(scenario, id)?);
            c.peers
                .insert(NodeId(server.id), resolve(id, NodeId(server.id), addr)?);
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
        let plain = LinkSecurity {
            tls_dir: None,
            insecure: true,
        };
        let TransportConfig::Tcp(c) =
            transport_config(&s, NodeId(10), TransportKind::Tcp, &clock, None, &plain).unwrap()
        else {
            panic!("tcp")
        };
        assert_eq!(c.peers.len(), 2);
        assert_eq!(c.listen, None);
        // A camera can reach every head (the server may assign it to any), and only the
        // scenario's nodes may connect, in their roles.
        assert_eq!(
            c.directory.keys().copied().collect::<Vec<_>>(),
            vec![NodeId(2), NodeId(3)]
        );
        assert_eq!(c.roster.as_ref().unwrap().get(&NodeId(3)), Some(&Role::Head));
        assert!(matches!(c.security, Security::Insecure));
        let TransportConfig::Tcp(c) =
            transport_config(&s, NodeId(2), TransportKind::Tcp, &clock, None, &plain).unwrap()
        else {
            panic!("tcp")
        };
        assert!(c.listen.is_some());
        // Names resolve like literals; a bad address names both nodes.
        let mut named = s.clone();
        named.nodes.iter_mut().find(|n| n.id == 1).unwrap().listen = Some("localhost:7400".into());
        assert!(transport_config(&named, NodeId(10), TransportKind::Tcp, &clock, None, &plain).is_ok());
        named.nodes.iter_mut().find(|n| n.id == 1).unwrap().listen = Some("no-such-host.invalid:7400".into());
        let e = transport_config(&named, NodeId(10), TransportKind::Tcp, &clock, None, &plain)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("n10") && e.contains("n1") && e.contains("no-such-host.invalid:7400"),
            "{e}"
        );
        assert!(matches!(
            transport_config(&s, NodeId(99), TransportKind::Ipc, &clock, None, &plain),
            Err(ConfigError::NoSuchNode(NodeId(99)))
        ));
    }

    #[test]
    fn tcp_needs_tls_files_unless_insecure_is_said() {
        let s = Scenario::default_scenario();
        let clock = HostClock::follower();
        let e = transport_config(
            &s,
            NodeId(10),
            TransportKind::Tcp,
            &clock,
            None,
            &LinkSecurity::default(),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("--tls-dir") && e.contains("insecure"), "{e}");
        let mut open = s.clone();
        open.network.insecure = true;
        let TransportConfig::Tcp(c) = transport_config(
            &open,
            NodeId(10),
            TransportKind::Tcp,
            &clock,
            None,
            &LinkSecurity::default(),
        )
        .unwrap() else {
            panic!("tcp")
        };
        assert!(matches!(c.security, Security::Insecure));
        let dir = std::env::temp_dir().join(format!("ocelli-config-tls-{}", std::process::id()));
        let ca = crate::transport::ClusterCa::generate("t").unwrap();
        crate::transport::TlsFiles::in_dir(&dir, NodeId(10))
            .write(ca.cert_pem(), &ca.issue(NodeId(10), Role::Camera).unwrap())
            .unwrap();
        let sec = LinkSecurity {
            tls_dir: Some(dir.clone()),
            insecure: false,
        };
        let TransportConfig::Tcp(c) =
            transport_config(&s, NodeId(10), TransportKind::Tcp, &clock, None, &sec).unwrap()
        else {
            panic!("tcp")
        };
        assert!(matches!(c.security, Security::Tls(_)));
        // iceoryx2 needs no certificates.
        assert!(
            transport_config(
                &s,
                NodeId(10),
                TransportKind::Ipc,
                &clock,
                None,
                &LinkSecurity::default()
            )
            .is_ok()
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
