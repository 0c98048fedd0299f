//! Integration tests of the `deploy` crate (one binary).

mod replay;
mod rerun;
mod sim;
