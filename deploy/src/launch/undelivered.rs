//! What the nodes' links could not deliver, from the lines each node appends to its exit
//! summary when it stops (`--exit-summary`, [`RunDir::exit_summary`]), split at the moment the
//! launcher began stopping the cluster.
//!
//! The launcher signals every node within milliseconds, but a hundred processes on two cores
//! act on the signal over a few hundred: a node still running sends to peers that have already
//! stopped reading. Those messages are the stop's, not the run's. What was not delivered before
//! the stop began is the run's loss, which the nodes' statuses also bring to the recording's
//! `dropped` (all but what followed a node's last status).

use super::run_dir::RunDir;
use proto::ClusterTime;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// The launch's account of undelivered messages.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Undelivered {
    /// Exit summaries read: one per run of a node process (a restarted node leaves one per run
    /// that stopped cleanly).
    pub summaries: usize,
    /// Nodes that left no exit summary (killed, or crashed on every run).
    pub nodes_without_summary: Vec<String>,
    /// Lines of the exit summaries that could not be read.
    pub unreadable_lines: usize,
    /// Sent before the stop began: lost during the run.
    pub during_run: u64,
    /// Sent after the stop began, to peers that had stopped first.
    pub at_stop: u64,
    /// Beyond the times a node keeps (`runtime::process::UNDELIVERED_TIMES_KEPT`): when is not
    /// known.
    pub untimed: u64,
    pub during_run_by_kind: BTreeMap<String, u64>,
    pub at_stop_by_kind: BTreeMap<String, u64>,
}

/// The part of a node's exit summary (`runtime::RunSummary`) read here.
#[derive(Deserialize)]
struct ExitLine {
    undelivered: BTreeMap<String, u64>,
    undelivered_at: Vec<At>,
}

#[derive(Deserialize)]
struct At {
    at_ns: i64,
    kind: String,
}

impl Undelivered {
    /// Add one exit summary line (`stop_began`: when the launcher began stopping the nodes).
    fn add_line(&mut self, line: &str, stop_began: ClusterTime) -> Result<(), serde_json::Error> {
        let exit: ExitLine = serde_json::from_str(line)?;
        self.summaries += 1;
        let total: u64 = exit.undelivered.values().sum();
        for a in &exit.undelivered_at {
            let (n, by_kind) = if a.at_ns >= stop_began.0 {
                (&mut self.at_stop, &mut self.at_stop_by_kind)
            } else {
                (&mut self.during_run, &mut self.during_run_by_kind)
            };
            *n += 1;
            *by_kind.entry(a.kind.clone()).or_default() += 1;
        }
        self.untimed += total.saturating_sub(exit.undelivered_at.len() as u64);
        Ok(())
    }

    /// Add a node's exit summary file (`text`: its lines).
    fn add_node(&mut self, node: &str, text: &str, stop_began: ClusterTime) {
        let before = self.summaries;
        for line in text.lines().filter(|l| !l.trim().is_empty()) {
            if let Err(e) = self.add_line(line, stop_began) {
                self.unreadable_lines += 1;
                tracing::warn!(node, error = %e, "an exit summary line cannot be read");
            }
        }
        if self.summaries == before {
            self.nodes_without_summary.push(node.to_string());
        }
    }

    /// The line printed after a launch's report.
    pub fn to_line(&self) -> String {
        let mut out = format!(
            "undelivered     {} during the run, {} at the stop (to peers that stopped first)",
            self.during_run, self.at_stop
        );
        if self.untimed > 0 {
            out.push_str(&format!(", {} at unknown times", self.untimed));
        }
        if !self.nodes_without_summary.is_empty() {
            out.push_str(&format!(
                "; no exit summary from {}",
                self.nodes_without_summary.join(", ")
            ));
        }
        out.push('\n');
        out
    }
}

/// The account of `nodes`' exit summaries in `run`.
pub fn read(run: &RunDir, nodes: &[String], stop_began: ClusterTime) -> Undelivered {
    let mut u = Undelivered::default();
    for node in nodes {
        let path = run.exit_summary(node);
        // A node killed on every run leaves no file: it is named, not an error.
        let text = std::fs::read_to_string(&path).unwrap_or_default();
        u.add_node(node, &text, stop_began);
    }
    u
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(kinds: &[(&str, u64)], at: &[(i64, &str)]) -> String {
        serde_json::json!({
            "sent": 10,
            "undelivered": kinds.iter().map(|(k, n)| (k.to_string(), *n)).collect::<BTreeMap<_, _>>(),
            "undelivered_at": at.iter().map(|(t, k)| serde_json::json!({"at_ns": t, "to": 3, "kind": k})).collect::<Vec<_>>(),
        })
        .to_string()
    }

    /// Each undelivered message falls on its side of the stop; those beyond the kept times are
    /// untimed; a run with no summary is named; a damaged line is counted and the rest read.
    #[test]
    fn undelivered_messages_are_split_at_the_stop() {
        let stop = ClusterTime(1_000);
        let mut u = Undelivered::default();
        // A camera: one status lost mid-run, one at the stop.
        let camera = line(
            &[("node_status", 2)],
            &[(400, "node_status"), (1_000, "node_status")],
        );
        u.add_node("camera-10", &camera, stop);
        // A head restarted once: its first run lost 5 priors, 3 of them with times kept; its
        // second run lost 2 at the stop.
        let first = line(
            &[("priors", 5)],
            &[(100, "priors"), (200, "priors"), (300, "priors")],
        );
        let second = line(&[("priors", 2)], &[(1_500, "priors"), (1_600, "priors")]);
        u.add_node("head-2", &format!("{first}\n{second}\nnot json\n"), stop);
        u.add_node("camera-11", "", stop);
        assert_eq!(u.summaries, 3);
        assert_eq!(u.unreadable_lines, 1);
        assert_eq!(u.nodes_without_summary, vec!["camera-11".to_string()]);
        assert_eq!((u.during_run, u.at_stop, u.untimed), (4, 3, 2));
        assert_eq!(u.during_run_by_kind["priors"], 3);
        assert_eq!(u.during_run_by_kind["node_status"], 1);
        assert_eq!(u.at_stop_by_kind["priors"], 2);
        assert_eq!(u.at_stop_by_kind["node_status"], 1);
        let text = u.to_line();
        assert!(text.contains("4 during the run, 3 at the stop"), "{text}");
        assert!(
            text.contains("2 at unknown times") && text.contains("camera-11"),
            "{text}"
        );
    }

    /// The runtime's own summary is what the launcher reads (the field names are shared).
    #[test]
    fn a_runtime_summary_is_read() {
        let mut s = runtime::RunSummary::default();
        s.undelivered.insert("priors", 1);
        s.undelivered_at.push(runtime::UndeliveredAt {
            at_ns: 5,
            to: proto::NodeId(100),
            kind: "priors",
        });
        let mut u = Undelivered::default();
        u.add_node("head-2", &serde_json::to_string(&s).unwrap(), ClusterTime(5));
        assert_eq!((u.summaries, u.at_stop, u.during_run, u.untimed), (1, 1, 0, 0));
    }
}
