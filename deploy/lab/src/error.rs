//! The lab's one error type: what an experiment, a replay or a benchmark can fail on, typed, so
//! that only the `ocelli` binary turns it into words for a person.

use std::path::PathBuf;
use thiserror::Error;

/// Why an experiment, a re-run or a benchmark could not finish.
#[derive(Debug, Error)]
pub enum LabError {
    #[error(transparent)]
    Scenario(#[from] proto::scenario::ScenarioError),
    #[error(transparent)]
    Sim(#[from] sim::SimError),
    #[error(transparent)]
    Recording(#[from] node_server::analysis::LoadError),
    #[error(transparent)]
    Data(#[from] crate::experiment::ble_rssi::data::DataError),
    #[error(transparent)]
    Transport(#[from] runtime::transport::TransportError),
    #[error(transparent)]
    Wire(#[from] proto::WireError),
    #[error(transparent)]
    Send(#[from] runtime::transport::SendError),
    #[error(transparent)]
    Tls(#[from] runtime::transport::TlsError),
    #[error(transparent)]
    RecordingFile(#[from] node_server::RecordingError),
    #[error(transparent)]
    Camera(#[from] node_camera::config::ConfigError),
    #[error(transparent)]
    Frame(#[from] proto::sensor::FrameError),
    #[error(transparent)]
    Particle(#[from] proto::scenario::particle::ParamsError),
    #[error(transparent)]
    Tracker(#[from] node_camera::tracker::manager::TrackerError),
    #[error(transparent)]
    Metrics(#[from] node_server::metrics::MetricsError),
    /// Encoding a frame for the bandwidth comparison (JPEG).
    #[error("encoding an image: {0}")]
    Image(#[from] image::ImageError),
    /// The operating system refused something a benchmark needs (a thread, a runtime).
    #[error("the system: {0}")]
    System(#[from] std::io::Error),
    #[error("{path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error("unknown experiment `{name}`; known: {known}")]
    UnknownExperiment { name: String, known: String },
    /// An experiment or benchmark whose own premise failed (a fit with too few points, a
    /// bench step that did not apply what it was given).
    #[error("{what}: {problem}")]
    Failed { what: String, problem: String },
}

impl LabError {
    /// A failed premise of `what`.
    pub fn failed(what: impl Into<String>, problem: impl Into<String>) -> LabError {
        LabError::Failed {
            what: what.into(),
            problem: problem.into(),
        }
    }
}

/// The lab's results.
pub type Result<T, E = LabError> = std::result::Result<T, E>;

/// Turns a missing value or a foreign error into [`LabError::Failed`], naming what failed.
pub(crate) trait OrFailed<T> {
    fn or_failed(self, what: impl Into<String>) -> Result<T>;
}

impl<T> OrFailed<T> for Option<T> {
    fn or_failed(self, what: impl Into<String>) -> Result<T> {
        self.ok_or_else(|| LabError::failed(what, "nothing came out"))
    }
}

impl<T, E: std::fmt::Display> OrFailed<T> for std::result::Result<T, E> {
    fn or_failed(self, what: impl Into<String>) -> Result<T> {
        self.map_err(|e| LabError::failed(what, e.to_string()))
    }
}
