//! Integration tests of the simulation runtime (one binary).

mod default_scenario;
mod handback;
mod particle;
