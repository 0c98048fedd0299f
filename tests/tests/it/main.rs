//! End-to-end tests: real `ocelli` processes.

mod cluster;
mod harness;
mod layering;
mod netns;
mod operations;
mod transport;
