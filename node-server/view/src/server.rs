//! The viewer's HTTP side (axum on tokio): the pages, the live event stream, the JSON
//! snapshot, Prometheus metrics, KML for Google Earth and the playback controls.
//!
//! | route | answer |
//! |---|---|
//! | `GET /` | the live map (floor plan, cameras' wedges, tracks with ids, ellipses, trails, handovers, health) |
//! | `GET /3d` | the 3D view (room, camera frusta, people as upright boxes; drag to orbit, wheel to zoom) |
//! | `GET /events` | server-sent events: `event: state`, `id: <seq>`, `data: <snapshot JSON>` at the producer's rate |
//! | `GET /api/state` | the JSON snapshot `{"seq", "time", "nodes": [...], "tracks": [...], ...}` |
//! | `GET /metrics` | Prometheus text, every metric under `ocelli_` |
//! | `GET /live.kml` | a KML NetworkLink refreshing `/tracks.kml` every second |
//! | `GET /tracks.kml` | one placemark per track and per camera (409 without `[world.geo]`) |
//! | `POST /api/playback/{play,pause,seek?t=S,speed?x=F}` | playback controls (409 on a live view) |
//!
//! Every handler only reads the newest published state ([`crate::feed`]); none can hold up the
//! producer. An event stream holds one state at a time: a client slower than the producer gets
//! the newest state when it can take one, and the states it missed are counted. A browser that
//! disconnects ends its stream; shutting the server down ends every stream.

use crate::feed::{Feed, FeedStats};
use crate::playback::Command;
use crate::{kml, metrics};
use axum::Router;
use axum::extract::{Path, Query, State};
use axum::http::{HeaderMap, StatusCode, header};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use futures_util::stream::Stream;
use std::collections::HashMap;
use std::convert::Infallible;
use std::sync::Arc;
use std::time::Duration;
use thiserror::Error;
use tokio::net::TcpListener;
use tokio_util::sync::CancellationToken;

const MAP_HTML: &str = include_str!("web/map.html");
const VIEW3D_HTML: &str = include_str!("web/view3d.html");
const STYLE_CSS: &str = include_str!("web/style.css");
const COMMON_JS: &str = include_str!("web/common.js");
const MAP_JS: &str = include_str!("web/map.js");
const VIEW3D_JS: &str = include_str!("web/view3d.js");

/// Why serving stopped.
#[derive(Debug, Error)]
pub enum ServeError {
    #[error("viewer HTTP server: {0}")]
    Io(#[from] std::io::Error),
}

#[derive(Clone)]
struct App {
    feed: Feed,
    shutdown: CancellationToken,
}

/// The viewer's routes over `feed`; event streams end when `shutdown` is cancelled.
pub fn router(feed: Feed, shutdown: CancellationToken) -> Router {
    Router::new()
        .route("/", get(|| async { html(MAP_HTML) }))
        .route("/3d", get(|| async { html(VIEW3D_HTML) }))
        .route("/static/{file}", get(asset))
        .route("/events", get(events))
        .route("/api/state", get(api_state))
        .route("/metrics", get(metrics_text))
        .route("/live.kml", get(live_kml))
        .route("/tracks.kml", get(tracks_kml))
        .route("/api/playback/{action}", post(playback))
        .fallback(|| async {
            text(
                StatusCode::NOT_FOUND,
                "no such page: try / (map), /3d, /api/state, /metrics, /live.kml",
            )
        })
        .with_state(App { feed, shutdown })
}

/// Serve the viewer on `listener` until `shutdown` is cancelled.
///
/// # Errors
/// The listener fails.
pub async fn serve(listener: TcpListener, feed: Feed, shutdown: CancellationToken) -> Result<(), ServeError> {
    let app = router(feed, shutdown.clone());
    axum::serve(listener, app)
        .with_graceful_shutdown(shutdown.cancelled_owned())
        .await?;
    Ok(())
}

fn html(body: &'static str) -> Response {
    ([(header::CONTENT_TYPE, "text/html; charset=utf-8")], body).into_response()
}

fn text(status: StatusCode, body: impl Into<String>) -> Response {
    (
        status,
        [(header::CONTENT_TYPE, "text/plain; charset=utf-8")],
        body.into(),
    )
        .into_response()
}

async fn asset(Path(file): Path<String>) -> Response {
    let (body, kind) = match file.as_str() {
        "style.css" => (STYLE_CSS, "text/css; charset=utf-8"),
        "common.js" => (COMMON_JS, "text/javascript; charset=utf-8"),
        "map.js" => (MAP_JS, "text/javascript; charset=utf-8"),
        "view3d.js" => (VIEW3D_JS, "text/javascript; charset=utf-8"),
        _ => return text(StatusCode::NOT_FOUND, format!("no such file: /static/{file}")),
    };
    (
        [(header::CONTENT_TYPE, kind), (header::CACHE_CONTROL, "no-cache")],
        body,
    )
        .into_response()
}

async fn api_state(State(app): State<App>) -> Response {
    count(&app);
    let json = app.feed.latest().json();
    (
        [
            (header::CONTENT_TYPE, "application/json"),
            (header::CACHE_CONTROL, "no-store"),
        ],
        json.to_string(),
    )
        .into_response()
}

async fn metrics_text(State(app): State<App>) -> Response {
    count(&app);
    match metrics::render(&app.feed.latest(), app.feed.stats()) {
        Ok(body) => ([(header::CONTENT_TYPE, metrics::CONTENT_TYPE)], body).into_response(),
        Err(e) => text(StatusCode::INTERNAL_SERVER_ERROR, format!("metrics: {e}")),
    }
}

fn count(app: &App) {
    FeedStats::add(&app.feed.stats().requests, 1);
}

/// `http://host/` of the request, for links that must be absolute (KML).
fn base_url(headers: &HeaderMap) -> String {
    let host = headers
        .get(header::HOST)
        .and_then(|h| h.to_str().ok())
        .filter(|h| {
            h.chars()
                .all(|c| c.is_ascii_alphanumeric() || ".-:[]".contains(c))
        })
        .unwrap_or("127.0.0.1:8080");
    format!("http://{host}")
}

fn kml_response(body: String) -> Response {
    ([(header::CONTENT_TYPE, kml::CONTENT_TYPE)], body).into_response()
}

async fn live_kml(State(app): State<App>, headers: HeaderMap) -> Response {
    count(&app);
    let published = app.feed.latest();
    match &published.state.geo {
        Some(_) => kml_response(kml::network_link(&format!("{}/tracks.kml", base_url(&headers)))),
        None => text(StatusCode::CONFLICT, kml::NO_GEO),
    }
}

async fn tracks_kml(State(app): State<App>) -> Response {
    count(&app);
    let published = app.feed.latest();
    match kml::live_document(&published.state) {
        Ok(body) => kml_response(body),
        Err(kml::KmlError::NoGeo) => text(StatusCode::CONFLICT, kml::NO_GEO),
        Err(e) => text(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()),
    }
}

async fn playback(
    State(app): State<App>,
    Path(action): Path<String>,
    Query(q): Query<HashMap<String, String>>,
) -> Response {
    count(&app);
    let Some(control) = &app.feed.control else {
        return text(
            StatusCode::CONFLICT,
            "this viewer shows a live cluster; play, pause and seek are for recordings (ocelli view RECORDING)",
        );
    };
    let number = |key: &str| {
        q.get(key)
            .and_then(|v| v.parse::<f64>().ok())
            .filter(|v| v.is_finite())
    };
    let command = match action.as_str() {
        "play" => Command::Play,
        "pause" => Command::Pause,
        "seek" => match number("t") {
            Some(t) => Command::Seek(t),
            None => return text(StatusCode::BAD_REQUEST, "seek needs t=<seconds from the start>"),
        },
        "speed" => match number("x") {
            Some(x) if x > 0.0 => Command::Speed(x),
            _ => return text(StatusCode::BAD_REQUEST, "speed needs x=<positive factor>"),
        },
        other => {
            return text(
                StatusCode::NOT_FOUND,
                format!("no playback action {other:?}: play, pause, seek?t=S, speed?x=F"),
            );
        }
    };
    match control.try_send(command) {
        Ok(()) => text(StatusCode::ACCEPTED, format!("{action}: accepted")),
        Err(tokio::sync::mpsc::error::TrySendError::Full(_)) => {
            text(StatusCode::SERVICE_UNAVAILABLE, "playback is busy; try again")
        }
        Err(tokio::sync::mpsc::error::TrySendError::Closed(_)) => {
            text(StatusCode::GONE, "playback has stopped (see the server's log)")
        }
    }
}

/// Counts an open event stream for as long as it lives.
struct StreamGuard(Arc<FeedStats>);

impl Drop for StreamGuard {
    fn drop(&mut self) {
        self.0
            .sse_clients
            .fetch_sub(1, std::sync::atomic::Ordering::Relaxed);
    }
}

struct StreamState {
    feed: Feed,
    last: Option<u64>,
    shutdown: CancellationToken,
    _guard: StreamGuard,
}

async fn events(State(app): State<App>) -> Sse<impl Stream<Item = Result<Event, Infallible>>> {
    count(&app);
    let stats = app.feed.stats.clone();
    FeedStats::add(&stats.sse_clients, 1);
    let mut feed = app.feed.clone();
    feed.rx.mark_changed(); // send the current state at once
    let start = StreamState {
        feed,
        last: None,
        shutdown: app.shutdown.clone(),
        _guard: StreamGuard(stats),
    };
    let stream = futures_util::stream::unfold(start, |mut st| async move {
        tokio::select! {
            () = st.shutdown.cancelled() => return None,
            changed = st.feed.rx.changed() => changed.ok()?,
        }
        let p = st.feed.rx.borrow_and_update().clone();
        let stats = &st.feed.stats;
        if let Some(last) = st.last
            && p.seq > last + 1
        {
            FeedStats::add(&stats.sse_dropped, p.seq - last - 1);
        }
        FeedStats::add(&stats.sse_sent, 1);
        st.last = Some(p.seq);
        let event = Event::default()
            .event("state")
            .id(p.seq.to_string())
            .data(&*p.json());
        Some((Ok(event), st))
    });
    Sse::new(stream).keep_alive(KeepAlive::new().interval(Duration::from_secs(10)))
}

#[cfg(test)]
mod tests;
