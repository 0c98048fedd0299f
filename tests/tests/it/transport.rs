//! Two real processes exchange messages over iceoryx2 and over TCP (`ocelli peer`): delivery
//! in order, a restarted peer is survived, malformed and oversized frames are rejected with a
//! clear error while the receiver keeps running, and no `/dev/shm` file of the test's domain
//! is left behind.

use crate::harness::now;
use serde_json::Value;
use std::io::{BufRead, BufReader};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, channel};
use std::sync::{Arc, Mutex};
use std::time::Duration;

const WAIT: Duration = Duration::from_secs(15);

/// A running `ocelli peer`; killed and reaped on drop.
struct Peer {
    name: String,
    child: Option<Child>,
    lines: Receiver<Value>,
    seen: Vec<Value>,
    stderr: Arc<Mutex<Vec<String>>>,
}

impl Peer {
    fn spawn(name: &str, args: &[&str]) -> Peer {
        let mut child = Command::new(crate::harness::EXE)
            .arg("peer")
            .args(args)
            .env("RUST_LOG", "warn")
            .env("NO_COLOR", "1")
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("spawning ocelli peer");
        let (tx, lines) = channel();
        let out = child.stdout.take().expect("stdout");
        std::thread::spawn(move || {
            for line in BufReader::new(out).lines().map_while(Result::ok) {
                match serde_json::from_str::<Value>(&line) {
                    Ok(v) => {
                        if tx.send(v).is_err() {
                            return;
                        }
                    }
                    Err(e) => panic!("peer printed a non-JSON line {line:?}: {e}"),
                }
            }
        });
        let stderr = Arc::new(Mutex::new(Vec::new()));
        let err = child.stderr.take().expect("stderr");
        let sink = stderr.clone();
        std::thread::spawn(move || {
            for line in BufReader::new(err).lines().map_while(Result::ok) {
                sink.lock().unwrap().push(line);
            }
        });
        Peer {
            name: name.into(),
            child: Some(child),
            lines,
            seen: Vec::new(),
            stderr,
        }
    }

    fn stderr(&self) -> String {
        self.stderr.lock().unwrap().join("\n")
    }

    /// Wait for a line matching `pred`; panics (with what was seen) after [`WAIT`].
    fn wait_for(&mut self, what: &str, pred: impl Fn(&Value) -> bool) -> Value {
        let deadline = now() + WAIT;
        loop {
            let left = deadline.saturating_duration_since(now());
            match self.lines.recv_timeout(left) {
                Ok(v) => {
                    self.seen.push(v.clone());
                    if pred(&v) {
                        return v;
                    }
                }
                Err(RecvTimeoutError::Timeout) | Err(RecvTimeoutError::Disconnected) => panic!(
                    "{}: no {what} within {WAIT:?}; last lines: {:?}\nstderr:\n{}",
                    self.name,
                    self.seen.iter().rev().take(5).collect::<Vec<_>>(),
                    self.stderr()
                ),
            }
        }
    }

    fn ready(&mut self) -> Value {
        self.wait_for("ready line", |v| v["event"] == "ready")
    }

    /// Rounds of beacons received from `from`, in arrival order, until `n` were seen.
    fn rounds_from(&mut self, from: u64, n: usize) -> Vec<u64> {
        let mut got = Vec::new();
        while got.len() < n {
            let v = self.wait_for("beacon", |v| v["event"] == "message" && v["from"] == from);
            got.push(v["round"].as_u64().expect("round"));
        }
        got
    }

    /// The latest stats line that satisfies `pred`.
    fn stats_where(&mut self, what: &str, pred: impl Fn(&Value) -> bool) -> Value {
        if let Some(v) = self.seen.iter().rev().find(|v| v["event"] == "stats" && pred(v)) {
            return v.clone();
        }
        self.wait_for(what, |v| v["event"] == "stats" && pred(v))
    }

    fn pid(&self) -> i32 {
        self.child.as_ref().expect("running").id() as i32
    }

    fn signal(&self, sig: i32) {
        assert!(send_signal(self.pid(), sig), "{}: kill failed", self.name);
    }

    fn wait_exit(&mut self) -> ExitStatus {
        let mut child = self.child.take().expect("running");
        let deadline = now() + WAIT;
        loop {
            if let Some(status) = child.try_wait().expect("try_wait") {
                // Drain what it printed last.
                while let Ok(v) = self.lines.recv_timeout(Duration::from_millis(200)) {
                    self.seen.push(v);
                }
                return status;
            }
            if now() > deadline {
                let _ = child.kill();
                let _ = child.wait();
                panic!(
                    "{}: did not exit within {WAIT:?}\nstderr:\n{}",
                    self.name,
                    self.stderr()
                );
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// SIGTERM and wait: a clean stop.
    fn stop(&mut self) -> ExitStatus {
        self.signal(libc::SIGTERM);
        self.wait_exit()
    }

    /// SIGKILL and reap: a crash.
    fn crash(&mut self) {
        self.signal(libc::SIGKILL);
        let _ = self.wait_exit();
    }
}

impl Drop for Peer {
    fn drop(&mut self) {
        if let Some(mut c) = self.child.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// Signal a child. `libc::kill` needs `unsafe`, which the workspace denies, so this goes
/// through the `kill` utility.
fn send_signal(pid: i32, sig: i32) -> bool {
    Command::new("kill")
        .arg(format!("-{sig}"))
        .arg(pid.to_string())
        .status()
        .expect("running kill")
        .success()
}

static NEXT: AtomicU32 = AtomicU32::new(0);

/// A domain no other test (or test run) uses.
fn domain() -> String {
    format!(
        "it-{}-{}",
        std::process::id(),
        NEXT.fetch_add(1, Ordering::Relaxed)
    )
}

/// Files in `/dev/shm` that belong to `domain` (iceoryx2 prefixes them `iox2_{domain}_`).
fn shm_files(domain: &str) -> Vec<String> {
    let prefix = format!("iox2_{domain}_");
    std::fs::read_dir("/dev/shm")
        .expect("/dev/shm must exist")
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with(&prefix))
        .collect()
}

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

fn assert_in_order(rounds: &[u64], from: u64) {
    let expected: Vec<u64> = (from..from + rounds.len() as u64).collect();
    assert_eq!(rounds, expected.as_slice(), "beacons out of order or missing");
}

fn assert_rejections(receiver: &mut Peer) {
    let s = receiver.stats_where("rejection counters", |v| {
        v["rejected_malformed"].as_u64() >= Some(1)
            && v["rejected_oversized"].as_u64() >= Some(1)
            && v["rejected_version"].as_u64() >= Some(1)
    });
    assert_eq!(s["rejected_malformed"], 1, "{s}");
    assert_eq!(s["rejected_oversized"], 1, "{s}");
    assert_eq!(s["rejected_version"], 1, "{s}");
    // The log is read by another thread than the stats line: give it the same patience.
    let deadline = now() + WAIT;
    let wanted = [
        "frame rejected",
        "exceeds the maximum",
        "malformed frame",
        "protocol version 9",
    ];
    while !wanted.iter().all(|w| receiver.stderr().contains(w)) && now() < deadline {
        std::thread::sleep(Duration::from_millis(20));
    }
    let log = receiver.stderr();
    assert!(log.contains("frame rejected"), "no warning logged:\n{log}");
    assert!(
        log.contains("exceeds the maximum"),
        "oversized frame not named:\n{log}"
    );
    assert!(
        log.contains("malformed frame"),
        "malformed frame not named:\n{log}"
    );
    assert!(
        log.contains("protocol version 9"),
        "wrong version not named:\n{log}"
    );
}

// ------------------------------------------------------------------ iceoryx2

#[test]
fn ipc_delivers_in_order_and_leaves_no_shared_memory() {
    let d = domain();
    let mut rx = Peer::spawn("receiver", &["--transport", "ipc", "--id", "1", "--domain", &d]);
    rx.ready();
    let mut tx = Peer::spawn(
        "sender",
        &[
            "--transport",
            "ipc",
            "--id",
            "2",
            "--domain",
            &d,
            "--to",
            "1",
            "--send",
            "1000",
            "--linger-ms",
            "200",
        ],
    );
    tx.ready();
    // 1000 back to back overrun the inbox buffer (256): beacons must wait, never drop.
    assert_in_order(&rx.rounds_from(2, 1000), 0);
    assert!(tx.wait_exit().success(), "sender failed:\n{}", tx.stderr());
    assert!(rx.stop().success(), "receiver failed:\n{}", rx.stderr());
    let s = rx.stats_where("final stats", |v| v["received"] == 1000);
    assert_eq!(s["dropped_inbox_full"], 0);
    assert_eq!(shm_files(&d), Vec::<String>::new(), "shared memory left behind");
}

#[test]
fn ipc_rejects_garbage_and_keeps_receiving() {
    let d = domain();
    let mut rx = Peer::spawn("receiver", &["--transport", "ipc", "--id", "1", "--domain", &d]);
    rx.ready();
    let mut tx = Peer::spawn(
        "sender",
        &[
            "--transport",
            "ipc",
            "--id",
            "2",
            "--domain",
            &d,
            "--to",
            "1",
            "--send",
            "20",
            "--inject-garbage",
            "--linger-ms",
            "200",
        ],
    );
    assert_in_order(&rx.rounds_from(2, 20), 0);
    assert_rejections(&mut rx);
    assert!(tx.wait_exit().success());
    assert!(
        rx.stop().success(),
        "receiver did not survive garbage:\n{}",
        rx.stderr()
    );
    assert_eq!(shm_files(&d), Vec::<String>::new(), "shared memory left behind");
}

#[test]
fn ipc_survives_a_receiver_crash_and_restart() {
    let d = domain();
    let rx_args = ["--transport", "ipc", "--id", "1", "--domain", d.as_str()];
    let mut rx = Peer::spawn("receiver", &rx_args);
    rx.ready();
    let mut tx = Peer::spawn(
        "sender",
        &[
            "--transport",
            "ipc",
            "--id",
            "2",
            "--domain",
            &d,
            "--to",
            "1",
            "--send",
            "1000000",
            "--interval-ms",
            "5",
        ],
    );
    rx.rounds_from(2, 5);
    rx.crash();
    let mut rx2 = Peer::spawn("restarted receiver", &rx_args);
    rx2.ready();
    let rounds = rx2.rounds_from(2, 30);
    assert!(
        rounds.windows(2).all(|w| w[1] == w[0] + 1),
        "gap or reorder after restart: {rounds:?}"
    );
    assert!(tx.stop().success(), "sender failed:\n{}", tx.stderr());
    assert!(rx2.stop().success(), "receiver failed:\n{}", rx2.stderr());
    assert_eq!(
        shm_files(&d),
        Vec::<String>::new(),
        "stale or live shared memory left behind"
    );
}

// ------------------------------------------------------------------ TCP

fn listen_addr(ready: &Value) -> String {
    ready["listen"].as_str().expect("listen address").to_string()
}

#[test]
fn tcp_delivers_in_order_both_ways() {
    let mut rx = Peer::spawn(
        "listener",
        &[
            "--transport",
            "tcp",
            "--insecure",
            "--id",
            "1",
            "--listen",
            "127.0.0.1:0",
            "--echo",
        ],
    );
    let addr = listen_addr(&rx.ready());
    let peer = format!("1={addr}");
    let mut tx = Peer::spawn(
        "dialer",
        &[
            "--transport",
            "tcp",
            "--insecure",
            "--id",
            "2",
            "--peer",
            &peer,
            "--to",
            "1",
            "--send",
            "300",
            "--linger-ms",
            "1500",
        ],
    );
    assert_in_order(&rx.rounds_from(2, 300), 0);
    // Echoes travel back over the accepted connection, in order too.
    assert_in_order(&tx.rounds_from(1, 300), 0);
    assert!(tx.wait_exit().success(), "dialer failed:\n{}", tx.stderr());
    rx.wait_for("peer_down", |v| v["event"] == "peer_down" && v["node"] == 2);
    assert!(rx.stop().success());
}

#[test]
fn tcp_rejects_garbage_and_keeps_receiving() {
    let mut rx = Peer::spawn(
        "listener",
        &[
            "--transport",
            "tcp",
            "--insecure",
            "--id",
            "1",
            "--listen",
            "127.0.0.1:0",
        ],
    );
    let peer = format!("1={}", listen_addr(&rx.ready()));
    let mut tx = Peer::spawn(
        "dialer",
        &[
            "--transport",
            "tcp",
            "--insecure",
            "--id",
            "2",
            "--peer",
            &peer,
            "--to",
            "1",
            "--send",
            "20",
            "--inject-garbage",
            "--linger-ms",
            "300",
        ],
    );
    assert_in_order(&rx.rounds_from(2, 20), 0);
    assert_rejections(&mut rx);
    assert!(tx.wait_exit().success());
    // The link stayed up through the garbage: one connection, never lost.
    let s = rx.stats_where("stats", |v| v["received"] == 20);
    assert_eq!(s["peers_up"], 1, "{s}");
    assert!(
        rx.stop().success(),
        "listener did not survive garbage:\n{}",
        rx.stderr()
    );
}

#[test]
fn tcp_dialer_survives_a_listener_crash_and_restart() {
    let listen = format!("127.0.0.1:{}", free_port());
    let rx_args = [
        "--transport",
        "tcp",
        "--insecure",
        "--id",
        "1",
        "--listen",
        listen.as_str(),
    ];
    let mut rx = Peer::spawn("listener", &rx_args);
    rx.ready();
    let peer = format!("1={listen}");
    let mut tx = Peer::spawn(
        "dialer",
        &[
            "--transport",
            "tcp",
            "--insecure",
            "--id",
            "2",
            "--peer",
            &peer,
            "--to",
            "1",
            "--send",
            "1000000",
            "--interval-ms",
            "5",
        ],
    );
    rx.rounds_from(2, 5);
    rx.crash();
    tx.wait_for("peer_down", |v| v["event"] == "peer_down" && v["node"] == 1);
    let mut rx2 = Peer::spawn("restarted listener", &rx_args);
    rx2.ready();
    tx.wait_for("peer_up again", |v| v["event"] == "peer_up" && v["node"] == 1);
    let rounds = rx2.rounds_from(2, 30);
    assert!(
        rounds.windows(2).all(|w| w[1] == w[0] + 1),
        "gap or reorder after restart: {rounds:?}"
    );
    let s = tx.stats_where("reconnect counted", |v| v["reconnects"].as_u64() >= Some(1));
    assert_eq!(s["peers_lost"], 1, "{s}");
    assert!(tx.stop().success());
    assert!(rx2.stop().success());
}

/// Two processes over mutual TLS, each with a certificate of the same CA; a third whose
/// certificate comes from another CA is refused and counted, and gets nothing through.
#[test]
fn tcp_with_tls_delivers_and_refuses_a_certificate_of_another_ca() {
    use proto::{NodeId, Role};
    use runtime::transport::{ClusterCa, TlsFiles};
    let dir = crate::harness::scratch("peer-tls");
    let ca = ClusterCa::generate("e2e").unwrap();
    for id in [1, 2] {
        TlsFiles::in_dir(&dir.join("ours"), NodeId(id))
            .write(ca.cert_pem(), &ca.issue(NodeId(id), Role::Tool).unwrap())
            .unwrap();
    }
    let other = ClusterCa::generate("e2e").unwrap();
    TlsFiles::in_dir(&dir.join("theirs"), NodeId(3))
        .write(other.cert_pem(), &other.issue(NodeId(3), Role::Tool).unwrap())
        .unwrap();
    let ours = dir.join("ours");
    let ours = ours.to_str().unwrap();
    let theirs = dir.join("theirs");
    let theirs = theirs.to_str().unwrap();
    let mut rx = Peer::spawn(
        "listener",
        &[
            "--transport",
            "tcp",
            "--tls-dir",
            ours,
            "--id",
            "1",
            "--listen",
            "127.0.0.1:0",
        ],
    );
    let peer = format!("1={}", listen_addr(&rx.ready()));
    let dialer = |id: &str, tls: &str| {
        vec![
            "--transport".to_string(),
            "tcp".into(),
            "--tls-dir".into(),
            tls.into(),
            "--id".into(),
            id.into(),
            "--peer".into(),
            peer.clone(),
            "--to".into(),
            "1".into(),
            "--send".into(),
            "100".into(),
            "--linger-ms".into(),
            "500".into(),
        ]
    };
    let args = dialer("3", theirs);
    let mut impostor = Peer::spawn("impostor", &args.iter().map(String::as_str).collect::<Vec<_>>());
    let args = dialer("2", ours);
    let mut tx = Peer::spawn("dialer", &args.iter().map(String::as_str).collect::<Vec<_>>());
    assert_in_order(&rx.rounds_from(2, 100), 0);
    assert!(tx.wait_exit().success(), "dialer failed:\n{}", tx.stderr());
    let s = rx.stats_where("the impostor refused", |v| {
        v["rejected_identity"].as_u64() >= Some(1)
    });
    assert_eq!(
        s["peers_up"], 1,
        "only the dialer with our certificate got a link: {s}"
    );
    assert!(
        !rx.seen.iter().any(|v| v["event"] == "message" && v["from"] == 3),
        "a message from the impostor arrived"
    );
    impostor.crash();
    assert!(rx.stop().success());
}
