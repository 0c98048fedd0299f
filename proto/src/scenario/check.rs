//! Semantic checks of a parsed scenario: what serde's types cannot say (unique ids, cameras
//! naming an existing head, finite geometry, positive rates, deadline inside the step).

use super::{NodeRole, PowerFigures, Scenario, ScenarioError};
use std::collections::BTreeSet;

fn all_finite(xs: &[f64]) -> bool {
    xs.iter().all(|x| x.is_finite())
}

impl Scenario {
    /// Check what the types cannot. `origin` names the file in errors.
    ///
    /// # Errors
    /// The first problem, naming the field and what was expected.
    pub fn validate(&self, origin: &str, _unused: Option<()>) -> Result<(), ScenarioError> {
        let bad = |field: String, problem: String| ScenarioError::Invalid {
            path: origin.into(),
            field,
            problem,
        };
        let positive = |field: String, x: f64| {
            if x.is_finite() && x > 0.0 {
                Ok(())
            } else {
                Err(bad(field, format!("expected a positive number, got {x}")))
            }
        };
        let power = |field: String, p: &PowerFigures| {
            let xs = [p.camera_mw, p.node_active_mw, p.node_low_power_mw];
            if xs.iter().all(|x| x.is_finite() && *x >= 0.0) {
                Ok(())
            } else {
                Err(bad(
                    field,
                    format!("expected finite, non-negative mW, got {xs:?}"),
                ))
            }
        };

        // World.
        for (i, (lo, hi)) in self.world.min.iter().zip(&self.world.max).enumerate() {
            if !(lo.is_finite() && hi.is_finite() && lo < hi) {
                return Err(bad(
                    format!("world.min/max[{i}]"),
                    format!("expected finite min < max, got {lo} and {hi}"),
                ));
            }
        }
        for (i, w) in self.world.walls.iter().enumerate() {
            if !all_finite(&[w.from[0], w.from[1], w.to[0], w.to[1]]) || w.from == w.to {
                return Err(bad(
                    format!("world.walls[{i}]"),
                    "expected two distinct, finite end points".into(),
                ));
            }
            positive(format!("world.walls[{i}].height"), w.height)?;
            if !(w.attenuation_db.is_finite() && w.attenuation_db >= 0.0) {
                return Err(bad(
                    format!("world.walls[{i}].attenuation-db"),
                    format!("expected a non-negative number, got {}", w.attenuation_db),
                ));
            }
        }
        if let Some(g) = &self.world.geo {
            g.validate().map_err(|e| bad("world.geo".into(), e.to_string()))?;
        }
        let r = &self.world.radio;
        if !all_finite(&[
            r.tx_power_dbm,
            r.path_loss_exponent,
            r.multipath_db,
            r.noise_db,
            r.node_offset_db,
        ]) || r.multipath_db < 0.0
            || r.noise_db < 0.0
            || r.node_offset_db < 0.0
        {
            return Err(bad(
                "world.radio".into(),
                "expected finite numbers and non-negative multipath-db, noise-db, node-offset-db".into(),
            ));
        }
        positive("world.radio.multipath-length-m".into(), r.multipath_length_m)?;

        // Network.
        let n = &self.network;
        if n.heartbeat_ms == 0 || n.liveness_timeout_ms <= n.heartbeat_ms {
            return Err(bad(
                "network.liveness-timeout-ms".into(),
                "expected 0 < heartbeat-ms < liveness-timeout-ms".into(),
            ));
        }
        if n.sync_beacon_ms == 0 || n.queue_len == 0 {
            return Err(bad(
                "network".into(),
                "expected positive sync-beacon-ms and queue-len".into(),
            ));
        }

        // Method.
        let m = &self.method;
        if m.step_ms == 0 || m.deadline_ms == 0 || m.deadline_ms >= m.step_ms {
            return Err(bad(
                "method.deadline-ms".into(),
                format!(
                    "expected 0 < deadline-ms < step-ms, got deadline-ms = {} and step-ms = {}",
                    m.deadline_ms, m.step_ms
                ),
            ));
        }
        positive("method.pixel-sigma".into(), m.pixel_sigma)?;
        positive("method.gate-chi2".into(), m.gate_chi2)?;
        positive("method.rssi-epsilon".into(), m.rssi_epsilon)?;
        if let Some(z) = m.target_plane_z
            && !z.is_finite()
        {
            return Err(bad(
                "method.target-plane-z".into(),
                format!("expected a finite height in metres, got {z}"),
            ));
        }
        positive("method.rssi-default.variance".into(), m.rssi_default.variance())?;
        if m.rssi_window < 2 {
            return Err(bad(
                "method.rssi-window".into(),
                format!("expected at least 2 readings, got {}", m.rssi_window),
            ));
        }
        if !(m.energy_weight.is_finite() && m.energy_weight >= 0.0) {
            return Err(bad(
                "method.energy-weight".into(),
                format!("expected a non-negative number, got {}", m.energy_weight),
            ));
        }
        if !m.motion.accel_psd.iter().all(|q| q.is_finite() && *q >= 0.0) {
            return Err(bad(
                "method.motion.accel-psd".into(),
                format!("expected non-negative numbers, got {:?}", m.motion.accel_psd),
            ));
        }
        if let Err(e) = m.particle.validate() {
            return Err(bad(
                format!("method.particle.{}", e.field),
                format!("expected {}, got {}", e.expected, e.value),
            ));
        }
        power("power".into(), &self.power)?;

        // Nodes.
        if self.nodes.len() > crate::MAX_NODES {
            return Err(bad(
                "nodes".into(),
                format!(
                    "{} nodes exceed the maximum of {}",
                    self.nodes.len(),
                    crate::MAX_NODES
                ),
            ));
        }
        let mut ids = BTreeSet::new();
        for n in &self.nodes {
            if !ids.insert(n.id) {
                return Err(bad(format!("nodes[id={}]", n.id), "duplicate node id".into()));
            }
        }
        let heads: BTreeSet<u32> = self.heads().map(|n| n.id).collect();
        let servers = self.nodes.iter().filter(|n| n.role == NodeRole::Server).count();
        if servers > 1 {
            return Err(bad(
                "nodes".into(),
                format!("expected at most one server, found {servers}"),
            ));
        }
        for n in &self.nodes {
            let field = |f: &str| format!("nodes[id={}].{f}", n.id);
            if n.role != NodeRole::Camera {
                if n.camera.is_some() {
                    return Err(bad(
                        field("camera"),
                        "only camera nodes have camera geometry".into(),
                    ));
                }
                if n.head.is_some() && n.role != NodeRole::Acoustic {
                    return Err(bad(
                        field("head"),
                        "only camera and acoustic nodes report to a head".into(),
                    ));
                }
            }
            if let Some(region) = n.region {
                if n.role != NodeRole::Head {
                    return Err(bad(field("region"), "only heads cover a region".into()));
                }
                if !(all_finite(&region) && region[0] < region[2] && region[1] < region[3]) {
                    return Err(bad(
                        field("region"),
                        format!("expected finite [xmin, ymin, xmax, ymax] with min < max, got {region:?}"),
                    ));
                }
            }
            if let Some(p) = &n.power {
                power(field("power"), p)?;
            }
            positive(field("cost-factor"), n.cost_factor)?;
            if n.role != NodeRole::Camera {
                if n.position.is_some() || n.radio.is_some() {
                    return Err(bad(
                        field(if n.radio.is_some() { "radio" } else { "position" }),
                        "only camera nodes carry a radio".into(),
                    ));
                }
                continue;
            }
            if let Some(p) = n.position
                && !all_finite(&p)
            {
                return Err(bad(
                    field("position"),
                    format!("expected finite [x, y, z], got {p:?}"),
                ));
            }
            if let Some(h) = n.head
                && !heads.contains(&h)
            {
                return Err(bad(field("head"), format!("no head with id {h}")));
            }
            let Some(cam) = &n.camera else {
                // A radio-only node: it needs a place and a radio.
                if n.position.is_none() {
                    return Err(bad(
                        field("camera"),
                        "a camera node needs camera geometry, or `position` (and rssi) to be a radio-only node"
                            .into(),
                    ));
                }
                if !n.rssi {
                    return Err(bad(
                        field("rssi"),
                        "a node without a camera must hear radio (rssi = true)".into(),
                    ));
                }
                continue;
            };
            if cam.opencv_intrinsic.is_none() && cam.intrinsics.is_none() {
                return Err(bad(
                    field("camera"),
                    "expected `intrinsics` or `opencv-intrinsic`".into(),
                ));
            }
            if cam.opencv_extrinsic.is_none() && cam.pose.is_none() {
                return Err(bad(
                    field("camera"),
                    "expected `pose` or `opencv-extrinsic`".into(),
                ));
            }
            if let Some(k) = &cam.intrinsics {
                if !(k.fx.is_finite() && k.fy.is_finite() && k.fx > 0.0 && k.fy > 0.0) {
                    return Err(bad(
                        field("camera.intrinsics"),
                        format!(
                            "expected positive focal lengths, got fx = {} and fy = {}",
                            k.fx, k.fy
                        ),
                    ));
                }
                if !(k.cx.is_finite() && k.cy.is_finite()) || k.width == 0 || k.height == 0 {
                    return Err(bad(
                        field("camera.intrinsics"),
                        "expected a finite principal point and a non-empty image".into(),
                    ));
                }
            }
            let d = &cam.distortion;
            if !all_finite(&[d.k1, d.k2, d.p1, d.p2, d.k3]) {
                return Err(bad(
                    field("camera.distortion"),
                    "expected finite coefficients".into(),
                ));
            }
            if let Some(p) = &cam.pose {
                let numbers = match p {
                    super::PoseSpec::LookAt { position, look_at } => [*position, *look_at],
                    super::PoseSpec::Rodrigues { rvec, tvec } => [*rvec, *tvec],
                };
                if !numbers.iter().all(|v| all_finite(v)) {
                    return Err(bad(field("camera.pose"), "expected finite numbers".into()));
                }
                if p.to_pose().is_none() {
                    return Err(bad(
                        field("camera.pose"),
                        "degenerate pose (look-at equals position or is straight up/down)".into(),
                    ));
                }
            }
            positive(field("camera.fps"), cam.fps)?;
        }
        self.check_acoustic(origin)?;
        Ok(())
    }
}
