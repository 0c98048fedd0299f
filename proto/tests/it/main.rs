//! proto's integration tests: the wire contract, the camera and measurement models, the scenario
//! files. One binary (matklad, "Delete Cargo Integration Tests").

// (i, j) index loops over 6×6 matrices read clearer than zipped iterators.
#![allow(clippy::needless_range_loop)]

mod camera;
mod models;
mod scenario;
mod wire;
