//! The Ocelli visualization node's web side (paper 004 §3.1, §3.4): every tracked target placed
//! live in one model of the site, in a browser map, a 3D view and Google Earth, with metrics for
//! Prometheus and recordings for Foxglove.
//!
//! - [`state`]: the view model, [`ViewState`], built from the server's recording records
//!   ([`ViewState::apply`]), live or played back.
//! - [`feed`]: the hand-off from the producer to the HTTP side (a `tokio::sync::watch`).
//! - [`server`]: axum routes — the map (`/`), the 3D view (`/3d`), server-sent events,
//!   `/api/state`, `/metrics`, `/live.kml` and `/tracks.kml`, playback controls; [`serve`].
//! - [`playback`]: a recording with checkpoints, played, paused and sought.
//! - [`node`], [`live`]: the visualization node — its core, a client of the server's view
//!   feed, and its process (`ocelli viewer`).
//! - [`geo`], [`kml`]: `[world.geo]`, local metres → WGS84, KML live and for whole recordings.
//! - [`mod@mcap`]: recordings as MCAP for Foxglove Studio.
//! - [`geometry`]: cameras' fields of view and tracks' ellipses; [`metrics`]: Prometheus text.
//! - [`bench`]: timings of the hot paths.
//!
//! The pages (HTML, JavaScript, CSS in `src/web/`) are written here and embedded in the binary:
//! no build step, no network beyond the viewer itself.

pub mod bench;
pub mod feed;
pub use proto::geo;
pub mod geometry;
pub mod kml;
pub mod live;
pub mod mcap;
pub mod metrics;
pub mod node;
pub mod playback;
pub mod server;
pub mod state;
#[cfg(test)]
pub(crate) mod testkit;

pub use feed::{Feed, Publisher, channel};
pub use geo::Geo;
pub use playback::{Player, RecordingIndex};
pub use server::{ServeError, router, serve};
pub use state::ViewState;

use std::path::Path;
use std::sync::Arc;
use std::time::Duration;
use thiserror::Error;
use tokio::net::TcpListener;
use tokio_util::sync::CancellationToken;

/// Why a recording could not be served.
#[derive(Debug, Error)]
pub enum ViewError {
    #[error(transparent)]
    Playback(#[from] playback::PlaybackError),
    #[error(transparent)]
    Serve(#[from] ServeError),
}

/// `ocelli view RECORDING`: index the recording, then serve it on `listener` with play, pause,
/// seek and speed until `shutdown`. Playback starts at the first record, playing at real time;
/// the pages are updated every `tick` (the filter's step period is a good choice).
///
/// # Errors
/// The recording cannot be read (not a recording, another format version, empty), or the
/// listener fails. Records that do not decode and a torn tail are not errors: the pages show
/// them.
pub async fn serve_recording(
    path: &Path,
    geo: Option<Geo>,
    listener: TcpListener,
    tick: Duration,
    shutdown: CancellationToken,
) -> Result<(), ViewError> {
    let owned = path.to_path_buf();
    let index = tokio::task::spawn_blocking(move || RecordingIndex::build(&owned, geo))
        .await
        .map_err(|e| playback::PlaybackError::Io {
            path: path.into(),
            source: std::io::Error::other(e.to_string()),
        })??;
    let mut player = Player::new(Arc::new(index))?;
    player.playing = true;
    let (publisher, feed) = channel(player.state().clone());
    let (tx, rx) = tokio::sync::mpsc::channel(16);
    let feed = feed.with_control(tx);
    let producer = tokio::spawn(playback::run(player, publisher, rx, tick, shutdown.clone()));
    let served = serve(listener, feed, shutdown.clone()).await;
    shutdown.cancel();
    let played = producer.await.map_err(|e| playback::PlaybackError::Io {
        path: path.into(),
        source: std::io::Error::other(e.to_string()),
    })?;
    served?;
    played?;
    Ok(())
}
