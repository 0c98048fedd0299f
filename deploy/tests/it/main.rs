//! Integration tests of the `deploy` crate (one binary).

mod experiment;
mod replay;
mod rerun;
mod sim;
