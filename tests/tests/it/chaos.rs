//! Chaos soak: `ocelli launch` runs the default scenario while random nodes — cameras, heads,
//! the server — are killed (`SIGKILL`) at random times and started again with the same command
//! line, over iceoryx2 and over TCP (mutual TLS). Afterwards every record of the recording is
//! valid, nothing the server recorded before a crash is lost, tracking recovers within a few
//! seconds of each kill, and the nodes' memory, file descriptors and `/dev/shm` files have not
//! grown.
//!
//! The restarts are this harness's: the launch runs with `--no-restart`, so its supervisor
//! leaves a killed node down and the harness starts it again with the same command line. CI runs a short soak; `OCELLI_CHAOS_SECONDS=600` gives the figures of the note
//! (printed as one `chaos …` JSON line per transport, `--no-capture` to see it);
//! `OCELLI_CHAOS_SEED` picks the victims and times.

use crate::cluster::{Launch, f, median, robot_error};
use crate::harness::{cluster_now_s, now, owner_rows, signal};
use serde_json::{Value, json};
use std::collections::BTreeMap;
use std::ffi::OsString;
use std::os::unix::ffi::OsStringExt;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

/// Soak length unless `OCELLI_CHAOS_SECONDS` says otherwise.
const CI_SECONDS: f64 = 60.0;
/// Time from start before the first kill and the baseline measurement: every node up and the
/// robot tracked.
const WARM_UP_S: f64 = 10.0;
/// A kill is recovered from when the robot is estimated within this of the truth again.
const RECOVERED_ERROR_M: f64 = 0.5;
/// ... within this many seconds of the kill.
const RECOVERY_BOUND_S: f64 = 5.0;

fn env_or<T: std::str::FromStr>(name: &str, default: T) -> T {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// splitmix64: seeded, no dependency.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }

    fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[(self.next() % items.len() as u64) as usize]
    }
}

/// How to start a node process again: what the running one was started with.
struct Recipe {
    argv: Vec<OsString>,
    env: Vec<(OsString, OsString)>,
    cwd: PathBuf,
}

fn nul_separated(bytes: Vec<u8>) -> Vec<OsString> {
    bytes
        .split(|b| *b == 0)
        .filter(|s| !s.is_empty())
        .map(|s| OsString::from_vec(s.to_vec()))
        .collect()
}

fn recipe(pid: u32) -> Recipe {
    let proc = PathBuf::from(format!("/proc/{pid}"));
    let argv = nul_separated(std::fs::read(proc.join("cmdline")).expect("cmdline"));
    let env = nul_separated(std::fs::read(proc.join("environ")).expect("environ"))
        .into_iter()
        .filter_map(|kv| {
            let kv = kv.into_vec();
            let eq = kv.iter().position(|b| *b == b'=')?;
            Some((
                OsString::from_vec(kv[..eq].to_vec()),
                OsString::from_vec(kv[eq + 1..].to_vec()),
            ))
        })
        .collect();
    let cwd = std::fs::read_link(proc.join("cwd")).expect("cwd");
    assert!(!argv.is_empty(), "process {pid} has no command line");
    Recipe { argv, env, cwd }
}

/// What the nodes hold: resident memory, open descriptors, the domain's shared-memory files.
#[derive(Clone, Debug)]
struct Usage {
    rss_kib: u64,
    fds: usize,
    shm_files: usize,
    shm_names: std::collections::BTreeSet<String>,
}

fn usage(pids: &[u32], domain: &str) -> Usage {
    let rss_kib = pids
        .iter()
        .filter_map(|p| std::fs::read_to_string(format!("/proc/{p}/status")).ok())
        .filter_map(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix("VmRSS:"))
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
        })
        .sum();
    let fds = pids
        .iter()
        .filter_map(|p| std::fs::read_dir(format!("/proc/{p}/fd")).ok())
        .map(Iterator::count)
        .sum();
    let prefix = format!("iox2_{domain}_");
    let shm_names: std::collections::BTreeSet<String> = std::fs::read_dir("/dev/shm")
        .map(|d| {
            d.flatten()
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .filter(|n| n.starts_with(&prefix))
                .collect()
        })
        .unwrap_or_default();
    Usage {
        rss_kib,
        fds,
        shm_files: shm_names.len(),
        shm_names,
    }
}

fn sleep_s(s: f64) {
    std::thread::sleep(Duration::from_secs_f64(s));
}

/// One kill: who, when (cluster seconds) and, for the server, what it had recorded.
struct Kill {
    node: String,
    at: f64,
    recorded: Option<Vec<node_server::record::Stamped>>,
}

fn chaos(transport: &str) {
    let seconds: f64 = env_or("OCELLI_CHAOS_SECONDS", CI_SECONDS);
    let mut rng = Rng(env_or("OCELLI_CHAOS_SEED", 1));
    let run = Launch::start_with(
        &format!("chaos-{transport}"),
        transport,
        seconds,
        None,
        &["--no-restart"],
    );
    let started = now();
    let mut pids: BTreeMap<String, u32> = ["server-1", "head-2", "head-3"]
        .into_iter()
        .map(|n| (n.to_string(), run.pid_of(n)))
        .collect();
    let text = std::fs::read_to_string(run.run_dir().join("pids")).expect("pids");
    for (name, pid) in text.lines().filter_map(|l| l.split_once(' ')) {
        pids.insert(name.to_string(), pid.parse().expect("pid"));
    }
    let cameras: Vec<String> = pids
        .keys()
        .filter(|n| n.starts_with("camera-"))
        .cloned()
        .collect();
    sleep_s(WARM_UP_S);
    let live = |pids: &BTreeMap<String, u32>| pids.values().copied().collect::<Vec<_>>();
    let before = usage(&live(&pids), &run.domain);
    // Ours: the nodes this harness started again, by name.
    let mut ours: BTreeMap<String, Child> = BTreeMap::new();
    let mut kills: Vec<Kill> = Vec::new();
    // Stop killing early enough that the last kill is recovered from and our restarted nodes
    // are stopped before the launch stops its own.
    let stop_at = Duration::from_secs_f64((seconds - RECOVERY_BOUND_S - 3.0).max(WARM_UP_S));
    loop {
        let gap = rng.uniform(2.0, 5.0);
        if started.elapsed() + Duration::from_secs_f64(gap) >= stop_at {
            break;
        }
        sleep_s(gap);
        let draw = rng.uniform(0.0, 1.0);
        let victim = if draw < 0.2 {
            "server-1".to_string()
        } else if draw < 0.5 {
            rng.pick(&["head-2", "head-3"]).to_string()
        } else {
            rng.pick(&cameras).clone()
        };
        let pid = pids[&victim];
        let how = recipe(pid);
        signal(pid, libc::SIGKILL);
        let at = cluster_now_s();
        if let Some(mut child) = ours.remove(&victim) {
            let _ = child.wait();
        }
        sleep_s(0.2);
        let recorded = (victim == "server-1").then(|| {
            node_server::recording::read_all(&run.record())
                .expect("the recording at the crash")
                .records
        });
        kills.push(Kill {
            node: victim.clone(),
            at,
            recorded,
        });
        sleep_s(rng.uniform(0.3, 1.3));
        let log = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(run.run_dir().join(format!("{victim}.log")))
            .expect("node log");
        let child = Command::new(&how.argv[0])
            .args(&how.argv[1..])
            .env_clear()
            .envs(how.env)
            .current_dir(how.cwd)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(log)
            .spawn()
            .expect("restarting a node");
        pids.insert(victim.clone(), child.id());
        ours.insert(victim, child);
    }
    sleep_s(RECOVERY_BOUND_S);
    let after = usage(&live(&pids), &run.domain);
    for (_, mut child) in ours {
        signal(child.id(), libc::SIGTERM);
        let _ = child.wait();
    }
    let (_report, run) = run.finish(Duration::from_secs_f64(seconds + 90.0));

    // Every record valid; everything recorded before each server crash still there.
    let final_read = node_server::recording::read_all(&run.record()).expect("the recording");
    assert!(
        final_read.skipped.is_empty(),
        "{transport}: damaged stretches in the recording: {:?}",
        final_read.skipped
    );
    for k in &kills {
        if let Some(rec) = &k.recorded {
            assert!(
                final_read.records.len() >= rec.len() && final_read.records[..rec.len()] == rec[..],
                "{transport}: records from before the server crash at {:.1} s were lost or changed",
                k.at
            );
        }
    }
    // Tracking recovers after each kill.
    let error_of = robot_error(&run);
    let rows = owner_rows(&run.record());
    let recovery: Vec<(String, f64)> = kills
        .iter()
        .map(|k| {
            let back = rows
                .iter()
                .filter(|r| f(r, "t") > k.at + 0.3)
                .find(|r| error_of(r) < RECOVERED_ERROR_M)
                .map_or(f64::INFINITY, |r| f(r, "t") - k.at);
            (k.node.clone(), back)
        })
        .collect();
    let worst = recovery.iter().map(|(_, s)| *s).fold(0.0, f64::max);
    let by_role = |prefix: &str| -> Value {
        let v: Vec<f64> = recovery
            .iter()
            .filter(|(n, _)| n.starts_with(prefix))
            .map(|(_, s)| *s)
            .collect();
        json!({"kills": v.len(), "median_s": median(v.clone()), "max_s": v.iter().copied().fold(0.0, f64::max)})
    };
    let summary = json!({
        "transport": transport,
        "seconds": seconds,
        "kills": kills.len(),
        "recovery": {"camera": by_role("camera-"), "head": by_role("head-"), "server": by_role("server-")},
        "records": final_read.records.len(),
        "skipped": final_read.skipped.len(),
        "rss_kib": [before.rss_kib, after.rss_kib],
        "fds": [before.fds, after.fds],
        "shm_files": [before.shm_files, after.shm_files],
        "shm_new": after.shm_names.difference(&before.shm_names).take(12).collect::<Vec<_>>(),
    });
    eprintln!("chaos {summary}");
    assert!(
        kills.iter().any(|k| k.node == "server-1") || seconds < 30.0,
        "no server kill in {seconds} s: {summary}"
    );
    assert!(
        worst <= RECOVERY_BOUND_S,
        "{transport}: tracking not recovered within {RECOVERY_BOUND_S} s of a kill: {recovery:?}"
    );
    // Nothing grows with the kills: descriptors and shared-memory files within a quarter of
    // what the cluster held before, memory at most half again (restarted nodes start small, the
    // server's state grows with the run). Measured over iceoryx2 (seed 1): 9 kills in 60 s,
    // descriptors 1633 -> 1801 and /dev/shm files 249 -> 277; 129 kills in 600 s, 1633 -> 1945
    // and 249 -> 301 (the new files are data segments of restarted publishers, not cleaned
    // until a node of the domain starts): more than before, but not in proportion to the
    // kills. Over TCP: 356 -> 376 and 356 -> 396 descriptors, no shared memory.
    assert!(
        after.fds <= before.fds + before.fds / 4 + 8,
        "{transport}: descriptors grew: {summary}"
    );
    assert!(
        after.shm_files <= before.shm_files + before.shm_files / 4 + 4,
        "{transport}: /dev/shm files grew: {summary}"
    );
    assert!(
        after.rss_kib <= before.rss_kib + before.rss_kib / 2,
        "{transport}: memory grew: {summary}"
    );
    run.assert_clean();
}

#[test]
fn chaos_soak_over_ipc_loses_nothing_and_recovers() {
    chaos("ipc");
}

#[test]
fn chaos_soak_over_tcp_loses_nothing_and_recovers() {
    chaos("tcp");
}
