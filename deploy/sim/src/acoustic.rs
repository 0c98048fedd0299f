//! Simulated acoustic nodes: each node's core fed, at its frame times, what its two
//! microphones hear of the simulated room (`world::sources::SyntheticAudio`), and the room's
//! fingerprint survey that a real deployment makes with `ocelli acoustic survey` — here made
//! before the run the same way, by rendering a source at each lattice position and analysing it
//! as the node does (node-acoustic), so fingerprints and observations share one pipeline.

use node_acoustic::config::AcousticConfig;
use node_acoustic::ild::{IldAnalyzer, block_starts};
use node_acoustic::node::{AcousticInput, AcousticNode};
use proto::acoustic::{Fingerprint, FingerprintDb};
use proto::node::{Input, Node, Outgoing};
use proto::scenario::Scenario;
use proto::sensor::AudioFrame;
use proto::{ClusterTime, NodeId};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::collections::HashMap;
use std::sync::{Arc, Mutex, OnceLock};
use world::acoustics::{AcousticParams, TwoMicNode, render_stereo};
use world::sources::SyntheticAudio;

/// Seconds of audio rendered per survey position.
pub const SURVEY_SECONDS: f64 = 0.5;
/// Seed of every survey (made once, a priori, whatever the run's seed).
const SURVEY_SEED: u64 = 0x5375_7276_6579;
/// Survey positions closer than this to a wall are skipped (a speaker cannot stand in it), m.
const WALL_CLEARANCE_M: f64 = 0.05;

/// An acoustic node and its microphones.
pub(crate) struct AcousticSlot {
    pub core: AcousticNode,
    pub audio: SyntheticAudio,
    pub samples: usize,
    pub period_ns: i64,
}

impl AcousticSlot {
    /// Node `id` of `scenario`, its clock at `now`.
    ///
    /// # Errors
    /// Not an acoustic node, unusable ILD settings, or targets that do not parse.
    pub fn new(scenario: &Scenario, id: u32, seed: u64, now: ClusterTime) -> Result<AcousticSlot, String> {
        let cfg = AcousticConfig::from_scenario(scenario, id).map_err(|e| e.to_string())?;
        let samples = cfg.frame_samples();
        let period_ns = (cfg.frame_ms * 1e6).round() as i64;
        Ok(AcousticSlot {
            core: AcousticNode::new(cfg, now).map_err(|e| e.to_string())?,
            audio: SyntheticAudio::new(scenario, id, seed, ClusterTime::ZERO).map_err(|e| e.to_string())?,
            samples,
            period_ns,
        })
    }

    /// The frame that ends at true time `t_ns`, stamped with the node's `now`.
    pub fn listen(&mut self, t_ns: i64, now: ClusterTime) -> Vec<Outgoing> {
        if !self.core.listening() {
            return Vec::new();
        }
        let mut frame = AudioFrame::default();
        self.audio
            .render(t_ns as f64 * 1e-9, now, self.samples, &mut frame);
        self.core.handle(now, Input::Sensor(AcousticInput::Frame(frame)))
    }
}

type Cache = Mutex<HashMap<String, Arc<FingerprintDb>>>;

fn cache() -> &'static Cache {
    static CACHE: OnceLock<Cache> = OnceLock::new();
    CACHE.get_or_init(Cache::default)
}

/// The fingerprints of acoustic node `id` in `scenario`'s room: a source rendered for
/// [`SURVEY_SECONDS`] at every position of a lattice of the node's `survey-spacing-m` over the
/// world's box (clear of walls), each analysed as the node analyses its frames. Surveys are
/// kept per room, node and settings for the life of the process (experiments run many seeds).
///
/// # Errors
/// Not an acoustic node, or a survey the fingerprint database refuses.
pub fn survey(scenario: &Scenario, id: u32) -> Result<Arc<FingerprintDb>, String> {
    let spec = scenario
        .node(id)
        .and_then(|n| n.acoustic.clone())
        .ok_or_else(|| format!("node {id} is not an acoustic node"))?;
    let world = &scenario.world;
    let key = format!("{:?}|{spec:?}", proto::acoustic::RoomSignature::of(world));
    if let Some(db) = cache().lock().ok().and_then(|c| c.get(&key).cloned()) {
        return Ok(db);
    }
    let node = TwoMicNode::from_spec(&spec);
    let params = AcousticParams::default();
    let s = &spec.ild;
    let mut analyzer = IldAnalyzer::new(s).map_err(|e| e.to_string())?;
    let mut rng = ChaCha8Rng::seed_from_u64(SURVEY_SEED);
    let spacing = spec.survey_spacing_m;
    let (nx, ny) = (
        ((world.max[0] - world.min[0]) / spacing).floor() as usize,
        ((world.max[1] - world.min[1]) / spacing).floor() as usize,
    );
    let samples = (SURVEY_SECONDS * f64::from(s.sample_rate)).round() as usize;
    let mut fingerprints = Vec::with_capacity(nx * ny);
    for j in 0..ny {
        for i in 0..nx {
            let p = [
                world.min[0] + spacing * (i as f64 + 0.5),
                world.min[1] + spacing * (j as f64 + 0.5),
            ];
            let clear = world
                .walls
                .iter()
                .all(|w| node_head::grid::layout::distance_to_segment(p, w.from, w.to) >= WALL_CLEARANCE_M);
            if !clear {
                continue;
            }
            let (l, r) = render_stereo(world, &params, &node, p, samples, s.sample_rate, &mut rng);
            for start in block_starts(l.len(), s.block_len) {
                let end = start + s.block_len;
                analyzer
                    .accumulate(&l[start..end], &r[start..end])
                    .map_err(|e| e.to_string())?;
            }
            let values = analyzer.finish().map_err(|e| e.to_string())?.values;
            fingerprints.push(Fingerprint { position: p, values });
        }
    }
    let db = Arc::new(FingerprintDb::new(world, s.clone(), fingerprints).map_err(|e| e.to_string())?);
    if let Ok(mut c) = cache().lock() {
        c.insert(key, db.clone());
    }
    Ok(db)
}

/// Give every acoustic node of `cfg` that has no fingerprint file the simulated room's survey.
///
/// # Errors
/// A survey that cannot be made, naming the node.
pub fn fill_fingerprints(
    scenario: &Scenario,
    cfg: &mut node_head::HeadConfig,
) -> Result<(), (NodeId, String)> {
    for a in cfg.acoustic.iter_mut().filter(|a| a.fingerprints.is_none()) {
        let db = survey(scenario, a.id.0).map_err(|e| (a.id, e))?;
        a.fingerprints = Some((*db).clone());
    }
    Ok(())
}
