//! The simulated world as the sources a node process is given: [`SyntheticFrames`] renders
//! what a camera sees, [`SyntheticRadio`] what its radio hears of every tagged target. `ocelli
//! launch` injects them into real camera processes; the nodes cannot tell them from devices.

use crate::radio::{self, MultipathField};
use crate::render::Renderer;
use crate::targets::{Target, targets};
use nalgebra::Vector3;
use proto::scenario::{Scenario, ScenarioError};
use proto::sensor::{Frame, FrameSource, RadioSource, SourceError, TagReading};
use proto::{ClusterTime, TagId};

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
