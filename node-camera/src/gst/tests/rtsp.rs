//! The RTSP source against a real RTSP server (GStreamer's own, feature `rtsp-tests`): an IP
//! camera's usual stream, JPEG over RTP, read through `rtsp://127.0.0.1:PORT/cam`.

use super::kit::{Clock, colours, near};
use super::{CAMERA, RED};
use crate::gst::{GstInput, GstOptions, GstSource, init};
use crate::source_spec::SharedStats;
use gstreamer::glib;
use gstreamer_rtsp_server as rtsp;
use gstreamer_rtsp_server::prelude::*;
use proto::ClusterTime;
use proto::sensor::Frame;
use proto::sensor::FrameSource;
use std::thread::JoinHandle;
use std::time::Duration;

/// An RTSP server on a free port serving a solid red 80×60 MJPEG stream at `/cam`, run by
/// its own GLib main loop on its own thread.
struct Server {
    port: i32,
    main_loop: glib::MainLoop,
    thread: Option<JoinHandle<()>>,
    _source: glib::SourceId,
}

impl Server {
    fn start() -> Server {
        init().unwrap();
        let server = rtsp::RTSPServer::new();
        server.set_address("127.0.0.1");
        server.set_service("0");
        let factory = rtsp::RTSPMediaFactory::new();
        factory.set_launch(
            "( videotestsrc is-live=true pattern=solid-color foreground-color=0xffdc1e1e \
             ! video/x-raw,format=I420,width=80,height=60,framerate=15/1 ! jpegenc quality=95 \
             ! rtpjpegpay name=pay0 pt=26 )",
        );
        factory.set_shared(true);
        server.mount_points().unwrap().add_factory("/cam", factory);
        let context = glib::MainContext::new();
        let source = server.attach(Some(&context)).unwrap();
        let port = server.bound_port();
        let main_loop = glib::MainLoop::new(Some(&context), false);
        let running = main_loop.clone();
        let thread = std::thread::spawn(move || {
            let _keep = server;
            context.with_thread_default(|| running.run()).unwrap();
        });
        Server {
            port,
            main_loop,
            thread: Some(thread),
            _source: source,
        }
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        self.main_loop.quit();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

#[test]
fn rtsp_stream_arrives_at_the_camera_size() {
    let server = Server::start();
    assert!(server.port > 0);
    let input = GstInput::Rtsp {
        url: format!("rtsp://127.0.0.1:{}/cam", server.port),
    };
    let mut options = GstOptions::for_camera(&input, 15.0);
    options.max_wait = Duration::from_millis(200);
    let stats = SharedStats::default();
    let mut source = GstSource::open(input, CAMERA.0, CAMERA.1, options, stats.clone()).unwrap();
    let clock = Clock::start();
    let mut frame = Frame::new(1, 1, ClusterTime::ZERO);
    let mut red = 0;
    while red < 5 && clock.elapsed() < Duration::from_secs(20) {
        if let Ok(true) = source.capture(clock.now(), &mut frame) {
            assert_eq!((frame.width, frame.height), CAMERA);
            let top = colours(&frame).0;
            assert!(near(top, RED), "{top:?}");
            red += 1;
        }
    }
    let s = stats.snapshot();
    assert_eq!(red, 5, "{s:?}");
    assert_eq!((s.decode_errors, s.stalls), (0, 0), "{s:?}");
}
