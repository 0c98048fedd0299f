//! Operating `ocelli launch` as a user and an init system would (issue 20): every stop signal
//! stops every node and prints the report, a launcher killed outright takes its nodes along, a
//! crashed node comes back, every run gets its own private folder, the report of the recording
//! is the launch's, logs are plain text, and a second process for a live node id is refused.
//! A small scenario (a server, a head, four cameras) keeps each launch cheap: these tests are
//! about operations, not tracking quality.

use crate::harness::{EXE, Scratch, alive, now, scratch, signal, wait_exit};
use proto::scenario::{NodeRole, Scenario};
use serde_json::Value;
use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

/// The default scenario cut down to its server, head 2 and four of head 2's cameras.
fn small_scenario(dir: &Path) -> PathBuf {
    let mut s = Scenario::default_scenario();
    s.nodes.retain(|n| matches!(n.id, 1 | 2 | 10..=13));
    for n in &mut s.nodes {
        if n.role == NodeRole::Camera {
            n.head = Some(2);
        }
        n.region = None;
    }
    let path = dir.join("small.toml");
    std::fs::write(&path, s.to_toml()).expect("writing the scenario");
    path
}

/// Wait until `done` or panic after `within`, saying `what`.
fn wait_for(within: Duration, what: &str, mut done: impl FnMut() -> bool) {
    let deadline = now() + within;
    while !done() {
        assert!(now() < deadline, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// A running `ocelli launch` of the small scenario in its own scratch folder (the current
/// directory, so default run folders land there), killed on drop.
struct Run {
    child: Option<Child>,
    dir: Scratch,
}

impl Run {
    fn start(name: &str, extra: &[&str]) -> Run {
        let dir = scratch(&format!("ops-{name}"));
        let scenario = small_scenario(&dir);
        let child = Command::new(EXE)
            .current_dir(&dir)
            .arg("launch")
            .arg("--scenario")
            .arg(&scenario)
            .args(["--json", "--quiet"])
            .args(extra)
            .env("RUST_LOG", "info")
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(std::fs::File::create(dir.join("launch.log")).expect("log"))
            .spawn()
            .expect("spawning ocelli launch");
        Run {
            child: Some(child),
            dir,
        }
    }

    fn pid(&self) -> u32 {
        self.child.as_ref().expect("running").id()
    }

    /// The run's folder: the only one under `ocelli-runs/`, once the launch made it.
    fn run_dir(&self) -> PathBuf {
        let runs = self.dir.join("ocelli-runs");
        let mut found = Vec::new();
        wait_for(Duration::from_secs(20), "the run folder", || {
            found = std::fs::read_dir(&runs)
                .map(|d| d.flatten().map(|e| e.path()).collect())
                .unwrap_or_default();
            found.len() == 1 && found[0].join("pids").exists()
        });
        found.remove(0)
    }

    /// Node name → pid, from the run's `pids` file.
    fn pids(&self) -> Vec<(String, u32)> {
        std::fs::read_to_string(self.run_dir().join("pids"))
            .unwrap_or_default()
            .lines()
            .filter_map(|l| l.split_once(' '))
            .filter_map(|(n, p)| Some((n.to_string(), p.parse().ok()?)))
            .collect()
    }

    fn launch_log(&self) -> String {
        std::fs::read_to_string(self.dir.join("launch.log")).unwrap_or_default()
    }

    /// Wait for the launch to exit; its status and standard output.
    fn wait(&mut self, within: Duration) -> (std::process::ExitStatus, String) {
        let child = self.child.take().expect("running");
        wait_exit(child, within, || self.launch_log())
    }

    fn domain_files(&self, launcher: u32) -> Vec<String> {
        let prefix = format!("iox2_ocelli-{launcher}_");
        std::fs::read_dir("/dev/shm")
            .map(|d| {
                d.flatten()
                    .map(|e| e.file_name().to_string_lossy().into_owned())
                    .filter(|n| n.starts_with(&prefix))
                    .collect()
            })
            .unwrap_or_default()
    }
}

impl Drop for Run {
    fn drop(&mut self) {
        if let Some(mut c) = self.child.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

fn ocelli(dir: &Path, args: &[&str]) -> std::process::Output {
    Command::new(EXE)
        .current_dir(dir)
        .args(args)
        .env("RUST_LOG", "warn")
        .stdin(Stdio::null())
        .output()
        .expect("ocelli runs")
}

/// SIGTERM (systemd, docker, `timeout`), SIGHUP (a closed terminal) and SIGINT (Ctrl-C) each
/// stop every node cleanly: the launch prints its report, exits 0 and leaves no process and
/// nothing in /dev/shm; its files are private, its logs plain text; `ocelli report` on the
/// recording prints exactly the launch's report.
#[test]
fn every_stop_signal_stops_every_node_and_prints_the_report() {
    for (sig, name) in [
        (libc::SIGTERM, "SIGTERM"),
        (libc::SIGHUP, "SIGHUP"),
        (libc::SIGINT, "SIGINT"),
    ] {
        let mut run = Run::start(&format!("stop-{name}"), &[]);
        let launcher = run.pid();
        let pids = run.pids();
        // Server, head, four cameras and the viewer.
        assert_eq!(pids.len(), 7, "{pids:?}");
        // Every node is running and the server has recorded something.
        let dir = run.run_dir();
        wait_for(Duration::from_secs(30), "the recording", || {
            std::fs::metadata(dir.join("recording.ocrec")).is_ok_and(|m| m.len() > 1000)
        });
        signal(launcher, sig);
        let (status, out) = run.wait(Duration::from_secs(40));
        let log = run.launch_log();
        assert!(status.success(), "{name}: launch ended with {status}:\n{log}");
        assert!(log.contains(&format!("signal=\"{name}\"")), "{name}:\n{log}");
        let report: Value = serde_json::from_str(&out)
            .unwrap_or_else(|e| panic!("{name}: stdout is not one JSON report ({e}):\n{out}"));
        for (node, pid) in &pids {
            assert!(!alive(*pid), "{name}: {node} ({pid}) outlived the launch");
        }
        assert_eq!(
            run.domain_files(launcher),
            Vec::<String>::new(),
            "{name}: /dev/shm"
        );
        // `ocelli report` reproduces the launch's report from the recording alone.
        let again = ocelli(
            &run.dir,
            &["report", "--json", dir.join("recording.ocrec").to_str().unwrap()],
        );
        assert!(
            again.status.success(),
            "{}",
            String::from_utf8_lossy(&again.stderr)
        );
        let again: Value = serde_json::from_slice(&again.stdout).expect("report JSON");
        // All but the launch's account of undelivered messages, which it reads from the nodes'
        // exit summaries in the run folder, not from the recording.
        let mut report = report;
        let undelivered = report
            .as_object_mut()
            .and_then(|m| m.remove("undelivered"))
            .unwrap_or_else(|| panic!("{name}: the launch's report has no undelivered account"));
        // Every node is accounted for: by its exit summary, or named for having none (a camera
        // still starting when the signal came may not have its handler yet, and ends without
        // one).
        let missing = undelivered["nodes_without_summary"]
            .as_array()
            .expect("a list")
            .len();
        assert_eq!(
            undelivered["summaries"].as_u64().expect("a count") as usize + missing,
            pids.len(),
            "{name}: {undelivered}"
        );
        assert_eq!(again, report, "{name}: ocelli report differs from the launch's");
        assert_eq!(report["truth"], true, "a launch's world is simulated: {report}");
        if sig == libc::SIGTERM {
            check_files(&dir);
        }
    }
}

/// Every file of a run is 0640; node logs are plain text and quiet about iceoryx2.
fn check_files(dir: &Path) {
    let mut logs = 0;
    for e in std::fs::read_dir(dir).expect("run folder").flatten() {
        let mode = e.metadata().expect("metadata").permissions().mode() & 0o777;
        let name = e.file_name().to_string_lossy().into_owned();
        assert_eq!(mode, 0o640, "{name} has mode {mode:o}");
        if name.ends_with(".log") {
            logs += 1;
            let text = std::fs::read_to_string(e.path()).unwrap();
            assert!(!text.contains('\u{1b}'), "{name} holds colour codes:\n{text}");
            assert!(
                !text.contains("Config::global_config"),
                "{name} holds iceoryx2's noise:\n{text}"
            );
        }
    }
    assert_eq!(logs, 7, "one log per node and the viewer");
    let mode = std::fs::metadata(dir).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode, 0o750, "the run folder has mode {mode:o}");
}

/// A launcher killed with SIGKILL cannot stop anything itself: its nodes go anyway (their
/// parent-death signal).
#[test]
fn a_launcher_killed_outright_takes_its_nodes_with_it() {
    let run = Run::start("sigkill", &[]);
    let launcher = run.pid();
    let pids = run.pids();
    assert_eq!(pids.len(), 7, "{pids:?}");
    std::thread::sleep(Duration::from_secs(3));
    signal(launcher, libc::SIGKILL);
    wait_for(Duration::from_secs(20), "every node to stop", || {
        pids.iter().all(|(_, p)| !alive(*p))
    });
}

/// A crashed node is restarted after a short backoff, the launch says so, the pids file names
/// the new process, and the run's logs and `--log-json` reach every node.
#[test]
fn a_crashed_node_is_restarted_and_the_launch_says_so() {
    let mut run = Run::start("restart", &["--duration", "12", "--log-json"]);
    let first = run
        .pids()
        .into_iter()
        .find(|(n, _)| n == "camera-12")
        .expect("camera-12")
        .1;
    std::thread::sleep(Duration::from_secs(3));
    signal(first, libc::SIGKILL);
    wait_for(Duration::from_secs(10), "camera-12 to come back", || {
        run.pids().iter().any(|(n, p)| n == "camera-12" && *p != first)
    });
    let dir = run.run_dir();
    let (status, _) = run.wait(Duration::from_secs(40));
    assert!(status.success());
    let log = run.launch_log();
    for want in [
        "camera-12 ended (killed by signal 9); restarting it in 0.5 s",
        "camera-12 restarted as pid",
    ] {
        assert!(log.contains(want), "the launch log lacks {want:?}:\n{log}");
    }
    // --log-json reached every node: each log line is a JSON object.
    for e in std::fs::read_dir(&dir).unwrap().flatten() {
        if e.file_name().to_string_lossy().ends_with(".log") {
            let text = std::fs::read_to_string(e.path()).unwrap();
            for l in text.lines() {
                serde_json::from_str::<Value>(l)
                    .unwrap_or_else(|_| panic!("not JSON in {:?}: {l}", e.file_name()));
            }
        }
    }
}

/// Runs never share or overwrite a folder; a named folder that holds files and an existing
/// recording are refused (naming them) unless `--force`; a second process for a live node id
/// is refused over iceoryx2; a node's `--id` must have its role.
#[test]
fn runs_keep_their_files_and_node_ids_are_not_claimed_twice() {
    let mut run = Run::start("claims", &["--duration", "8"]);
    let dir = run.run_dir();
    let scenario = dir.join("scenario.toml");
    wait_for(Duration::from_secs(30), "the head to be up", || {
        std::fs::read_to_string(dir.join("head-2.log")).is_ok_and(|l| l.contains("running"))
    });
    let second = ocelli(
        &run.dir,
        &["head", "--id", "2", "--scenario", scenario.to_str().unwrap()],
    );
    let err = String::from_utf8_lossy(&second.stderr);
    assert!(!second.status.success(), "a second head 2 started:\n{err}");
    assert!(err.contains("node n2 is already up"), "{err}");
    let wrong = ocelli(
        &run.dir,
        &[
            "server",
            "--id",
            "10",
            "--record",
            "x.ocrec",
            "--scenario",
            scenario.to_str().unwrap(),
        ],
    );
    let err = String::from_utf8_lossy(&wrong.stderr);
    assert!(!wrong.status.success());
    assert!(
        err.contains("--id 10: node 10 of scenario default is a camera, not a server"),
        "{err}"
    );
    let (status, _) = run.wait(Duration::from_secs(40));
    assert!(status.success(), "{}", run.launch_log());
    // The run folder is taken: refused, naming it; the recording too.
    let scenario_arg = run.dir.join("small.toml");
    let again = ocelli(
        &run.dir,
        &[
            "launch",
            "--scenario",
            scenario_arg.to_str().unwrap(),
            "--run-dir",
            dir.to_str().unwrap(),
            "--duration",
            "1",
        ],
    );
    let err = String::from_utf8_lossy(&again.stderr);
    assert!(!again.status.success());
    assert!(
        err.contains("already holds files") && err.contains(dir.to_str().unwrap()),
        "{err}"
    );
    let rec = dir.join("recording.ocrec");
    let again = ocelli(
        &run.dir,
        &[
            "launch",
            "--scenario",
            scenario_arg.to_str().unwrap(),
            "--record",
            rec.to_str().unwrap(),
            "--duration",
            "1",
        ],
    );
    let err = String::from_utf8_lossy(&again.stderr);
    assert!(!again.status.success());
    assert!(
        err.contains("already exists") && err.contains("recording.ocrec"),
        "{err}"
    );
    // Nothing was made or touched by the refused launches.
    let runs = std::fs::read_dir(run.dir.join("ocelli-runs")).unwrap().count();
    assert_eq!(runs, 1, "a refused launch made a run folder");
}
