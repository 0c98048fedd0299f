//! The tracker's parameters live in the scenario (`[method.particle]`, so that a deployment
//! file sets them): [`proto::scenario::particle`], re-exported here under the names the
//! tracker's modules use.

pub use proto::scenario::particle::{MAX_PARTICLES, MotionMode, ParamsError, ParticleParams};
