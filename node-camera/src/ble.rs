//! [`BleRadio`]: a [`RadioSource`] hearing real BLE tags through BlueZ (feature `ble`, crate
//! `bluer`; needs the system D-Bus and `bluetoothd`).
//!
//! A thread of its own runs a small tokio runtime that powers the adapter, scans LE
//! advertisements (duplicates reported, no RSSI threshold) and turns every RSSI BlueZ reports
//! for a device into a [`TagReading`] of its MAC, stamped with the node's cluster clock as it
//! arrives, into a bounded [`ReadingBuffer`] that [`RadioSource::read`] drains. An adapter or
//! bus error is counted and the scan restarts after a back-off (1 s doubling to 30 s), so a
//! node keeps running while its adapter is unplugged or `bluetoothd` restarts.
//!
//! BlueZ publishes RSSI as a device property: it says nothing when two advertisements in a row
//! arrive at the same RSSI, so the readings are the changes (at most one per advertisement).

use crate::radio::{RadioCounters, ReadingBuffer, reading};
use bluer::{AdapterEvent, DeviceEvent, DeviceProperty, DiscoveryFilter, DiscoveryTransport};
use futures_util::StreamExt;
use futures_util::stream::SelectAll;
use proto::ClusterTime;
use proto::sensor::{RadioSource, SourceError, TagReading};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;
use tokio_util::sync::CancellationToken;
use tracing::{info, warn};

/// The node's cluster clock, as the receiving thread stamps readings with it.
pub type Clock = Arc<dyn Fn() -> ClusterTime + Send + Sync>;

/// First and longest wait before scanning again after an adapter error.
const BACKOFF_FIRST: Duration = Duration::from_secs(1);
const BACKOFF_MAX: Duration = Duration::from_secs(30);

/// Why a scan ended.
#[derive(Debug, thiserror::Error)]
enum ScanError {
    #[error(transparent)]
    Bluez(#[from] bluer::Error),
    #[error("the adapter stopped discovering")]
    Ended,
}

/// BLE tags heard by one BlueZ adapter.
pub struct BleRadio {
    buffer: Arc<Mutex<ReadingBuffer>>,
    cancel: CancellationToken,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl std::fmt::Debug for BleRadio {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BleRadio")
            .field("counters", &self.counters())
            .finish()
    }
}

fn lock(b: &Mutex<ReadingBuffer>) -> MutexGuard<'_, ReadingBuffer> {
    b.lock().unwrap_or_else(|p| p.into_inner())
}

impl BleRadio {
    /// Start scanning on `adapter` (`None`: BlueZ's default), buffering at most `capacity`
    /// readings between reads. An adapter that is absent or fails now is retried in the
    /// background: opening succeeds whenever the thread starts.
    ///
    /// # Errors
    /// The receiving thread cannot be started.
    pub fn open(adapter: Option<String>, clock: Clock, capacity: usize) -> Result<BleRadio, SourceError> {
        let buffer = Arc::new(Mutex::new(ReadingBuffer::new(capacity)));
        let cancel = CancellationToken::new();
        let thread = {
            let (buffer, cancel) = (buffer.clone(), cancel.clone());
            std::thread::Builder::new()
                .name("ble-scan".into())
                .spawn(move || scan_until_cancelled(adapter, &clock, &buffer, &cancel))
                .map_err(|e| SourceError::Device(format!("BLE thread: {e}")))?
        };
        Ok(BleRadio {
            buffer,
            cancel,
            thread: Some(thread),
        })
    }

    /// What the radio heard, refused and lost so far.
    pub fn counters(&self) -> RadioCounters {
        lock(&self.buffer).counters()
    }
}

impl RadioSource for BleRadio {
    fn read(&mut self, _now: ClusterTime, out: &mut Vec<TagReading>) -> Result<bool, SourceError> {
        lock(&self.buffer).drain_into(out);
        Ok(true)
    }
}

impl Drop for BleRadio {
    fn drop(&mut self) {
        self.cancel.cancel();
        if let Some(t) = self.thread.take()
            && t.join().is_err()
        {
            warn!("the BLE thread panicked");
        }
        info!(counters = ?self.counters(), "BLE radio stopped");
    }
}

/// The receiving thread: scan, and after an error count it, wait and scan again.
fn scan_until_cancelled(
    adapter: Option<String>,
    clock: &Clock,
    buffer: &Mutex<ReadingBuffer>,
    cancel: &CancellationToken,
) {
    let rt = match tokio::runtime::Builder::new_current_thread().enable_all().build() {
        Ok(rt) => rt,
        Err(e) => {
            warn!(error = %e, "BLE: no runtime; the radio hears nothing");
            return;
        }
    };
    rt.block_on(async {
        let mut backoff = BACKOFF_FIRST;
        while !cancel.is_cancelled() {
            match scan(adapter.as_deref(), clock, buffer, cancel).await {
                Ok(()) => return,
                Err(e) => {
                    lock(buffer).adapter_error();
                    warn!(error = %e, retry_s = backoff.as_secs(), "BLE adapter error; scanning again later");
                }
            }
            tokio::select! {
                () = cancel.cancelled() => return,
                () = tokio::time::sleep(backoff) => {}
            }
            backoff = (backoff * 2).min(BACKOFF_MAX);
        }
    });
}

/// One scan until cancelled (`Ok`) or an error.
async fn scan(
    name: Option<&str>,
    clock: &Clock,
    buffer: &Mutex<ReadingBuffer>,
    cancel: &CancellationToken,
) -> Result<(), ScanError> {
    let session = bluer::Session::new().await?;
    let adapter = match name {
        Some(n) => session.adapter(n)?,
        None => session.default_adapter().await?,
    };
    adapter.set_powered(true).await?;
    adapter
        .set_discovery_filter(DiscoveryFilter {
            transport: DiscoveryTransport::Le,
            duplicate_data: true,
            ..DiscoveryFilter::default()
        })
        .await?;
    info!(adapter = adapter.name(), "BLE scanning");
    let events = adapter.discover_devices().await?;
    let mut events = std::pin::pin!(events);
    let mut changes = SelectAll::new();
    loop {
        tokio::select! {
            () = cancel.cancelled() => return Ok(()),
            ev = events.next() => match ev {
                Some(AdapterEvent::DeviceAdded(addr)) => {
                    let device = adapter.device(addr)?;
                    // Absent for a device BlueZ remembers but has not heard in this scan.
                    if let Some(rssi) = device.rssi().await? {
                        lock(buffer).offer(reading(addr.0, i32::from(rssi), clock()));
                    }
                    changes.push(device.events().await?.map(move |e| (addr, e)));
                }
                Some(_) => {}
                None => return Err(ScanError::Ended),
            },
            Some((addr, DeviceEvent::PropertyChanged(DeviceProperty::Rssi(rssi)))) = changes.next() => {
                lock(buffer).offer(reading(addr.0, i32::from(rssi), clock()));
            }
        }
    }
}
