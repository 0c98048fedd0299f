//! A supervisor for child processes: spawn each node in its own process group, tied to the
//! supervisor's life (a child gets SIGTERM when the supervisor dies, even by SIGKILL), restart
//! a child that ended on its own with exponential backoff, stop in order with escalation
//! (SIGTERM → wait → SIGKILL) and always reap — an unreaped child keeps iceoryx2 from seeing
//! that a node died.
//!
//! A child the supervisor kills on purpose ([`Supervisor::chaos_kill`], `ocelli launch
//! --chaos-every`) is restarted after the first delay and never counts towards giving up; a
//! crash still does.
//!
//! Time is passed in ([`Supervisor::watch`] takes `now`), so the restart schedule is a plain
//! function of when children ended.

use std::fmt;
use std::io;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

/// Builds a child's command afresh for each start (a `Command` cannot be reused once spawned).
pub type MakeCommand = Box<dyn FnMut() -> io::Result<Command> + Send>;

/// When and how often a child that ended on its own is started again.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RestartPolicy {
    /// Wait before the first restart; doubled for each further one in a row.
    pub first_delay: Duration,
    /// The longest wait between restarts.
    pub max_delay: Duration,
    /// A child that ran this long before it ended counts as healthy: its next restart is a
    /// first one again.
    pub stable_after: Duration,
    /// Restarts in a row (each run shorter than `stable_after`) before giving up on a child.
    pub max_in_a_row: u32,
}

impl Default for RestartPolicy {
    fn default() -> Self {
        RestartPolicy {
            first_delay: Duration::from_millis(500),
            max_delay: Duration::from_secs(30),
            stable_after: Duration::from_secs(30),
            max_in_a_row: 5,
        }
    }
}

impl RestartPolicy {
    /// The wait before restart number `n` in a row (1-based).
    pub fn delay(&self, n: u32) -> Duration {
        let factor = 1u32.checked_shl(n.saturating_sub(1)).unwrap_or(u32::MAX);
        self.first_delay.saturating_mul(factor).min(self.max_delay)
    }
}

/// Where a supervised child is in its life.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    Running {
        since: Instant,
    },
    /// Ended on its own with `status`; started again at `at`.
    Waiting {
        at: Instant,
        status: ExitStatus,
    },
    /// Ended and stays so (stopped, or given up on).
    Ended(ExitStatus),
}

/// One supervised child.
pub struct Supervised {
    pub name: String,
    make: MakeCommand,
    child: Child,
    state: State,
    /// Restarts in a row without a stable run.
    in_a_row: u32,
    /// Restarts over the child's whole life.
    pub restarts: u32,
    /// Killed on purpose by [`Supervisor::chaos_kill`]; its next restart is not a failure's.
    chaos_killed: bool,
}

impl fmt::Debug for Supervised {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Supervised")
            .field("name", &self.name)
            .field("pid", &self.child.id())
            .field("state", &self.state)
            .field("restarts", &self.restarts)
            .finish_non_exhaustive()
    }
}

impl Supervised {
    /// The pid of the child's current (or last) process.
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// Whether the child's process is running now (reaps it if it ended).
    pub fn running(&mut self) -> bool {
        self.try_reap();
        matches!(self.state, State::Running { .. })
    }

    /// The status it ended with, while it is not running.
    fn try_reap(&mut self) -> Option<ExitStatus> {
        if let State::Running { .. } = self.state {
            let status = self.child.try_wait().ok().flatten()?;
            // Seen ended here first: the caller decides what follows (`watch` restarts).
            self.state = State::Ended(status);
            return Some(status);
        }
        None
    }
}

/// What [`Supervisor::watch`] saw happen.
#[derive(Debug)]
pub enum Event {
    /// A child ended on its own; it is started again after `restart_in`, or not at all.
    Ended {
        name: String,
        status: ExitStatus,
        restart_in: Option<Duration>,
    },
    /// A child was started again (its `n`-th restart in a row; `after_chaos`: it had been
    /// killed on purpose, which does not count).
    Restarted {
        name: String,
        pid: u32,
        n: u32,
        after_chaos: bool,
    },
    /// The supervisor killed a running child on purpose ([`Supervisor::chaos_kill`]); it is
    /// started again after `restart_in`.
    ChaosKilled {
        name: String,
        pid: u32,
        restart_in: Duration,
    },
    /// A child kept ending soon after each start; it is left stopped.
    GaveUp { name: String, restarts: u32 },
    /// A child could not be started again.
    RestartFailed { name: String, error: io::Error },
}

impl fmt::Display for Event {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Event::Ended {
                name,
                status,
                restart_in: Some(d),
            } => write!(
                f,
                "{name} ended ({}); restarting it in {:.1} s",
                describe(*status),
                d.as_secs_f64()
            ),
            Event::Ended {
                name,
                status,
                restart_in: None,
            } => write!(f, "{name} ended ({})", describe(*status)),
            Event::Restarted {
                name,
                pid,
                after_chaos: true,
                ..
            } => write!(f, "{name} restarted as pid {pid} (after a chaos kill)"),
            Event::Restarted { name, pid, n, .. } => {
                write!(f, "{name} restarted as pid {pid} (restart {n} in a row)")
            }
            Event::ChaosKilled {
                name,
                pid,
                restart_in,
            } => write!(
                f,
                "chaos: killed {name} (pid {pid}); restarting it in {:.1} s",
                restart_in.as_secs_f64()
            ),
            Event::GaveUp { name, restarts } => write!(
                f,
                "{name} gave up after {restarts} restarts in a row, each ending within moments; \
                 see its log"
            ),
            Event::RestartFailed { name, error } => write!(f, "{name} could not be restarted: {error}"),
        }
    }
}

/// An exit status in words: `exit code 3`, `killed by signal 9`.
pub fn describe(status: ExitStatus) -> String {
    use std::os::unix::process::ExitStatusExt;
    match (status.code(), status.signal()) {
        (Some(c), _) => format!("exit code {c}"),
        (None, Some(s)) => format!("killed by signal {s}"),
        _ => status.to_string(),
    }
}

/// The children of a launch, stopped and reaped on drop.
pub struct Supervisor {
    children: Vec<Supervised>,
    /// How long a child gets between SIGTERM and SIGKILL.
    pub grace: Duration,
    /// Restart children that end on their own (none: leave them ended).
    pub restart: Option<RestartPolicy>,
}

impl fmt::Debug for Supervisor {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Supervisor")
            .field("children", &self.children)
            .field("grace", &self.grace)
            .field("restart", &self.restart)
            .finish()
    }
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

/// Start `cmd` in its own process group (so a terminal's Ctrl-C reaches only the supervisor,
/// which stops children in order) with SIGTERM as its parent-death signal (so a supervisor
/// killed outright takes its children with it).
fn start(name: &str, mut cmd: Command) -> io::Result<Child> {
    use std::os::unix::process::CommandExt;
    let parent = std::process::id();
    cmd.process_group(0).stdin(Stdio::null());
    #[allow(unsafe_code)]
    // SAFETY: between fork and exec the closure only calls async-signal-safe functions
    // (prctl, getppid, _exit) and allocates nothing.
    unsafe {
        cmd.pre_exec(move || {
            if libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM) != 0 {
                return Err(io::Error::last_os_error());
            }
            // The parent died before the signal was armed: nothing would stop this child.
            if libc::getppid() as u32 != parent {
                libc::_exit(1);
            }
            Ok(())
        });
    }
    cmd.spawn()
        .map_err(|e| io::Error::new(e.kind(), format!("cannot start {name}: {e}")))
}

impl Supervisor {
    pub fn new(grace: Duration, restart: Option<RestartPolicy>) -> Self {
        Supervisor {
            children: Vec::new(),
            grace,
            restart,
        }
    }

    /// Start a child named `name` from the command `make` builds (called again for each
    /// restart). Spawn from the thread that keeps running for the supervisor's whole life: the
    /// parent-death signal follows the spawning thread.
    ///
    /// # Errors
    /// The command cannot be built or started, naming the child.
    pub fn spawn(
        &mut self,
        name: impl Into<String>,
        mut make: MakeCommand,
        now: Instant,
    ) -> io::Result<&mut Supervised> {
        let name = name.into();
        let child = start(&name, make()?)?;
        self.children.push(Supervised {
            name,
            make,
            child,
            state: State::Running { since: now },
            in_a_row: 0,
            restarts: 0,
            chaos_killed: false,
        });
        Ok(self.children.last_mut().expect("just pushed"))
    }

    pub fn children_mut(&mut self) -> &mut [Supervised] {
        &mut self.children
    }

    /// Find a child by name.
    pub fn get_mut(&mut self, name: &str) -> Option<&mut Supervised> {
        self.children.iter_mut().find(|c| c.name == name)
    }

    /// Reap children that ended, schedule their restarts and start those that are due.
    pub fn watch(&mut self, now: Instant) -> Vec<Event> {
        let policy = self.restart;
        let mut events = Vec::new();
        for c in &mut self.children {
            let since = match c.state {
                State::Running { since } => since,
                State::Waiting { at, status } if now >= at => {
                    restart(c, now, status, policy.unwrap_or_default(), &mut events);
                    continue;
                }
                State::Waiting { .. } | State::Ended(_) => continue,
            };
            let Some(status) = c.try_reap() else { continue };
            let Some(policy) = policy else {
                events.push(Event::Ended {
                    name: c.name.clone(),
                    status,
                    restart_in: None,
                });
                continue;
            };
            if now.saturating_duration_since(since) >= policy.stable_after {
                c.in_a_row = 0;
            }
            if c.in_a_row >= policy.max_in_a_row {
                events.push(Event::Ended {
                    name: c.name.clone(),
                    status,
                    restart_in: None,
                });
                events.push(Event::GaveUp {
                    name: c.name.clone(),
                    restarts: c.in_a_row,
                });
                continue;
            }
            let delay = policy.delay(c.in_a_row + 1);
            c.state = State::Waiting {
                at: now + delay,
                status,
            };
            events.push(Event::Ended {
                name: c.name.clone(),
                status,
                restart_in: Some(delay),
            });
        }
        events
    }

    /// Kill the running child `name` on purpose (SIGKILL to its group, reaped at once) and
    /// schedule its restart after the policy's first delay, not counted towards giving up. A
    /// child that is not running, or a supervisor without a restart policy, is left alone.
    /// The event says who was killed and when it comes back.
    pub fn chaos_kill(&mut self, name: &str, now: Instant) -> Option<Event> {
        let policy = self.restart?;
        let c = self.children.iter_mut().find(|c| c.name == name)?;
        let State::Running { since } = c.state else {
            return None;
        };
        // Ended on its own already: a crash, for `watch` to count (std keeps the status).
        if !matches!(c.child.try_wait(), Ok(None)) {
            return None;
        }
        let pid = c.pid();
        signal_group(pid, libc::SIGKILL);
        let status = c.child.wait().ok()?;
        if now.saturating_duration_since(since) >= policy.stable_after {
            c.in_a_row = 0;
        }
        c.chaos_killed = true;
        c.state = State::Waiting {
            at: now + policy.first_delay,
            status,
        };
        Some(Event::ChaosKilled {
            name: c.name.clone(),
            pid,
            restart_in: policy.first_delay,
        })
    }

    /// Stop the named children (in the given order): SIGTERM each, wait up to `grace` for all,
    /// SIGKILL what remains, reap everything; none is restarted. Returns names that had to be
    /// killed.
    pub fn stop(&mut self, names: &[String]) -> Vec<String> {
        let targets: Vec<usize> = names
            .iter()
            .filter_map(|n| self.children.iter().position(|c| &c.name == n))
            .collect();
        for &i in &targets {
            let c = &mut self.children[i];
            match c.state {
                State::Running { .. } => {
                    if c.try_reap().is_none() {
                        signal_group(c.pid(), libc::SIGTERM);
                    }
                }
                // A pending restart is called off; the last status stands.
                State::Waiting { status, .. } => c.state = State::Ended(status),
                State::Ended(_) => {}
            }
        }
        #[allow(clippy::disallowed_methods)] // the supervisor is a runtime, it owns a clock
        let deadline = Instant::now() + self.grace;
        let mut killed = Vec::new();
        loop {
            let pending = targets.iter().filter(|&&i| self.children[i].running()).count();
            if pending == 0 {
                break;
            }
            #[allow(clippy::disallowed_methods)]
            let now = Instant::now();
            if now >= deadline {
                for &i in &targets {
                    let c = &mut self.children[i];
                    if c.running() {
                        signal_group(c.pid(), libc::SIGKILL);
                        if let Ok(s) = c.child.wait() {
                            c.state = State::Ended(s);
                        }
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
            .filter_map(|c| c.running().then(|| c.pid()))
            .collect()
    }
}

/// Start `c` (which ended with `status`) again now; if it cannot start, try again after the
/// next delay, or give up.
fn restart(
    c: &mut Supervised,
    now: Instant,
    status: ExitStatus,
    policy: RestartPolicy,
    events: &mut Vec<Event>,
) {
    let after_chaos = std::mem::take(&mut c.chaos_killed);
    let started = (c.make)().and_then(|cmd| start(&c.name, cmd));
    // A kill made on purpose is no failure; failing to start again always is.
    if !after_chaos || started.is_err() {
        c.in_a_row += 1;
    }
    match started {
        Ok(child) => {
            c.child = child;
            c.state = State::Running { since: now };
            c.restarts += 1;
            events.push(Event::Restarted {
                name: c.name.clone(),
                pid: c.pid(),
                n: c.in_a_row,
                after_chaos,
            });
        }
        Err(error) => {
            events.push(Event::RestartFailed {
                name: c.name.clone(),
                error,
            });
            if c.in_a_row >= policy.max_in_a_row {
                c.state = State::Ended(status);
                events.push(Event::GaveUp {
                    name: c.name.clone(),
                    restarts: c.in_a_row,
                });
            } else {
                c.state = State::Waiting {
                    at: now + policy.delay(c.in_a_row + 1),
                    status,
                };
            }
        }
    }
}

impl Drop for Supervisor {
    fn drop(&mut self) {
        if self.children.iter_mut().any(Supervised::running) {
            self.stop_all();
        }
    }
}

#[cfg(test)]
mod tests;
