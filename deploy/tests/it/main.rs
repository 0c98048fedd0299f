//! Integration tests of the `ocelli` binary (one binary).

mod cli;
mod scenarios;
