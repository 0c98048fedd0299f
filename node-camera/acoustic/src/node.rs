//! The acoustic node's sans-IO core, a [`proto::node::Node`] whose sensors deliver
//! [`AcousticInput`]s: audio frames of both microphones, or word that the stream stalled.
//!
//! Each good frame becomes one weighted ILD vector (eq. 13–15), sent to its head as an
//! `Observation::Acoustic` in a `Measurement`; frames that are silent or clipped, of another
//! sample rate, of unequal channels or stamped far from now are counted and skipped, and the
//! node keeps running. Modes follow the head's `Command`s (Inactive: nothing analysed); a
//! `NodeStatus` goes to the head and the server every status period, as a camera's does.

use crate::config::AcousticConfig;
use crate::ild::IldAnalyzer;
use crate::wav::{FrameQuality, frame_quality};
use proto::msg::{Measurement, Message, Mode, NodeStatus, PoseWire};
use proto::node::{Input, Node, Outgoing};
use proto::observation::Observation;
use proto::sensor::AudioFrame;
use proto::{ClusterTime, Envelope, NodeId};
use tracing::warn;

/// What an acoustic node's source delivers.
#[derive(Debug)]
pub enum AcousticInput {
    /// Both channels of one frame.
    Frame(AudioFrame),
    /// A live stream delivered nothing in time.
    Stalled,
}

/// Counters of what the node did and refused.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counters {
    /// Frames analysed into ILD vectors (each sent).
    pub frames: u64,
    pub silent: u64,
    pub clipped: u64,
    /// Frames refused: another sample rate, unequal or short channels, a stale stamp, a bad
    /// message.
    pub rejected: u64,
    /// Times the stream stalled.
    pub stalls: u64,
    /// Frames not analysed because the node was Inactive.
    pub skipped: u64,
    /// Messages with nowhere to go (no head or server known).
    pub unsent: u64,
    /// Messages the runtime could not deliver.
    pub dropped: u64,
}

/// The acoustic node core.
#[derive(Debug)]
pub struct AcousticNode {
    cfg: AcousticConfig,
    analyzer: IldAnalyzer,
    mode: Mode,
    mode_since: ClusterTime,
    time_in_mode_ns: [u64; 3],
    last_status: Option<ClusterTime>,
    sync: (i64, i64),
    counters: Counters,
}

impl AcousticNode {
    /// # Errors
    /// ILD settings that cannot be analysed with.
    pub fn new(cfg: AcousticConfig, now: ClusterTime) -> Result<AcousticNode, crate::IldError> {
        Ok(AcousticNode {
            analyzer: IldAnalyzer::new(&cfg.ild)?,
            cfg,
            mode: Mode::Active,
            mode_since: now,
            time_in_mode_ns: [0; 3],
            last_status: None,
            sync: (0, -1),
            counters: Counters::default(),
        })
    }

    pub fn config(&self) -> &AcousticConfig {
        &self.cfg
    }

    pub fn counters(&self) -> Counters {
        self.counters
    }

    pub fn mode(&self) -> Mode {
        self.mode
    }

    /// Whether the node wants audio (not Inactive).
    pub fn listening(&self) -> bool {
        self.mode != Mode::Inactive
    }

    fn reject(&mut self, what: &'static str, problem: String) {
        self.counters.rejected += 1;
        warn!(node = %self.cfg.id, what, %problem, "rejected input");
    }

    fn send(&mut self, to: Option<NodeId>, body: Message, out: &mut Vec<Outgoing>) {
        match to {
            Some(n) => out.push(Outgoing::new(n, body)),
            None => self.counters.unsent += 1,
        }
    }

    fn on_frame(&mut self, now: ClusterTime, frame: &AudioFrame) -> Vec<Outgoing> {
        let mut out = Vec::new();
        if !self.listening() {
            self.counters.skipped += 1;
            return out;
        }
        let rate = self.cfg.ild.sample_rate;
        if frame.sample_rate != rate {
            self.reject(
                "audio",
                format!("{} Hz frame, the node analyses {rate} Hz", frame.sample_rate),
            );
            return out;
        }
        if frame.left.len() != frame.right.len() || frame.left.len() < self.cfg.ild.block_len {
            self.reject(
                "audio",
                format!(
                    "{} left and {} right samples (equal channels of at least {} needed)",
                    frame.left.len(),
                    frame.right.len(),
                    self.cfg.ild.block_len
                ),
            );
            return out;
        }
        let off_ms = (now - frame.captured).abs() / 1_000_000;
        if off_ms > self.cfg.max_age_ms as i64 {
            self.reject("audio", format!("frame stamped {off_ms} ms from now"));
            return out;
        }
        match frame_quality(&frame.left, &frame.right) {
            FrameQuality::Good => {}
            FrameQuality::Silent => {
                self.counters.silent += 1;
                return out;
            }
            FrameQuality::Clipped => {
                self.counters.clipped += 1;
                return out;
            }
        }
        let observation = self
            .analyzer
            .analyze(&frame.left, &frame.right)
            .map_err(|e| e.to_string())
            .and_then(|v| v.to_observation(frame.captured).map_err(|e| e.to_string()));
        match observation {
            Ok(o) => {
                self.counters.frames += 1;
                let m = Measurement {
                    target: None,
                    step: 0,
                    // An acoustic node has no camera pose; its microphones are in the scenario.
                    pose: PoseWire {
                        rvec: [0.0; 3],
                        tvec: [0.0; 3],
                    },
                    mode: self.mode,
                    observations: vec![Observation::Acoustic(o)],
                };
                self.send(self.cfg.head, Message::Measurement(m), &mut out);
            }
            Err(problem) => self.reject("audio", problem),
        }
        out
    }

    fn on_message(&mut self, now: ClusterTime, env: Envelope) -> Vec<Outgoing> {
        if let Err(e) = proto::validate::Validate::validate(&env) {
            self.reject("message", e.to_string());
            return Vec::new();
        }
        match env.body {
            Message::Command(c) if c.node == self.cfg.id => {
                if c.mode != self.mode {
                    self.time_in_mode_ns = self.time_in_mode_ns(now);
                    self.mode_since = now;
                    self.mode = c.mode;
                }
            }
            Message::Assignment(a) if a.node == self.cfg.id => self.cfg.head = Some(a.head),
            Message::Command(_) | Message::Assignment(_) => {
                self.reject("message", "addressed to another node".into());
            }
            Message::Heartbeat
            | Message::Hello(_)
            | Message::HelloAck(_)
            | Message::SyncBeacon(_)
            | Message::Liveness(_)
            | Message::Priors(_) => {}
            other => self.reject(
                "message",
                format!("an acoustic node does not take {}", other.kind()),
            ),
        }
        Vec::new()
    }

    /// Cumulative time in Active, CameraOff, Inactive up to `now`, ns.
    pub fn time_in_mode_ns(&self, now: ClusterTime) -> [u64; 3] {
        let mut t = self.time_in_mode_ns;
        t[self.mode.index()] += (now - self.mode_since).max(0) as u64;
        t
    }

    fn tick(&mut self, now: ClusterTime) -> Vec<Outgoing> {
        let mut out = Vec::new();
        let period = self.cfg.status_period_ms as i64 * 1_000_000;
        if self.last_status.is_some_and(|t| now - t < period) {
            return out;
        }
        self.last_status = Some(now);
        let c = self.counters;
        let status = NodeStatus {
            mode: self.mode,
            time_in_mode_ns: self.time_in_mode_ns(now),
            frames: c.frames + c.silent + c.clipped,
            detections: c.frames,
            dropped: c.dropped + c.unsent,
            rejected: c.rejected + c.stalls,
            sync_offset_ns: self.sync.0,
            sync_error_ns: self.sync.1,
            // The runtime fills it in as the status goes out.
            bytes_sent: 0,
        };
        self.send(self.cfg.head, Message::NodeStatus(status.clone()), &mut out);
        if self.cfg.server != self.cfg.head {
            self.send(self.cfg.server, Message::NodeStatus(status), &mut out);
        }
        out
    }
}

impl Node for AcousticNode {
    type Sensor = AcousticInput;

    fn id(&self) -> NodeId {
        self.cfg.id
    }

    fn handle(&mut self, now: ClusterTime, input: Input<AcousticInput>) -> Vec<Outgoing> {
        match input {
            Input::Message(env) => self.on_message(now, env),
            Input::Tick => self.tick(now),
            Input::Sensor(AcousticInput::Frame(f)) => self.on_frame(now, &f),
            Input::Sensor(AcousticInput::Stalled) => {
                self.counters.stalls += 1;
                Vec::new()
            }
            Input::Sync { offset_ns, error_ns } => {
                self.sync = (offset_ns, error_ns);
                Vec::new()
            }
            Input::Undelivered(n) => {
                self.counters.dropped += n;
                Vec::new()
            }
            Input::Link { .. } => Vec::new(),
        }
    }
}

#[cfg(test)]
mod tests;
