//! The simulated world as the sources a node process is given: [`SyntheticFrames`] renders
//! what a camera sees, [`SyntheticRadio`] what its radio hears of every tagged target,
//! [`SyntheticAudio`] what an acoustic node's two microphones hear of every target (each emits
//! white noise, as paper 001's target does). `ocelli launch` injects them into real node
//! processes; the nodes cannot tell them from devices.

use crate::acoustics::{AcousticParams, TwoMicNode, render_stereo};
use crate::radio::{self, MultipathField};
use crate::render::Renderer;
use crate::targets::{Target, targets};
use nalgebra::Vector3;
use proto::scenario::{Scenario, ScenarioError};
use proto::sensor::{AudioFrame, AudioSource, Frame, FrameSource, RadioSource, SourceError, TagReading};
use proto::{ClusterTime, TagId};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// What camera node `id` sees of the world: scene time is `now − epoch`.
#[derive(Debug, Clone)]
pub struct SyntheticFrames {
    renderer: Renderer,
    targets: Vec<Target>,
    epoch: ClusterTime,
}

impl SyntheticFrames {
    /// Camera node `id` of `scenario`; cluster time `epoch` is scenario time 0.
    ///
    /// # Errors
    /// The node has no usable camera geometry, or the targets do not parse.
    pub fn new(
        scenario: &Scenario,
        id: u32,
        seed: u64,
        epoch: ClusterTime,
    ) -> Result<SyntheticFrames, ScenarioError> {
        Ok(SyntheticFrames {
            renderer: Renderer::for_node(scenario, id, seed)?,
            targets: targets(scenario)?,
            epoch,
        })
    }
}

impl FrameSource for SyntheticFrames {
    fn size(&self) -> (u32, u32) {
        self.renderer.size()
    }

    fn capture(&mut self, now: ClusterTime, frame: &mut Frame) -> Result<bool, SourceError> {
        self.renderer
            .render(&self.targets, now.secs_since(self.epoch), now, frame);
        Ok(true)
    }
}

/// What node `id`'s radio hears: one reading of every tagged target per call, at the call's
/// time (the runtime calls it at the node's frame rate).
#[derive(Debug, Clone)]
pub struct SyntheticRadio {
    scenario: Scenario,
    targets: Vec<Target>,
    field: MultipathField,
    node: u32,
    position: Vector3<f64>,
    seed: u64,
    epoch: ClusterTime,
}

impl SyntheticRadio {
    /// Node `id` of `scenario` (its radio sits at its camera's centre); cluster time `epoch` is
    /// scenario time 0.
    ///
    /// # Errors
    /// The node has no camera geometry, or the targets do not parse.
    pub fn new(
        scenario: &Scenario,
        id: u32,
        seed: u64,
        epoch: ClusterTime,
    ) -> Result<SyntheticRadio, ScenarioError> {
        Ok(SyntheticRadio {
            position: scenario.camera_model(id)?.pose.centre(),
            targets: targets(scenario)?,
            field: MultipathField::new(&scenario.world.radio, id, seed),
            scenario: scenario.clone(),
            node: id,
            seed,
            epoch,
        })
    }

    /// One reading of every tagged target at scene time `t` seconds, stamped `received` (the
    /// node's clock, which may differ from the world's).
    pub fn readings(&self, t: f64, received: ClusterTime, out: &mut Vec<TagReading>) {
        for target in self.targets.iter().filter(|t| t.rssi_tag) {
            let dbm = radio::reading(
                &self.scenario.world,
                &self.field,
                self.node,
                &self.position,
                target.id,
                &target.position_at(t),
                t,
                self.seed,
            );
            out.push(TagReading {
                tag: TagId::simulated(target.id),
                dbm,
                time: received,
            });
        }
    }
}

impl RadioSource for SyntheticRadio {
    fn read(&mut self, now: ClusterTime, out: &mut Vec<TagReading>) -> Result<bool, SourceError> {
        self.readings(now.secs_since(self.epoch), now, out);
        Ok(true)
    }
}

/// What acoustic node `id` hears: every target at its position in the middle of the frame,
/// each an independent white-noise source, summed, with the microphones' own noise.
#[derive(Debug, Clone)]
pub struct SyntheticAudio {
    world: proto::scenario::World,
    params: AcousticParams,
    node: TwoMicNode,
    targets: Vec<Target>,
    rate: u32,
    rng: ChaCha8Rng,
    epoch: ClusterTime,
}

impl SyntheticAudio {
    /// Acoustic node `id` of `scenario`; cluster time `epoch` is scenario time 0.
    ///
    /// # Errors
    /// The node is not an acoustic node, or the targets do not parse.
    pub fn new(
        scenario: &Scenario,
        id: u32,
        seed: u64,
        epoch: ClusterTime,
    ) -> Result<SyntheticAudio, ScenarioError> {
        let spec = scenario
            .node(id)
            .and_then(|n| n.acoustic.as_ref())
            .ok_or_else(|| ScenarioError::Invalid {
                path: scenario.name.clone(),
                field: format!("nodes[id={id}].acoustic"),
                problem: "not an acoustic node".into(),
            })?;
        Ok(SyntheticAudio {
            world: scenario.world.clone(),
            params: AcousticParams::default(),
            node: TwoMicNode::from_spec(spec),
            targets: targets(scenario)?,
            rate: spec.ild.sample_rate,
            rng: ChaCha8Rng::seed_from_u64(seed ^ 0x6175_6469_6f00 ^ u64::from(id)),
            epoch,
        })
    }

    /// `samples` of both channels ending at scene time `t` seconds, stamped `captured`.
    pub fn render(&mut self, t: f64, captured: ClusterTime, samples: usize, frame: &mut AudioFrame) {
        let mid = t - 0.5 * samples as f64 / f64::from(self.rate.max(1));
        frame.sample_rate = self.rate;
        frame.captured = captured;
        frame.left.clear();
        frame.left.resize(samples, 0.0);
        frame.right.clear();
        frame.right.resize(samples, 0.0);
        // Each target a source; the microphones' noise once.
        let quiet = AcousticParams {
            noise_rms: 0.0,
            ..self.params
        };
        for (k, target) in self.targets.iter().enumerate() {
            let p = target.position_at(mid);
            let params = if k == 0 { &self.params } else { &quiet };
            let (l, r) = render_stereo(
                &self.world,
                params,
                &self.node,
                [p.x, p.y],
                samples,
                self.rate,
                &mut self.rng,
            );
            frame.left.iter_mut().zip(l).for_each(|(a, b)| *a += b);
            frame.right.iter_mut().zip(r).for_each(|(a, b)| *a += b);
        }
        if self.targets.is_empty() {
            let silent = AcousticParams {
                source_rms: 0.0,
                ..self.params
            };
            let c = self.node.left.position;
            let (l, r) = render_stereo(
                &self.world,
                &silent,
                &self.node,
                [c[0], c[1]],
                samples,
                self.rate,
                &mut self.rng,
            );
            frame.left = l;
            frame.right = r;
        }
    }
}

impl AudioSource for SyntheticAudio {
    fn sample_rate(&self) -> u32 {
        self.rate
    }

    fn capture(
        &mut self,
        now: ClusterTime,
        samples: usize,
        frame: &mut AudioFrame,
    ) -> Result<bool, SourceError> {
        self.render(now.secs_since(self.epoch), now, samples, frame);
        Ok(true)
    }
}
