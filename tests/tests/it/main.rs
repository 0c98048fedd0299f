//! End-to-end tests: real `ocelli` processes.

mod cluster;
mod harness;
mod netns;
mod transport;
