//! The benchmarks behind `ocelli bench`: each times a hot path and returns its figures as JSON.

pub mod assign;
pub mod camera;
pub mod fuse;
pub mod grid;
pub mod head;
pub mod particle;
pub mod server;
pub mod transport;
mod wake;
