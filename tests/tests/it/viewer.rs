//! The visualization node as a user meets it: `ocelli launch` starts a cluster with its viewer
//! (`ocelli viewer`, a client of the server), prints the viewer's URL, `/api/state` shows a
//! track with its global id, and headless Chromium (Debian's `chromium`) loads the map (`/`)
//! and the 3D view (`/3d`) until the track's label is on the page, then screenshots both into
//! the test's scratch folder; with `OCELLI_WRITE_SCREENSHOTS=1` they replace
//! `docs/view-live-map.png` and `docs/view-live-3d.png` (a test run never touches the tree
//! otherwise).
//!
//! Without Chromium this test fails and says which package to install: it never passes
//! silently.

use crate::harness::{EXE, now, signal};
use serde_json::Value;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

/// A running `ocelli launch`, stopped (SIGINT, then killed) on drop.
struct Cluster {
    child: Child,
    dir: crate::harness::Scratch,
}

impl Drop for Cluster {
    fn drop(&mut self) {
        signal(self.child.id(), libc::SIGINT);
        let deadline = now() + Duration::from_secs(30);
        while self.child.try_wait().ok().flatten().is_none() && now() < deadline {
            std::thread::sleep(Duration::from_millis(200));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Cluster {
    fn log(&self) -> String {
        std::fs::read_to_string(self.dir.join("launch.log")).unwrap_or_default()
    }

    /// The viewer's address, once the launch has printed its URL.
    fn viewer(&self) -> String {
        let deadline = now() + Duration::from_secs(60);
        loop {
            if let Some(url) = self.log().lines().find_map(|l| l.strip_prefix("viewer: http://")) {
                return url.trim().to_owned();
            }
            assert!(
                now() < deadline,
                "the launch printed no viewer URL:\n{}",
                self.log()
            );
            std::thread::sleep(Duration::from_millis(200));
        }
    }
}

/// `GET path` on `addr` (HTTP/1.0, the whole body); `None` if the viewer does not answer yet.
fn get(addr: &str, path: &str) -> Option<String> {
    let mut s = std::net::TcpStream::connect(addr).ok()?;
    s.set_read_timeout(Some(Duration::from_secs(10))).ok()?;
    write!(s, "GET {path} HTTP/1.0\r\nHost: {addr}\r\n\r\n").ok()?;
    let mut out = String::new();
    s.read_to_string(&mut out).ok()?;
    let (head, body) = out.split_once("\r\n\r\n")?;
    // hyper answers in the request's version: `HTTP/1.0 200 OK`.
    (head.split(' ').nth(1) == Some("200")).then(|| body.to_owned())
}

fn chromium() -> PathBuf {
    for name in ["chromium", "chromium-browser"] {
        for dir in std::env::var("PATH").unwrap_or_default().split(':') {
            let p = Path::new(dir).join(name);
            if p.is_file() {
                return p;
            }
        }
    }
    panic!(
        "headless Chromium is needed to test the viewer's pages and was not found on PATH: \
         install Debian's `chromium` package (apt-get install -y chromium)"
    );
}

/// Chromium headless on `url`, stopped after `timeout_ms` (the pages keep an event stream open,
/// so a virtual-time budget would never run out); its standard output.
fn chromium_run(url: &str, timeout_ms: u64, extra: &str, profile: &Path) -> String {
    let _ = std::fs::remove_dir_all(profile);
    let out = Command::new(chromium())
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-background-networking",
            "--no-first-run",
            "--hide-scrollbars",
            "--force-device-scale-factor=1",
            "--window-size=1400,860",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg(format!("--timeout={timeout_ms}"))
        .arg(extra)
        .arg(url)
        .stdin(Stdio::null())
        .stderr(Stdio::null())
        .output()
        .expect("start chromium");
    assert!(out.status.success(), "chromium failed on {url}");
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// A track label the page drew (`>t<digits><`), tried with longer timeouts on a loaded machine.
fn page_with_a_track(url: &str, label: &str, profile: &Path) -> String {
    let mut dom = String::new();
    for timeout in [5000, 15000, 40000] {
        dom = chromium_run(url, timeout, "--dump-dom", profile);
        if has_track_label(&dom, label) {
            break;
        }
    }
    dom
}

/// Whether `dom` holds `label` followed by `t<digits><` (a track's id on the page).
fn has_track_label(dom: &str, label: &str) -> bool {
    dom.match_indices(label).any(|(i, _)| {
        let rest = &dom[i + label.len()..];
        let digits = rest.strip_prefix('t').unwrap_or("");
        let n = digits.bytes().take_while(u8::is_ascii_digit).count();
        n > 0 && digits[n..].starts_with('<')
    })
}

#[test]
fn launch_serves_a_live_map_and_3d_view_with_tracks_in_a_real_browser() {
    let chromium_path = chromium();
    let dir = crate::harness::scratch("viewer");
    let child = Command::new(EXE)
        .args(["launch", "--duration", "300", "--quiet", "--view", "127.0.0.1:0"])
        .arg("--run-dir")
        .arg(dir.join("run"))
        .arg("--record")
        .arg(dir.join("rec.ocrec"))
        .env("RUST_LOG", "info")
        .env("NO_COLOR", "1")
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(dir.join("launch.log")).expect("log"))
        .spawn()
        .expect("spawning ocelli launch");
    let cluster = Cluster { child, dir };
    let addr = cluster.viewer();

    // The server feeds the viewer: a track with its global id shows up in the JSON snapshot,
    // and the metrics say the server is up and stepping.
    let deadline = now() + Duration::from_secs(180);
    let global = loop {
        let state: Option<Value> = get(&addr, "/api/state").and_then(|b| serde_json::from_str(&b).ok());
        if let Some(g) = state
            .as_ref()
            .and_then(|s| s["tracks"].as_array()?.first()?["global"].as_u64())
        {
            break g;
        }
        assert!(
            now() < deadline,
            "the viewer never showed a track; last state: {state:?}\nviewer log:\n{}",
            std::fs::read_to_string(cluster.dir.join("run/viewer.log")).unwrap_or_default()
        );
        std::thread::sleep(Duration::from_millis(500));
    };
    let metrics = get(&addr, "/metrics").expect("/metrics answers");
    assert!(metrics.contains("ocelli_node_up{"), "per-node up:\n{metrics}");
    assert!(metrics.contains("ocelli_tracks "), "tracks:\n{metrics}");
    eprintln!(
        "viewer at {addr} shows global track {global} ({})",
        chromium_path.display()
    );

    let profile = cluster.dir.join("chromium");
    let map = page_with_a_track(&format!("http://{addr}/"), "\">", &profile);
    assert!(
        has_track_label(&map, "\">"),
        "the map shows no track label:\n{}",
        &map[map.len().saturating_sub(3000)..]
    );
    let view3d = page_with_a_track(&format!("http://{addr}/3d"), "\">", &profile);
    assert!(
        view3d.contains("class=\"label3d\" data-global="),
        "the 3D view labels no track:\n{}",
        &view3d[view3d.len().saturating_sub(3000)..]
    );

    let docs = if std::env::var_os("OCELLI_WRITE_SCREENSHOTS").is_some_and(|v| v == "1") {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs")
    } else {
        profile.with_extension("shots")
    };
    std::fs::create_dir_all(&docs).expect("screenshot folder");
    for (path, file) in [("/", "view-live-map.png"), ("/3d", "view-live-3d.png")] {
        let png = docs.join(file);
        let _ = std::fs::remove_file(&png);
        chromium_run(
            &format!("http://{addr}{path}"),
            8000,
            &format!("--screenshot={}", png.display()),
            &profile,
        );
        let bytes = std::fs::read(&png).unwrap_or_else(|e| panic!("no screenshot {}: {e}", png.display()));
        assert!(
            bytes.starts_with(b"\x89PNG") && bytes.len() > 20_000,
            "{file}: {} bytes",
            bytes.len()
        );
    }
}
