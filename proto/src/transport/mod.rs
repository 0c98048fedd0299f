//! Transports: one interface, three implementations (iceoryx2, TCP, in-process).
