//! The text of what `ocelli deploy` writes: systemd units, the `sysusers.d` snippet and each
//! host's `nodes.txt`.

use super::{BINARY, Options, SCENARIO_PATH, STATE_DIR, role_name};
use proto::scenario::{NodeRole, NodeSpec, Scenario, TransportKind};
use std::fmt::Write as _;

/// The unit file name of a node: `ocelli-camera-10.service`.
pub fn unit_name(node: &NodeSpec) -> String {
    format!("ocelli-{}-{}.service", role_name(node.role), node.id)
}

fn transport_arg(t: TransportKind) -> &'static str {
    match t {
        TransportKind::Ipc => "ipc",
        TransportKind::Tcp => "tcp",
    }
}

/// The recording path of the server node `id`.
pub fn recording_path(scenario: &Scenario, id: u32) -> String {
    format!("{STATE_DIR}/{}-server-{id}.ocrec", scenario.name)
}

/// Where a host keeps the TLS files of its nodes (root-only; handed to each service by
/// systemd's `LoadCredential=`).
pub const TLS_DIR: &str = "/etc/ocelli/tls";

/// Whether this deployment's nodes speak TLS (TCP, and the scenario does not say insecure).
pub fn uses_tls(scenario: &Scenario, transport: TransportKind) -> bool {
    transport == TransportKind::Tcp && !scenario.network.insecure
}

/// The sandbox every unit gets: no new privileges, no capabilities, a read-only system with
/// only the recording's directory writable (`StateDirectory=`), no access to home
/// directories, kernel settings or other users' processes, native system calls of ordinary
/// services only, and files not readable by others (`UMask=0027`). iceoryx2 shares `/tmp`
/// and `/dev/shm` between the host's Ocelli processes, so over `ipc` the unit keeps the host's
/// `/tmp` (writable) and devices; over TCP it gets a private `/tmp` and, but for cameras
/// (V4L2), no devices.
fn sandbox(node: &NodeSpec, transport: TransportKind) -> String {
    let mut s = String::from(
        "NoNewPrivileges=yes\n\
         CapabilityBoundingSet=\n\
         AmbientCapabilities=\n\
         UMask=0027\n\
         ProtectSystem=strict\n\
         ProtectHome=yes\n\
         ProtectKernelTunables=yes\n\
         ProtectKernelModules=yes\n\
         ProtectKernelLogs=yes\n\
         ProtectControlGroups=yes\n\
         ProtectClock=yes\n\
         ProtectHostname=yes\n\
         ProtectProc=invisible\n\
         RestrictNamespaces=yes\n\
         RestrictRealtime=yes\n\
         RestrictSUIDSGID=yes\n\
         LockPersonality=yes\n\
         MemoryDenyWriteExecute=yes\n\
         RestrictAddressFamilies=AF_INET AF_INET6 AF_UNIX AF_NETLINK\n\
         SystemCallArchitectures=native\n\
         SystemCallFilter=@system-service\n\
         SystemCallFilter=~@privileged\n",
    );
    match transport {
        TransportKind::Ipc => s.push_str(
            "# iceoryx2 needs the host's /tmp and /dev/shm, not a private copy.\n\
             PrivateTmp=no\n\
             ReadWritePaths=/tmp\n\
             RemoveIPC=no\n",
        ),
        TransportKind::Tcp => {
            s.push_str("PrivateTmp=yes\nRemoveIPC=yes\n");
            if node.role != NodeRole::Camera {
                s.push_str("PrivateDevices=yes\n");
            }
        }
    }
    s
}

/// `LoadCredential=` lines handing node `id` its TLS files (readable by root only on the
/// host; systemd gives the service a private copy in `$CREDENTIALS_DIRECTORY`).
fn credentials(id: u32) -> String {
    format!(
        "LoadCredential=ca.pem:{TLS_DIR}/ca.pem\n\
         LoadCredential=node-{id}.pem:{TLS_DIR}/node-{id}.pem\n\
         LoadCredential=node-{id}.key:{TLS_DIR}/node-{id}.key\n"
    )
}

/// One node's systemd unit.
pub fn unit(scenario: &Scenario, node: &NodeSpec, transport: TransportKind, opts: &Options) -> String {
    let role = role_name(node.role);
    let name = format!("{role}-{}", node.id);
    let tls = uses_tls(scenario, transport);
    let mut exec = format!(
        "{BINARY} {role} --scenario {SCENARIO_PATH} --id {} --transport {}",
        node.id,
        transport_arg(transport)
    );
    if tls {
        exec.push_str(" --tls-dir ${CREDENTIALS_DIRECTORY}");
    }
    match node.role {
        NodeRole::Server => {
            let _ = write!(exec, " --record {}", recording_path(scenario, node.id));
        }
        NodeRole::Camera if opts.camera_source != "synthetic" => {
            let _ = write!(exec, " --source {}", opts.camera_source);
        }
        _ => {}
    }
    // The server keeps its recording in /var/lib/ocelli and runs there; the others run in
    // their own runtime directory.
    let (state, workdir) = if node.role == NodeRole::Server {
        (
            "StateDirectory=ocelli\nStateDirectoryMode=0750\n",
            STATE_DIR.to_string(),
        )
    } else {
        ("", format!("/run/ocelli/{name}"))
    };
    let groups = if node.role == NodeRole::Camera {
        "SupplementaryGroups=video\n"
    } else {
        ""
    };
    let creds = if tls {
        format!(
            "# Mutual TLS: this node's certificate and key, and the cluster's CA.\n{}",
            credentials(node.id)
        )
    } else if transport == TransportKind::Tcp {
        "# INSECURE: the scenario says `insecure = true`: plain TCP, no certificates.\n".to_string()
    } else {
        String::new()
    };
    format!(
        "# Generated by `ocelli deploy` from scenario {scenario:?}; see /etc/ocelli/nodes.txt.\n\
         [Unit]\n\
         Description=Ocelli {role} node {id} (scenario {scenario})\n\
         Wants=network-online.target time-sync.target\n\
         After=network-online.target time-sync.target\n\
         # At most 5 automatic restarts in 5 minutes, then the unit stays failed for an operator:\n\
         # a node that keeps crashing is not restarted forever over its recording.\n\
         StartLimitIntervalSec=300\n\
         StartLimitBurst=5\n\
         \n\
         [Service]\n\
         Type=exec\n\
         # One system user per host: iceoryx2's shared memory (/dev/shm, /tmp/iceoryx2) is then\n\
         # readable by every Ocelli process on the host.\n\
         User=ocelli\n\
         Group=ocelli\n\
         {groups}\
         RuntimeDirectory=ocelli/{name}\n\
         {state}\
         WorkingDirectory={workdir}\n\
         {creds}\
         # Sandbox.\n\
         {sandbox}\
         Environment=RUST_LOG=info\n\
         # Rejections are logged rate-limited by the node; journald limits what remains.\n\
         LogRateLimitIntervalSec=30s\n\
         LogRateLimitBurst=1000\n\
         ExecStart={exec}\n\
         # Restarted after a crash only (a clean stop stays stopped), after 2 s, within the\n\
         # start limit above. The server resumes its recording: damage is skipped, never cut.\n\
         Restart=on-failure\n\
         RestartSec=2s\n\
         # Ocelli nodes stop cleanly on SIGTERM (the server flushes its recording).\n\
         KillSignal=SIGTERM\n\
         TimeoutStopSec=15s\n\
         \n\
         [Install]\n\
         WantedBy=multi-user.target\n",
        scenario = scenario.name,
        id = node.id,
        sandbox = sandbox(node, transport),
    )
}

/// The `sysusers.d` snippet creating the `ocelli` system user (in `video` where cameras run).
pub fn sysusers(cameras: bool) -> String {
    let mut s = String::from(
        "# Generated by `ocelli deploy`: the system user every Ocelli node on this host runs as.\n\
         u ocelli - \"Ocelli camera network\" /var/lib/ocelli\n",
    );
    if cameras {
        s.push_str("# Camera nodes read V4L2 devices.\nm ocelli video\n");
    }
    s
}

/// The host's `nodes.txt`: what runs here and how to install it.
pub fn nodes_txt(scenario: &Scenario, host: &str, nodes: &[&NodeSpec], transport: TransportKind) -> String {
    let mut s = format!(
        "Ocelli deployment of scenario {:?} on host {host}\ntransport: {}\n\nnodes:\n",
        scenario.name,
        transport_arg(transport)
    );
    for n in nodes {
        let mut line = format!("  {:<7} {:>4}  {}", role_name(n.role), n.id, unit_name(n));
        if let Some(h) = n.head {
            let _ = write!(line, "  reports to head {h}");
        }
        if matches!(n.role, NodeRole::Head | NodeRole::Server)
            && let Some(l) = &n.listen
        {
            let _ = write!(line, "  listens on {l}");
        }
        s.push_str(&line);
        s.push('\n');
    }
    let units: Vec<String> = nodes.iter().map(|n| unit_name(n)).collect();
    let tls_step = if uses_tls(scenario, transport) {
        format!(" && chown -R root:root {TLS_DIR} && chmod 0700 {TLS_DIR} && chmod 0600 {TLS_DIR}/*.key")
    } else {
        String::new()
    };
    let _ = write!(
        s,
        "\ninstall (as root on {host}, with {BINARY} in place):\n\
         \x20 scp -rp rootfs/. root@{host}:/\n\
         \x20 ssh root@{host} 'systemd-sysusers{tls_step} && systemctl daemon-reload && systemctl enable --now {}'\n",
        units.join(" ")
    );
    if uses_tls(scenario, transport) {
        let _ = write!(
            s,
            "\nTLS: {TLS_DIR} holds the cluster's CA certificate and this host's node certificates and\n\
             keys (root only; each unit gets its own via LoadCredential=). The CA's private key stays\n\
             in the deploy output's ca/ directory, not on any node.\n"
        );
    } else if transport == TransportKind::Tcp {
        s.push_str("\nINSECURE: the scenario says `insecure = true`: nodes talk plain TCP; anyone on the\nnetwork can pose as any node.\n");
    }
    s
}
