//! One module per `ocelli` subcommand.

pub mod acoustic;
pub mod bar;
pub mod bench;
pub mod camera;
pub mod common;
pub mod deploy;
pub mod experiment;
pub mod export;
pub mod fuse;
pub mod head;
pub mod launch;
pub mod peer;
pub mod radio;
pub mod replay;
pub mod report;
pub mod scenario;
pub mod server;
pub mod shell;
pub mod sim;
pub mod undistort;
pub mod view;
pub mod viewer;
