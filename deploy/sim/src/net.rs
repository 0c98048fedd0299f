//! The simulated network of the simulation runtime: per-link latency with jitter, loss,
//! partitions over time windows, and per-node clock skew. Fully determined by its seed.

use proto::NodeId;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

/// Network impairments, all optional (zero = perfect network).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct NetworkModel {
    /// One-way base latency, milliseconds.
    #[serde(default)]
    pub latency_ms: f64,
    /// Uniform extra latency in `[0, jitter_ms)`, milliseconds.
    #[serde(default)]
    pub jitter_ms: f64,
    /// Probability that any one message is lost.
    #[serde(default)]
    pub loss: f64,
    /// Windows during which nodes are cut off.
    #[serde(default)]
    pub partitions: Vec<Partition>,
    /// Largest clock offset given to a node, milliseconds (uniform in ±).
    #[serde(default)]
    pub clock_offset_ms: f64,
    /// Largest clock drift given to a node, parts per million (uniform in ±).
    #[serde(default)]
    pub clock_drift_ppm: f64,
}

/// Nodes in `isolated` can neither send nor receive between `from_s` and `to_s` (sim seconds).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct Partition {
    pub from_s: f64,
    pub to_s: f64,
    pub isolated: Vec<u32>,
}

/// A node's local clock: `local = true · (1 + drift) + offset`, nanoseconds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SkewedClock {
    pub offset_ns: i64,
    pub drift: f64,
}

impl SkewedClock {
    pub const PERFECT: SkewedClock = SkewedClock {
        offset_ns: 0,
        drift: 0.0,
    };

    pub fn local(&self, true_ns: i64) -> i64 {
        true_ns + (true_ns as f64 * self.drift).round() as i64 + self.offset_ns
    }
}

/// What happens to one message.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fate {
    /// Delivered after this many nanoseconds.
    Deliver(i64),
    Lost,
    Partitioned,
}

/// The network with its random stream.
#[derive(Debug)]
pub struct SimNetwork {
    model: NetworkModel,
    rng: ChaCha8Rng,
}

impl SimNetwork {
    pub fn new(model: NetworkModel, seed: u64) -> Self {
        SimNetwork {
            model,
            rng: ChaCha8Rng::seed_from_u64(seed ^ 0x6e65_7477_6f72_6b00),
        }
    }

    pub fn model(&self) -> &NetworkModel {
        &self.model
    }

    /// A clock for each node, drawn from the model's bounds (same seed → same clocks).
    pub fn clock_for(&self, node: NodeId, seed: u64) -> SkewedClock {
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ (u64::from(node.0) << 20) ^ 0x0063_6c6f_636b);
        let m = &self.model;
        let offset_ns = if m.clock_offset_ms > 0.0 {
            (rng.random_range(-1.0..1.0) * m.clock_offset_ms * 1e6) as i64
        } else {
            0
        };
        let drift = if m.clock_drift_ppm > 0.0 {
            rng.random_range(-1.0..1.0) * m.clock_drift_ppm * 1e-6
        } else {
            0.0
        };
        SkewedClock { offset_ns, drift }
    }

    fn cut(&self, node: NodeId, t_s: f64) -> bool {
        self.model
            .partitions
            .iter()
            .any(|p| t_s >= p.from_s && t_s < p.to_s && p.isolated.contains(&node.0))
    }

    /// Decide the fate of a message sent at `t_ns` (true time) from `from` to `to`.
    pub fn fate(&mut self, t_ns: i64, from: NodeId, to: NodeId) -> Fate {
        let t_s = t_ns as f64 * 1e-9;
        if self.cut(from, t_s) || self.cut(to, t_s) {
            return Fate::Partitioned;
        }
        // Always draw both numbers so one message's fate does not shift the stream of others
        // depending on the model's parameters.
        let lost = self.rng.random::<f64>() < self.model.loss;
        let jitter = self.rng.random::<f64>() * self.model.jitter_ms;
        if lost {
            return Fate::Lost;
        }
        Fate::Deliver(((self.model.latency_ms + jitter) * 1e6).round() as i64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_seed_gives_same_fates_and_loss_rate_matches_the_model() {
        let model = NetworkModel {
            latency_ms: 2.0,
            jitter_ms: 1.0,
            loss: 0.1,
            ..Default::default()
        };
        let mut a = SimNetwork::new(model.clone(), 7);
        let mut b = SimNetwork::new(model, 7);
        let (mut lost, n) = (0, 20_000);
        for i in 0..n {
            let fa = a.fate(i * 1000, NodeId(1), NodeId(2));
            assert_eq!(fa, b.fate(i * 1000, NodeId(1), NodeId(2)));
            match fa {
                Fate::Lost => lost += 1,
                Fate::Deliver(ns) => assert!((2_000_000..3_000_000).contains(&ns), "latency {ns}"),
                Fate::Partitioned => panic!("no partition configured"),
            }
        }
        let rate = lost as f64 / n as f64;
        assert!((rate - 0.1).abs() < 0.01, "loss rate {rate}");
    }

    #[test]
    fn partitions_cut_both_directions_only_inside_their_window() {
        let model = NetworkModel {
            partitions: vec![Partition {
                from_s: 1.0,
                to_s: 2.0,
                isolated: vec![5],
            }],
            ..Default::default()
        };
        let mut net = SimNetwork::new(model, 1);
        assert_eq!(net.fate(1_500_000_000, NodeId(5), NodeId(1)), Fate::Partitioned);
        assert_eq!(net.fate(1_500_000_000, NodeId(1), NodeId(5)), Fate::Partitioned);
        assert_eq!(net.fate(1_500_000_000, NodeId(1), NodeId(2)), Fate::Deliver(0));
        assert_eq!(net.fate(2_000_000_000, NodeId(5), NodeId(1)), Fate::Deliver(0));
    }

    #[test]
    fn skewed_clocks_stay_within_bounds() {
        let model = NetworkModel {
            clock_offset_ms: 50.0,
            clock_drift_ppm: 100.0,
            ..Default::default()
        };
        let net = SimNetwork::new(model, 3);
        for id in 0..50 {
            let c = net.clock_for(NodeId(id), 3);
            assert!(c.offset_ns.abs() <= 50_000_000);
            assert!(c.drift.abs() <= 100e-6);
            assert_eq!(c, net.clock_for(NodeId(id), 3));
        }
    }
}
