//! The visualization node as its own process (`ocelli viewer`): the [`ViewerNode`] core on
//! the shared process loop (`runtime::process::run`), a client of the server over the same
//! transports as every node, publishing its view to the HTTP side ([`crate::serve`]) after
//! each step that changed it.
//!
//! Nothing here can slow the cluster: the server's updates are droppable and the viewer reads
//! them as they come; publishing replaces the newest state (`tokio::sync::watch`) and never
//! waits for a browser.

use crate::feed::{Publisher, channel};
use crate::node::{ViewerConfig, ViewerNode};
use crate::state::ViewState;
use crate::{ServeError, serve};
use proto::ClusterTime;
use runtime::process::no_sensors;
use runtime::transport::TransportConfig;
use runtime::{Hooks, HostClock, RunError, RunSummary};
use std::sync::Arc;
use std::time::Duration;
use thiserror::Error;
use tokio::net::TcpListener;
use tokio_util::sync::CancellationToken;

/// How often the viewer's loop ticks (renewals, the quiet check).
pub const TICK: Duration = Duration::from_millis(100);

/// Why the viewer process stopped with an error.
#[derive(Debug, Error)]
pub enum LiveError {
    #[error("transport: {0}")]
    Transport(#[from] runtime::transport::TransportError),
    #[error(transparent)]
    Serve(#[from] ServeError),
}

/// Publish the view after each step that changed it.
struct Publish(Publisher);

impl Hooks<ViewerNode> for Publish {
    type Error = std::convert::Infallible;

    fn after(
        &mut self,
        node: &mut ViewerNode,
        _now: ClusterTime,
        _sent: &[proto::node::Outgoing],
    ) -> Result<(), Self::Error> {
        if let Some(state) = node.take_changed() {
            self.0.publish(Arc::new(state.clone()));
        }
        Ok(())
    }
}

/// Run the viewer: subscribe to the server over `transport`, serve the pages on `listener`,
/// until `shutdown`.
///
/// # Errors
/// The transport cannot open, or the HTTP server fails.
pub async fn run(
    cfg: ViewerConfig,
    initial: ViewState,
    transport: TransportConfig,
    listener: TcpListener,
    shutdown: CancellationToken,
) -> Result<RunSummary, LiveError> {
    let server = cfg.server;
    let mut node = ViewerNode::new(cfg, initial);
    let (publisher, feed) = channel(node.state().clone());
    let http = tokio::spawn(serve(listener, feed, shutdown.clone()));
    let process = runtime::ProcessConfig::new(transport, Some(server), TICK);
    let mut hooks = Publish(publisher);
    let run = runtime::run(
        &mut node,
        process,
        HostClock::follower(),
        no_sensors(),
        &mut hooks,
        shutdown.clone(),
    )
    .await;
    shutdown.cancel();
    let served = http.await.unwrap_or(Ok(()));
    let c = node.counters();
    tracing::info!(
        updates = c.updates,
        lost = c.lost,
        undelivered = c.undelivered,
        "viewer stopped"
    );
    let summary = match run {
        Ok(s) => s,
        Err(RunError::Transport(e)) => return Err(e.into()),
        Err(RunError::Node(never)) => match never {},
    };
    served?;
    Ok(summary)
}
