//! How old a fused estimate is when the server has it, from the recording: for every track
//! report the server received, its recording stamp (the server's cluster time on receipt)
//! minus
//! - the report's time (the head's filter step the estimate is for): step to server;
//! - the capture time of the oldest camera frame fused into it (`TrackReport::captured`):
//!   frame capture to the fused estimate at the server, end to end.

use node_server::analysis::Loaded;
use node_server::record::Record;
use proto::msg::Message;
use serde::Serialize;

/// Percentiles of one latency over the track reports, milliseconds.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Percentiles {
    pub reports: usize,
    pub p50_ms: f64,
    pub p99_ms: f64,
    pub max_ms: f64,
}

/// The estimates' ages at the server.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ReportAge {
    /// From the head's step to the server.
    pub step_to_server: Percentiles,
    /// From the capture of the oldest frame fused into the estimate to the server (reports that
    /// fused a camera frame only); `None` when none did.
    pub capture_to_server: Option<Percentiles>,
}

/// The `q`-quantile of sorted `xs` (nearest rank).
fn quantile(sorted: &[f64], q: f64) -> f64 {
    let rank = (q * sorted.len() as f64).ceil() as usize;
    sorted[rank.clamp(1, sorted.len()) - 1]
}

fn percentiles(mut xs: Vec<f64>) -> Option<Percentiles> {
    if xs.is_empty() {
        return None;
    }
    xs.sort_by(f64::total_cmp);
    Some(Percentiles {
        reports: xs.len(),
        p50_ms: quantile(&xs, 0.5),
        p99_ms: quantile(&xs, 0.99),
        max_ms: xs[xs.len() - 1],
    })
}

/// The ages of every track report in `loaded`; `None` without any.
pub fn of(loaded: &Loaded) -> Option<ReportAge> {
    let mut steps = Vec::new();
    let mut captures = Vec::new();
    for s in &loaded.records {
        if let Record::Received(env) = &s.record
            && let Message::TrackReport(r) = &env.body
        {
            steps.push(s.at.secs_since(r.time) * 1e3);
            if let Some(c) = r.captured {
                captures.push(s.at.secs_since(c) * 1e3);
            }
        }
    }
    Some(ReportAge {
        step_to_server: percentiles(steps)?,
        capture_to_server: percentiles(captures),
    })
}

/// `report` as JSON with the estimates' ages under `latency` (absent without track reports).
///
/// # Errors
/// `report` does not serialize to a JSON object.
pub fn report_json(report: &impl Serialize, loaded: &Loaded) -> serde_json::Result<serde_json::Value> {
    let mut json = serde_json::to_value(report)?;
    if let (Some(age), Some(map)) = (of(loaded), json.as_object_mut()) {
        map.insert("latency".into(), serde_json::to_value(age)?);
    }
    Ok(json)
}

/// The lines printed after a report.
pub fn to_line(a: &ReportAge) -> String {
    let s = &a.step_to_server;
    let mut out = format!(
        "estimate age     step to server p50 {:.1} ms, p99 {:.1} ms, max {:.1} ms over {} track reports\n",
        s.p50_ms, s.p99_ms, s.max_ms, s.reports
    );
    match &a.capture_to_server {
        Some(c) => out.push_str(&format!(
            "end to end       frame capture to estimate at the server p50 {:.1} ms, p99 {:.1} ms, max {:.1} ms over {} track reports with a camera frame\n",
            c.p50_ms, c.p99_ms, c.max_ms, c.reports
        )),
        None => out.push_str("end to end       no track report fused a camera frame\n"),
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_are_nearest_rank() {
        let xs: Vec<f64> = (1..=100).map(f64::from).collect();
        assert_eq!((quantile(&xs, 0.5), quantile(&xs, 0.99)), (50.0, 99.0));
        assert_eq!(quantile(&[7.0], 0.99), 7.0);
    }

    #[test]
    fn ages_are_receipt_stamp_minus_step_and_capture_times() {
        use node_server::record::Stamped;
        use proto::ClusterTime;
        use proto::msg::Envelope;
        let fixture = proto::examples::messages()
            .into_iter()
            .find_map(|e| match e.body {
                Message::TrackReport(r) => Some(r),
                _ => None,
            })
            .expect("the TrackReport fixture");
        let report = |step_ms: i64, captured_ms: Option<i64>| {
            let mut r = fixture.clone();
            r.time = ClusterTime(step_ms * 1_000_000);
            r.captured = captured_ms.map(|c| ClusterTime(c * 1_000_000));
            Message::TrackReport(r)
        };
        let other = proto::examples::messages()
            .into_iter()
            .find(|e| !matches!(e.body, Message::TrackReport(_)))
            .expect("another fixture")
            .body;
        let rec = |at_ms: i64, body: Message| {
            Stamped::new(
                ClusterTime(at_ms * 1_000_000),
                Record::Received(Envelope {
                    source: proto::NodeId(2),
                    seq: 0,
                    time: ClusterTime(0),
                    body,
                }),
            )
        };
        let loaded = Loaded {
            scenario: proto::scenario::Scenario::default_scenario(),
            records: vec![
                rec(1_090, report(1_000, Some(960))),
                rec(1_230, report(1_200, None)),
                rec(5, other),
            ],
            skipped: Vec::new(),
        };
        let a = of(&loaded).expect("two reports");
        let s = &a.step_to_server;
        assert_eq!(s.reports, 2);
        assert!(
            (s.p50_ms - 30.0).abs() < 1e-9 && (s.max_ms - 90.0).abs() < 1e-9,
            "{a:?}"
        );
        // Only the report with a camera frame: received at 1090, captured at 960.
        let c = a.capture_to_server.as_ref().expect("one report with a frame");
        assert_eq!(c.reports, 1);
        assert!((c.p50_ms - 130.0).abs() < 1e-9, "{a:?}");
    }
}
