//! Integration tests of the head, driven by a tiny measurement-level simulator.

mod activation;
mod filter;
mod fusion;
mod process;
mod rssi;
mod sim;
mod step;
mod targets;
