//! What the GStreamer tests need around the source: videos encoded with GStreamer itself from
//! rendered frames, a tiny HTTP MJPEG server that can stop, fall silent and come back, and a
//! clock for the `now` a runtime would pass.

use super::super::init;
use gstreamer as gst;
use gstreamer::prelude::*;
use gstreamer_app as gst_app;
use gstreamer_video as gst_video;
use gstreamer_video::prelude::*;
use proto::ClusterTime;
use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// One rendered frame: `top` colour over a mid-grey bottom half (rows in the wrong place or a
/// wrong stride show up as the wrong colour).
#[derive(Clone, Copy, Debug)]
pub struct Picture {
    pub width: u32,
    pub height: u32,
    pub top: [u8; 3],
}

pub const GREY: [u8; 3] = [128, 128, 128];

impl Picture {
    pub fn rgb(self) -> image::RgbImage {
        image::RgbImage::from_fn(self.width, self.height, |_, y| {
            image::Rgb(if y < self.height / 2 { self.top } else { GREY })
        })
    }

    pub fn jpeg(self) -> Vec<u8> {
        let mut out = Vec::new();
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, 95)
            .encode(
                self.rgb().as_raw(),
                self.width,
                self.height,
                image::ExtendedColorType::Rgb8,
            )
            .unwrap();
        out
    }
}

/// The top and bottom colours of a frame, sampled a quarter in from each edge.
pub fn colours(f: &proto::sensor::Frame) -> ([u8; 3], [u8; 3]) {
    (
        f.pixel(f.width / 2, f.height / 4),
        f.pixel(f.width / 2, 3 * f.height / 4),
    )
}

/// Whether two colours agree within a lossy codec's error.
pub fn near(a: [u8; 3], b: [u8; 3]) -> bool {
    a.iter().zip(b).all(|(&x, y)| x.abs_diff(y) <= 28)
}

/// A path named `name` in a scratch folder of its own, removed when the folder is dropped.
pub fn tmp(name: &str) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::Builder::new().prefix("ocelli-gst-").tempdir().unwrap();
    let path = dir.path().join(name);
    (dir, path)
}

/// Encode `pictures` at `fps` into `path` with `encoder` (e.g. `jpegenc ! avimux`): appsrc →
/// videoconvert → encoder → filesink, each picture a sample with its own caps (so sizes may
/// change).
pub fn encode(path: &Path, pictures: &[Picture], fps: u64, encoder: &str) {
    init().unwrap();
    let description = format!("appsrc name=src format=time ! videoconvert ! {encoder} ! filesink name=out");
    let pipeline = gst::parse::launch(&description)
        .unwrap()
        .downcast::<gst::Pipeline>()
        .unwrap();
    pipeline
        .by_name("out")
        .unwrap()
        .set_property("location", path.to_str().unwrap());
    let src = pipeline
        .by_name("src")
        .unwrap()
        .dynamic_cast::<gst_app::AppSrc>()
        .unwrap();
    pipeline.set_state(gst::State::Playing).unwrap();
    let period = 1_000_000_000 / fps;
    for (i, p) in pictures.iter().enumerate() {
        let info = gst_video::VideoInfo::builder(gst_video::VideoFormat::Rgb, p.width, p.height)
            .fps(gst::Fraction::new(fps as i32, 1))
            .build()
            .unwrap();
        let mut buffer = gst::Buffer::with_size(info.size()).unwrap();
        {
            let b = buffer.get_mut().unwrap();
            b.set_pts(gst::ClockTime::from_nseconds(i as u64 * period));
            b.set_duration(gst::ClockTime::from_nseconds(period));
            let mut frame = gst_video::VideoFrameRef::from_buffer_ref_writable(b, &info).unwrap();
            let stride = frame.plane_stride()[0] as usize;
            let data = frame.plane_data_mut(0).unwrap();
            let rgb = p.rgb();
            for (y, row) in rgb.rows().enumerate() {
                for (x, px) in row.enumerate() {
                    data[y * stride + x * 3..][..3].copy_from_slice(&px.0);
                }
            }
        }
        let caps = info.to_caps().unwrap();
        src.push_sample(&gst::Sample::builder().buffer(&buffer).caps(&caps).build())
            .unwrap();
    }
    src.end_of_stream().unwrap();
    let bus = pipeline.bus().unwrap();
    let msg = bus
        .timed_pop_filtered(
            gst::ClockTime::from_seconds(30),
            &[gst::MessageType::Eos, gst::MessageType::Error],
        )
        .expect("encoder finished");
    assert!(
        matches!(msg.view(), gst::MessageView::Eos(_)),
        "encoding failed: {msg:?}"
    );
    pipeline.set_state(gst::State::Null).unwrap();
}

/// The runtime's clock for tests: cluster time from the start of the test.
pub struct Clock(Instant);

impl Clock {
    #[allow(clippy::disallowed_methods)] // a test plays the runtime, which owns the clock
    pub fn start() -> Clock {
        Clock(Instant::now())
    }

    pub fn now(&self) -> ClusterTime {
        ClusterTime(self.0.elapsed().as_nanos() as i64)
    }

    pub fn elapsed(&self) -> Duration {
        self.0.elapsed()
    }
}

struct Shared {
    stop: AtomicBool,
    silent: AtomicBool,
    jpeg: Mutex<Vec<u8>>,
}

/// An HTTP server sending `multipart/x-mixed-replace` JPEGs every 30 ms to each client.
pub struct MjpegServer {
    pub port: u16,
    shared: Arc<Shared>,
    thread: Option<JoinHandle<()>>,
}

impl MjpegServer {
    /// Listen on 127.0.0.1:`port` (0: any free port).
    pub fn start(port: u16, picture: Picture) -> MjpegServer {
        let listener = TcpListener::bind(("127.0.0.1", port)).unwrap();
        listener.set_nonblocking(true).unwrap();
        let port = listener.local_addr().unwrap().port();
        let shared = Arc::new(Shared {
            stop: AtomicBool::new(false),
            silent: AtomicBool::new(false),
            jpeg: Mutex::new(picture.jpeg()),
        });
        let s = shared.clone();
        let thread = std::thread::spawn(move || {
            let mut clients = Vec::new();
            while !s.stop.load(Ordering::Relaxed) {
                match listener.accept() {
                    Ok((stream, _)) => {
                        let s = s.clone();
                        clients.push(std::thread::spawn(move || serve(stream, &s)));
                    }
                    Err(_) => std::thread::sleep(Duration::from_millis(10)),
                }
            }
            drop(listener);
            for c in clients {
                let _ = c.join();
            }
        });
        MjpegServer {
            port,
            shared,
            thread: Some(thread),
        }
    }

    pub fn show(&self, picture: Picture) {
        *self.shared.jpeg.lock().unwrap() = picture.jpeg();
    }

    /// Keep connections open but send nothing (a stalled camera).
    pub fn silence(&self, on: bool) {
        self.shared.silent.store(on, Ordering::Relaxed);
    }

    /// Close the listener and every connection.
    pub fn stop(mut self) {
        self.halt();
    }

    fn halt(&mut self) {
        self.shared.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for MjpegServer {
    fn drop(&mut self) {
        self.halt();
    }
}

fn serve(mut stream: TcpStream, s: &Shared) {
    stream.set_nonblocking(false).unwrap();
    stream.set_read_timeout(Some(Duration::from_secs(2))).unwrap();
    let mut request = Vec::new();
    let mut byte = [0u8; 1];
    while !request.ends_with(b"\r\n\r\n") {
        match stream.read(&mut byte) {
            Ok(1) => request.push(byte[0]),
            _ => return,
        }
    }
    let header = "HTTP/1.0 200 OK\r\nContent-Type: multipart/x-mixed-replace; boundary=ocelli\r\n\
                  Cache-Control: no-cache\r\nConnection: close\r\n\r\n";
    if stream.write_all(header.as_bytes()).is_err() {
        return;
    }
    while !s.stop.load(Ordering::Relaxed) {
        if !s.silent.load(Ordering::Relaxed) {
            let jpeg = s.jpeg.lock().unwrap().clone();
            let part = format!(
                "--ocelli\r\nContent-Type: image/jpeg\r\nContent-Length: {}\r\n\r\n",
                jpeg.len()
            );
            let sent = stream
                .write_all(part.as_bytes())
                .and_then(|()| stream.write_all(&jpeg))
                .and_then(|()| stream.write_all(b"\r\n"));
            if sent.is_err() {
                return;
            }
        }
        std::thread::sleep(Duration::from_millis(30));
    }
    let _ = stream.shutdown(std::net::Shutdown::Both);
}
