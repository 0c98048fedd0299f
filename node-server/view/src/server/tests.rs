use super::*;
use crate::feed::{Publisher, channel};
use crate::geo::Geo;
use crate::state::ViewState;
use crate::testkit::{run_records, with_decisions};
use proto::scenario::Scenario;
use std::net::SocketAddr;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;
use tokio::sync::mpsc;

const WAIT: Duration = Duration::from_secs(20);

struct Running {
    addr: SocketAddr,
    publisher: Publisher,
    feed: Feed,
    stop: CancellationToken,
    task: tokio::task::JoinHandle<Result<(), ServeError>>,
}

fn view(geo: bool) -> ViewState {
    let mut v = ViewState::new();
    for r in with_decisions(&run_records(2)) {
        v.apply(&r);
    }
    if geo {
        v.set_geo(Some(Geo {
            origin: [48.5, 9.06, 320.0],
            heading_deg: 0.0,
        }));
    }
    v
}

async fn start(state: ViewState, control: Option<mpsc::Sender<Command>>) -> Running {
    let (publisher, feed) = channel(state);
    let feed = match control {
        Some(c) => feed.with_control(c),
        None => feed,
    };
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    let stop = CancellationToken::new();
    let task = tokio::spawn(serve(listener, feed.clone(), stop.clone()));
    Running {
        addr,
        publisher,
        feed,
        stop,
        task,
    }
}

impl Running {
    async fn stop(self) {
        self.stop.cancel();
        tokio::time::timeout(WAIT, self.task)
            .await
            .unwrap()
            .unwrap()
            .unwrap();
    }
}

/// Undo HTTP/1.1 chunked transfer coding.
fn dechunk(mut b: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    while let Some(i) = b.windows(2).position(|w| w == b"\r\n") {
        let size = usize::from_str_radix(std::str::from_utf8(&b[..i]).unwrap().trim(), 16).unwrap();
        if size == 0 {
            break;
        }
        out.extend_from_slice(&b[i + 2..i + 2 + size]);
        b = &b[i + 2 + size + 2..];
    }
    out
}

/// One request over a fresh connection: status, headers (lower-case names), body.
async fn request(addr: SocketAddr, method: &str, path: &str, host: &str) -> (u16, String, String) {
    let mut s = TcpStream::connect(addr).await.unwrap();
    let req =
        format!("{method} {path} HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\nContent-Length: 0\r\n\r\n");
    s.write_all(req.as_bytes()).await.unwrap();
    let mut raw = Vec::new();
    tokio::time::timeout(WAIT, s.read_to_end(&mut raw))
        .await
        .unwrap()
        .unwrap();
    let split = raw.windows(4).position(|w| w == b"\r\n\r\n").unwrap();
    let head = String::from_utf8_lossy(&raw[..split]).to_lowercase();
    let body = &raw[split + 4..];
    let body = if head.contains("transfer-encoding: chunked") {
        dechunk(body)
    } else {
        body.to_vec()
    };
    let status = head[9..12].parse().unwrap();
    (status, head, String::from_utf8_lossy(&body).into_owned())
}

async fn get(addr: SocketAddr, path: &str) -> (u16, String, String) {
    request(addr, "GET", path, &addr.to_string()).await
}

#[tokio::test]
async fn pages_assets_and_the_json_snapshot() {
    let r = start(view(false), None).await;
    let (status, head, body) = get(r.addr, "/").await;
    assert_eq!(status, 200);
    assert!(head.contains("content-type: text/html"));
    assert!(body.contains("/static/map.js"));
    let (status, _, body) = get(r.addr, "/3d").await;
    assert_eq!(status, 200);
    assert!(body.contains("/static/view3d.js"));
    for asset in ["style.css", "common.js", "map.js", "view3d.js"] {
        let (status, _, body) = get(r.addr, &format!("/static/{asset}")).await;
        assert_eq!(status, 200, "{asset}");
        assert!(!body.is_empty());
    }
    let (status, _, body) = get(r.addr, "/static/../../etc/passwd").await;
    assert_eq!(status, 404, "{body}");
    let (status, _, body) = get(r.addr, "/nope").await;
    assert_eq!(status, 404);
    assert!(body.contains("/3d"));
    let (status, head, body) = get(r.addr, "/api/state").await;
    assert_eq!(status, 200);
    assert!(head.contains("application/json"));
    let v: serde_json::Value = serde_json::from_str(&body).unwrap();
    assert!(v["time"].as_f64().unwrap() > 0.0);
    assert_eq!(v["nodes"].as_array().unwrap().len(), 24);
    assert_eq!(v["tracks"][0]["global"], 1);
    r.stop().await;
}

#[tokio::test]
async fn metrics_are_prometheus_text() {
    let r = start(view(false), None).await;
    let (status, head, body) = get(r.addr, "/metrics").await;
    assert_eq!(status, 200);
    assert!(head.contains("text/plain; version=0.0.4"), "{head}");
    assert!(body.contains("ocelli_tracks 1"), "{body}");
    assert!(body.contains(r#"ocelli_node_up{node="2",role="head"} 1"#));
    r.stop().await;
}

#[tokio::test]
async fn kml_needs_geo_and_says_so() {
    let r = start(view(false), None).await;
    for path in ["/live.kml", "/tracks.kml"] {
        let (status, _, body) = get(r.addr, path).await;
        assert_eq!(status, 409, "{path}");
        assert!(body.contains("[world.geo]") && body.contains("origin"), "{body}");
    }
    r.stop().await;
    let r = start(view(true), None).await;
    let (status, head, body) = request(r.addr, "GET", "/live.kml", "viewer.local:8080").await;
    assert_eq!(status, 200);
    assert!(head.contains("application/vnd.google-earth.kml+xml"));
    assert!(
        body.contains("<href>http://viewer.local:8080/tracks.kml</href>"),
        "{body}"
    );
    let (status, _, body) = request(r.addr, "GET", "/live.kml", "evil\"><x").await;
    assert_eq!(status, 200);
    assert!(!body.contains("evil"), "a strange Host header is not echoed");
    let (status, _, body) = get(r.addr, "/tracks.kml").await;
    assert_eq!(status, 200);
    assert!(body.contains("<name>t1</name>") && body.contains("<name>camera 10</name>"));
    r.stop().await;
}

#[tokio::test]
async fn playback_controls_reach_the_player_or_explain_why_not() {
    let r = start(view(false), None).await;
    let (status, _, body) = request(r.addr, "POST", "/api/playback/play", "x").await;
    assert_eq!(status, 409);
    assert!(body.contains("ocelli view RECORDING"), "{body}");
    r.stop().await;

    let (tx, mut rx) = mpsc::channel(4);
    let r = start(view(false), Some(tx)).await;
    for (path, want) in [
        ("/api/playback/play", Command::Play),
        ("/api/playback/pause", Command::Pause),
        ("/api/playback/seek?t=12.5", Command::Seek(12.5)),
        ("/api/playback/speed?x=4", Command::Speed(4.0)),
    ] {
        let (status, _, _) = request(r.addr, "POST", path, "x").await;
        assert_eq!(status, 202, "{path}");
        assert_eq!(rx.recv().await, Some(want));
    }
    for (path, code) in [
        ("/api/playback/seek", 400),
        ("/api/playback/seek?t=NaN", 400),
        ("/api/playback/speed?x=-1", 400),
        ("/api/playback/rewind", 404),
    ] {
        let (status, _, _) = request(r.addr, "POST", path, "x").await;
        assert_eq!(status, code, "{path}");
    }
    // A full queue says busy; a stopped player says gone.
    for _ in 0..4 {
        request(r.addr, "POST", "/api/playback/play", "x").await;
    }
    let (status, _, _) = request(r.addr, "POST", "/api/playback/play", "x").await;
    assert_eq!(status, 503);
    drop(rx);
    let (status, _, _) = request(r.addr, "POST", "/api/playback/play", "x").await;
    assert_eq!(status, 410);
    r.stop().await;
}

/// Open `/events` and return the connection after the response head.
async fn open_events(addr: SocketAddr) -> TcpStream {
    let mut s = TcpStream::connect(addr).await.unwrap();
    s.write_all(b"GET /events HTTP/1.1\r\nHost: x\r\n\r\n")
        .await
        .unwrap();
    s
}

/// Read from an event stream until an event with `id` arrives; the ids seen.
async fn read_until(s: &mut TcpStream, buf: &mut Vec<u8>, id: u64) -> Vec<u64> {
    let marker = b"event: state\nid: ";
    let mut chunk = vec![0u8; 1 << 16];
    loop {
        let ids: Vec<u64> = buf
            .windows(marker.len())
            .enumerate()
            .filter(|(_, w)| *w == marker)
            .filter_map(|(i, _)| {
                let rest = &buf[i + marker.len()..];
                let end = rest.iter().position(|&c| c == b'\n')?;
                std::str::from_utf8(&rest[..end]).ok()?.parse().ok()
            })
            .collect();
        if ids.contains(&id) {
            return ids;
        }
        let n = tokio::time::timeout(WAIT, s.read(&mut chunk))
            .await
            .unwrap()
            .unwrap();
        assert!(n > 0, "stream ended before event {id}");
        buf.extend_from_slice(&chunk[..n]);
    }
}

#[tokio::test]
async fn events_push_the_current_state_then_each_new_one() {
    let mut r = start(view(false), None).await;
    let mut s = open_events(r.addr).await;
    let mut buf = Vec::new();
    let ids = read_until(&mut s, &mut buf, 0).await;
    assert_eq!(ids, vec![0], "the current state at once");
    let head = String::from_utf8_lossy(&buf).to_lowercase();
    assert!(head.contains("content-type: text/event-stream"));
    assert!(
        head.contains("\"tracks\":[{\"global\":1"),
        "the snapshot is the data"
    );
    r.publisher.publish(Arc::new(view(false)));
    let ids = read_until(&mut s, &mut buf, 1).await;
    assert_eq!(ids, vec![0, 1]);
    assert_eq!(FeedStats::get(&r.feed.stats().sse_clients), 1);
    // A browser that goes away closes its stream.
    drop(s);
    r.publisher.publish(Arc::new(view(false)));
    tokio::time::timeout(WAIT, async {
        while FeedStats::get(&r.feed.stats().sse_clients) > 0 {
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
    })
    .await
    .unwrap();
    r.stop().await;
}

/// A client that does not read while the producer publishes 2000 large states: publishing never
/// waits, the client then gets only what fitted in the socket's buffers plus the newest state,
/// and every state it skipped is counted.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_slow_client_gets_the_newest_state_and_drops_are_counted() {
    let mut big = ViewState::with_scenario(&Scenario::default_scenario());
    big.scenario = "x".repeat(100_000);
    let big = Arc::new(big);
    let mut r = start(ViewState::new(), None).await;
    let mut slow = open_events(r.addr).await;
    let mut buf = Vec::new();
    read_until(&mut slow, &mut buf, 0).await;
    const N: u64 = 2000;
    for _ in 0..N {
        r.publisher.publish(big.clone());
        tokio::task::yield_now().await;
    }
    let ids = read_until(&mut slow, &mut buf, N).await;
    let received = ids.len() as u64;
    assert!(
        received < N / 2,
        "{received} of {N} states reached a client that did not read"
    );
    assert!(ids.windows(2).all(|w| w[0] < w[1]), "in order");
    let stats = r.feed.stats();
    assert_eq!(
        FeedStats::get(&stats.sse_dropped),
        N + 1 - received,
        "every skipped state counted"
    );
    assert_eq!(FeedStats::get(&stats.sse_sent), received);
    // A fast client still gets the newest state at once.
    let mut fast = open_events(r.addr).await;
    let mut fbuf = Vec::new();
    assert_eq!(read_until(&mut fast, &mut fbuf, N).await, vec![N]);
    // Shutting down ends both streams.
    r.stop().await;
    let mut rest = Vec::new();
    let end = tokio::time::timeout(WAIT, slow.read_to_end(&mut rest)).await;
    assert!(end.is_ok(), "the stream ended");
}
