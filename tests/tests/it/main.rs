//! End-to-end tests: real `ocelli` processes.

mod chaos;
mod cluster;
mod fuzz_seeds;
mod harness;
mod layering;
mod netns;
mod operations;
mod radio;
mod transport;
mod viewer;
