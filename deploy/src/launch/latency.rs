//! How old a fused estimate is when the server has it: for every track report the server
//! received, its recording stamp (the server's cluster time on receipt) minus the report's
//! time (the head's filter step the estimate is for). The frames fused into that step were
//! captured up to one frame period around the step's start (they are fused at their capture
//! time); that part is not in this figure, since no report carries its frames' capture times.

use node_server::analysis::Loaded;
use node_server::record::Record;
use proto::msg::Message;
use serde::Serialize;

/// Percentiles of the step-to-server age of the estimates, milliseconds.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ReportAge {
    pub reports: usize,
    pub p50_ms: f64,
    pub p99_ms: f64,
    pub max_ms: f64,
}

/// The `q`-quantile of sorted `xs` (nearest rank).
fn quantile(sorted: &[f64], q: f64) -> f64 {
    let rank = (q * sorted.len() as f64).ceil() as usize;
    sorted[rank.clamp(1, sorted.len()) - 1]
}

/// The ages of every track report in `loaded`; `None` without any.
pub fn of(loaded: &Loaded) -> Option<ReportAge> {
    let mut ages: Vec<f64> = loaded
        .records
        .iter()
        .filter_map(|s| match &s.record {
            Record::Received(env) => match &env.body {
                Message::TrackReport(r) => Some(s.at.secs_since(r.time) * 1e3),
                _ => None,
            },
            _ => None,
        })
        .collect();
    if ages.is_empty() {
        return None;
    }
    ages.sort_by(f64::total_cmp);
    Some(ReportAge {
        reports: ages.len(),
        p50_ms: quantile(&ages, 0.5),
        p99_ms: quantile(&ages, 0.99),
        max_ms: ages[ages.len() - 1],
    })
}

/// The line printed after a report.
pub fn to_line(a: &ReportAge) -> String {
    format!(
        "estimate age     step to server p50 {:.1} ms, p99 {:.1} ms, max {:.1} ms over {} track reports (frame capture to step not included)\n",
        a.p50_ms, a.p99_ms, a.max_ms, a.reports
    )
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
    fn ages_are_receipt_stamp_minus_step_time() {
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
        let report = |step_ms: i64| {
            let mut r = fixture.clone();
            r.time = ClusterTime(step_ms * 1_000_000);
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
                rec(1_090, report(1_000)),
                rec(1_230, report(1_200)),
                rec(5, other),
            ],
            skipped: Vec::new(),
        };
        let a = of(&loaded).expect("two reports");
        assert_eq!(a.reports, 2);
        assert!(
            (a.p50_ms - 30.0).abs() < 1e-9 && (a.max_ms - 90.0).abs() < 1e-9,
            "{a:?}"
        );
    }
}
