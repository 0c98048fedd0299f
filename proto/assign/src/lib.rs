//! Optimal assignment, shared by every role that pairs things up: a camera pairing its
//! detections with a head's priors, a head pairing detections (and tags) with tracks, the
//! server's tracking metrics pairing truths with hypotheses.
//!
//! - [`matching`]: a maximum-weight matching over float weights with forbidden pairs, of any
//!   shape, optionally with as many pairs as possible first (py-motmetrics' rule).
//! - [`gnn`]: global nearest neighbour association — the optimal assignment of a frame's
//!   detections to tracks over gated costs, each detection to at most one track and each track
//!   to at most one detection per sensor.
//!
//! The solver is `pathfinding`'s Kuhn–Munkres on quantised weights. This crate depends on
//! nothing else, so that the node crates (which may not depend on each other) all reach one
//! copy of it.

pub mod gnn;
pub mod matching;

pub use gnn::{AssignError, GatedCosts, assign};
pub use matching::{max_weight_matching, max_weight_matching_exact};
