//! Integration tests of the lab (one binary).

mod experiment;
mod replay;
mod rerun;
