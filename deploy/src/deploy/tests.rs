//! Rendering checks: unit contents, per-host split, transport choice, bad scenarios.

use super::*;
use proto::scenario::DEFAULT_SCENARIO_TOML;

/// The default scenario spread over three hosts: server on `pc`, heads on `hub`, cameras on Pis.
fn multi_host(server_listen: &str) -> (Scenario, String) {
    let mut s = Scenario::default_scenario();
    for n in &mut s.nodes {
        match n.role {
            NodeRole::Server => {
                n.host = "pc".into();
                n.listen = Some(server_listen.into());
            }
            NodeRole::Head => {
                n.host = "hub".into();
                n.listen = Some(format!("192.168.1.20:{}", 7400 + n.id));
            }
            NodeRole::Camera | NodeRole::Acoustic => n.host = format!("pi-{}", n.id),
        }
    }
    let text = s.to_toml();
    (s, text)
}

fn file<'a>(plan: &'a Plan, host: &str, rel: &str) -> &'a str {
    let h = plan.hosts.iter().find(|h| h.host == host).expect("host rendered");
    h.files
        .iter()
        .find(|(p, _)| p == Path::new(rel))
        .map(|(_, t)| t.as_str())
        .unwrap_or_else(|| panic!("{host}: no {rel}"))
}

#[test]
fn single_host_uses_ipc_and_one_directory() {
    let s = Scenario::default_scenario();
    let plan = render(&s, DEFAULT_SCENARIO_TOML, &Options::default()).unwrap();
    assert_eq!(plan.transport, TransportKind::Ipc);
    assert_eq!(plan.hosts.len(), 1);
    let unit = file(
        &plan,
        "localhost",
        "rootfs/etc/systemd/system/ocelli-head-2.service",
    );
    assert!(unit.contains(
        "ExecStart=/usr/local/bin/ocelli head --scenario /etc/ocelli/scenario.toml --id 2 --transport ipc\n"
    ));
    // The scenario is copied verbatim.
    assert_eq!(
        file(&plan, "localhost", "rootfs/etc/ocelli/scenario.toml"),
        DEFAULT_SCENARIO_TOML
    );
    // One unit per node.
    let units = plan.hosts[0]
        .files
        .iter()
        .filter(|(p, _)| p.extension().is_some_and(|e| e == "service"))
        .count();
    assert_eq!(units, s.nodes.len());
}

#[test]
fn multi_host_units_use_tcp_and_the_right_settings() {
    let (s, text) = multi_host("192.168.1.10:7400");
    let plan = render(&s, &text, &Options::default()).unwrap();
    assert_eq!(plan.transport, TransportKind::Tcp);
    // pc, hub and one Pi per camera.
    assert_eq!(plan.hosts.len(), 2 + s.cameras().count());

    let server = file(&plan, "pc", "rootfs/etc/systemd/system/ocelli-server-1.service");
    for line in [
        "ExecStart=/usr/local/bin/ocelli server --scenario /etc/ocelli/scenario.toml --id 1 --transport tcp --tls-dir ${CREDENTIALS_DIRECTORY} --record /var/lib/ocelli/default-server-1.ocrec\n",
        "StateDirectory=ocelli\n",
        "WorkingDirectory=/var/lib/ocelli\n",
        "User=ocelli\n",
        "Group=ocelli\n",
        "Restart=on-failure\n",
        "KillSignal=SIGTERM\n",
        "TimeoutStopSec=15s\n",
        "PrivateTmp=yes\n",
        "PrivateDevices=yes\n",
        "RuntimeDirectory=ocelli/server-1\n",
        "LoadCredential=node-1.key:/etc/ocelli/tls/node-1.key\n",
    ] {
        assert!(server.contains(line), "server unit lacks {line:?}:\n{server}");
    }

    let cam = file(
        &plan,
        "pi-10",
        "rootfs/etc/systemd/system/ocelli-camera-10.service",
    );
    assert!(
        cam.contains("--id 10 --transport tcp --tls-dir ${CREDENTIALS_DIRECTORY}\n"),
        "{cam}"
    );
    assert!(!cam.contains("PrivateDevices"), "a camera reads its V4L2 device");
    assert!(cam.contains("WorkingDirectory=/run/ocelli/camera-10\n"));
    assert!(cam.contains("SupplementaryGroups=video\n"));
    assert!(!cam.contains("StateDirectory"), "only the server keeps state");
    assert!(!cam.contains("--record"));

    let nodes = file(&plan, "hub", "nodes.txt");
    assert!(
        nodes.contains("head       2  ocelli-head-2.service  listens on 192.168.1.20:7402"),
        "{nodes}"
    );
    assert!(nodes.contains("head       3"));
    assert!(
        !nodes.contains("camera"),
        "cameras run on the Pis, not the hub:\n{nodes}"
    );

    assert!(file(&plan, "pi-10", "rootfs/usr/lib/sysusers.d/ocelli.conf").contains("m ocelli video"));
    assert!(!file(&plan, "pc", "rootfs/usr/lib/sysusers.d/ocelli.conf").contains("video"));
    assert!(file(&plan, "pc", "rootfs/usr/lib/sysusers.d/ocelli.conf").contains("u ocelli -"));
}

#[test]
fn camera_source_is_passed_to_cameras_only() {
    let (s, text) = multi_host("192.168.1.10:7400");
    let opts = Options {
        camera_source: "v4l2:/dev/video0".into(),
    };
    let plan = render(&s, &text, &opts).unwrap();
    let cam = file(
        &plan,
        "pi-11",
        "rootfs/etc/systemd/system/ocelli-camera-11.service",
    );
    assert!(
        cam.contains("--tls-dir ${CREDENTIALS_DIRECTORY} --source v4l2:/dev/video0\n"),
        "{cam}"
    );
    let head = file(&plan, "hub", "rootfs/etc/systemd/system/ocelli-head-2.service");
    assert!(!head.contains("--source"));
}

#[test]
fn loopback_listen_across_hosts_is_refused_naming_the_node() {
    for addr in ["127.0.0.1:7400", "localhost:7400", "0.0.0.0:7400", "[::1]:7400"] {
        let (s, text) = multi_host(addr);
        let err = render(&s, &text, &Options::default()).unwrap_err();
        assert!(
            matches!(err, DeployError::LocalOnly { id: 1, .. }),
            "{addr}: {err:?}"
        );
        assert!(err.to_string().contains("node 1 (server)"), "{err}");
    }
}

#[test]
fn missing_or_malformed_listen_across_hosts_is_refused() {
    let (mut s, text) = multi_host("192.168.1.10:7400");
    s.nodes.iter_mut().find(|n| n.id == 3).unwrap().listen = None;
    assert_eq!(
        render(&s, &text, &Options::default()).unwrap_err(),
        DeployError::NoListen { id: 3, role: "head" }
    );
    let (s, text) = multi_host("192.168.1.10");
    assert!(matches!(
        render(&s, &text, &Options::default()).unwrap_err(),
        DeployError::BadListen { id: 1, .. }
    ));
}

#[test]
fn host_names_that_are_not_plain_names_are_refused() {
    let (mut s, text) = multi_host("192.168.1.10:7400");
    s.nodes.iter_mut().find(|n| n.id == 12).unwrap().host = "../etc".into();
    assert!(matches!(
        render(&s, &text, &Options::default()).unwrap_err(),
        DeployError::BadHost { id: 12, .. }
    ));
}

#[test]
fn written_plan_lands_under_host_directories() {
    let (s, text) = multi_host("192.168.1.10:7400");
    let plan = render(&s, &text, &Options::default()).unwrap();
    let out = std::env::temp_dir().join(format!("ocelli-deploy-test-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    write_plan(&plan, &out).unwrap();
    let unit =
        std::fs::read_to_string(out.join("pc/rootfs/etc/systemd/system/ocelli-server-1.service")).unwrap();
    assert!(unit.contains("--record /var/lib/ocelli/"));
    assert!(out.join("pi-20/nodes.txt").exists() || s.node(20).is_none());
    assert!(out.join("hub/rootfs/etc/ocelli/scenario.toml").exists());
    // The units point at the installed copy of nodes.txt.
    assert!(out.join("hub/rootfs/etc/ocelli/nodes.txt").exists());
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn every_unit_is_sandboxed_and_restarts_within_limits() {
    for (s, text) in [
        (Scenario::default_scenario(), DEFAULT_SCENARIO_TOML.to_string()),
        multi_host("192.168.1.10:7400"),
    ] {
        let plan = render(&s, &text, &Options::default()).unwrap();
        for host in &plan.hosts {
            for (path, unit) in host
                .files
                .iter()
                .filter(|(p, _)| p.extension().is_some_and(|e| e == "service"))
            {
                for line in [
                    "NoNewPrivileges=yes\n",
                    "ProtectSystem=strict\n",
                    "ProtectHome=yes\n",
                    "CapabilityBoundingSet=\n",
                    "UMask=0027\n",
                    "RestrictSUIDSGID=yes\n",
                    "SystemCallFilter=@system-service\n",
                    "Restart=on-failure\n",
                    "StartLimitIntervalSec=300\n",
                    "StartLimitBurst=5\n",
                ] {
                    assert!(
                        unit.contains(line),
                        "{}: {line:?} missing:\n{unit}",
                        path.display()
                    );
                }
                assert!(!unit.contains("Restart=always"), "{unit}");
                // The sandbox is in [Service], the start limit in [Unit].
                let service = unit.find("[Service]").unwrap();
                assert!(unit.find("StartLimitBurst").unwrap() < service);
                assert!(unit.find("ProtectSystem").unwrap() > service);
            }
        }
    }
    // On one host (iceoryx2) the shared /tmp stays writable and shared.
    let plan = render(
        &Scenario::default_scenario(),
        DEFAULT_SCENARIO_TOML,
        &Options::default(),
    )
    .unwrap();
    let head = file(
        &plan,
        "localhost",
        "rootfs/etc/systemd/system/ocelli-head-2.service",
    );
    assert!(
        head.contains("PrivateTmp=no\nReadWritePaths=/tmp\n") && !head.contains("LoadCredential"),
        "{head}"
    );
    let server = file(
        &plan,
        "localhost",
        "rootfs/etc/systemd/system/ocelli-server-1.service",
    );
    assert!(
        server.contains("StateDirectory=ocelli\nStateDirectoryMode=0750\n"),
        "{server}"
    );
}

#[test]
fn an_insecure_multi_host_scenario_gets_no_certificates_and_says_so() {
    let (mut s, _) = multi_host("192.168.1.10:7400");
    s.network.insecure = true;
    let text = s.to_toml();
    let plan = render(&s, &text, &Options::default()).unwrap();
    let unit = file(&plan, "pc", "rootfs/etc/systemd/system/ocelli-server-1.service");
    assert!(!unit.contains("--tls-dir") && unit.contains("INSECURE"), "{unit}");
    assert!(file(&plan, "pc", "nodes.txt").contains("INSECURE"));
}

#[test]
fn certificates_go_to_their_hosts_only_and_a_second_deploy_keeps_the_ca() {
    use runtime::transport::Tls;
    use std::os::unix::fs::PermissionsExt;
    let (s, text) = multi_host("192.168.1.10:7400");
    let plan = render(&s, &text, &Options::default()).unwrap();
    let out = std::env::temp_dir().join(format!("ocelli-deploy-certs-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    write_plan(&plan, &out).unwrap();
    let first = certs::issue(&s, &plan, &out).unwrap();
    assert_eq!((first.certificates, first.reused_ca), (s.nodes.len(), false));
    let tls = |host: &str| out.join(host).join("rootfs/etc/ocelli/tls");
    assert!(tls("pi-10").join("node-10.key").exists());
    assert!(
        !tls("pi-10").join("node-11.key").exists(),
        "a Pi holds only its own key"
    );
    assert!(tls("hub").join("node-2.pem").exists() && tls("hub").join("node-3.pem").exists());
    for key in [tls("pi-10").join("node-10.key"), out.join("ca/ca.key")] {
        let mode = std::fs::metadata(&key).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o600, "{}", key.display());
    }
    assert!(
        !tls("pc").join("ca.key").exists(),
        "the CA key stays off the hosts"
    );
    let ca_before = std::fs::read_to_string(out.join("ca/ca.pem")).unwrap();
    // Deploy again: the same CA signs, so a new node certificate works with the old ca.pem.
    let again = certs::issue(&s, &plan, &out).unwrap();
    assert!(again.reused_ca);
    assert_eq!(std::fs::read_to_string(out.join("ca/ca.pem")).unwrap(), ca_before);
    assert!(Tls::load(&tls("pi-10"), proto::NodeId(10)).is_ok());
    let _ = std::fs::remove_dir_all(&out);
}
