//! End-to-end tests: real `ocelli` processes.

mod transport;
