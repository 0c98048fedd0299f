//! [`GstSource`]'s capture: take the newest (or next) decoded frame, and turn what the bus says
//! — errors, warnings, the end — and missing frames into counts, log lines and restarts.

use super::{AtEnd, GstSource, Phase, describe, device};
use crate::source_spec::{Count, worth_logging};
use gstreamer as gst;
use gstreamer::prelude::*;
use gstreamer_video as gst_video;
use gstreamer_video::prelude::*;
use proto::ClusterTime;
use proto::sensor::Frame;
use proto::sensor::{FrameSource, SourceError};
use std::time::Duration;
use tracing::{info, warn};

/// What the bus said since the last look.
enum BusNews {
    Nothing,
    /// The stream or file ended.
    End,
    /// An error: the pipeline is dead.
    Failed,
}

fn nanos(d: Duration) -> i64 {
    i64::try_from(d.as_nanos()).unwrap_or(i64::MAX)
}

impl GstSource {
    /// Count a failed capture and make its error.
    fn fail(&self, problem: impl std::fmt::Display) -> SourceError {
        self.stats.bump(Count::Error);
        device(&self.input, problem)
    }

    /// Tear the pipeline down and start it again after the next backoff delay.
    fn restart_later(&mut self, now: ClusterTime) {
        self.pipeline = None;
        let delay = self.backoff.next_delay(&mut self.rng);
        info!(source = %self.input, delay_ms = delay.as_millis() as u64, attempt = self.backoff.attempt(),
            "reconnecting after backoff");
        self.phase = Phase::Waiting {
            at: now + nanos(delay),
            reconnect: true,
        };
    }

    /// Build and start a new pipeline (after a failure or a file's loop).
    fn start(&mut self, now: ClusterTime) -> Result<(), SourceError> {
        let p = self.build()?;
        p.pipeline
            .set_state(gst::State::Playing)
            .map_err(|e| device(&self.input, format!("cannot start: {e}")))?;
        self.pipeline = Some(p);
        self.phase = Phase::Playing { progress: Some(now) };
        Ok(())
    }

    /// The end of a file or a stream.
    fn on_end(&mut self, now: ClusterTime) {
        let n = self.stats.bump(Count::End);
        let frames = self.stats.snapshot().frames;
        match (self.input.is_live(), self.options.at_end) {
            (false, AtEnd::Stop) => {
                info!(source = %self.input, frames, "video ended");
                self.pipeline = None;
                self.phase = Phase::Ended;
            }
            (false, AtEnd::Loop) => {
                info!(source = %self.input, frames, laps = n, "video ended; starting over");
                self.pipeline = None;
                self.phase = Phase::Waiting {
                    at: now,
                    reconnect: false,
                };
            }
            (true, _) => {
                warn!(source = %self.input, frames, ends = n, "stream ended");
                self.restart_later(now);
            }
        }
    }

    /// An error from the pipeline: count it by kind; a stream reconnects, a file ends (or
    /// starts over when it loops).
    fn on_error(&mut self, now: ClusterTime, m: &gst::Message) {
        let decoding = matches!(m.view(), gst::MessageView::Error(e) if e.error().is::<gst::StreamError>());
        let n = self.stats.bump(if decoding {
            Count::DecodeError
        } else {
            Count::StreamError
        });
        let what = if decoding {
            "decoding failed"
        } else {
            "stream failed"
        };
        if worth_logging(n) {
            warn!(source = %self.input, error = %describe(m), count = n, "{what}");
        }
        match (self.input.is_live(), self.options.at_end) {
            (false, AtEnd::Stop) => {
                info!(source = %self.input, "video ends at the error");
                self.stats.bump(Count::End);
                self.pipeline = None;
                self.phase = Phase::Ended;
            }
            _ => self.restart_later(now),
        }
    }

    /// Read the bus: warnings are counted, an error or the end changes the phase.
    fn read_bus(&mut self, now: ClusterTime) -> BusNews {
        loop {
            let Some(m) = self.pipeline.as_ref().and_then(|p| p.bus.pop()) else {
                return BusNews::Nothing;
            };
            match m.view() {
                gst::MessageView::Error(_) => {
                    self.on_error(now, &m);
                    return BusNews::Failed;
                }
                gst::MessageView::Eos(_) => {
                    self.on_end(now);
                    return BusNews::End;
                }
                gst::MessageView::Warning(_) => {
                    let n = self.stats.bump(Count::CorruptFrame);
                    if worth_logging(n) {
                        warn!(source = %self.input, warning = %describe(&m), count = n, "corrupt data");
                    }
                }
                _ => {}
            }
        }
    }

    /// Camera time that passed without capturing (the camera was off) is not a stall.
    fn forgive_pause(&mut self, now: ClusterTime) {
        let paused = self
            .last_call
            .is_some_and(|last| now - last > nanos(self.options.stall_timeout));
        self.last_call = Some(now);
        if let Phase::Playing { progress } = &mut self.phase
            && (paused || progress.is_none())
        {
            *progress = Some(now);
        }
    }

    /// Copy a sample's RGB rows (GStreamer pads rows to 4 bytes) into `frame`.
    fn copy_sample(&self, sample: &gst::Sample, now: ClusterTime, frame: &mut Frame) -> Result<(), String> {
        let buffer = sample.buffer().ok_or("sample without a buffer")?;
        let caps = sample.caps().ok_or("sample without caps")?;
        let info = gst_video::VideoInfo::from_caps(caps).map_err(|e| format!("caps {caps}: {e}"))?;
        if (info.width(), info.height()) != self.size {
            return Err(format!(
                "frame is {}x{}, not the camera's size",
                info.width(),
                info.height()
            ));
        }
        let video = gst_video::VideoFrameRef::from_buffer_ref_readable(buffer, &info)
            .map_err(|e| format!("unreadable buffer: {e}"))?;
        let stride = usize::try_from(video.plane_stride()[0]).map_err(|_| "negative stride")?;
        let plane = video.plane_data(0).map_err(|e| e.to_string())?;
        let (w, h) = (self.size.0 as usize, self.size.1 as usize);
        if stride < w * 3 || plane.len() < stride * (h - 1) + w * 3 {
            return Err(format!(
                "buffer of {} bytes, stride {stride}, is too small",
                plane.len()
            ));
        }
        frame.width = self.size.0;
        frame.height = self.size.1;
        frame.captured = now;
        frame.data.resize(w * h * 3, 0);
        for (row, out) in frame.data.chunks_exact_mut(w * 3).enumerate() {
            out.copy_from_slice(&plane[row * stride..row * stride + w * 3]);
        }
        Ok(())
    }
}

impl FrameSource for GstSource {
    fn size(&self) -> (u32, u32) {
        self.size
    }

    fn capture(&mut self, now: ClusterTime, frame: &mut Frame) -> Result<bool, SourceError> {
        self.forgive_pause(now);
        self.capture_at(now, frame, true)
    }
}

impl GstSource {
    /// One capture; `again`: a file that ends here may start its next lap and deliver its
    /// first frame in this same call.
    fn capture_at(&mut self, now: ClusterTime, frame: &mut Frame, again: bool) -> Result<bool, SourceError> {
        // At most one restart per capture: a file's new lap, or a reconnect that is due.
        for restarts in 0.. {
            if let Phase::Waiting { at, reconnect } = self.phase {
                if now < at {
                    let left = Duration::from_nanos(u64::try_from(at - now).unwrap_or(0));
                    std::thread::sleep(left.min(self.options.max_wait));
                    return Err(self.fail(format!("reconnecting in {:.2} s", left.as_secs_f64())));
                }
                if let Err(e) = self.start(now) {
                    self.restart_later(now);
                    return Err(self.fail(e));
                }
                if reconnect {
                    self.stats.bump(Count::Reconnect);
                }
            }
            match self.read_bus(now) {
                BusNews::Nothing => break,
                BusNews::End | BusNews::Failed if self.phase == Phase::Ended => return Ok(false),
                BusNews::End | BusNews::Failed if restarts > 0 => {
                    return Err(self.fail("no frame: restarting"));
                }
                BusNews::End | BusNews::Failed => {}
            }
        }
        let Phase::Playing { progress } = self.phase else {
            return Ok(false);
        };
        let Some(p) = self.pipeline.as_ref() else {
            return Err(self.fail("no pipeline"));
        };
        let wait = gst::ClockTime::from_nseconds(self.options.max_wait.as_nanos() as u64);
        if let Some(sample) = p.sink.try_pull_sample(wait) {
            return match self.copy_sample(&sample, now, frame) {
                Ok(()) => {
                    self.stats.bump(Count::Frame);
                    self.backoff.reset();
                    self.phase = Phase::Playing { progress: Some(now) };
                    Ok(true)
                }
                Err(problem) => Err(self.fail(problem)),
            };
        }
        // No frame within `max_wait`: the bus may say why.
        let eos = p.sink.is_eos();
        match self.read_bus(now) {
            BusNews::Nothing if eos => self.on_end(now),
            BusNews::Nothing => {}
            BusNews::End | BusNews::Failed => {}
        }
        match self.phase {
            Phase::Ended => return Ok(false),
            Phase::Waiting { at, .. } if again && at <= now => return self.capture_at(now, frame, false),
            _ => {}
        }
        let since = progress.unwrap_or(now);
        if matches!(self.phase, Phase::Playing { .. }) && now - since > nanos(self.options.stall_timeout) {
            let n = self.stats.bump(Count::Stall);
            warn!(source = %self.input, silent_s = now.secs_since(since), stalls = n, "stream stalled");
            self.restart_later(now);
        }
        Err(self.fail(format!(
            "no frame within {:.2} s",
            self.options.max_wait.as_secs_f64()
        )))
    }
}
