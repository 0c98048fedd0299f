//! End-to-end tests: real `ocelli` processes.

mod cluster;
mod netns;
mod transport;
