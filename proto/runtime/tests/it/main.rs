//! The runtime's integration tests: transports over real sockets. One binary (matklad, "Delete
//! Cargo Integration Tests").

mod tcp_seq;
