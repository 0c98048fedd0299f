//! The `ocelli` binary as a user runs it: experiments, replays of recordings and of external
//! detections, each through the real command line.

use std::io::Write;
use std::path::Path;
use std::process::{Command, Stdio};

#[test]
fn the_cli_prints_the_issue_json_labelled_with_its_level_and_writes_figures() {
    let dir = std::env::temp_dir().join(format!("ocelli-experiment-plots-{}", std::process::id()));
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_ocelli"))
        .args(["experiment", "paper000-table1", "--runs", "1", "--duration", "20"])
        .args(["--level", "measurement", "--json", "--plot"])
        .arg(&dir)
        .env("RUST_LOG", "error")
        .output()
        .expect("ocelli runs");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON object");
    assert_eq!(v["experiment"], "paper000-table1");
    assert_eq!(v["level"], "measurement");
    let rows = v["rows"].as_array().expect("rows");
    assert_eq!(rows.len(), 5);
    for r in rows {
        for k in [
            "method",
            "mean_error_m",
            "std_m",
            "measurements",
            "active_cameras",
            "rssi_measurements",
            "power_mw",
        ] {
            assert!(r.get(k).is_some(), "{k} missing in {r}");
        }
        assert!(r["rssi_measurements"].is_null(), "camera-only methods: {r}");
    }
    let pngs = std::fs::read_dir(&dir).map(|d| d.count()).unwrap_or(0);
    let _ = std::fs::remove_dir_all(&dir);
    assert_eq!(pngs, 5, "one figure per method");
    assert!(
        ocelli_err(&["experiment", "no-such-thing"]).contains("paper000-table1"),
        "the error lists the known names"
    );
}

/// The default scenario's cameras see a point on the floor: detections made by projecting it
/// come back from `ocelli fuse` as one estimate at that point, one per `t`; a bad line is
/// skipped and named by its number; nothing fused exits non-zero and says why; `replay
/// --detections` points to `fuse`.
#[test]
fn binary_fuses_json_lines_and_names_a_bad_line() {
    let scenario_path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../proto/scenarios/default.toml");
    let scenario = proto::scenario::Scenario::load(&scenario_path).expect("default scenario");
    let w = &scenario.world;
    let target = nalgebra::Vector3::new(0.5 * (w.min[0] + w.max[0]), 0.5 * (w.min[1] + w.max[1]), 0.0);
    let mut lines = String::new();
    let mut seen = 0;
    for node in scenario.cameras() {
        let cam = scenario.camera_model(node.id).expect("camera model");
        let Some(px) = cam.project(&target) else { continue };
        let k = &cam.intrinsics;
        if px.x < 0.0 || px.y < 0.0 || px.x >= f64::from(k.width) || px.y >= f64::from(k.height) {
            continue;
        }
        seen += 1;
        for t in [0.0, 0.5] {
            lines += &format!(
                "{{\"t\": {t}, \"camera\": \"{}\", \"u\": {}, \"v\": {}}}\n",
                node.id, px.x, px.y
            );
        }
    }
    assert!(seen >= 2, "the scenario centre is seen by {seen} cameras");
    let run_args = |input: &str, args: &[&str]| {
        let mut child = Command::new(env!("CARGO_BIN_EXE_ocelli"))
            .args(args)
            .arg("--scenario")
            .arg(&scenario_path)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("ocelli runs");
        // A command that refuses its input (replay --detections) may exit before reading
        // it; the pipe then breaks, and what it printed is what the test looks at.
        match child.stdin.take().expect("stdin").write_all(input.as_bytes()) {
            Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => panic!("write detections: {e}"),
            _ => {}
        }
        child.wait_with_output().expect("ocelli finishes")
    };
    let run_with =
        |input: &str, method: &str| run_args(input, &["fuse", "-", "--method", method, "--plane-z", "0"]);
    let run = |input: &str| run_with(input, "ml");
    let out = run(&lines);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8(out.stdout).expect("utf-8");
    let rows: Vec<serde_json::Value> = text
        .lines()
        .map(|l| serde_json::from_str(l).expect("each line is JSON"))
        .collect();
    assert_eq!(rows.len(), 2, "one estimate per t: {text}");
    for (row, t) in rows.iter().zip([0.0, 0.5]) {
        assert_eq!(row["t"], t);
        assert_eq!(row["cameras"], seen);
        let p = nalgebra::Vector3::new(
            row["x"].as_f64().unwrap(),
            row["y"].as_f64().unwrap(),
            row["z"].as_f64().unwrap(),
        );
        assert!((p - target).norm() < 1e-6, "{p} vs {target}");
        assert!(row["cov"][0][0].as_f64().unwrap() > 0.0);
    }
    assert!(rows.iter().all(|r| r.get("track").is_none()));
    let out = run_with(&lines, "eif");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let tracks: Vec<u64> = String::from_utf8(out.stdout)
        .expect("utf-8")
        .lines()
        .map(|l| {
            serde_json::from_str::<serde_json::Value>(l).expect("JSON")["track"]
                .as_u64()
                .expect("track id")
        })
        .collect();
    assert_eq!(tracks, [1, 1], "one target, one track");
    // A malformed line is skipped, counted and named; the good lines still give their estimates.
    let bad = format!("{lines}{{\"t\": 1, \"camera\": \"1\", \"u\": 3}}\n");
    let out = run(&bad);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(String::from_utf8_lossy(&out.stdout).lines().count(), 2);
    let err = String::from_utf8_lossy(&out.stderr);
    let want = format!("line {}", lines.lines().count() + 1);
    assert!(
        err.contains("1 line(s) skipped") && err.contains(&want),
        "should name {want}: {err}"
    );
    // One camera, two people at one time stamp, no plane: nothing can be placed, and it says so.
    let first = lines.lines().next().expect("a detection");
    let two = format!("{first}\n{}\n", first.replace("\"u\": ", "\"u\": 1"));
    let out = run_args(&two, &["fuse", "-"]);
    assert!(!out.status.success(), "no estimate is a failure");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--plane-z"), "the hint names --plane-z: {err}");
    // External detections are fused, not replayed.
    let out = run_args(&lines, &["replay", "--detections", "-"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("ocelli fuse"), "points to ocelli fuse: {err}");
}

/// The commands as a user runs them: `ocelli sim --record-measurements --record F`, then
/// `ocelli replay F` with the run's seed prints the run's own estimates (those `ocelli export`
/// reads from F) and, with `--json`, the report; `--activation all-on` keeps more cameras on.
#[test]
fn binary_replays_a_sim_recording_to_its_own_estimates() {
    let dir = tempfile::Builder::new()
        .prefix("ocelli-rerun-bin-")
        .tempdir()
        .unwrap();
    let rec = dir.path().join("run.ocrec");
    let rec_s = rec.to_str().unwrap();
    ocelli_ok(&[
        "sim",
        "--seed",
        "9",
        "--duration",
        "6",
        "--level",
        "measurement",
        "--json",
        "--record",
        rec_s,
        "--record-measurements",
    ]);
    let json_lines = |text: &str| -> Vec<serde_json::Value> {
        text.lines()
            .map(|l| serde_json::from_str(l).expect("each line is JSON"))
            .collect()
    };
    let exported: Vec<_> = json_lines(&ocelli_ok(&["export", rec_s, "--format", "jsonl"]))
        .into_iter()
        .filter(|r| r["owner"] == true)
        .collect();
    // The run's seed and level; `extra` changes the method or policy.
    let replay = |extra: &[&str]| {
        let args = [
            "replay",
            rec_s,
            "--seed",
            "9",
            "--recorded-level",
            "measurement",
            "--json",
        ];
        json_lines(&ocelli_ok(&[&args[..], extra].concat()))
    };
    let mut replayed = replay(&[]);
    let report = replayed.pop().expect("a report line");
    assert!(exported.len() > 10, "only {} exported rows", exported.len());
    assert_eq!(replayed, exported, "the replay's estimates are the run's");
    let report = &report["report"];
    assert!(
        report["mean_error_m"].as_f64().expect("truth known") < 0.5,
        "{report}"
    );
    let three = report["active_cameras_mean"].as_f64().unwrap();
    let mut all_on = replay(&["--activation", "all-on"]);
    let all_on = all_on.pop().unwrap()["report"]["active_cameras_mean"]
        .as_f64()
        .unwrap();
    assert!(three < all_on, "three-mode {three} vs all-on {all_on} cameras");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `ocelli report REC --events FILE`: every scored frame of a simulated run as JSON Lines, whose
/// pairs, switches, misses and false positives add up to the report's own counts, with the
/// truth and the tracks it compared; `--events -` prints the frames instead of the report. The
/// crowd at measurement level has all four kinds within 30 s.
#[test]
fn report_writes_the_scored_frames_that_make_its_counts() {
    let dir = tempfile::Builder::new()
        .prefix("ocelli-events-")
        .tempdir()
        .unwrap();
    let rec = dir.path().join("run.ocrec");
    let events = dir.path().join("events.jsonl");
    let crowd = concat!(env!("CARGO_MANIFEST_DIR"), "/../proto/scenarios/crowd.toml");
    let (rec_s, events_s) = (rec.to_str().unwrap(), events.to_str().unwrap());
    ocelli_ok(&[
        "sim",
        "-s",
        crowd,
        "--seed",
        "3",
        "--duration",
        "30",
        "--level",
        "measurement",
        "--json",
        "--record",
        rec_s,
    ]);
    let report: serde_json::Value =
        serde_json::from_str(&ocelli_ok(&["report", rec_s, "--json", "--events", events_s]))
            .expect("the report");
    let mot = &report["mot"];
    let frames: Vec<serde_json::Value> = std::fs::read_to_string(&events)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).expect("each line is JSON"))
        .collect();
    assert_eq!(frames.len() as u64, mot["frames"].as_u64().unwrap());
    let count = |key: &str| -> u64 {
        frames
            .iter()
            .map(|f| f[key].as_array().unwrap().len() as u64)
            .sum()
    };
    let pairs: Vec<&serde_json::Value> = frames
        .iter()
        .flat_map(|f| f["pairs"].as_array().unwrap())
        .collect();
    let switches = pairs.iter().filter(|p| p["switch"] == true).count() as u64;
    let got = [
        pairs.len() as u64 - switches,
        switches,
        count("misses"),
        count("false_positives"),
    ];
    let want = ["matches", "id_switches", "misses", "false_positives"].map(|k| mot[k].as_u64().unwrap());
    assert_eq!(got, want, "matches, switches, misses, false positives");
    assert!(
        got.iter().all(|&n| n > 0),
        "the run has every kind of event: {got:?}"
    );
    // Each pair names a truth and a track of its frame, as far apart as it says.
    for f in &frames {
        for p in f["pairs"].as_array().unwrap() {
            let find = |list: &str, id: &serde_json::Value| {
                f[list]
                    .as_array()
                    .unwrap()
                    .iter()
                    .find(|e| e["id"] == *id)
                    .cloned()
                    .expect("listed")
            };
            let (t, h) = (find("truth", &p["truth"]), find("tracks", &p["track"]));
            let d = (t["x"].as_f64().unwrap() - h["x"].as_f64().unwrap())
                .hypot(t["y"].as_f64().unwrap() - h["y"].as_f64().unwrap());
            assert!((d - p["distance_m"].as_f64().unwrap()).abs() < 1e-9, "{f}");
        }
    }
    // To standard output: the frames alone, and so not with the report's own options.
    assert_eq!(
        ocelli_ok(&["report", rec_s, "--events", "-"]),
        std::fs::read_to_string(&events).unwrap()
    );
    let err = ocelli_err(&["report", rec_s, "--events", "-", "--json"]);
    assert!(err.contains("give --events a file"), "{err}");
}

/// A run too short to score has no events, and `report --events` says why.
#[test]
fn report_events_of_an_unscored_run_is_an_error_that_says_why() {
    let dir = tempfile::Builder::new()
        .prefix("ocelli-events-")
        .tempdir()
        .unwrap();
    let rec = dir.path().join("short.ocrec");
    let rec_s = rec.to_str().unwrap();
    ocelli_ok(&[
        "sim",
        "--duration",
        "1",
        "--level",
        "measurement",
        "--json",
        "--record",
        rec_s,
    ]);
    let err = ocelli_err(&[
        "report",
        rec_s,
        "--events",
        dir.path().join("e.jsonl").to_str().unwrap(),
    ]);
    assert!(err.contains("no events") && err.contains("warm-up"), "{err}");
    assert!(!dir.path().join("e.jsonl").exists(), "no file written");
}

/// `ocelli ARGS`' standard output; it must succeed.
fn ocelli_ok(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_ocelli"))
        .args(args)
        .output()
        .expect("ocelli runs");
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).expect("utf-8")
}

/// `ocelli ARGS`' standard error; it must fail.
fn ocelli_err(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_ocelli"))
        .args(args)
        .output()
        .expect("ocelli runs");
    assert!(!out.status.success(), "{args:?} succeeded");
    String::from_utf8(out.stderr).expect("utf-8")
}

/// Piped, a long command stays quiet: no progress bar, no colour codes.
#[test]
fn piped_output_has_no_progress_bar_and_no_colour_codes() {
    let out = Command::new(env!("CARGO_BIN_EXE_ocelli"))
        .args(["sim", "--duration", "2", "--level", "measurement", "--json"])
        .env_remove("RUST_LOG")
        .output()
        .expect("ocelli runs");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("simulated s"), "no bar when piped: {err}");
    assert!(!err.contains('\u{1b}'), "no escape codes when piped: {err}");
    serde_json::from_slice::<serde_json::Value>(&out.stdout).expect("--json prints only JSON");
}

/// `ocelli launch --skip` names what is wrong with a node it cannot leave out, before it starts
/// anything or claims a run folder: the server (the launch reports on its recording) and a node
/// the scenario does not declare.
#[test]
fn launch_refuses_to_skip_the_server_or_an_undeclared_node() {
    let dir = std::env::temp_dir().join(format!("ocelli-skip-{}", std::process::id()));
    for (skip, want) in [("1", "is the server"), ("999", "declares no node 999")] {
        let run_dir = dir.join(skip);
        let out = Command::new(env!("CARGO_BIN_EXE_ocelli"))
            .args([
                "launch",
                "--no-view",
                "--quiet",
                "--duration",
                "5",
                "--skip",
                skip,
            ])
            .arg("--run-dir")
            .arg(&run_dir)
            .env("NO_COLOR", "1")
            .stdin(Stdio::null())
            .output()
            .expect("ocelli launch");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "--skip {skip} was accepted: {err}");
        assert!(err.contains(want), "--skip {skip}: {err}");
        assert!(!run_dir.exists(), "--skip {skip} claimed a run folder");
    }
}
