//! What the process tests share: the CLI under test, the harness clock, signals, and reading a
//! recording's tracks back through `ocelli export`.

use serde_json::Value;
use std::path::Path;
use std::process::{Child, Command, ExitStatus};
use std::time::Duration;

/// The `ocelli` CLI under test.
pub const EXE: &str = env!("CARGO_BIN_EXE_ocelli-e2e");

/// The harness's own clock, for wait deadlines (never asserted on).
#[allow(clippy::disallowed_methods)]
pub fn now() -> std::time::Instant {
    std::time::Instant::now()
}

/// Cluster time now, seconds: a launch's cluster time is the wall clock (for marking when the
/// harness did something to a run; never asserted on by itself).
#[allow(clippy::disallowed_methods)]
pub fn cluster_now_s() -> f64 {
    proto::ClusterTime::wall_clock().as_secs_f64()
}

pub fn signal(pid: u32, sig: libc::c_int) {
    #[allow(unsafe_code)]
    // SAFETY: kill(2) has no memory-safety preconditions.
    unsafe {
        libc::kill(pid as libc::pid_t, sig);
    }
}

/// The owner track rows of a recording (`ocelli export --format jsonl`); none while the
/// recording does not exist yet.
pub fn owner_rows(record: &Path) -> Vec<Value> {
    if !record.exists() {
        return Vec::new();
    }
    let out = Command::new(EXE)
        .args(["export", "--format", "jsonl"])
        .arg(record)
        .env("RUST_LOG", "error")
        .output()
        .expect("ocelli export");
    assert!(
        out.status.success(),
        "export failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str::<Value>(l).expect("export JSON line"))
        .filter(|r| r["owner"].as_bool() == Some(true))
        .collect()
}

/// A fresh, empty scratch folder for one test, named for it: removed when dropped, kept (and
/// its path printed) when the test is failing, for its logs and recording.
pub fn scratch(name: &str) -> Scratch {
    let dir = tempfile::Builder::new()
        .prefix(&format!("ocelli-e2e-{name}-"))
        .tempdir()
        .expect("scratch dir");
    Scratch(dir)
}

/// See [`scratch`].
#[derive(Debug)]
pub struct Scratch(tempfile::TempDir);

impl std::ops::Deref for Scratch {
    type Target = Path;

    fn deref(&self) -> &Path {
        self.0.path()
    }
}

impl AsRef<Path> for Scratch {
    fn as_ref(&self) -> &Path {
        self
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        if std::thread::panicking() {
            self.0.disable_cleanup(true);
            eprintln!("kept for the failing test: {}", self.0.path().display());
        }
    }
}

/// Whether process `pid` still exists.
pub fn alive(pid: u32) -> bool {
    #[allow(unsafe_code)]
    // SAFETY: signal 0 only checks for existence.
    let r = unsafe { libc::kill(pid as libc::pid_t, 0) };
    r == 0
}

/// Wait for `child` to exit by itself within `within`; its status and standard output. Past
/// the deadline it is killed and the test fails with `log()` (the launch's log).
pub fn wait_exit(mut child: Child, within: Duration, log: impl Fn() -> String) -> (ExitStatus, String) {
    let deadline = now() + within;
    let status = loop {
        if let Some(s) = child.try_wait().expect("try_wait") {
            break s;
        }
        if now() >= deadline {
            let _ = child.kill();
            let _ = child.wait();
            panic!("the process did not exit within {within:?}; log:\n{}", log());
        }
        std::thread::sleep(Duration::from_millis(100));
    };
    let mut out = String::new();
    use std::io::Read;
    let _ = child.stdout.take().expect("stdout").read_to_string(&mut out);
    (status, out)
}
