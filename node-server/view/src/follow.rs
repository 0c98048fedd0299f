//! A live view of a cluster from the recording its server is writing: the records appended
//! since the last look are applied every period and the view is published.
//!
//! This is what a viewer can run before the server sends it records over the wire: the server
//! writes each record with one `write(2)`, so following the file is as live as the period.
//! Nothing here can slow the server: the file is only read, and
//! [`node_server::tail::Tailer`] waits on a record it sees half-written instead of failing.

use crate::feed::Publisher;
use crate::state::ViewState;
use node_server::tail::Tailer;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;
use tokio_util::sync::CancellationToken;

/// Follow the recording at `path` (it need not exist yet) into `publisher`, starting from
/// `initial` (the scenario and geo the viewer knows), until `shutdown`.
///
/// A record that does not decode (another build, another protocol version) stops the follower
/// where it is: the view says so in its problems and keeps serving what it had.
pub async fn follow_recording(
    path: PathBuf,
    initial: ViewState,
    mut publisher: Publisher,
    period: Duration,
    shutdown: CancellationToken,
) {
    let mut state = initial;
    let mut tailer = Some(Tailer::new(&path));
    let mut timer = tokio::time::interval(period);
    timer.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    publisher.publish(Arc::new(state.clone()));
    loop {
        tokio::select! {
            () = shutdown.cancelled() => return,
            _ = timer.tick() => {}
        }
        let Some(mut t) = tailer.take() else { return };
        let Ok((t, polled)) = tokio::task::spawn_blocking(move || {
            let r = t.poll();
            (t, r)
        })
        .await
        else {
            return; // the blocking pool is shutting down
        };
        tailer = Some(t);
        match polled {
            Ok(records) if records.is_empty() => continue,
            Ok(records) => {
                for r in &records {
                    state.apply(r);
                }
            }
            Err(e) => {
                let at = state.time_ns;
                state.undecodable(at, format!("following {}: {e}", path.display()));
            }
        }
        publisher.publish(Arc::new(state.clone()));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testkit::{TempFile, run_records, with_decisions, write};

    #[tokio::test]
    async fn a_growing_recording_shows_up() {
        let f = TempFile::new("follow.ocrec");
        let (publisher, feed) = crate::feed::channel(ViewState::new());
        let stop = CancellationToken::new();
        let task = tokio::spawn(follow_recording(
            f.0.clone(),
            ViewState::new(),
            publisher,
            Duration::from_millis(20),
            stop.clone(),
        ));
        let mut rx = feed.rx.clone();
        write(&f.0, &with_decisions(&run_records(2)));
        let seen = tokio::time::timeout(Duration::from_secs(10), async {
            loop {
                if rx.borrow_and_update().state.tracks.contains_key(&1) {
                    break;
                }
                rx.changed().await.unwrap();
            }
        })
        .await;
        assert!(seen.is_ok(), "the track never appeared");
        let p = feed.latest();
        assert_eq!(p.state.scenario, "default");
        assert!((p.state.tracks[&1].position[0] - 2.0).abs() < 1e-9);
        stop.cancel();
        tokio::time::timeout(Duration::from_secs(5), task)
            .await
            .unwrap()
            .unwrap();
    }
}
