//! `ocelli launch`: every node of a scenario on this host, each its own OS process, supervised.
//!
//! The launch writes the effective scenario (a domain of its own, free TCP ports) to a run
//! directory, starts the server, the heads and the cameras as `ocelli server|head|camera`
//! children and the visualization node as `ocelli viewer` (its URL printed), shows live progress read incrementally from the server's recording as it grows
//! (`node_server::tail::Tailer`: only the newly appended records, an incomplete last record
//! waited on), and stops in order on Ctrl-C or
//! after the duration. Whatever happened to the children, it reaps them all and removes the
//! domain's iceoryx2 files from `/dev/shm`. Over TCP the nodes speak mutual TLS with a CA and
//! certificates made for the run (`run-dir/tls`), or plain TCP if the scenario (or
//! `--insecure`) says `insecure`.

use crate::supervisor::Supervisor;
use anyhow::{Context, Result};
use node_server::export::{TrackRow, track_row};
use node_server::report;
use node_server::tail::Tailer;
use node_server::{ServerConfig, ServerNode};
use proto::scenario::{NodeRole, Scenario, TransportKind};
use proto::{ClusterTime, NodeId};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

/// What to launch and how.
#[derive(Clone, Debug)]
pub struct LaunchOptions {
    pub transport: TransportKind,
    pub duration: Option<Duration>,
    pub run_dir: PathBuf,
    pub record: PathBuf,
    /// Print live progress lines on standard error.
    pub progress: bool,
    /// A logging run: every camera measures every frame and the server records it.
    pub record_measurements: bool,
    /// Start the viewer serving here (`None`: no viewer).
    pub view: Option<std::net::SocketAddr>,
}

/// A free loopback port (bound then released; the child binds it right after).
fn free_port() -> Result<u16> {
    Ok(std::net::TcpListener::bind("127.0.0.1:0")?.local_addr()?.port())
}

/// The scenario as this launch runs it: its own iceoryx2 domain and, over TCP, free ports.
pub fn effective_scenario(mut s: Scenario, transport: TransportKind) -> Result<Scenario> {
    s.network.transport = transport;
    s.network.domain = format!("ocelli-{}", std::process::id());
    if transport == TransportKind::Tcp {
        for n in &mut s.nodes {
            if matches!(n.role, NodeRole::Head | NodeRole::Server) {
                n.listen = Some(format!("127.0.0.1:{}", free_port()?));
            }
        }
    }
    Ok(s)
}

/// How to start one node process.
struct Spawn<'a> {
    exe: &'a Path,
    scenario_path: &'a Path,
    epoch: ClusterTime,
    opts: &'a LaunchOptions,
    /// The run's certificates (TCP with TLS).
    tls_dir: Option<PathBuf>,
}

fn spawn_node(sup: &mut Supervisor, how: &Spawn<'_>, role: &str, id: u32) -> Result<()> {
    let (exe, scenario_path, opts) = (how.exe, how.scenario_path, how.opts);
    let mut cmd = Command::new(exe);
    cmd.arg(role)
        .arg("--scenario")
        .arg(scenario_path)
        .arg("--id")
        .arg(id.to_string());
    cmd.arg("--transport").arg(match opts.transport {
        TransportKind::Ipc => "ipc",
        TransportKind::Tcp => "tcp",
    });
    if let Some(dir) = &how.tls_dir {
        cmd.arg("--tls-dir").arg(dir);
    }
    match role {
        "server" => {
            cmd.arg("--record").arg(&opts.record);
        }
        "acoustic" => {
            cmd.arg("--epoch-ns").arg(how.epoch.0.to_string());
        }
        // Scenario time 0 for the synthetic world, the same for every camera.
        "camera" => {
            cmd.arg("--epoch-ns").arg(how.epoch.0.to_string());
            if opts.record_measurements {
                cmd.arg("--record-measurements");
            }
        }
        _ => {}
    }
    let log = std::fs::File::create(opts.run_dir.join(format!("{role}-{id}.log")))?;
    cmd.stdout(Stdio::null()).stderr(log);
    sup.spawn(format!("{role}-{id}"), cmd)?;
    Ok(())
}

/// The viewer, a client of the server over the launch's transport, serving `addr`. Its URL is
/// printed: it is what a person opens.
fn spawn_viewer(sup: &mut Supervisor, how: &Spawn<'_>, addr: std::net::SocketAddr) -> Result<()> {
    let mut cmd = Command::new(how.exe);
    cmd.arg("viewer")
        .arg("--scenario")
        .arg(how.scenario_path)
        .arg("--listen")
        .arg(addr.to_string())
        .arg("--transport")
        .arg(match how.opts.transport {
            TransportKind::Ipc => "ipc",
            TransportKind::Tcp => "tcp",
        });
    if let Some(dir) = &how.tls_dir {
        cmd.arg("--tls-dir").arg(dir);
    }
    let log = std::fs::File::create(how.opts.run_dir.join("viewer.log"))?;
    cmd.stdout(Stdio::null()).stderr(log);
    sup.spawn("viewer", cmd)?;
    eprintln!("viewer: http://{addr}");
    Ok(())
}

/// Live progress: follows the recording as it grows ([`Tailer`] reads only what was appended
/// since the last update) through a server core fed record by record, as `ocelli export` does
/// over a whole file, and keeps each global track's latest owner row.
struct Progress {
    tail: Tailer,
    node: ServerNode,
    latest: BTreeMap<u32, TrackRow>,
}

impl Progress {
    fn new(record: &Path, scenario: &Scenario) -> Self {
        let server = scenario.server().map_or(NodeId(0), |n| NodeId(n.id));
        let mut cfg = ServerConfig::from_scenario(scenario.clone(), server);
        cfg.journal = false;
        Progress {
            tail: Tailer::new(record),
            node: ServerNode::new(cfg),
            latest: BTreeMap::new(),
        }
    }

    /// Read what the server appended and take it in.
    fn update(&mut self) {
        let records = match self.tail.poll() {
            Ok(r) => r,
            Err(e) => {
                tracing::debug!(error = %e, "progress: recording not readable yet");
                return;
            }
        };
        for s in &records {
            self.node.feed(s);
            if let Some(row) = track_row(&self.node, s).filter(|r| r.owner) {
                self.latest.insert(row.global, row);
            }
        }
    }

    /// One line per global track reported in the last two seconds: position, σ, sensors and,
    /// with truth, error.
    fn lines(&self, targets: &[world::Target], epoch: ClusterTime) -> Vec<String> {
        let newest = self
            .latest
            .values()
            .map(|r| r.t)
            .fold(f64::NEG_INFINITY, f64::max);
        self.latest
            .values()
            .filter(|r| r.t >= newest - 2.0)
            .map(|r| {
                let err = targets
                    .iter()
                    .map(|t| {
                        let x = t.truth_at(r.t - epoch.as_secs_f64());
                        ((x[0] - r.x).powi(2) + (x[1] - r.y).powi(2) + (x[2] - r.z).powi(2)).sqrt()
                    })
                    .min_by(f64::total_cmp)
                    .map_or(String::new(), |e| format!("  error {e:.2} m"));
                format!(
                    "t={:6.1}s  target g{:<3} ({:6.2}, {:6.2}, {:5.2}) m  σ {:.2} m  cameras {:2}  rssi {:2}  head {}{err}",
                    r.t - epoch.as_secs_f64(), r.global, r.x, r.y, r.z, r.sigma_m, r.cameras, r.rssi_nodes, r.head
                )
            })
            .collect()
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

/// A grid-fusing scenario's acoustic nodes without a fingerprint file get the simulated room's
/// survey (`sim::acoustic::survey`), written to the run directory, as a deployment would
/// survey its room with `ocelli acoustic survey` before the run.
///
/// # Errors
/// A survey that cannot be made or written.
fn with_fingerprints(mut scenario: Scenario, run_dir: &Path) -> Result<Scenario> {
    if scenario.method.fusion != proto::scenario::Fusion::Grid {
        return Ok(scenario);
    }
    let missing: Vec<u32> = scenario
        .acoustic_nodes()
        .filter(|n| n.acoustic.as_ref().is_some_and(|a| a.fingerprints.is_none()))
        .map(|n| n.id)
        .collect();
    for id in missing {
        let db =
            sim::acoustic::survey(&scenario, id).map_err(|e| anyhow::anyhow!("acoustic node {id}: {e}"))?;
        let path = run_dir.join(format!("fingerprints-{id}.json"));
        db.save(&path)?;
        if let Some(a) = scenario
            .nodes
            .iter_mut()
            .find(|n| n.id == id)
            .and_then(|n| n.acoustic.as_mut())
        {
            a.fingerprints = Some(path);
        }
    }
    Ok(scenario)
}

/// Run a scenario to the end; returns the final report.
///
/// # Errors
/// The run directory or a child cannot be created, or the recording cannot be read at the end.
pub fn launch(scenario: Scenario, opts: &LaunchOptions) -> Result<report::Report> {
    let scenario = effective_scenario(scenario, opts.transport)?;
    // The cameras' synthetic world is the room the scenario is prepared for (its default RSSI
    // model surveyed in it, what the method needs of the targets filled in); every node reads
    // the prepared file.
    let scenario = world::prepare(&scenario, crate::cmd::camera::SYNTHETIC_SEED)?;
    let targets = world::targets(&scenario)?;
    std::fs::create_dir_all(&opts.run_dir).with_context(|| format!("creating {}", opts.run_dir.display()))?;
    // A recording left by an earlier launch would be resumed by the server: keep it aside.
    if opts.record.exists() {
        let aside = opts.record.with_extension("previous.ocrec");
        std::fs::rename(&opts.record, &aside)
            .with_context(|| format!("moving the earlier recording {} aside", opts.record.display()))?;
        tracing::info!(to = %aside.display(), "an earlier recording was moved aside");
    }
    let scenario = with_fingerprints(scenario, &opts.run_dir)?;
    let scenario_path = opts.run_dir.join("scenario.toml");
    std::fs::write(&scenario_path, scenario.to_toml())?;
    // Over TCP every link is mutual TLS with certificates made for this run (a CA of its own,
    // one certificate per node), unless the scenario says insecure.
    let tls_dir = (opts.transport == TransportKind::Tcp && !scenario.network.insecure)
        .then(|| opts.run_dir.join("tls"));
    if let Some(dir) = &tls_dir {
        let viewer = opts
            .view
            .map(|_| (view::node::free_id(&scenario), proto::Role::Viewer));
        crate::deploy::certs::issue_all_in(&scenario, viewer.as_slice(), dir)
            .context("making the run's certificates")?;
    }
    let exe = std::env::current_exe().context("locating the ocelli binary")?;
    let mut sup = Supervisor::new(Duration::from_secs(5));
    // Cluster time is the wall clock; one epoch for every camera's synthetic world.
    #[allow(clippy::disallowed_methods)] // the launcher is a runtime: it owns the clock
    let epoch = ClusterTime::wall_clock();
    let how = Spawn {
        exe: &exe,
        scenario_path: &scenario_path,
        epoch,
        opts,
        tls_dir,
    };
    let by_role = |r: NodeRole| scenario.nodes.iter().filter(move |n| n.role == r).map(|n| n.id);
    for (role, name) in [
        (NodeRole::Server, "server"),
        (NodeRole::Head, "head"),
        (NodeRole::Camera, "camera"),
        (NodeRole::Acoustic, "acoustic"),
    ] {
        for id in by_role(role) {
            spawn_node(&mut sup, &how, name, id)?;
        }
    }
    if let Some(addr) = opts.view {
        spawn_viewer(&mut sup, &how, addr)?;
    }
    // Who runs where, for operators and tests that need to stop one node on purpose.
    let pids: String = sup
        .children_mut()
        .iter()
        .map(|c| format!("{} {}\n", c.name, c.pid()))
        .collect();
    std::fs::write(opts.run_dir.join("pids"), pids)?;
    // The synthetic world's time 0 (cluster nanoseconds), for tests that score a run as it goes.
    std::fs::write(opts.run_dir.join("epoch-ns"), epoch.0.to_string())?;
    tracing::info!(
        nodes = scenario.nodes.len(),
        run_dir = %opts.run_dir.display(),
        "launched; Ctrl-C stops"
    );
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?;
    #[allow(clippy::disallowed_methods)] // the launcher is a runtime: it owns the clock
    let started = std::time::Instant::now();
    let mut progress = opts.progress.then(|| Progress::new(&opts.record, &scenario));
    rt.block_on(async {
        let mut ctrl_c = std::pin::pin!(tokio::signal::ctrl_c());
        loop {
            tokio::select! {
                _ = &mut ctrl_c => { tracing::info!("Ctrl-C: stopping (again to abort)"); break; }
                () = tokio::time::sleep(Duration::from_secs(1)) => {}
            }
            for (name, status) in sup.reap_ended() {
                tracing::warn!(child = %name, %status, "a node process ended");
            }
            if let Some(p) = progress.as_mut() {
                p.update();
                for line in p.lines(&targets, epoch) {
                    eprintln!("{line}");
                }
            }
            if opts.duration.is_some_and(|d| started.elapsed() >= d) {
                break;
            }
        }
        // Stop in order; a second Ctrl-C kills everything at once.
        let groups = sup.running_groups();
        let stop = tokio::task::spawn_blocking(move || {
            let killed = sup.stop_all();
            (sup, killed)
        });
        tokio::select! {
            r = stop => {
                if let Ok((_, killed)) = r && !killed.is_empty() {
                    tracing::warn!(?killed, "children ignored SIGTERM and were killed");
                }
            }
            _ = tokio::signal::ctrl_c() => {
                tracing::warn!("second Ctrl-C: aborting");
                crate::supervisor::kill_groups(&groups);
            }
        }
    });
    let removed = remove_domain_files(&scenario.network.domain);
    if removed > 0 {
        tracing::info!(files = removed, "removed iceoryx2 files left by crashed nodes");
    }
    let loaded = node_server::analysis::load(&opts.record, Some(scenario.clone()))
        .with_context(|| format!("reading the recording {}", opts.record.display()))?;
    if let Some(t) = sim::WorldTruth::of(&loaded.scenario, epoch)? {
        return Ok(report::compute(&loaded, Some(&t)));
    }
    // Radio-only nodes replaying a recording: its positions are the truth, and RSSI-only
    // tracks err metres, so a track is the beacon's within a wider gate.
    let recorded = sim::RecordedTruth::of(&scenario, epoch)?;
    Ok(match &recorded {
        Some(t) => report::compute_with(&loaded, Some(t), sim::recorded_truth::ASSOCIATION_GATE_M),
        None => report::compute(&loaded, None),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use node_server::Recorder;
    use node_server::analysis::Loaded;
    use node_server::export::track_rows;
    use sim::{Level, Sim, SimOptions};

    /// Progress read in pieces while the recording grows ends where a reading of the whole
    /// file does: the same latest owner row for every global track.
    #[test]
    fn progress_follows_the_growing_recording_like_a_whole_reading() {
        let scenario = Scenario::default_scenario();
        let opts = SimOptions {
            seed: 4,
            duration_s: 6.0,
            level: Level::Measurement,
            ..SimOptions::default()
        };
        let records = Sim::new(scenario.clone(), opts).unwrap().run().records;
        let dir = std::env::temp_dir().join(format!("ocelli-launch-progress-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("rec.ocrec");
        let mut progress = Progress::new(&path, &scenario);
        progress.update();
        assert!(progress.latest.is_empty(), "no file yet");
        let mut rec = Recorder::create(&path, &scenario.name).unwrap();
        let mut polls = 0;
        for chunk in records.chunks(records.len() / 20 + 1) {
            for s in chunk {
                rec.append(s).unwrap();
            }
            progress.update();
            polls += 1;
        }
        assert!(polls > 10);
        let whole = Loaded {
            scenario: scenario.clone(),
            records,
            skipped: Vec::new(),
        };
        let mut expected: BTreeMap<u32, TrackRow> = BTreeMap::new();
        for r in track_rows(&whole).into_iter().filter(|r| r.owner) {
            expected.insert(r.global, r);
        }
        assert!(!expected.is_empty(), "the sim tracked something");
        assert_eq!(progress.latest, expected);
        assert!(
            !progress
                .lines(&world::targets(&scenario).unwrap(), ClusterTime::ZERO)
                .is_empty()
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
