//! Integration tests of the lab (one binary).

mod experiment;
mod paper004;
mod replay;
mod rerun;
