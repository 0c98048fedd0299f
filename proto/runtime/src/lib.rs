//! `runtime` runs Ocelli node cores as OS processes: the [`transport`]s they talk over
//! (iceoryx2 shared memory on one host, TCP between hosts, in-process channels in tests).
//!
//! The vocabulary (messages, wire encoding, models) is `proto`'s; a crate that needs only the
//! vocabulary depends on `proto` and builds neither tokio nor iceoryx2.

pub mod transport;
