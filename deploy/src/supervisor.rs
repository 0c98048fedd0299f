//! A supervisor for child processes: spawn each node in its own process group, watch for
//! crashes, stop in order with escalation (SIGTERM → wait → SIGKILL) and always reap — an
//! unreaped child keeps iceoryx2 from seeing that a node died.

use std::io;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

/// One supervised child.
#[derive(Debug)]
pub struct Supervised {
    pub name: String,
    child: Child,
    status: Option<ExitStatus>,
}

impl Supervised {
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    pub fn child_mut(&mut self) -> &mut Child {
        &mut self.child
    }

    /// The exit status once the child has ended (reaps it).
    pub fn poll(&mut self) -> Option<ExitStatus> {
        if self.status.is_none() {
            self.status = self.child.try_wait().ok().flatten();
        }
        self.status
    }
}

/// The children of a launch, stopped and reaped on drop.
#[derive(Debug, Default)]
pub struct Supervisor {
    children: Vec<Supervised>,
    /// How long a child gets between SIGTERM and SIGKILL.
    pub grace: Duration,
}

/// Signal a child's whole process group (it leads its own group, see [`Supervisor::spawn`]), so
/// grandchildren are stopped too. The child is not reaped yet, so its pid cannot be reused.
fn signal_group(pid: u32, sig: libc::c_int) {
    #[allow(unsafe_code)]
    // SAFETY: kill(2) has no memory-safety preconditions.
    unsafe {
        libc::kill(-(pid as libc::pid_t), sig);
    }
}

/// SIGKILL the given process groups (children of a supervisor busy stopping elsewhere); the
/// supervisor still reaps them.
pub fn kill_groups(groups: &[u32]) {
    for &g in groups {
        signal_group(g, libc::SIGKILL);
    }
}

impl Supervisor {
    pub fn new(grace: Duration) -> Self {
        Supervisor {
            children: Vec::new(),
            grace,
        }
    }

    /// Spawn `cmd` as `name`, in its own process group so a terminal Ctrl-C reaches only the
    /// supervisor, which then stops children in order.
    ///
    /// # Errors
    /// The spawn error, naming the child.
    pub fn spawn(&mut self, name: impl Into<String>, mut cmd: Command) -> io::Result<&mut Supervised> {
        use std::os::unix::process::CommandExt;
        let name = name.into();
        cmd.process_group(0).stdin(Stdio::null());
        let child = cmd
            .spawn()
            .map_err(|e| io::Error::new(e.kind(), format!("cannot start {name}: {e}")))?;
        self.children.push(Supervised {
            name,
            child,
            status: None,
        });
        Ok(self.children.last_mut().expect("just pushed"))
    }

    pub fn children_mut(&mut self) -> &mut [Supervised] {
        &mut self.children
    }

    /// Children that have ended since the last call, with their status.
    pub fn reap_ended(&mut self) -> Vec<(String, ExitStatus)> {
        let mut ended = Vec::new();
        for c in &mut self.children {
            let was = c.status.is_some();
            if let Some(s) = c.poll()
                && !was
            {
                ended.push((c.name.clone(), s));
            }
        }
        ended
    }

    /// Find a child by name.
    pub fn get_mut(&mut self, name: &str) -> Option<&mut Supervised> {
        self.children.iter_mut().find(|c| c.name == name)
    }

    /// Stop the named children (in the given order): SIGTERM each, wait up to `grace` for all,
    /// SIGKILL what remains, reap everything. Returns names that had to be killed.
    pub fn stop(&mut self, names: &[String]) -> Vec<String> {
        let targets: Vec<usize> = names
            .iter()
            .filter_map(|n| self.children.iter().position(|c| &c.name == n))
            .collect();
        for &i in &targets {
            let c = &mut self.children[i];
            if c.poll().is_none() {
                signal_group(c.pid(), libc::SIGTERM);
            }
        }
        #[allow(clippy::disallowed_methods)] // the supervisor is a runtime, it owns a clock
        let deadline = Instant::now() + self.grace;
        let mut killed = Vec::new();
        loop {
            let pending = targets
                .iter()
                .filter(|&&i| self.children[i].poll().is_none())
                .count();
            #[allow(clippy::disallowed_methods)]
            let now = Instant::now();
            if pending == 0 {
                break;
            }
            if now >= deadline {
                for &i in &targets {
                    let c = &mut self.children[i];
                    if c.poll().is_none() {
                        signal_group(c.pid(), libc::SIGKILL);
                        c.status = c.child.wait().ok();
                        killed.push(c.name.clone());
                    }
                }
                break;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        killed
    }

    /// Stop every child, most recently started first (cameras before heads before the server,
    /// so the server records to the end).
    pub fn stop_all(&mut self) -> Vec<String> {
        let names: Vec<String> = self.children.iter().rev().map(|c| c.name.clone()).collect();
        self.stop(&names)
    }

    /// Process-group ids of the children still running (for [`kill_groups`] from elsewhere).
    pub fn running_groups(&mut self) -> Vec<u32> {
        self.children
            .iter_mut()
            .filter_map(|c| c.poll().is_none().then(|| c.pid()))
            .collect()
    }

    /// Kill every child at once and reap (second Ctrl-C).
    pub fn kill_all(&mut self) {
        for c in &mut self.children {
            if c.poll().is_none() {
                signal_group(c.pid(), libc::SIGKILL);
                c.status = c.child.wait().ok();
            }
        }
    }
}

impl Drop for Supervisor {
    fn drop(&mut self) {
        if self.children.iter_mut().any(|c| c.poll().is_none()) {
            self.stop_all();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stop_terminates_and_reaps_children_and_kills_those_ignoring_sigterm() {
        let mut sup = Supervisor::new(Duration::from_millis(300));
        let mut polite = Command::new("sleep");
        polite.arg("30");
        sup.spawn("polite", polite).unwrap();
        let mut stubborn = Command::new("sh");
        stubborn.args(["-c", "trap '' TERM; sleep 30 & wait"]);
        sup.spawn("stubborn", stubborn).unwrap();
        std::thread::sleep(Duration::from_millis(100));
        let killed = sup.stop_all();
        assert_eq!(killed, vec!["stubborn".to_string()]);
        for c in sup.children_mut() {
            assert!(c.poll().is_some(), "{} was not reaped", c.name);
        }
    }

    #[test]
    fn a_crashed_child_is_reported_once() {
        let mut sup = Supervisor::new(Duration::from_millis(100));
        let mut cmd = Command::new("sh");
        cmd.args(["-c", "exit 3"]);
        sup.spawn("crasher", cmd).unwrap();
        let mut ended = Vec::new();
        for _ in 0..100 {
            ended.extend(sup.reap_ended());
            if !ended.is_empty() {
                break;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        assert_eq!(ended.len(), 1);
        assert_eq!(ended[0].1.code(), Some(3));
        assert!(sup.reap_ended().is_empty());
    }
}
