//! Semantic checks of a parsed scenario: what serde's types cannot say (unique ids, cameras
//! naming an existing head, finite geometry, positive rates, deadline inside the step, listen
//! addresses that parse and do not collide). [`Scenario::validate`] runs one check per section
//! on every load; [`Scenario::check_deployment`] adds what needs files or geometry (calibration
//! files that read, cameras that see part of the world), for `ocelli scenario check`.

use super::{CameraSpec, NodeRole, NodeSpec, PowerFigures, Scenario, ScenarioError};
use std::collections::{BTreeMap, BTreeSet};

fn all_finite(xs: &[f64]) -> bool {
    xs.iter().all(|x| x.is_finite())
}

/// Builds the errors of one file.
struct Checker<'a> {
    origin: &'a str,
}

type Checked = Result<(), ScenarioError>;

impl Checker<'_> {
    fn bad(&self, field: impl Into<String>, problem: impl Into<String>) -> ScenarioError {
        ScenarioError::Invalid {
            path: self.origin.into(),
            field: field.into(),
            problem: problem.into(),
        }
    }

    fn fail(&self, field: impl Into<String>, problem: impl Into<String>) -> Checked {
        Err(self.bad(field, problem))
    }

    fn positive(&self, field: impl Into<String>, x: f64) -> Checked {
        if x.is_finite() && x > 0.0 {
            Ok(())
        } else {
            self.fail(field, format!("expected a positive number, got {x}"))
        }
    }

    fn non_negative(&self, field: impl Into<String>, x: f64) -> Checked {
        if x.is_finite() && x >= 0.0 {
            Ok(())
        } else {
            self.fail(field, format!("expected a non-negative number, got {x}"))
        }
    }

    fn power(&self, field: String, p: &PowerFigures) -> Checked {
        let xs = [p.camera_mw, p.node_active_mw, p.node_low_power_mw];
        if xs.iter().all(|x| x.is_finite() && *x >= 0.0) {
            Ok(())
        } else {
            self.fail(
                field,
                format!(
                    "expected finite, non-negative mW, got camera-mw = {}, node-active-mw = {}, node-low-power-mw = {}",
                    xs[0], xs[1], xs[2]
                ),
            )
        }
    }

    fn world(&self, s: &Scenario) -> Checked {
        for (i, (lo, hi)) in s.world.min.iter().zip(&s.world.max).enumerate() {
            if !(lo.is_finite() && hi.is_finite() && lo < hi) {
                return self.fail(
                    format!("world.min/max[{i}]"),
                    format!("expected finite min < max, got {lo} and {hi}"),
                );
            }
        }
        for (i, w) in s.world.walls.iter().enumerate() {
            if !all_finite(&[w.from[0], w.from[1], w.to[0], w.to[1]]) || w.from == w.to {
                return self.fail(
                    format!("world.walls[{i}]"),
                    "expected two distinct, finite end points",
                );
            }
            self.positive(format!("world.walls[{i}].height"), w.height)?;
            self.non_negative(format!("world.walls[{i}].attenuation-db"), w.attenuation_db)?;
        }
        if let Some(g) = &s.world.geo {
            g.validate().map_err(|e| self.bad("world.geo", e.to_string()))?;
        }
        self.radio(s)
    }

    fn radio(&self, s: &Scenario) -> Checked {
        let r = &s.world.radio;
        if !all_finite(&[r.tx_power_dbm, r.path_loss_exponent]) {
            return self.fail(
                "world.radio",
                "expected finite tx-power-dbm and path-loss-exponent",
            );
        }
        self.non_negative("world.radio.multipath-db", r.multipath_db)?;
        self.non_negative("world.radio.noise-db", r.noise_db)?;
        self.non_negative("world.radio.node-offset-db", r.node_offset_db)?;
        self.positive("world.radio.multipath-length-m", r.multipath_length_m)
    }

    fn network(&self, s: &Scenario) -> Checked {
        let n = &s.network;
        if n.heartbeat_ms == 0 || n.liveness_timeout_ms <= n.heartbeat_ms {
            return self.fail(
                "network.liveness-timeout-ms",
                format!(
                    "expected 0 < heartbeat-ms < liveness-timeout-ms, got heartbeat-ms = {} and liveness-timeout-ms = {}",
                    n.heartbeat_ms, n.liveness_timeout_ms
                ),
            );
        }
        if n.sync_beacon_ms == 0 {
            return self.fail("network.sync-beacon-ms", "expected a positive period");
        }
        if n.queue_len == 0 {
            return self.fail("network.queue-len", "expected a positive length");
        }
        Ok(())
    }

    fn method(&self, s: &Scenario) -> Checked {
        let m = &s.method;
        if m.step_ms == 0 || m.deadline_ms == 0 || m.deadline_ms >= m.step_ms {
            return self.fail(
                "method.deadline-ms",
                format!(
                    "expected 0 < deadline-ms < step-ms, got deadline-ms = {} and step-ms = {}",
                    m.deadline_ms, m.step_ms
                ),
            );
        }
        self.positive("method.pixel-sigma", m.pixel_sigma)?;
        self.positive("method.gate-chi2", m.gate_chi2)?;
        self.positive("method.rssi-epsilon", m.rssi_epsilon)?;
        if let Some(z) = m.target_plane_z
            && !z.is_finite()
        {
            return self.fail(
                "method.target-plane-z",
                format!("expected a finite height in metres, got {z}"),
            );
        }
        self.positive("method.rssi-default.variance", m.rssi_default.variance())?;
        if m.rssi_window < 2 {
            return self.fail(
                "method.rssi-window",
                format!("expected at least 2 readings, got {}", m.rssi_window),
            );
        }
        self.non_negative("method.energy-weight", m.energy_weight)?;
        if let Some(q) = m.motion.accel_psd.iter().find(|q| !(q.is_finite() && **q >= 0.0)) {
            return self.fail(
                "method.motion.accel-psd",
                format!("expected non-negative numbers, got {q}"),
            );
        }
        if let Err(e) = m.particle.validate() {
            return self.fail(
                format!("method.particle.{}", e.field),
                format!("expected {}, got {}", e.expected, e.value),
            );
        }
        self.power("power".into(), &s.power)
    }

    fn nodes(&self, s: &Scenario) -> Checked {
        if s.nodes.len() > crate::MAX_NODES {
            return self.fail(
                "nodes",
                format!(
                    "{} nodes exceed the maximum of {}",
                    s.nodes.len(),
                    crate::MAX_NODES
                ),
            );
        }
        let mut ids = BTreeSet::new();
        for n in &s.nodes {
            if !ids.insert(n.id) {
                return self.fail(format!("nodes[id={}]", n.id), "duplicate node id");
            }
        }
        let servers = s.nodes.iter().filter(|n| n.role == NodeRole::Server).count();
        if servers > 1 {
            return self.fail("nodes", format!("expected at most one server, found {servers}"));
        }
        let heads: BTreeSet<u32> = s.heads().map(|n| n.id).collect();
        for n in &s.nodes {
            self.node(n, &heads)?;
        }
        s.check_acoustic(self.origin)?;
        self.listen_addresses(s)
    }

    fn node(&self, n: &NodeSpec, heads: &BTreeSet<u32>) -> Checked {
        let field = |f: &str| format!("nodes[id={}].{f}", n.id);
        if n.role != NodeRole::Camera {
            if n.camera.is_some() {
                return self.fail(field("camera"), "only camera nodes have camera geometry");
            }
            if n.head.is_some() && n.role != NodeRole::Acoustic {
                return self.fail(field("head"), "only camera and acoustic nodes report to a head");
            }
        }
        if let Some(region) = n.region {
            if n.role != NodeRole::Head {
                return self.fail(field("region"), "only heads cover a region");
            }
            if !(all_finite(&region) && region[0] < region[2] && region[1] < region[3]) {
                return self.fail(
                    field("region"),
                    format!(
                        "expected finite [xmin, ymin, xmax, ymax] with min < max, got [{}, {}, {}, {}]",
                        region[0], region[1], region[2], region[3]
                    ),
                );
            }
        }
        if let Some(p) = &n.power {
            self.power(field("power"), p)?;
        }
        self.positive(field("cost-factor"), n.cost_factor)?;
        if let Some(addr) = &n.listen {
            if n.role == NodeRole::Camera {
                return self.fail(
                    field("listen"),
                    "cameras dial their head and the server; only heads and the server listen",
                );
            }
            listen_port(addr).map_err(|problem| self.bad(field("listen"), problem))?;
        }
        if n.role != NodeRole::Camera {
            if n.position.is_some() || n.radio.is_some() {
                return self.fail(
                    field(if n.radio.is_some() { "radio" } else { "position" }),
                    "only camera nodes carry a radio",
                );
            }
            return Ok(());
        }
        if let Some(p) = n.position
            && !all_finite(&p)
        {
            return self.fail(
                field("position"),
                format!("expected finite [x, y, z], got [{}, {}, {}]", p[0], p[1], p[2]),
            );
        }
        if let Some(h) = n.head
            && !heads.contains(&h)
        {
            return self.fail(field("head"), format!("no head with id {h}"));
        }
        let Some(cam) = &n.camera else {
            // A radio-only node: it needs a place and a radio.
            if n.position.is_none() {
                return self.fail(
                    field("camera"),
                    "a camera node needs camera geometry, or `position` (and rssi) to be a radio-only node",
                );
            }
            if !n.rssi {
                return self.fail(
                    field("rssi"),
                    "a node without a camera must hear radio (rssi = true)",
                );
            }
            return Ok(());
        };
        self.camera(cam, &field)
    }

    fn camera(&self, cam: &CameraSpec, field: &dyn Fn(&str) -> String) -> Checked {
        if cam.opencv_intrinsic.is_none() && cam.intrinsics.is_none() {
            return self.fail(field("camera"), "expected `intrinsics` or `opencv-intrinsic`");
        }
        if cam.opencv_extrinsic.is_none() && cam.pose.is_none() {
            return self.fail(field("camera"), "expected `pose` or `opencv-extrinsic`");
        }
        if let Some(k) = &cam.intrinsics {
            if !(k.fx.is_finite() && k.fy.is_finite() && k.fx > 0.0 && k.fy > 0.0) {
                return self.fail(
                    field("camera.intrinsics"),
                    format!(
                        "expected positive focal lengths, got fx = {} and fy = {}",
                        k.fx, k.fy
                    ),
                );
            }
            if !(k.cx.is_finite() && k.cy.is_finite()) || k.width == 0 || k.height == 0 {
                return self.fail(
                    field("camera.intrinsics"),
                    "expected a finite principal point and a non-empty image",
                );
            }
        }
        let d = &cam.distortion;
        if !all_finite(&[d.k1, d.k2, d.p1, d.p2, d.k3]) {
            return self.fail(field("camera.distortion"), "expected finite coefficients");
        }
        if let Some(p) = &cam.pose {
            let numbers = match p {
                super::PoseSpec::LookAt { position, look_at } => [*position, *look_at],
                super::PoseSpec::Rodrigues { rvec, tvec } => [*rvec, *tvec],
            };
            if !numbers.iter().all(|v| all_finite(v)) {
                return self.fail(field("camera.pose"), "expected finite numbers");
            }
            if p.to_pose().is_none() {
                return self.fail(
                    field("camera.pose"),
                    "degenerate pose (look-at equals position or is straight up/down)",
                );
            }
        }
        self.positive(field("camera.fps"), cam.fps)
    }

    /// No two nodes of one host listen on one port.
    fn listen_addresses(&self, s: &Scenario) -> Checked {
        let mut taken: BTreeMap<(&str, u16), u32> = BTreeMap::new();
        for n in &s.nodes {
            let Some(addr) = &n.listen else { continue };
            let Ok(port) = listen_port(addr) else { continue };
            if let Some(other) = taken.insert((n.host.as_str(), port), n.id) {
                return self.fail(
                    format!("nodes[id={}].listen", n.id),
                    format!(
                        "port {port} on host {} is already node {other}'s; each node of a host needs its own port",
                        n.host
                    ),
                );
            }
        }
        Ok(())
    }
}

/// The port of a `host:port` listen address (names are resolved later, by the transport).
///
/// # Errors
/// Not `host:port`, or a port outside 1–65535.
pub fn listen_port(addr: &str) -> Result<u16, String> {
    let Some((host, port)) = addr.rsplit_once(':') else {
        return Err(format!("expected `host:port`, got `{addr}`"));
    };
    if host.is_empty() {
        return Err(format!("expected `host:port`, got `{addr}` (no host)"));
    }
    match port.parse::<u32>() {
        Ok(p @ 1..=65535) => Ok(p as u16),
        _ => Err(format!("port `{port}` of `{addr}` is not in 1–65535")),
    }
}

impl Scenario {
    /// Check what the types cannot, one section at a time. `origin` names the file in errors.
    ///
    /// # Errors
    /// The first problem, naming the field and what was expected.
    pub fn validate(&self, origin: &str, _unused: Option<()>) -> Result<(), ScenarioError> {
        let c = Checker { origin };
        c.world(self)?;
        c.network(self)?;
        c.method(self)?;
        c.nodes(self)
    }

    /// What a deployment needs beyond [`Scenario::validate`]: every camera's model builds
    /// (calibration files exist and parse) and every camera sees part of the world (a point of
    /// its floor or volume lands in its image). `ocelli scenario check` runs it; a node would
    /// fail on the same problem later, alone and at run time.
    ///
    /// # Errors
    /// The first camera whose model does not build or that sees nothing of the world.
    pub fn check_deployment(&self) -> Result<(), ScenarioError> {
        let c = Checker { origin: &self.name };
        for n in self.cameras().filter(|n| n.camera.is_some()) {
            let model = self.camera_model(n.id)?;
            if !sees_the_world(&model, self) {
                let k = &model.intrinsics;
                return c.fail(
                    format!("nodes[id={}].camera", n.id),
                    format!(
                        "sees none of the world: no point of the room's floor or volume lands in its {}x{} image (check its pose)",
                        k.width, k.height
                    ),
                );
            }
        }
        Ok(())
    }
}

/// Whether any point of a grid over the world box lands inside the camera's image.
fn sees_the_world(model: &crate::camera::CameraModel, s: &Scenario) -> bool {
    const STEPS: usize = 24;
    let (lo, hi) = (s.world.min, s.world.max);
    let k = &model.intrinsics;
    let at = |a: f64, b: f64, i: usize| a + (b - a) * i as f64 / STEPS as f64;
    (0..=4).any(|iz| {
        (0..=STEPS).any(|ix| {
            (0..=STEPS).any(|iy| {
                let p = nalgebra::Vector3::new(
                    at(lo[0], hi[0], ix),
                    at(lo[1], hi[1], iy),
                    lo[2] + (hi[2] - lo[2]) * iz as f64 / 4.0,
                );
                model.project(&p).is_some_and(|px| {
                    px.x >= 0.0 && px.y >= 0.0 && px.x < f64::from(k.width) && px.y < f64::from(k.height)
                })
            })
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn default_with(edit: impl FnOnce(&mut Scenario)) -> Result<(), ScenarioError> {
        let mut s = Scenario::default_scenario();
        edit(&mut s);
        s.validate("t.toml", None)?;
        s.check_deployment()
    }

    fn err(r: Result<(), ScenarioError>) -> String {
        r.expect_err("should be refused").to_string()
    }

    #[test]
    fn the_default_scenario_is_deployable() {
        default_with(|_| {}).unwrap();
    }

    #[test]
    fn bad_listen_addresses_are_refused_naming_the_node() {
        let e = err(default_with(|s| {
            s.nodes.iter_mut().find(|n| n.id == 2).unwrap().listen = Some("127.0.0.1:99999".into());
        }));
        assert!(e.contains("nodes[id=2].listen") && e.contains("99999"), "{e}");
        let e = err(default_with(|s| {
            s.nodes.iter_mut().find(|n| n.id == 2).unwrap().listen = Some("7400".into());
        }));
        assert!(e.contains("host:port"), "{e}");
        let e = err(default_with(|s| {
            s.nodes.iter_mut().find(|n| n.id == 3).unwrap().listen = Some("127.0.0.1:7402".into());
        }));
        assert!(e.contains("nodes[id=3].listen") && e.contains("node 2"), "{e}");
        // Another host may use the same port.
        default_with(|s| {
            let n = s.nodes.iter_mut().find(|n| n.id == 3).unwrap();
            n.listen = Some("10.0.0.3:7402".into());
            n.host = "pi-3".into();
        })
        .unwrap();
    }

    /// Camera 12 of the default scenario, to change one setting.
    fn camera_12(s: &mut super::super::Scenario) -> &mut super::super::CameraSpec {
        s.nodes
            .iter_mut()
            .find(|n| n.id == 12)
            .and_then(|n| n.camera.as_mut())
            .expect("camera 12 in the default scenario")
    }

    #[test]
    fn a_camera_that_sees_nothing_or_a_missing_calibration_is_refused() {
        let e = err(default_with(|s| {
            let cam = camera_12(s);
            cam.pose = Some(super::super::PoseSpec::LookAt {
                // At the ceiling, looking up: every point of the room is behind it or level.
                position: [5.0, 4.0, 3.0],
                look_at: [5.0, 4.0 - 1e-3, 10.0],
            });
        }));
        assert!(
            e.contains("nodes[id=12].camera") && e.contains("sees none of the world"),
            "{e}"
        );
        let e = err(default_with(|s| {
            let cam = camera_12(s);
            cam.opencv_intrinsic = Some("/no/such/intr.xml".into());
        }));
        assert!(
            e.contains("nodes[id=12].camera.opencv-intrinsic") && e.contains("/no/such/intr.xml"),
            "{e}"
        );
    }
}
