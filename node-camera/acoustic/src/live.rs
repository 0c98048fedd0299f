//! Live two-microphone capture through cpal (ALSA on Linux), as a `proto::sensor::AudioSource`.
//!
//! The device's callback appends the first two channels' samples to a bounded queue (the
//! oldest are dropped and counted if the node falls behind); [`LiveSource::capture`] waits for
//! one frame of them, and a stream that delivers nothing within [`STALL_TIMEOUT`] is reported
//! as [`SourceError::Stalled`] — the node counts it and keeps running. The stream is opened on
//! the thread that reads it (a cpal stream is not `Send`).

use cpal::traits::{DeviceTrait, HostTrait, StreamTrait};
use proto::ClusterTime;
use proto::sensor::{AudioFrame, AudioSource, SourceError};
use std::collections::VecDeque;
use std::sync::{Arc, Condvar, Mutex};
use std::time::Duration;

/// How long a capture waits for its frame beyond the frame's own duration.
pub const STALL_TIMEOUT: Duration = Duration::from_millis(1000);
/// Most stereo samples buffered (seconds at the rate are what this many pairs hold).
const MAX_BUFFERED: usize = 1 << 20;

#[derive(Default)]
struct Shared {
    /// Interleaved left, right.
    samples: VecDeque<f32>,
    overflowed: u64,
    error: Option<String>,
}

/// A capture device opened for two channels at a rate.
pub struct LiveSource {
    name: String,
    rate: u32,
    shared: Arc<(Mutex<Shared>, Condvar)>,
    _stream: cpal::Stream,
}

impl std::fmt::Debug for LiveSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LiveSource")
            .field("name", &self.name)
            .field("rate", &self.rate)
            .finish_non_exhaustive()
    }
}

fn device_error(name: &str, problem: impl std::fmt::Display) -> SourceError {
    SourceError::Device(format!("audio device {name:?}: {problem}"))
}

/// Names of the host's capture devices.
pub fn input_devices() -> Vec<String> {
    cpal::default_host()
        .input_devices()
        .map(|ds| ds.filter_map(|d| d.name().ok()).collect())
        .unwrap_or_default()
}

impl LiveSource {
    /// Open capture device `name` (`default` for the host's default) for two channels of
    /// 32-bit float or 16-bit samples at `rate` Hz.
    ///
    /// # Errors
    /// No such device, a device without two input channels, or a stream that cannot be built
    /// or started; each names the device.
    pub fn open(name: &str, rate: u32) -> Result<LiveSource, SourceError> {
        let host = cpal::default_host();
        let device = if name == "default" {
            host.default_input_device()
        } else {
            host.input_devices()
                .map_err(|e| device_error(name, e))?
                .find(|d| d.name().is_ok_and(|n| n == name))
        }
        .ok_or_else(|| {
            device_error(
                name,
                format!("no such capture device (have: {:?})", input_devices()),
            )
        })?;
        let channels = device
            .supported_input_configs()
            .map_err(|e| device_error(name, e))?
            .filter(|c| c.channels() >= 2 && c.min_sample_rate().0 <= rate && rate <= c.max_sample_rate().0)
            .filter(|c| {
                matches!(
                    c.sample_format(),
                    cpal::SampleFormat::F32 | cpal::SampleFormat::I16
                )
            })
            .map(|c| (c.channels(), c.sample_format()))
            // Fewest channels, then float before 16-bit.
            .min_by_key(|(ch, f)| (*ch, *f != cpal::SampleFormat::F32))
            .ok_or_else(|| {
                device_error(
                    name,
                    format!("no 16-bit or float input of 2 or more channels at {rate} Hz"),
                )
            })?;
        let config = cpal::StreamConfig {
            channels: channels.0,
            sample_rate: cpal::SampleRate(rate),
            buffer_size: cpal::BufferSize::Default,
        };
        let shared = Arc::new((Mutex::new(Shared::default()), Condvar::new()));
        let stride = usize::from(channels.0);
        let on_error = {
            let shared = shared.clone();
            move |e: cpal::StreamError| {
                if let Ok(mut s) = shared.0.lock() {
                    s.error = Some(e.to_string());
                }
                shared.1.notify_all();
            }
        };
        let stream = match channels.1 {
            cpal::SampleFormat::I16 => {
                let shared = shared.clone();
                device.build_input_stream(
                    &config,
                    move |data: &[i16], _: &cpal::InputCallbackInfo| {
                        push(
                            &shared,
                            data.chunks_exact(stride)
                                .map(|c| (f32::from(c[0]) / 32768.0, f32::from(c[1]) / 32768.0)),
                        );
                    },
                    on_error,
                    None,
                )
            }
            _ => {
                let shared = shared.clone();
                device.build_input_stream(
                    &config,
                    move |data: &[f32], _: &cpal::InputCallbackInfo| {
                        push(&shared, data.chunks_exact(stride).map(|c| (c[0], c[1])));
                    },
                    on_error,
                    None,
                )
            }
        }
        .map_err(|e| device_error(name, e))?;
        stream.play().map_err(|e| device_error(name, e))?;
        Ok(LiveSource {
            name: name.into(),
            rate,
            shared,
            _stream: stream,
        })
    }

    /// Stereo samples dropped because the reader fell behind.
    pub fn overflowed(&self) -> u64 {
        self.shared.0.lock().map_or(0, |s| s.overflowed)
    }
}

fn push(shared: &(Mutex<Shared>, Condvar), pairs: impl Iterator<Item = (f32, f32)>) {
    let Ok(mut s) = shared.0.lock() else { return };
    for (l, r) in pairs {
        if s.samples.len() >= 2 * MAX_BUFFERED {
            s.samples.pop_front();
            s.samples.pop_front();
            s.overflowed += 1;
        }
        s.samples.push_back(l);
        s.samples.push_back(r);
    }
    drop(s);
    shared.1.notify_all();
}

impl AudioSource for LiveSource {
    fn sample_rate(&self) -> u32 {
        self.rate
    }

    fn capture(
        &mut self,
        now: ClusterTime,
        samples: usize,
        frame: &mut AudioFrame,
    ) -> Result<bool, SourceError> {
        let wait = Duration::from_secs_f64(samples as f64 / f64::from(self.rate.max(1))) + STALL_TIMEOUT;
        let (lock, ready) = &*self.shared;
        let guard = lock
            .lock()
            .map_err(|_| device_error(&self.name, "capture callback panicked"))?;
        let (mut s, timeout) = ready
            .wait_timeout_while(guard, wait, |s| {
                s.samples.len() < 2 * samples && s.error.is_none()
            })
            .map_err(|_| device_error(&self.name, "capture callback panicked"))?;
        if let Some(e) = s.error.take() {
            return Err(device_error(&self.name, e));
        }
        if timeout.timed_out() {
            return Err(SourceError::Stalled {
                source_name: format!("audio device {:?}", self.name),
                waited_ms: u64::try_from(wait.as_millis()).unwrap_or(u64::MAX),
            });
        }
        frame.sample_rate = self.rate;
        frame.left.clear();
        frame.right.clear();
        for _ in 0..samples {
            let (Some(l), Some(r)) = (s.samples.pop_front(), s.samples.pop_front()) else {
                break;
            };
            frame.left.push(l);
            frame.right.push(r);
        }
        frame.captured = now;
        Ok(true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Through ALSA's null plugin as a named capture device, `ocelli_null`, which `.ci/run`
    /// declares in `/etc/alsa/conf.d/50-ocelli-null.conf` (a machine without a sound card has
    /// no other): the device opens, and a capture delivers a frame (of silence) or reports a
    /// stall — never hangs or panics. A missing device is a clear error naming it.
    #[test]
    fn capture_from_the_null_device_delivers_or_stalls_and_names_missing_devices() {
        let e = LiveSource::open("no-such-device-ocelli", 8000).unwrap_err();
        assert!(e.to_string().contains("no-such-device-ocelli"), "{e}");
        let devices = input_devices();
        assert!(
            devices.iter().any(|d| d == "ocelli_null"),
            "no `ocelli_null` capture device (.ci/run declares it in /etc/alsa/conf.d): {devices:?}"
        );
        let mut s = LiveSource::open("ocelli_null", 8000).unwrap();
        let mut f = AudioFrame::default();
        for _ in 0..2 {
            match s.capture(ClusterTime(1), 800, &mut f) {
                Ok(true) => assert_eq!((f.left.len(), f.right.len(), f.sample_rate), (800, 800, 8000)),
                Ok(false) => panic!("a live device never ends"),
                Err(SourceError::Stalled { waited_ms, .. }) => assert!(waited_ms >= 1000),
                Err(e) => panic!("unexpected: {e}"),
            }
        }
    }
}
