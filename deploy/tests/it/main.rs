//! Integration tests of the `deploy` crate.
mod sim;
