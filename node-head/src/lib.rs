//! The cluster head: fuses its cluster's sensors with a distributed Extended Information Filter
//! and decides which of them stay on (paper 000 §4–5, paper 002 §III–V).
//!
//! A sans-IO core ([`head::HeadNode`]) plus its process ([`process::run`]). The filter math lives in its own
//! modules, each tested alone: [`eif`] (information form), [`ekf`] (covariance-form cross-check),
//! [`init`] (triangulation), [`ml`] (maximum likelihood), [`rssi_training`] (Algorithm 1), [`rssi_noise`] (RSSI weighed by its innovations),
//! [`activation`] (Algorithm 2), [`association`] (several targets) and [`step`] (the distributed
//! step's accounting).

pub mod activation;
pub mod assign;
pub mod association;
pub mod config;
pub mod eif;
pub mod ekf;
pub mod head;
pub mod init;
pub mod ml;
pub mod process;
pub mod rssi_noise;
pub mod rssi_training;
pub mod stats;
pub mod step;
pub mod track;

pub use config::{ConfigError, HeadConfig};
pub use head::HeadNode;
