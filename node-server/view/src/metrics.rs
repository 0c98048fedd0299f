//! `/metrics`: the view's counts in Prometheus text format, through the `prometheus` crate.
//!
//! Every metric is under `ocelli_`. They are computed from the newest published state at each
//! scrape (a fresh registry per scrape, so a node that left the scenario leaves no stale
//! series behind); counters carry the cumulative counts the nodes and the server report.
//!
//! | metric | labels | what |
//! |---|---|---|
//! | `ocelli_steps_total` | `head` | the head's last filter step |
//! | `ocelli_tracks` | | global tracks shown |
//! | `ocelli_handovers_total` | | handovers and owner changes |
//! | `ocelli_node_up` | `node`, `role` | 1 while the server counts the node as up |
//! | `ocelli_node_stale` | `node`, `role` | 1 while up but silent for 3 s |
//! | `ocelli_camera_mode` | `node`, `mode` | 1 for the camera's current mode |
//! | `ocelli_dropped_total` | `node` | messages the node could not deliver |
//! | `ocelli_lost_total` | `node` | its frames that never reached the server (sequence gaps) |
//! | `ocelli_late_total` | `head` | contributions past their step's deadline |
//! | `ocelli_rejected_total` | `node` | frames the node rejected |
//! | `ocelli_server_rejected_total` | | inputs the server rejected |
//! | `ocelli_sync_error_seconds` | `node` | the node's clock error |
//! | `ocelli_view_time_seconds` | | the newest record's time |
//! | `ocelli_view_records_total`, `ocelli_view_undecodable_total` | | records applied / skipped |
//! | `ocelli_view_published_total` | | states published by the producer |
//! | `ocelli_view_sse_clients` | | open event streams |
//! | `ocelli_view_sse_sent_total`, `ocelli_view_sse_dropped_total` | | states sent / skipped for slow clients |

use crate::feed::{FeedStats, Published};
use crate::state::{NodeKind, ViewState};
use prometheus::{
    Encoder, Gauge, IntCounter, IntCounterVec, IntGauge, IntGaugeVec, Opts, Registry, TextEncoder,
};
use proto::Mode;

/// The content type of the text format.
pub const CONTENT_TYPE: &str = prometheus::TEXT_FORMAT;

fn role(kind: NodeKind) -> &'static str {
    match kind {
        NodeKind::Camera => "camera",
        NodeKind::Head => "head",
        NodeKind::Server => "server",
        NodeKind::Viewer => "viewer",
        NodeKind::Acoustic => "acoustic",
        NodeKind::Unknown => "unknown",
    }
}

fn mode_name(m: Mode) -> &'static str {
    match m {
        Mode::Active => "active",
        Mode::CameraOff => "camera_off",
        Mode::Inactive => "inactive",
    }
}

struct Builder {
    registry: Registry,
}

impl Builder {
    fn gauge_vec(&self, name: &str, help: &str, labels: &[&str]) -> prometheus::Result<IntGaugeVec> {
        let g = IntGaugeVec::new(Opts::new(name, help), labels)?;
        self.registry.register(Box::new(g.clone()))?;
        Ok(g)
    }

    fn counter_vec(&self, name: &str, help: &str, labels: &[&str]) -> prometheus::Result<IntCounterVec> {
        let c = IntCounterVec::new(Opts::new(name, help), labels)?;
        self.registry.register(Box::new(c.clone()))?;
        Ok(c)
    }

    fn counter(&self, name: &str, help: &str, v: u64) -> prometheus::Result<()> {
        let c = IntCounter::new(name, help)?;
        c.inc_by(v);
        self.registry.register(Box::new(c))
    }

    fn gauge(&self, name: &str, help: &str, v: i64) -> prometheus::Result<()> {
        let g = IntGauge::new(name, help)?;
        g.set(v);
        self.registry.register(Box::new(g))
    }

    fn float(&self, name: &str, help: &str, v: f64) -> prometheus::Result<()> {
        let g = Gauge::new(name, help)?;
        g.set(v);
        self.registry.register(Box::new(g))
    }
}

fn per_node(b: &Builder, s: &ViewState) -> prometheus::Result<()> {
    let up = b.gauge_vec(
        "ocelli_node_up",
        "1 while the server counts the node as up",
        &["node", "role"],
    )?;
    let stale = b.gauge_vec(
        "ocelli_node_stale",
        "1 while the node is up but has not been heard from for 3 s",
        &["node", "role"],
    )?;
    let mode = b.gauge_vec(
        "ocelli_camera_mode",
        "1 for the camera's current sensing mode",
        &["node", "mode"],
    )?;
    let dropped = b.counter_vec(
        "ocelli_dropped_total",
        "messages the node could not deliver",
        &["node"],
    )?;
    let lost = b.counter_vec(
        "ocelli_lost_total",
        "the node's frames that never reached the server (sequence gaps)",
        &["node"],
    )?;
    let rejected = b.counter_vec(
        "ocelli_rejected_total",
        "frames the node received and rejected",
        &["node"],
    )?;
    let late = b.counter_vec(
        "ocelli_late_total",
        "contributions that reached the head after their step's deadline",
        &["head"],
    )?;
    let steps = b.counter_vec("ocelli_steps_total", "filter steps the head has run", &["head"])?;
    let sync = prometheus::GaugeVec::new(
        Opts::new(
            "ocelli_sync_error_seconds",
            "the node's clock error against the server's",
        ),
        &["node"],
    )?;
    b.registry.register(Box::new(sync.clone()))?;
    for n in s.nodes.values() {
        let id = n.id.to_string();
        let r = role(n.role);
        up.with_label_values(&[id.as_str(), r]).set(i64::from(n.up));
        stale.with_label_values(&[id.as_str(), r]).set(i64::from(n.stale));
        if let Some(m) = n.mode {
            for each in Mode::ALL {
                mode.with_label_values(&[id.as_str(), mode_name(each)])
                    .set(i64::from(each == m));
            }
        }
        dropped.with_label_values(&[id.as_str()]).inc_by(n.health.dropped);
        lost.with_label_values(&[id.as_str()]).inc_by(n.health.lost);
        rejected
            .with_label_values(&[id.as_str()])
            .inc_by(n.health.rejected);
        if n.role == NodeKind::Head {
            late.with_label_values(&[id.as_str()]).inc_by(n.health.late);
            steps.with_label_values(&[id.as_str()]).inc_by(n.health.steps);
        }
        if let Some(e) = n.health.sync_error_ms {
            sync.with_label_values(&[id.as_str()]).set(e * 1e-3);
        }
    }
    Ok(())
}

/// The metrics of a published state and of the HTTP side, as Prometheus text.
///
/// # Errors
/// A metric the registry refuses (a bug: names and labels are fixed here).
pub fn render(p: &Published, stats: &FeedStats) -> prometheus::Result<String> {
    let b = Builder {
        registry: Registry::new(),
    };
    let s = &p.state;
    per_node(&b, s)?;
    b.gauge("ocelli_tracks", "global tracks shown", s.tracks.len() as i64)?;
    b.counter(
        "ocelli_handovers_total",
        "handovers and owner changes",
        s.totals.handovers,
    )?;
    b.counter(
        "ocelli_server_rejected_total",
        "inputs the server rejected",
        s.totals.rejected,
    )?;
    b.float(
        "ocelli_view_time_seconds",
        "time of the newest record applied",
        s.time,
    )?;
    b.counter(
        "ocelli_view_records_total",
        "recording records applied to the view",
        s.totals.records,
    )?;
    b.counter(
        "ocelli_view_undecodable_total",
        "records the view could not read (another build or protocol version)",
        s.totals.undecodable,
    )?;
    b.counter(
        "ocelli_view_published_total",
        "states the producer published",
        p.seq,
    )?;
    b.gauge(
        "ocelli_view_sse_clients",
        "open event streams",
        i64::try_from(FeedStats::get(&stats.sse_clients)).unwrap_or(i64::MAX),
    )?;
    b.counter(
        "ocelli_view_sse_sent_total",
        "states sent to event streams",
        FeedStats::get(&stats.sse_sent),
    )?;
    b.counter(
        "ocelli_view_sse_dropped_total",
        "states event streams skipped because their client was slower than the producer",
        FeedStats::get(&stats.sse_dropped),
    )?;
    b.counter(
        "ocelli_view_requests_total",
        "HTTP requests answered",
        FeedStats::get(&stats.requests),
    )?;
    let mut out = Vec::new();
    TextEncoder::new().encode(&b.registry.gather(), &mut out)?;
    Ok(String::from_utf8_lossy(&out).into_owned())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::feed::channel;
    use proto::scenario::Scenario;
    use std::sync::Arc;

    fn sample() -> String {
        let mut s = ViewState::with_scenario(&Scenario::default_scenario());
        if let Some(n) = s.nodes.get_mut(&10) {
            n.up = true;
            n.mode = Some(Mode::CameraOff);
            n.health.dropped = 4;
            n.health.sync_error_ms = Some(0.5);
        }
        if let Some(n) = s.nodes.get_mut(&2) {
            n.up = true;
            n.health.late = 9;
            n.health.steps = 120;
        }
        let (mut p, feed) = channel(ViewState::new());
        p.publish(Arc::new(s));
        FeedStats::add(&feed.stats().sse_dropped, 3);
        render(&feed.latest(), feed.stats()).unwrap()
    }

    #[test]
    fn every_metric_is_under_ocelli_and_the_brief_s_are_there() {
        let text = sample();
        let names: std::collections::BTreeSet<&str> = text
            .lines()
            .filter(|l| !l.starts_with('#') && !l.is_empty())
            .map(|l| l.split(['{', ' ']).next().unwrap())
            .collect();
        assert!(names.iter().all(|n| n.starts_with("ocelli_")), "{names:?}");
        for want in [
            "ocelli_steps_total",
            "ocelli_tracks",
            "ocelli_dropped_total",
            "ocelli_late_total",
            "ocelli_rejected_total",
            "ocelli_server_rejected_total",
            "ocelli_sync_error_seconds",
            "ocelli_node_up",
            "ocelli_view_sse_dropped_total",
        ] {
            assert!(names.contains(want), "{want} missing from {names:?}");
        }
        // Every sample line is `name{labels} value` with a number.
        for l in text.lines().filter(|l| !l.starts_with('#') && !l.is_empty()) {
            let v = l.rsplit(' ').next().unwrap();
            assert!(v.parse::<f64>().is_ok(), "{l}");
        }
    }

    #[test]
    fn values_follow_the_state() {
        let text = sample();
        let has = |line: &str| text.lines().any(|l| l == line);
        assert!(has(r#"ocelli_node_up{node="10",role="camera"} 1"#), "{text}");
        assert!(has(r#"ocelli_node_up{node="11",role="camera"} 0"#));
        assert!(has(r#"ocelli_camera_mode{mode="camera_off",node="10"} 1"#));
        assert!(has(r#"ocelli_camera_mode{mode="active",node="10"} 0"#));
        assert!(has(r#"ocelli_dropped_total{node="10"} 4"#));
        assert!(has(r#"ocelli_late_total{head="2"} 9"#));
        assert!(has(r#"ocelli_steps_total{head="2"} 120"#));
        assert!(has(r#"ocelli_sync_error_seconds{node="10"} 0.0005"#));
        assert!(has("ocelli_view_sse_dropped_total 3"));
        assert!(has("ocelli_view_published_total 1"));
        assert!(text.contains("# TYPE ocelli_dropped_total counter"));
    }
}
