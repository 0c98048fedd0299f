//! `ocelli deploy`: turn one scenario into per-host configuration — the scenario file, a
//! `nodes.txt` saying what runs on the host, one systemd unit per node and a `sysusers.d`
//! snippet for the `ocelli` user. Rendering is pure (strings in, files as strings out) so it is
//! unit-tested; [`write_plan`] puts the files on disk.
//!
//! Transport: a node process speaks one transport to every peer, and a head talks to its
//! cameras *and* the server. So a deployment on a single host uses iceoryx2 (`ipc`, shared
//! memory); as soon as the scenario names two hosts every node uses TCP (peers on one host then
//! talk over the loopback, which costs a little latency but needs no bridge between transports).
//! TCP links are mutual TLS: [`certs::issue`] makes the cluster's CA (kept in the output's
//! `ca/`, never installed) and gives each host its own nodes' certificates, which the units
//! hand to their service with `LoadCredential=`. Every unit is sandboxed (no privileges, a
//! read-only system but for the recording's directory) and restarts after a crash only,
//! within a start limit.

pub mod certs;
mod units;

use proto::scenario::{NodeRole, NodeSpec, Scenario, TransportKind};
use std::collections::BTreeMap;
use std::net::IpAddr;
use std::path::{Path, PathBuf};
use thiserror::Error;

pub use units::{TLS_DIR, unit_name, uses_tls};

/// Where the binary and the scenario live on a target host.
pub const BINARY: &str = "/usr/local/bin/ocelli";
pub const SCENARIO_PATH: &str = "/etc/ocelli/scenario.toml";
/// The server's recording directory (systemd `StateDirectory=ocelli`).
pub const STATE_DIR: &str = "/var/lib/ocelli";

/// A scenario that cannot be deployed as written.
#[derive(Debug, Error, PartialEq)]
pub enum DeployError {
    #[error(
        "node {id} ({role}): no `listen` address, but cameras or heads on other hosts must reach it over TCP"
    )]
    NoListen { id: u32, role: &'static str },
    #[error("node {id} ({role}): listen address {addr:?} is not `host:port`")]
    BadListen {
        id: u32,
        role: &'static str,
        addr: String,
    },
    #[error(
        "node {id} ({role}) on host {host:?}: listen address {addr:?} is only reachable from its own host; the scenario spans hosts {hosts:?}, so give it an address the other hosts can reach"
    )]
    LocalOnly {
        id: u32,
        role: &'static str,
        host: String,
        addr: String,
        hosts: Vec<String>,
    },
    #[error("node {id}: host name {host:?} cannot be a directory name (letters, digits, '.', '-', '_' only)")]
    BadHost { id: u32, host: String },
    #[error(
        "node {id}: uses OpenCV calibration files, which `ocelli deploy` does not copy; inline the intrinsics and pose in the scenario"
    )]
    CalibrationFiles { id: u32 },
}

/// What to render.
#[derive(Clone, Debug)]
pub struct Options {
    /// `--source` for camera units (`synthetic` adds nothing to the command line).
    pub camera_source: String,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            camera_source: "synthetic".into(),
        }
    }
}

/// The files of one host, paths relative to that host's output directory.
#[derive(Clone, Debug)]
pub struct HostPlan {
    pub host: String,
    pub files: Vec<(PathBuf, String)>,
}

/// Every host's files.
#[derive(Clone, Debug)]
pub struct Plan {
    pub transport: TransportKind,
    pub hosts: Vec<HostPlan>,
}

pub(crate) fn role_name(role: NodeRole) -> &'static str {
    match role {
        NodeRole::Camera => "camera",
        NodeRole::Head => "head",
        NodeRole::Server => "server",
        NodeRole::Acoustic => "acoustic",
    }
}

/// The transport every node of this scenario uses: `ipc` on one host, `tcp` across hosts.
pub fn transport_for(scenario: &Scenario) -> TransportKind {
    if distinct_hosts(scenario).len() > 1 {
        TransportKind::Tcp
    } else {
        TransportKind::Ipc
    }
}

fn distinct_hosts(scenario: &Scenario) -> Vec<String> {
    let mut hosts: Vec<String> = scenario.nodes.iter().map(|n| n.host.clone()).collect();
    hosts.sort();
    hosts.dedup();
    hosts
}

/// Whether an address in `host:port` form is reachable only from the machine itself.
fn local_only(host: &str) -> bool {
    let bare = host.trim_start_matches('[').trim_end_matches(']');
    if bare.eq_ignore_ascii_case("localhost") {
        return true;
    }
    match bare.parse::<IpAddr>() {
        Ok(ip) => ip.is_loopback() || ip.is_unspecified(),
        Err(_) => false, // a DNS name: trust it
    }
}

fn check_node(node: &NodeSpec, hosts: &[String]) -> Result<(), DeployError> {
    let role = role_name(node.role);
    let dir_safe = !node.host.is_empty()
        && node.host != "."
        && node.host != ".."
        && node
            .host
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '.' | '-' | '_'));
    if !dir_safe {
        return Err(DeployError::BadHost {
            id: node.id,
            host: node.host.clone(),
        });
    }
    if let Some(cam) = &node.camera
        && (cam.opencv_intrinsic.is_some() || cam.opencv_extrinsic.is_some())
    {
        return Err(DeployError::CalibrationFiles { id: node.id });
    }
    if node.role == NodeRole::Camera || hosts.len() < 2 {
        return Ok(());
    }
    let addr = node
        .listen
        .as_deref()
        .ok_or(DeployError::NoListen { id: node.id, role })?;
    let (host, port) = addr.rsplit_once(':').ok_or_else(|| DeployError::BadListen {
        id: node.id,
        role,
        addr: addr.into(),
    })?;
    if host.is_empty() || port.parse::<u16>().is_err() {
        return Err(DeployError::BadListen {
            id: node.id,
            role,
            addr: addr.into(),
        });
    }
    if local_only(host) {
        return Err(DeployError::LocalOnly {
            id: node.id,
            role,
            host: node.host.clone(),
            addr: addr.into(),
            hosts: hosts.to_vec(),
        });
    }
    Ok(())
}

/// Render every host's files from a validated scenario and its TOML text (copied verbatim, so
/// the TCP endpoints are exactly the scenario's).
///
/// # Errors
/// A node on a multi-host scenario whose head or server cannot be reached from other hosts, a
/// host name that is not a plain name, or OpenCV calibration files (not copied).
pub fn render(scenario: &Scenario, toml_text: &str, opts: &Options) -> Result<Plan, DeployError> {
    let hosts = distinct_hosts(scenario);
    for node in &scenario.nodes {
        check_node(node, &hosts)?;
    }
    let transport = transport_for(scenario);
    let mut by_host: BTreeMap<&str, Vec<&NodeSpec>> = BTreeMap::new();
    for node in &scenario.nodes {
        by_host.entry(node.host.as_str()).or_default().push(node);
    }
    let plans = by_host
        .into_iter()
        .map(|(host, nodes)| {
            let nodes_txt = units::nodes_txt(scenario, host, &nodes, transport);
            let mut files = vec![
                (PathBuf::from("nodes.txt"), nodes_txt.clone()),
                (PathBuf::from("rootfs/etc/ocelli/nodes.txt"), nodes_txt),
                (
                    PathBuf::from("rootfs/etc/ocelli/scenario.toml"),
                    toml_text.to_string(),
                ),
                (
                    PathBuf::from("rootfs/usr/lib/sysusers.d/ocelli.conf"),
                    units::sysusers(nodes.iter().any(|n| n.role == NodeRole::Camera)),
                ),
            ];
            for node in &nodes {
                files.push((
                    PathBuf::from("rootfs/etc/systemd/system").join(unit_name(node)),
                    units::unit(scenario, node, transport, opts),
                ));
            }
            HostPlan {
                host: host.to_string(),
                files,
            }
        })
        .collect();
    Ok(Plan {
        transport,
        hosts: plans,
    })
}

/// Write a plan under `out/<host>/…`.
///
/// # Errors
/// A directory or file cannot be created.
pub fn write_plan(plan: &Plan, out: &Path) -> std::io::Result<()> {
    for host in &plan.hosts {
        for (rel, text) in &host.files {
            let path = out.join(&host.host).join(rel);
            if let Some(dir) = path.parent() {
                std::fs::create_dir_all(dir)?;
            }
            std::fs::write(&path, text)?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests;
