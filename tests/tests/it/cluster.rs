//! The product as a user meets it: `ocelli launch` starts every node of the default scenario as
//! its own process, over iceoryx2 and over TCP; nodes are killed mid-run on purpose. Each test
//! reads the launch's final JSON report and the server's recording (through `ocelli export`),
//! and checks that no process and no `/dev/shm` file is left behind.

use crate::harness::{EXE, Scratch, alive, cluster_now_s, now, owner_rows, scratch, signal, wait_exit};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

/// Mean-error bound for a whole run over real processes, metres. The simulation of the same
/// scenario (`ocelli sim`, seeds 1–5, see `deploy/tests/it/sim.rs`) tracks within a few
/// decimetres; real processes add scheduling jitter, start-up (tracks born late) and the
/// two-core CI machine running 24 processes at once, so the bound leaves a margin of about 3×.
const MEAN_ERROR_BOUND_M: f64 = 1.0;

/// A running `ocelli launch`, killed on drop.
pub(crate) struct Launch {
    child: Option<Child>,
    pub(crate) dir: Scratch,
    pub(crate) domain: String,
}

impl Launch {
    pub(crate) fn start(name: &str, transport: &str, seconds: f64, scenario: Option<&Path>) -> Launch {
        Launch::start_with(name, transport, seconds, scenario, &[])
    }

    /// As [`Launch::start`], with more `ocelli launch` flags.
    pub(crate) fn start_with(
        name: &str,
        transport: &str,
        seconds: f64,
        scenario: Option<&Path>,
        extra: &[&str],
    ) -> Launch {
        let dir = scratch(name);
        let mut cmd = Command::new(EXE);
        cmd.arg("launch");
        if let Some(s) = scenario {
            cmd.arg("--scenario").arg(s);
        }
        cmd.args(extra);
        cmd.args([
            "--transport",
            transport,
            "--duration",
            &seconds.to_string(),
            "--json",
            "--quiet",
        ])
        .arg("--run-dir")
        .arg(dir.join("run"))
        .arg("--record")
        .arg(dir.join("rec.ocrec"))
        .env("RUST_LOG", "info")
        .env("NO_COLOR", "1")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(std::fs::File::create(dir.join("launch.log")).expect("log"));
        let child = cmd.spawn().expect("spawning ocelli launch");
        let domain = format!("ocelli-{}", child.id());
        Launch {
            child: Some(child),
            dir,
            domain,
        }
    }

    pub(crate) fn record(&self) -> PathBuf {
        self.dir.join("rec.ocrec")
    }

    pub(crate) fn run_dir(&self) -> PathBuf {
        self.dir.join("run")
    }

    /// Node name (`camera-12`, `head-2`, `server-1`) → pid, once the launch has written it.
    pub(crate) fn pid_of(&self, node: &str) -> u32 {
        let deadline = now() + Duration::from_secs(20);
        loop {
            if let Ok(text) = std::fs::read_to_string(self.run_dir().join("pids"))
                && let Some(pid) = text
                    .lines()
                    .filter_map(|l| l.split_once(' '))
                    .find(|(n, _)| *n == node)
                    .and_then(|(_, p)| p.parse().ok())
            {
                return pid;
            }
            assert!(now() < deadline, "launch never listed {node}");
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    pub(crate) fn all_pids(&self) -> Vec<u32> {
        std::fs::read_to_string(self.run_dir().join("pids"))
            .unwrap_or_default()
            .lines()
            .filter_map(|l| l.split_once(' ').and_then(|(_, p)| p.parse().ok()))
            .collect()
    }

    fn log(&self, node: &str) -> String {
        std::fs::read_to_string(self.run_dir().join(format!("{node}.log"))).unwrap_or_default()
    }

    /// Wait for the launch to end by itself; its JSON report.
    pub(crate) fn finish(mut self, within: Duration) -> (Value, Launch) {
        let child = self.child.take().expect("running");
        let (status, out) = wait_exit(child, within, || self.launch_log());
        assert!(
            status.success(),
            "launch failed ({status}); log:\n{}",
            self.launch_log()
        );
        let report: Value = serde_json::from_str(&out).unwrap_or_else(|e| {
            panic!(
                "launch printed no JSON report ({e}):\n{out}\n{}",
                self.launch_log()
            )
        });
        (report, self)
    }

    pub(crate) fn launch_log(&self) -> String {
        std::fs::read_to_string(self.dir.join("launch.log")).unwrap_or_default()
    }

    /// Nothing of the run is left: no node process, no shared-memory file of its domain.
    pub(crate) fn assert_clean(&self) {
        for pid in self.all_pids() {
            assert!(!alive(pid), "node process {pid} outlived the launch");
        }
        let left = self.shm_files();
        assert!(left.is_empty(), "files left in /dev/shm: {left:?}");
    }

    /// The run's domain's files in `/dev/shm`.
    pub(crate) fn shm_files(&self) -> std::collections::BTreeSet<String> {
        let prefix = format!("iox2_{}_", self.domain);
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

impl Drop for Launch {
    fn drop(&mut self) {
        if let Some(mut c) = self.child.take() {
            signal(c.id(), libc::SIGINT);
            std::thread::sleep(Duration::from_millis(200));
            signal(c.id(), libc::SIGINT);
            let _ = c.kill();
            let _ = c.wait();
        }
        for pid in self.all_pids() {
            signal(pid, libc::SIGKILL);
        }
    }
}

pub(crate) fn f(v: &Value, key: &str) -> f64 {
    v[key]
        .as_f64()
        .unwrap_or_else(|| panic!("report has no number {key}: {v}"))
}

fn assert_tracked(report: &Value) {
    let targets = report["targets"].as_array().expect("targets");
    assert_eq!(targets.len(), 1, "one robot in the default scenario: {report}");
    assert!(
        f(&targets[0], "samples") >= 30.0,
        "too few track samples: {report}"
    );
    let err = f(report, "mean_error_m");
    assert!(
        err < MEAN_ERROR_BOUND_M,
        "mean error {err} m ≥ {MEAN_ERROR_BOUND_M} m: {report}"
    );
}

/// Every node of the run left its exit summary, and the launch's account of undelivered
/// messages adds up: what a node did not deliver is either before the stop, after it, or
/// beyond the times it keeps.
fn assert_undelivered_accounted(report: &Value, run: &Launch) {
    let u = &report["undelivered"];
    let processes = run.all_pids().len() as f64;
    assert_eq!(f(u, "summaries"), processes, "one exit summary per node: {u}");
    assert_eq!(u["nodes_without_summary"], serde_json::json!([]), "{u}");
    assert_eq!(f(u, "unreadable_lines"), 0.0, "{u}");
    let sum = |key: &str| -> f64 {
        u[key]
            .as_object()
            .unwrap_or_else(|| panic!("no {key}: {u}"))
            .values()
            .filter_map(Value::as_f64)
            .sum()
    };
    assert_eq!(sum("during_run_by_kind"), f(u, "during_run"), "{u}");
    assert_eq!(sum("at_stop_by_kind"), f(u, "at_stop"), "{u}");
}

fn cluster_tracks(transport: &str) {
    let run = Launch::start(&format!("track-{transport}"), transport, 20.0, None);
    let (report, run) = run.finish(Duration::from_secs(90));
    assert_tracked(&report);
    assert_undelivered_accounted(&report, &run);
    run.assert_clean();
}

#[test]
fn ipc_cluster_tracks_the_default_scenario() {
    cluster_tracks("ipc");
}

#[test]
fn tcp_cluster_tracks_the_default_scenario() {
    cluster_tracks("tcp");
}

/// A camera killed mid-run: tracking continues and its head stops waiting for it.
#[test]
fn killing_a_camera_mid_run_leaves_tracking_running() {
    // Every camera on, so the head expects the victim in every step.
    let scenario_dir = scratch("kill-camera-scenario");
    let text = proto::scenario::DEFAULT_SCENARIO_TOML
        .replace("activation = \"three-mode\"", "activation = \"all-on\"");
    assert_ne!(
        text,
        proto::scenario::DEFAULT_SCENARIO_TOML,
        "default scenario layout changed"
    );
    let path = scenario_dir.join("all-on.toml");
    std::fs::write(&path, text).unwrap();
    // Left down: the launch would otherwise restart it (see the restart test below).
    let run = Launch::start_with("kill-camera", "ipc", 20.0, Some(&path), &["--no-restart"]);
    let victim = "camera-12";
    let pid = run.pid_of(victim);
    std::thread::sleep(Duration::from_secs(8));
    let listed = |what: &str| {
        runtime::transport::ipc_nodes(&run.domain)
            .unwrap_or_else(|e| panic!("listing the domain's nodes {what}: {e}"))
    };
    let before = listed("before the kill");
    assert!(
        before.alive >= 24,
        "the run's nodes are not all listed: {before:?}"
    );
    signal(pid, libc::SIGKILL);
    // No node starts after the kill (the victim stays down), so iceoryx2's own cleanup, which
    // runs when a node is created, never comes: the live nodes' janitors must remove the dead
    // camera's resources (its publishers' data segments, its connections, its service places).
    std::thread::sleep(Duration::from_secs(1));
    // The launch runs 20 s and the kill is at 8 s: look until 17 s, while the others run.
    let deadline = now() + Duration::from_secs(8);
    let mut after = listed("after the kill");
    while now() < deadline && after.dead > 0 {
        std::thread::sleep(Duration::from_millis(250));
        after = listed("after the kill");
    }
    assert!(
        after.dead == 0 && after.alive + 1 == before.alive,
        "the killed camera's iceoryx2 resources were not removed within 9 s: before {before:?}, after {after:?}"
    );
    let (report, run) = run.finish(Duration::from_secs(90));
    assert_tracked(&report);
    // The head's last word on camera 12 is that it is down: it no longer waits for it.
    let head_log = run.log("head-2");
    let last = head_log
        .lines()
        .rfind(|l| l.contains("node=n12") && (l.contains("liveness") || l.contains("not waiting")))
        .unwrap_or_default();
    assert!(
        last.contains("up=false") || last.contains("not waiting for it"),
        "head 2 still counts on camera 12 (last liveness line: {last:?}):\n{head_log}"
    );
    run.assert_clean();
}

/// A head that never starts (`ocelli launch --skip 2`): once the server's start-up grace has
/// run out it declares head 2 down, head 3 is given its cameras and may start tracks on its
/// floor, and the robot, walking on head 2's floor, is tracked by head 3 with head 2's cameras.
/// Before, its floor stayed untracked for the whole run (head 3 starts no track on a live
/// head's floor, and a head never seen was never down).
#[test]
fn a_head_that_never_starts_leaves_its_floor_to_the_other_head() {
    // The robot stays on head 2's floor, more than head 3's birth margin (1 m) from its region
    // (x ≥ 6): a loop through (2.5, 6), (2.5, 2), (4.5, 2) and (4.5, 6).
    let scenario_dir = scratch("skip-head-scenario");
    let text = proto::scenario::DEFAULT_SCENARIO_TOML.replace(
        "waypoints = [[2.5, 2.0], [9.5, 2.0], [9.5, 6.0], [2.5, 6.0]]",
        "waypoints = [[2.5, 6.0], [2.5, 2.0], [4.5, 2.0], [4.5, 6.0]]",
    );
    assert_ne!(
        text,
        proto::scenario::DEFAULT_SCENARIO_TOML,
        "default scenario layout changed"
    );
    let path = scenario_dir.join("robot-on-head-2.toml");
    std::fs::write(&path, text).unwrap();
    let run = Launch::start_with("skip-head", "ipc", 24.0, Some(&path), &["--skip", "2"]);
    let (_report, run) = run.finish(Duration::from_secs(90));
    let pids = std::fs::read_to_string(run.run_dir().join("pids")).expect("the launch's pids");
    assert!(
        pids.contains("head-3 ") && !pids.contains("head-2 "),
        "head 2 was started, or head 3 not:\n{pids}"
    );
    let error_of = robot_error(&run);
    let rows = owner_rows(&run.record());
    assert!(
        rows.iter().all(|r| r["head"].as_u64() == Some(3)),
        "a track owned by a head that never ran"
    );
    // The robot's truth at a row, to keep the rows while it is on head 2's floor.
    let (targets, epoch) = world_truth(&run);
    let robot = &targets[0];
    let on_head_2: Vec<&Value> = rows
        .iter()
        .filter(|r| robot.position_at(f(r, "t") - epoch).x < 5.0 && f(r, "cameras") >= 1.0)
        .collect();
    assert!(
        on_head_2.len() >= 10,
        "the robot on head 2's floor was never tracked by head 3 with cameras ({} rows); launch log:\n{}",
        on_head_2.len(),
        run.launch_log()
    );
    let errors: Vec<f64> = on_head_2.iter().map(|r| error_of(r)).collect();
    let m = median(errors);
    assert!(m < 0.5, "median error on head 2's floor {m:.2} m");
    run.assert_clean();
}

/// The head owning the robot's track is killed: the server fails over to the other head, the
/// robot keeps its global id, the surviving head has cameras within the liveness timeout
/// and three steps (over TCP the cameras dial the head they are reassigned to) and the error
/// is back under half a metre.
fn owning_head_fails_over(transport: &str) {
    // The head stays dead (`--no-restart`): the failover, not the supervisor's restart, is
    // what this tests.
    let run = Launch::start_with(
        &format!("kill-head-{transport}"),
        transport,
        24.0,
        None,
        &["--no-restart"],
    );
    // Wait until the robot is tracked, then kill whichever head owns it. The robot is the
    // global reported most often: a ghost more than a metre off can hold a second, short-lived
    // id, and the latest row may be the ghost's.
    let deadline = now() + Duration::from_secs(30);
    let (global, owner) = loop {
        let rows = owner_rows(&run.record());
        let mut counts = std::collections::BTreeMap::<u64, usize>::new();
        for r in &rows {
            *counts.entry(r["global"].as_u64().unwrap()).or_default() += 1;
        }
        let robot = counts.iter().max_by_key(|(_, n)| **n).map(|(g, n)| (*g, *n));
        if let Some((robot, n)) = robot
            && n >= 10
            && let Some(last) = rows.iter().rfind(|r| r["global"].as_u64() == Some(robot))
        {
            break (robot, last["head"].as_u64().unwrap());
        }
        assert!(
            now() < deadline,
            "the robot was never tracked; launch log:\n{}",
            run.launch_log()
        );
        std::thread::sleep(Duration::from_millis(500));
    };
    signal(run.pid_of(&format!("head-{owner}")), libc::SIGKILL);
    // Cluster time is the wall clock in a launch.
    let t_kill = cluster_now_s();
    let (_report, run) = run.finish(Duration::from_secs(90));
    let error_of = robot_error(&run);
    let after: Vec<Value> = owner_rows(&run.record())
        .into_iter()
        .filter(|r| f(r, "t") > t_kill + 0.5)
        .collect();
    assert!(!after.is_empty(), "no track after the head {owner} died");
    assert!(
        after.iter().all(|r| r["head"].as_u64() != Some(owner)),
        "the dead head {owner} still owns a track"
    );
    let robot: Vec<&Value> = after
        .iter()
        .filter(|r| r["global"].as_u64() == Some(global))
        .collect();
    assert!(
        !robot.is_empty(),
        "global id {global} was lost at failover; after: {:?}",
        after.iter().map(|r| r["global"].clone()).collect::<Vec<_>>()
    );
    let describe = |rows: &[&Value]| -> Vec<String> {
        rows.iter()
            .take(40)
            .map(|r| {
                format!(
                    "t+{:.2} head {} cameras {} rssi {} error {:.2}",
                    f(r, "t") - t_kill,
                    r["head"],
                    r["cameras"],
                    r["rssi_nodes"],
                    error_of(r)
                )
            })
            .collect()
    };
    // Cameras on the surviving head once the server can know: the surviving head did not
    // track the robot on the live owner's floor (a head starts no track there), so it takes
    // the track by handover once the server declares the owner down (at the liveness timeout
    // over iceoryx2, when the link drops over TCP), and its cameras answer a step later.
    // Allowed: that timeout and three steps (1.27 s measured over iceoryx2).
    let scenario =
        proto::scenario::Scenario::load(&run.run_dir().join("scenario.toml")).expect("the launch's scenario");
    let bound_s = (scenario.network.liveness_timeout_ms + 3 * scenario.method.step_ms) as f64 / 1e3;
    let first_seen = robot
        .iter()
        .find(|r| f(r, "cameras") >= 1.0)
        .map(|r| f(r, "t") - t_kill);
    assert!(
        first_seen.is_some_and(|dt| dt <= bound_s),
        "{transport}: no camera on the surviving head within {bound_s} s of the kill (first at {first_seen:?} s): {:#?}",
        describe(&robot)
    );
    // The error back under half a metre: within 3 s of the kill and for the rest of the run
    // (median, so one late frame does not decide).
    let settled: Vec<f64> = robot
        .iter()
        .filter(|r| f(r, "t") > t_kill + 3.0)
        .map(|r| error_of(r))
        .collect();
    let back = robot
        .iter()
        .find(|r| error_of(r) < 0.5)
        .map(|r| f(r, "t") - t_kill);
    assert!(
        back.is_some_and(|dt| dt <= 3.0) && median(settled.clone()) < 0.5,
        "{transport}: error not back under 0.5 m (first under at {back:?} s, median after 3 s {:.2} m): {:#?}",
        median(settled),
        describe(&robot)
    );
    run.assert_clean();
}

/// The launch's targets (its scenario's) and the synthetic world's time 0, in cluster seconds.
pub(crate) fn world_truth(run: &Launch) -> (Vec<world::Target>, f64) {
    let scenario =
        proto::scenario::Scenario::load(&run.run_dir().join("scenario.toml")).expect("the launch's scenario");
    let targets = world::targets(&scenario).expect("its targets");
    let epoch_ns: i64 = std::fs::read_to_string(run.run_dir().join("epoch-ns"))
        .expect("the launch's epoch")
        .trim()
        .parse()
        .expect("epoch nanoseconds");
    (targets, proto::ClusterTime(epoch_ns).as_secs_f64())
}

/// The robot's error at an exported row: the launch's scenario and synthetic-world epoch.
pub(crate) fn robot_error(run: &Launch) -> impl Fn(&Value) -> f64 {
    let (targets, epoch) = world_truth(run);
    move |r: &Value| {
        targets
            .iter()
            .map(|t| {
                let p = t.position_at(f(r, "t") - epoch);
                (p.x - f(r, "x")).hypot(p.y - f(r, "y"))
            })
            .fold(f64::INFINITY, f64::min)
    }
}

pub(crate) fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::INFINITY)
}

#[test]
fn killing_the_owning_head_fails_over_and_keeps_the_global_id() {
    owning_head_fails_over("ipc");
}

#[test]
fn killing_the_owning_head_over_tcp_fails_over_and_keeps_the_global_id() {
    owning_head_fails_over("tcp");
}

/// The server is killed: the launch restarts it on its recording, nodes keep tracking and
/// reconnect, and everything recorded before the crash is still in the recording.
#[test]
fn a_killed_server_is_restarted_by_the_launch_and_loses_no_recorded_data() {
    let run = Launch::start("kill-server", "ipc", 24.0, None);
    let server_pid = run.pid_of("server-1");
    std::thread::sleep(Duration::from_secs(9));
    signal(server_pid, libc::SIGKILL);
    std::thread::sleep(Duration::from_millis(200));
    // What the crashed server left on disk, read as the recording reader reads it.
    let snapshot = run.dir.join("at-crash.ocrec");
    std::fs::copy(run.record(), &snapshot).expect("copying the recording");
    let recorded_before = node_server::recording::read_all(&snapshot)
        .expect("reading the crash-time recording")
        .records;
    let before = owner_rows(&snapshot);
    assert!(!before.is_empty(), "nothing was recorded before the crash");
    // The launch restarts it after its backoff and says so; the pids file names the new one.
    let deadline = now() + Duration::from_secs(10);
    while run.pid_of("server-1") == server_pid {
        assert!(
            now() < deadline,
            "the server was not restarted:\n{}",
            run.launch_log()
        );
        std::thread::sleep(Duration::from_millis(200));
    }
    let (_report, run) = run.finish(Duration::from_secs(90));
    let log = run.launch_log();
    assert!(
        log.contains("server-1 ended (killed by signal 9); restarting it in")
            && log.contains("server-1 restarted as pid"),
        "the launch did not say it restarted the server:\n{log}"
    );
    let after = owner_rows(&run.record());
    assert!(
        after.len() > before.len(),
        "no tracking recorded after the restart"
    );
    let recorded_after = node_server::recording::read_all(&run.record())
        .expect("reading the recording")
        .records;
    assert!(
        recorded_after.len() > recorded_before.len()
            && recorded_after[..recorded_before.len()] == recorded_before[..],
        "records from before the crash were lost or changed ({} before, {} after)",
        recorded_before.len(),
        recorded_after.len()
    );
    let globals_before: std::collections::BTreeSet<u64> =
        before.iter().filter_map(|r| r["global"].as_u64()).collect();
    let last_global = after.last().and_then(|r| r["global"].as_u64()).unwrap();
    assert!(
        globals_before.contains(&last_global),
        "the robot got a new global id after the restart"
    );
    run.assert_clean();
}

/// `ocelli replay RECORDING --activation POLICY --json`: the replay's report (its last line).
fn replay_report(record: &Path, activation: &str) -> Value {
    let out = Command::new(EXE)
        .arg("replay")
        .arg(record)
        .args(["--activation", activation, "--json"])
        .env("RUST_LOG", "warn")
        .stdin(Stdio::null())
        .output()
        .expect("ocelli replay");
    assert!(
        out.status.success(),
        "replay --activation {activation} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    let last = text.lines().last().unwrap_or_default();
    let v: Value = serde_json::from_str(last).unwrap_or_else(|e| panic!("no report line ({e}): {text}"));
    v["report"].clone()
}

/// A logging run over real processes (`ocelli launch --record-measurements`): every camera
/// measures every frame whatever its mode and the server records it, so the recording
/// re-runs through the heads with any policy. Both policies track within the bound of a live
/// run (the replay only approximates the live timing; see `deploy::replay::rerun`), and on
/// the same measurements all-on uses more cameras and more power than three-mode.
#[test]
fn a_launch_logging_run_replays_with_any_policy() {
    let run = Launch::start_with("logging", "ipc", 14.0, None, &["--record-measurements"]);
    let (_report, run) = run.finish(Duration::from_secs(60));
    run.assert_clean();
    let frames = node_server::recording::read_all(&run.record())
        .expect("reading the recording")
        .records
        .iter()
        .filter(|s| matches!(s.record, node_server::Record::Measured(_)))
        .count();
    // 21 cameras at 5 fps for about 14 s, whatever their mode (start-up and drops aside).
    assert!(frames >= 21 * 5 * 5, "only {frames} measured frames recorded");
    let all_on = replay_report(&run.record(), "all-on");
    let three = replay_report(&run.record(), "three-mode");
    for (policy, report) in [("all-on", &all_on), ("three-mode", &three)] {
        let targets = report["targets"].as_array().expect("targets");
        assert_eq!(targets.len(), 1, "{policy}: {report}");
        assert!(
            f(&targets[0], "samples") >= 20.0,
            "{policy}: too few samples: {report}"
        );
        let err = f(report, "mean_error_m");
        assert!(
            err < MEAN_ERROR_BOUND_M,
            "{policy}: mean error {err} m ≥ {MEAN_ERROR_BOUND_M} m: {report}"
        );
    }
    let (cams_all, cams_three) = (
        f(&all_on, "active_cameras_mean"),
        f(&three, "active_cameras_mean"),
    );
    assert!(
        cams_all > cams_three,
        "all-on {cams_all} cameras vs three-mode {cams_three}"
    );
    let (mw_all, mw_three) = (f(&all_on, "power_mw_mean"), f(&three, "power_mw_mean"));
    assert!(
        mw_all > mw_three,
        "all-on {mw_all} mW vs three-mode {mw_three} mW"
    );
}
