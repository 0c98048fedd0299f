//! `ocelli launch`: every node of a scenario on this host, each its own OS process, supervised.
//!
//! A launch claims its own run folder ([`run_dir`]), writes the effective scenario there (a
//! domain of its own, free TCP ports), starts the server, the heads and the cameras as
//! `ocelli server|head|camera` children and the visualization node as `ocelli viewer` (its URL
//! printed), each tied to the launcher's life, each logging to its own file, each restarted with
//! backoff if it crashes, shows live progress read from the server's recording as it grows
//! ([`progress`]), and stops in order on SIGINT, SIGTERM or SIGHUP or after the duration.
//! Whatever happened to the children, it reaps them all, removes the domain's iceoryx2 files
//! from `/dev/shm` and reports on the recording exactly as `ocelli report` does, with what the
//! nodes could not deliver from their exit summaries ([`undelivered`]). Over TCP the
//! nodes speak mutual TLS with a CA and certificates made for the run (`run-dir/tls`), or plain
//! TCP if the scenario (or `--insecure`) says `insecure`.

mod acoustic;
pub mod chaos;
pub mod latency;
pub mod progress;
pub mod run_dir;
pub mod undelivered;
pub mod usage;

use crate::supervisor::{Event, MakeCommand, RestartPolicy, Supervisor};
use anyhow::{Context, Result};
use lab::report::RecordingReport;
use progress::Progress;
use proto::ClusterTime;
use proto::scenario::{NodeRole, Scenario, TransportKind};
use run_dir::RunDir;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// What to launch and how.
#[derive(Clone, Debug)]
pub struct LaunchOptions {
    pub transport: TransportKind,
    pub duration: Option<Duration>,
    /// The run's folder (default: a new time-stamped one under `ocelli-runs/`).
    pub run_dir: Option<PathBuf>,
    /// The server's recording (default: `recording.ocrec` in the run's folder).
    pub record: Option<PathBuf>,
    /// Write over an existing run folder or recording.
    pub force: bool,
    /// Print live progress lines on standard error.
    pub progress: bool,
    /// A logging run: every camera measures every frame and the server records it.
    pub record_measurements: bool,
    /// Children log JSON lines (the launcher's `--log-json`).
    pub log_json: bool,
    /// Restart crashed nodes (none: leave them down).
    pub restart: Option<RestartPolicy>,
    /// Start the viewer serving here (`None`: no viewer).
    pub view: Option<std::net::SocketAddr>,
    /// Kill random nodes at random times for the supervisor to restart (needs `restart`).
    pub chaos: Option<chaos::ChaosOptions>,
    /// Nodes of the scenario not to start here (they run on other hosts, or are left out to
    /// see how the others cope); never the server, whose recording the launch reports on.
    pub skip: Vec<u32>,
}

/// What a launch leaves behind.
#[derive(Debug)]
pub struct Launched {
    pub run: RunDir,
    /// The recording's report, as `ocelli report` computes it.
    pub report: RecordingReport,
    /// Restarts per node that needed any.
    pub restarts: BTreeMap<String, u32>,
    /// CPU and memory per role, read just before the nodes were stopped.
    pub usage: Vec<usage::RoleUsage>,
    /// Seconds from the start of the nodes to that reading.
    pub wall_s: f64,
    /// What the nodes could not deliver, during the run and at its stop (their exit summaries).
    pub undelivered: undelivered::Undelivered,
}

/// A free loopback port, with the socket that holds it: the caller keeps it until every port
/// of the launch is chosen (released at once, the kernel may hand the same port out again: a
/// 100-camera hall once got one port for two heads), then drops it so the child can bind.
fn free_port() -> Result<(u16, std::net::TcpListener)> {
    let l = std::net::TcpListener::bind("127.0.0.1:0")?;
    Ok((l.local_addr()?.port(), l))
}

/// The scenario as this launch runs it: its own iceoryx2 domain and, over TCP, free ports.
///
/// # Errors
/// No free loopback port.
pub fn effective_scenario(mut s: Scenario, transport: TransportKind) -> Result<Scenario> {
    s.network.transport = transport;
    s.network.domain = format!("ocelli-{}", std::process::id());
    if transport == TransportKind::Tcp {
        let mut held = Vec::new();
        for n in &mut s.nodes {
            if matches!(n.role, NodeRole::Head | NodeRole::Server) {
                let (port, socket) = free_port()?;
                n.listen = Some(format!("127.0.0.1:{port}"));
                held.push(socket);
            }
        }
    }
    Ok(s)
}

/// How to start one node process.
#[derive(Clone)]
struct Spawn {
    exe: PathBuf,
    scenario_path: PathBuf,
    epoch: ClusterTime,
    opts: LaunchOptions,
    recording: PathBuf,
    /// The run's certificates (TCP with TLS).
    tls_dir: Option<PathBuf>,
}

impl Spawn {
    /// The command that starts node `id` as `role`, logging to `log` and appending its exit
    /// summary to `exit` (both appended to, so a restarted node's follow its previous run's).
    fn command(&self, role: &'static str, id: u32, log: PathBuf, exit: PathBuf) -> MakeCommand {
        let how = self.clone();
        Box::new(move || {
            let mut cmd = how.base(role);
            cmd.arg("--id").arg(id.to_string());
            cmd.arg("--exit-summary").arg(&exit);
            match role {
                // The recording says where scenario time 0 is and that the world is simulated.
                "server" => {
                    cmd.arg("--record").arg(&how.recording);
                    cmd.arg("--epoch-ns")
                        .arg(how.epoch.0.to_string())
                        .arg("--simulated");
                }
                "acoustic" => {
                    cmd.arg("--epoch-ns").arg(how.epoch.0.to_string());
                }
                // Scenario time 0 for the synthetic world, the same for every camera.
                "camera" => {
                    cmd.arg("--epoch-ns").arg(how.epoch.0.to_string());
                    if how.opts.record_measurements {
                        cmd.arg("--record-measurements");
                    }
                }
                _ => {}
            }
            let file = std::fs::OpenOptions::new().create(true).append(true).open(&log)?;
            cmd.stdout(Stdio::null()).stderr(file);
            Ok(cmd)
        })
    }

    /// `ocelli [--log-json] ROLE --scenario … --transport … [--tls-dir …]`: what every child
    /// is started with.
    fn base(&self, role: &str) -> Command {
        let mut cmd = Command::new(&self.exe);
        if self.opts.log_json {
            cmd.arg("--log-json");
        }
        cmd.arg(role)
            .arg("--scenario")
            .arg(&self.scenario_path)
            .arg("--transport")
            .arg(match self.opts.transport {
                TransportKind::Ipc => "ipc",
                TransportKind::Tcp => "tcp",
            });
        if let Some(dir) = &self.tls_dir {
            cmd.arg("--tls-dir").arg(dir);
        }
        cmd
    }

    /// The viewer, a client of the server over the launch's transport, serving `addr`, logging
    /// to `log`, its exit summary to `exit`.
    fn viewer_command(&self, addr: std::net::SocketAddr, log: PathBuf, exit: PathBuf) -> MakeCommand {
        let how = self.clone();
        Box::new(move || {
            let mut cmd = how.base("viewer");
            cmd.arg("--listen").arg(addr.to_string());
            cmd.arg("--exit-summary").arg(&exit);
            let file = std::fs::OpenOptions::new().create(true).append(true).open(&log)?;
            cmd.stdout(Stdio::null()).stderr(file);
            Ok(cmd)
        })
    }
}

#[allow(clippy::disallowed_methods)] // the launcher is a runtime: it owns the clock
fn instant_now() -> Instant {
    Instant::now()
}

#[allow(clippy::disallowed_methods)] // the launcher is a runtime: it owns the clock
fn wall_now() -> ClusterTime {
    ClusterTime::wall_clock()
}

/// Who runs where (`name pid` per line), for operators and tests that stop one node on purpose;
/// rewritten when a node restarts.
fn write_pids(sup: &mut Supervisor, path: &Path) -> Result<()> {
    let pids: String = sup
        .children_mut()
        .iter()
        .map(|c| format!("{} {}\n", c.name, c.pid()))
        .collect();
    std::fs::write(path, pids).with_context(|| format!("writing {}", path.display()))
}

/// Every node `--skip` names is one the scenario declares, and none is the server.
fn check_skip(scenario: &Scenario, skip: &[u32]) -> Result<()> {
    for id in skip {
        match scenario.node(*id).map(|n| n.role) {
            None => anyhow::bail!("--skip {id}: the scenario declares no node {id}"),
            Some(NodeRole::Server) => {
                anyhow::bail!("--skip {id}: node {id} is the server, whose recording the launch reports on")
            }
            Some(_) => {}
        }
    }
    Ok(())
}

/// Start every node but the skipped: the server, then heads, then cameras, then acoustic nodes.
fn spawn_all(sup: &mut Supervisor, scenario: &Scenario, how: &Spawn, run: &RunDir) -> Result<()> {
    for (role, name) in [
        (NodeRole::Server, "server"),
        (NodeRole::Head, "head"),
        (NodeRole::Camera, "camera"),
        (NodeRole::Acoustic, "acoustic"),
    ] {
        for n in scenario
            .nodes
            .iter()
            .filter(|n| n.role == role && !how.opts.skip.contains(&n.id))
        {
            let node = format!("{name}-{}", n.id);
            let make = how.command(name, n.id, run.log(&node), run.exit_summary(&node));
            sup.spawn(node, make, instant_now())?;
        }
    }
    // The viewer's URL is printed: it is what a person opens.
    if let Some(addr) = how.opts.view {
        let make = how.viewer_command(addr, run.log("viewer"), run.exit_summary("viewer"));
        sup.spawn("viewer", make, instant_now())?;
        eprintln!("viewer: http://{addr}");
    }
    Ok(())
}

/// Over TCP every link is mutual TLS with certificates made for this run (a CA of its own, one
/// certificate per node and one for the viewer), unless the scenario says insecure; where they
/// are.
fn issue_certificates(scenario: &Scenario, opts: &LaunchOptions, run: &RunDir) -> Result<Option<PathBuf>> {
    if opts.transport != TransportKind::Tcp || scenario.network.insecure {
        return Ok(None);
    }
    let dir = run.dir.join("tls");
    let viewer = opts
        .view
        .map(|_| (view::node::free_id(scenario), proto::Role::Viewer));
    crate::deploy::certs::issue_all_in(scenario, viewer.as_slice(), &dir)
        .context("making the run's certificates")?;
    Ok(Some(dir))
}

/// The stop signals a launch obeys: SIGINT (Ctrl-C), SIGTERM (systemd, docker, `timeout`),
/// SIGHUP (a closed terminal).
struct StopSignals {
    int: tokio::signal::unix::Signal,
    term: tokio::signal::unix::Signal,
    hup: tokio::signal::unix::Signal,
}

impl StopSignals {
    fn new() -> Result<Self> {
        use tokio::signal::unix::{SignalKind, signal};
        Ok(StopSignals {
            int: signal(SignalKind::interrupt()).context("handling SIGINT")?,
            term: signal(SignalKind::terminate()).context("handling SIGTERM")?,
            hup: signal(SignalKind::hangup()).context("handling SIGHUP")?,
        })
    }

    /// The name of the next stop signal.
    async fn next(&mut self) -> &'static str {
        tokio::select! {
            _ = self.int.recv() => "SIGINT",
            _ = self.term.recv() => "SIGTERM",
            _ = self.hup.recv() => "SIGHUP",
        }
    }
}

/// Say what the supervisor saw; restarted nodes get a fresh line in the pids file.
fn tell(events: &[Event], sup: &mut Supervisor, pids: &Path) {
    for e in events {
        match e {
            Event::Restarted { .. } | Event::ChaosKilled { .. } => tracing::warn!("{e}"),
            Event::GaveUp { .. } | Event::RestartFailed { .. } => tracing::error!("{e}"),
            Event::Ended { .. } => tracing::warn!("{e}"),
        }
    }
    if events.iter().any(|e| matches!(e, Event::Restarted { .. }))
        && let Err(e) = write_pids(sup, pids)
    {
        tracing::warn!("{e:#}");
    }
}

/// What [`supervise`] hands back once every child is stopped.
struct Supervised {
    sup: Supervisor,
    usage: Vec<usage::RoleUsage>,
    wall_s: f64,
    /// When the first child was sent its stop signal (cluster time, the wall clock here).
    stop_began: ClusterTime,
}

/// Supervise until a stop signal or the duration; then stop every child in order (a second
/// signal kills them all at once).
async fn supervise(
    sup: Supervisor,
    opts: &LaunchOptions,
    mut progress: Option<(Progress, Vec<world::Target>, ClusterTime)>,
    pids: &Path,
    mut chaos: Option<chaos::Chaos>,
) -> Result<Supervised> {
    let mut signals = StopSignals::new()?;
    let mut sup = sup;
    let started = instant_now();
    loop {
        tokio::select! {
            sig = signals.next() => {
                tracing::info!(signal = sig, "stopping every node (a second signal kills them at once)");
                break;
            }
            () = tokio::time::sleep(Duration::from_millis(500)) => {}
        }
        let mut events = sup.watch(instant_now());
        if let Some(c) = chaos.as_mut()
            && let Some(kill) = c.strike(&mut sup, started.elapsed(), instant_now())?
        {
            events.push(kill);
        }
        tell(&events, &mut sup, pids);
        if let Some((p, targets, epoch)) = progress.as_mut() {
            p.update();
            for line in p.lines(targets, *epoch, wall_now()) {
                eprintln!("{line}");
            }
        }
        if opts.duration.is_some_and(|d| started.elapsed() >= d) {
            break;
        }
    }
    let wall_s = started.elapsed().as_secs_f64();
    let samples: Vec<(String, usage::ProcessUsage)> = sup
        .children_mut()
        .iter()
        .filter_map(|c| Some((c.name.clone(), usage::sample(c.pid())?)))
        .collect();
    let roles = usage::by_role(&samples, wall_s);
    let groups = sup.running_groups();
    let stop_began = wall_now();
    let stop = tokio::task::spawn_blocking(move || {
        let killed = sup.stop_all();
        (sup, killed)
    });
    tokio::pin!(stop);
    loop {
        tokio::select! {
            r = &mut stop => {
                let (sup, killed) = r.context("the stopping thread failed")?;
                if !killed.is_empty() {
                    tracing::warn!(nodes = killed.join(", "), "nodes ignored SIGTERM and were killed");
                }
                return Ok(Supervised { sup, usage: roles, wall_s, stop_began });
            }
            sig = signals.next() => {
                tracing::warn!(signal = sig, "second stop signal: killing every node");
                crate::supervisor::kill_groups(&groups);
            }
        }
    }
}

/// Remove every iceoryx2 file of `domain` from `/dev/shm` (the domain is this launch's own,
/// and every process of it has been reaped).
fn remove_domain_files(domain: &str) -> usize {
    let prefix = runtime::transport::file_prefix(domain);
    let Ok(dir) = std::fs::read_dir("/dev/shm") else {
        return 0;
    };
    dir.flatten()
        .filter(|e| e.file_name().to_string_lossy().starts_with(&prefix))
        .filter(|e| std::fs::remove_file(e.path()).is_ok())
        .count()
}

/// Run a scenario until a stop signal or the duration; the run's folder and report.
///
/// # Errors
/// The run folder or recording cannot be claimed, a child cannot be started, or the recording
/// cannot be read at the end.
pub fn launch(scenario: Scenario, opts: &LaunchOptions) -> Result<Launched> {
    check_skip(&scenario, &opts.skip)?;
    let scenario = effective_scenario(scenario, opts.transport)?;
    // The cameras' synthetic world is the room the scenario is prepared for (its default RSSI
    // model surveyed in it, what the method needs of the targets filled in); every node reads
    // the prepared file.
    let scenario = world::prepare(&scenario, crate::cmd::camera::SYNTHETIC_SEED)?;
    let targets = world::targets(&scenario)?;
    // Cluster time is the wall clock; one epoch for every camera's synthetic world.
    let epoch = wall_now();
    let run = RunDir::claim(
        opts.run_dir.as_deref(),
        opts.record.as_deref(),
        opts.force,
        epoch.0.div_euclid(1_000_000_000),
    )?;
    let scenario = acoustic::with_fingerprints(scenario, &run.dir)?;
    let scenario_path = run.dir.join("scenario.toml");
    std::fs::write(&scenario_path, scenario.to_toml())
        .with_context(|| format!("writing {}", scenario_path.display()))?;
    let how = Spawn {
        exe: std::env::current_exe().context("locating the ocelli binary")?,
        scenario_path,
        epoch,
        opts: opts.clone(),
        recording: run.recording.clone(),
        tls_dir: issue_certificates(&scenario, opts, &run)?,
    };
    let mut sup = Supervisor::new(Duration::from_secs(5), opts.restart);
    spawn_all(&mut sup, &scenario, &how, &run)?;
    let pids = run.dir.join("pids");
    write_pids(&mut sup, &pids)?;
    // The synthetic world's time 0 (cluster nanoseconds), for tests that score a run as it goes.
    let epoch_file = run.dir.join("epoch-ns");
    std::fs::write(&epoch_file, epoch.0.to_string())
        .with_context(|| format!("writing {}", epoch_file.display()))?;
    tracing::info!(
        nodes = scenario.nodes.len(),
        run = %run.dir.display(),
        recording = %run.recording.display(),
        "launched; Ctrl-C, SIGTERM or SIGHUP stops"
    );
    let progress = opts
        .progress
        .then(|| (Progress::new(&run.recording, &scenario), targets, epoch));
    // A current-thread runtime: restarts spawn from this (the main) thread, which lives as long
    // as the children's parent-death signal must not fire.
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("starting the launcher's runtime")?;
    let chaos = match (opts.chaos, opts.restart) {
        (Some(c), Some(_)) => Some(chaos::Chaos::new(&c, opts.duration, &run.dir, &run.recording)?),
        (Some(_), None) => anyhow::bail!("the chaos mode needs restarts: nodes it kills are started again"),
        (None, _) => None,
    };
    let Supervised {
        mut sup,
        usage,
        wall_s,
        stop_began,
    } = rt.block_on(supervise(sup, opts, progress, &pids, chaos))?;
    let restarts = sup
        .children_mut()
        .iter()
        .filter(|c| c.restarts > 0)
        .map(|c| (c.name.clone(), c.restarts))
        .collect();
    let nodes: Vec<String> = sup.children_mut().iter().map(|c| c.name.clone()).collect();
    let undelivered = undelivered::read(&run, &nodes, stop_began);
    drop(sup);
    let removed = remove_domain_files(&scenario.network.domain);
    if removed > 0 {
        tracing::info!(files = removed, "removed iceoryx2 files left by crashed nodes");
    }
    let report = lab::report::of_recording(&run.recording, None, None)
        .with_context(|| format!("reporting on {}", run.recording.display()))?;
    Ok(Launched {
        run,
        report,
        restarts,
        usage,
        wall_s,
        undelivered,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every head and the server of a launch over TCP get a port of their own, however many
    /// (the scenario's own check refuses two nodes of a host on one port).
    #[test]
    fn a_tcp_launch_gives_every_listener_its_own_port() {
        let text = include_str!("../../../proto/scenarios/hall.toml");
        let s = Scenario::from_toml(text, "hall.toml").unwrap();
        for _ in 0..20 {
            let e = effective_scenario(s.clone(), TransportKind::Tcp).unwrap();
            let ports: Vec<&String> = e.nodes.iter().filter_map(|n| n.listen.as_ref()).collect();
            let distinct: std::collections::BTreeSet<_> = ports.iter().collect();
            assert_eq!(distinct.len(), ports.len(), "{ports:?}");
            assert!(ports.len() >= 6, "five heads and the server");
            e.validate("launch", None).unwrap();
        }
    }
}
