//! What the process tests share: the CLI under test, the harness clock, signals, and reading a
//! recording's tracks back through `ocelli export`.

use serde_json::Value;
use std::path::Path;
use std::process::Command;

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
