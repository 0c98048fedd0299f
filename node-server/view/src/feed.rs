//! The hand-off between whoever builds the view (the live follower, the playback, the lead's
//! viewer process) and the HTTP side: a [`Publisher`] puts the newest state into a
//! `tokio::sync::watch`, every HTTP task reads from its [`Feed`].
//!
//! Publishing never blocks and never waits for a reader: the watch holds only the newest
//! state, so a reader that falls behind skips to it (the states it skipped are counted in
//! [`FeedStats::sse_dropped`]) and a reader that goes away costs nothing. A published state is
//! serialized to JSON at most once, by the first reader that needs it, never by the producer.

use crate::playback::{Command, PlaybackInfo};
use crate::state::ViewState;
use serde::Serialize;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};
use tokio::sync::{mpsc, watch};

/// One published state.
#[derive(Debug)]
pub struct Published {
    /// Increases by one per publish.
    pub seq: u64,
    pub state: Arc<ViewState>,
    /// Where a played-back recording is (none for a live view).
    pub playback: Option<PlaybackInfo>,
    json: OnceLock<Arc<str>>,
}

/// What `/api/state` and the pages' events carry: the state plus the publish number and the
/// playback position.
#[derive(Serialize)]
struct Snapshot<'a> {
    seq: u64,
    #[serde(flatten)]
    state: &'a ViewState,
    playback: Option<&'a PlaybackInfo>,
}

impl Published {
    fn new(seq: u64, state: Arc<ViewState>, playback: Option<PlaybackInfo>) -> Self {
        Published {
            seq,
            state,
            playback,
            json: OnceLock::new(),
        }
    }

    /// The snapshot as JSON, serialized once and shared.
    pub fn json(&self) -> Arc<str> {
        self.json
            .get_or_init(|| {
                let snap = Snapshot {
                    seq: self.seq,
                    state: &self.state,
                    playback: self.playback.as_ref(),
                };
                // Only non-finite floats could fail, and serde_json writes them as null.
                serde_json::to_string(&snap)
                    .unwrap_or_else(|e| format!("{{\"error\": \"state does not serialize: {e}\"}}"))
                    .into()
            })
            .clone()
    }
}

/// Counters of the HTTP side, for `/metrics`.
#[derive(Debug, Default)]
pub struct FeedStats {
    /// Event streams open now.
    pub sse_clients: AtomicU64,
    /// States sent to event streams.
    pub sse_sent: AtomicU64,
    /// States an event stream skipped because its client was slower than the producer.
    pub sse_dropped: AtomicU64,
    /// HTTP requests answered.
    pub requests: AtomicU64,
}

impl FeedStats {
    pub(crate) fn add(counter: &AtomicU64, n: u64) {
        counter.fetch_add(n, Ordering::Relaxed);
    }

    pub(crate) fn get(counter: &AtomicU64) -> u64 {
        counter.load(Ordering::Relaxed)
    }
}

/// The producer's end.
#[derive(Debug)]
pub struct Publisher {
    tx: watch::Sender<Arc<Published>>,
    seq: u64,
}

impl Publisher {
    /// Publish a state (never blocks; readers that have not taken the previous one skip it).
    pub fn publish(&mut self, state: Arc<ViewState>) {
        self.publish_with(state, None);
    }

    /// Publish a state with the playback position.
    pub fn publish_with(&mut self, state: Arc<ViewState>, playback: Option<PlaybackInfo>) {
        self.seq += 1;
        self.tx
            .send_replace(Arc::new(Published::new(self.seq, state, playback)));
    }

    /// How many states were published.
    pub fn published(&self) -> u64 {
        self.seq
    }

    /// Whether any HTTP side still reads (a producer may stop when none does).
    pub fn has_readers(&self) -> bool {
        self.tx.receiver_count() > 0
    }
}

/// The HTTP side's end: cheap to clone, one per task.
#[derive(Clone, Debug)]
pub struct Feed {
    pub(crate) rx: watch::Receiver<Arc<Published>>,
    pub(crate) stats: Arc<FeedStats>,
    /// Where the page's play / pause / seek go (playback only).
    pub(crate) control: Option<mpsc::Sender<Command>>,
}

/// A publisher and the feed it publishes to, starting from `initial`.
pub fn channel(initial: ViewState) -> (Publisher, Feed) {
    let (tx, rx) = watch::channel(Arc::new(Published::new(0, Arc::new(initial), None)));
    (
        Publisher { tx, seq: 0 },
        Feed {
            rx,
            stats: Arc::new(FeedStats::default()),
            control: None,
        },
    )
}

impl Feed {
    /// The newest published state.
    pub fn latest(&self) -> Arc<Published> {
        self.rx.borrow().clone()
    }

    /// The counters of the HTTP side.
    pub fn stats(&self) -> &FeedStats {
        &self.stats
    }

    /// This feed with playback controls going to `control`.
    pub fn with_control(mut self, control: mpsc::Sender<Command>) -> Self {
        self.control = Some(control);
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn readers_see_the_newest_and_json_is_made_once() {
        let (mut p, feed) = channel(ViewState::new());
        assert_eq!(feed.latest().seq, 0);
        for i in 1..=100 {
            let mut s = ViewState::new();
            s.advance(i);
            p.publish(Arc::new(s));
        }
        let latest = feed.latest();
        assert_eq!(latest.seq, 100);
        assert_eq!(latest.state.time_ns, 100);
        let a = latest.json();
        let b = latest.json();
        assert!(Arc::ptr_eq(&a, &b), "serialized once");
        let v: serde_json::Value = serde_json::from_str(&a).unwrap();
        assert_eq!(v["seq"], 100);
        assert_eq!(v["time_ns"], 100);
        assert!(v["nodes"].is_array() && v["tracks"].is_array() && v["playback"].is_null());
    }

    #[test]
    fn publishing_without_readers_is_fine() {
        let (mut p, feed) = channel(ViewState::new());
        assert!(p.has_readers());
        drop(feed);
        assert!(!p.has_readers());
        p.publish(Arc::new(ViewState::new()));
        assert_eq!(p.published(), 1);
    }
}
