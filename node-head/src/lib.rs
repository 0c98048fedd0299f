//! The cluster head: fuses its cluster's sensors and decides which of them stay on (paper 000
//! §4–5, paper 002 §III–V).
//!
//! A sans-IO core ([`head::HeadNode`], a `proto::node::Node`) plus its process
//! ([`process::run`]). How a step's observations become each track's posterior is the
//! method's [`fusion::Fusion`] (distributed EIF, centralized EIF, ML), chosen by the scenario;
//! [`observe`] is the one place an observation kind gets its model. The maths lives in its own
//! modules, each tested alone: [`eif`] (information form), [`ekf`] (covariance-form
//! cross-check), [`init`] (triangulation), [`rssi_training`] (Algorithm 1), [`rssi_noise`]
//! (RSSI weighed by its innovations), [`activation`] (Algorithm 2), [`association`] (several
//! targets), [`lifecycle`] (a track's states and the rules between them) and [`step`] (the
//! distributed step's accounting).

pub mod activation;
pub mod association;
pub mod config;
pub mod eif;
pub mod ekf;
pub mod fusion;
pub mod grid;
pub mod head;
pub mod init;
pub mod lifecycle;
pub mod observe;
pub mod process;
pub mod rssi_noise;
pub mod rssi_training;
pub mod stats;
pub mod step;
pub mod tags;
pub mod track;
pub mod unseen;

pub use config::{ConfigError, HeadConfig};
pub use head::HeadNode;
