//! CPU time and memory per role of a launch: every child process's `/proc/PID/stat` (user and
//! system CPU time, all its threads) and `/proc/PID/status` (resident set now and at its peak)
//! read once, just before the launch stops its nodes, and summed per role. A node restarted
//! during the run counts only its last process. Linux only; elsewhere nothing is read.

use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt::Write as _;

/// One process's figures.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ProcessUsage {
    /// User plus system CPU seconds.
    pub cpu_s: f64,
    pub rss_kib: u64,
    /// Peak resident set, KiB.
    pub peak_rss_kib: u64,
}

/// One role's processes together.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RoleUsage {
    pub role: String,
    pub processes: usize,
    /// CPU seconds of all of them.
    pub cpu_s: f64,
    /// Mean CPU of one process, in per cent of one core over the run's wall time.
    pub cpu_percent_per_process: f64,
    /// All of them, in cores.
    pub cores: f64,
    /// Mean resident set of one process at the end, MiB.
    pub rss_mib_per_process: f64,
    /// The largest peak resident set of one process, MiB.
    pub peak_rss_mib_max: f64,
    /// Resident sets of all of them at the end, MiB.
    pub rss_mib_total: f64,
}

/// User plus system CPU clock ticks from the text of `/proc/PID/stat` (fields 14 and 15; the
/// command name in parentheses may hold spaces, so fields are counted after its `)`).
pub fn parse_stat_ticks(stat: &str) -> Option<u64> {
    let rest = &stat[stat.rfind(')')? + 1..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    // After the name: state is field 3, so utime (14) and stime (15) are at 11 and 12.
    let utime: u64 = f.get(11)?.parse().ok()?;
    let stime: u64 = f.get(12)?.parse().ok()?;
    Some(utime + stime)
}

/// A `kB` line of `/proc/PID/status` (`VmRSS`, `VmHWM`), KiB.
pub fn parse_status_kib(status: &str, key: &str) -> Option<u64> {
    status.lines().find_map(|l| {
        let v = l.strip_prefix(key)?.strip_prefix(':')?;
        v.split_whitespace().next()?.parse().ok()
    })
}

/// The figures of process `pid`, `None` when it is gone or `/proc` cannot be read.
pub fn sample(pid: u32) -> Option<ProcessUsage> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    #[allow(unsafe_code)]
    // SAFETY: sysconf(3) only reads a configuration value.
    let hz = unsafe { libc::sysconf(libc::_SC_CLK_TCK) };
    let hz = if hz > 0 { hz as f64 } else { 100.0 };
    Some(ProcessUsage {
        cpu_s: parse_stat_ticks(&stat)? as f64 / hz,
        rss_kib: parse_status_kib(&status, "VmRSS").unwrap_or(0),
        peak_rss_kib: parse_status_kib(&status, "VmHWM").unwrap_or(0),
    })
}

/// The role of a child named `role-id` (`camera-100` → `camera`).
fn role_of(name: &str) -> &str {
    name.rsplit_once('-').map_or(name, |(role, _)| role)
}

/// Per-role sums of `(child name, figures)` over `wall_s` seconds of run, roles in name order.
pub fn by_role(samples: &[(String, ProcessUsage)], wall_s: f64) -> Vec<RoleUsage> {
    let mut groups: BTreeMap<&str, Vec<&ProcessUsage>> = BTreeMap::new();
    for (name, u) in samples {
        groups.entry(role_of(name)).or_default().push(u);
    }
    let mib = |kib: u64| kib as f64 / 1024.0;
    groups
        .into_iter()
        .map(|(role, us)| {
            let n = us.len();
            let cpu_s: f64 = us.iter().map(|u| u.cpu_s).sum();
            let rss: u64 = us.iter().map(|u| u.rss_kib).sum();
            let cores = if wall_s > 0.0 { cpu_s / wall_s } else { 0.0 };
            RoleUsage {
                role: role.to_string(),
                processes: n,
                cpu_s,
                cpu_percent_per_process: 100.0 * cores / n as f64,
                cores,
                rss_mib_per_process: mib(rss) / n as f64,
                peak_rss_mib_max: us.iter().map(|u| mib(u.peak_rss_kib)).fold(0.0, f64::max),
                rss_mib_total: mib(rss),
            }
        })
        .collect()
}

/// The table printed after a launch's report.
pub fn to_table(roles: &[RoleUsage], wall_s: f64) -> String {
    let mut s = format!("\nprocesses over {wall_s:.1} s (CPU in % of one core; memory resident)\n");
    let _ = writeln!(
        s,
        "{:>8} {:>5} {:>9} {:>7} {:>10} {:>12} {:>13} {:>10}",
        "role", "procs", "cpu s", "cores", "cpu%/proc", "rss MiB/proc", "peak MiB max", "rss MiB"
    );
    for r in roles {
        let _ = writeln!(
            s,
            "{:>8} {:>5} {:>9.1} {:>7.2} {:>10.1} {:>12.1} {:>13.1} {:>10.0}",
            r.role,
            r.processes,
            r.cpu_s,
            r.cores,
            r.cpu_percent_per_process,
            r.rss_mib_per_process,
            r.peak_rss_mib_max,
            r.rss_mib_total
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stat_fields_are_counted_after_the_command_name() {
        // A name with a space and a parenthesis in it; utime 1500, stime 250.
        let stat =
            "4242 (ocelli (x) y) S 1 4242 4242 0 -1 4194560 900 0 0 0 1500 250 0 0 20 0 9 0 100 1000 200";
        assert_eq!(parse_stat_ticks(stat), Some(1750));
        assert_eq!(parse_stat_ticks("4242 (short) S 1"), None);
        let status = "Name:\tocelli\nVmHWM:\t   20480 kB\nVmRSS:\t   10240 kB\n";
        assert_eq!(parse_status_kib(status, "VmRSS"), Some(10240));
        assert_eq!(parse_status_kib(status, "VmHWM"), Some(20480));
        assert_eq!(parse_status_kib(status, "VmSwap"), None);
    }

    #[test]
    fn roles_sum_their_processes() {
        let u = |cpu_s: f64, rss_kib: u64, peak_rss_kib: u64| ProcessUsage {
            cpu_s,
            rss_kib,
            peak_rss_kib,
        };
        let samples = vec![
            ("camera-100".to_string(), u(10.0, 1024, 2048)),
            ("camera-101".to_string(), u(20.0, 3072, 4096)),
            ("head-2".to_string(), u(30.0, 10240, 10240)),
        ];
        let roles = by_role(&samples, 60.0);
        assert_eq!(roles.len(), 2);
        let cam = &roles[0];
        assert_eq!((cam.role.as_str(), cam.processes), ("camera", 2));
        assert!((cam.cores - 0.5).abs() < 1e-12 && (cam.cpu_percent_per_process - 25.0).abs() < 1e-12);
        assert_eq!(
            (cam.rss_mib_per_process, cam.peak_rss_mib_max, cam.rss_mib_total),
            (2.0, 4.0, 4.0)
        );
        assert_eq!(roles[1].role, "head");
        assert!(to_table(&roles, 60.0).contains("camera"));
        // The launcher itself can be read.
        let me = sample(std::process::id()).expect("/proc/self");
        assert!(me.rss_kib > 0 && me.cpu_s >= 0.0);
    }
}
