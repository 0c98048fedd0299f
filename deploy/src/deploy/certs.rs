//! The cluster's certificates for a TCP deployment: one CA, one certificate per node naming its
//! id and role (`runtime::transport::tls`), each host given only its own nodes' keys.
//!
//! The CA lives in `out/ca/` (`ca.pem`, and `ca.key` readable by its owner only); it is never
//! copied to a host. Deploying again into the same output directory reuses that key, so
//! certificates issued later (a new host, a replaced Pi) chain to the `ca.pem` the other hosts
//! already trust. Each host gets `rootfs/etc/ocelli/tls/ca.pem` and `node-<id>.pem` /
//! `node-<id>.key` (0600) for the nodes it runs.

use super::units::TLS_DIR;
use super::{Plan, role_name};
use proto::scenario::Scenario;
use proto::{NodeId, Role};
use runtime::config::wire_role;
use runtime::transport::tls::write_file;
use runtime::transport::{ClusterCa, TlsError, TlsFiles};
use std::path::{Path, PathBuf};

/// What was made.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Issued {
    /// Where the CA is kept.
    pub ca_dir: PathBuf,
    /// Whether an existing CA key was reused.
    pub reused_ca: bool,
    /// Node certificates issued.
    pub certificates: usize,
}

/// The CA kept in `out/ca/`, made if there is none.
///
/// # Errors
/// The key cannot be read or written, or is not a key.
pub fn cluster_ca(scenario: &Scenario, out: &Path) -> Result<(ClusterCa, bool), TlsError> {
    let dir = out.join("ca");
    let key_path = dir.join("ca.key");
    if key_path.exists() {
        let pem = std::fs::read_to_string(&key_path).map_err(|e| TlsError::File {
            path: key_path.clone(),
            problem: e.to_string(),
        })?;
        let ca = ClusterCa::from_key_pem(&scenario.name, &pem)?;
        return Ok((ca, true));
    }
    let ca = ClusterCa::generate(&scenario.name)?;
    write_file(&key_path, &ca.key_pem(), 0o600)?;
    write_file(&dir.join("ca.pem"), ca.cert_pem(), 0o644)?;
    Ok((ca, false))
}

/// Issue every node's certificate into its host's `rootfs/etc/ocelli/tls/` under `out`.
///
/// # Errors
/// A certificate cannot be made or a file cannot be written.
pub fn issue(scenario: &Scenario, plan: &Plan, out: &Path) -> Result<Issued, TlsError> {
    let (ca, reused_ca) = cluster_ca(scenario, out)?;
    // The CA certificate as first made: the hosts trust that one.
    let ca_pem =
        std::fs::read_to_string(out.join("ca").join("ca.pem")).unwrap_or_else(|_| ca.cert_pem().into());
    let mut certificates = 0;
    for host in &plan.hosts {
        let dir = out
            .join(&host.host)
            .join("rootfs")
            .join(TLS_DIR.trim_start_matches('/'));
        for node in scenario.nodes.iter().filter(|n| n.host == host.host) {
            let id = NodeId(node.id);
            let cert = ca.issue(id, wire_role(node.role))?;
            TlsFiles::in_dir(&dir, id).write(&ca_pem, &cert)?;
            certificates += 1;
            tracing::debug!(node = node.id, role = role_name(node.role), host = %host.host, "certificate issued");
        }
    }
    Ok(Issued {
        ca_dir: out.join("ca"),
        reused_ca,
        certificates,
    })
}

/// Issue a certificate for every node of `scenario`, and for each client in `clients` (a
/// viewer: not in the scenario, no say in tracking), into one directory (a launch on one host:
/// every node reads its own from there).
///
/// # Errors
/// A certificate cannot be made or a file cannot be written.
pub fn issue_all_in(scenario: &Scenario, clients: &[(NodeId, Role)], dir: &Path) -> Result<(), TlsError> {
    let ca = ClusterCa::generate(&scenario.name)?;
    let nodes = scenario.nodes.iter().map(|n| (NodeId(n.id), wire_role(n.role)));
    for (id, role) in nodes.chain(clients.iter().copied()) {
        TlsFiles::in_dir(dir, id).write(ca.cert_pem(), &ca.issue(id, role)?)?;
    }
    Ok(())
}
