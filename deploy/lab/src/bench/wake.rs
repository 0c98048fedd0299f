//! The floors under `bench transport`'s fixed-rate latency: what waking a sleeping receiver
//! costs on this host before any transport code runs. Each baseline sends `count` timestamps
//! `interval` apart from one thread to another of this process and measures one-way latency,
//! like the transports' fixed-rate phase.
//!
//! - `thread`: a `std::sync::mpsc` channel (a futex wake) — the cheapest wake there is, but one
//!   that cannot cross a process boundary or sit in an event loop.
//! - `tokio`: a tokio channel from a timer-driven current-thread runtime to another parked on
//!   its reactor — the wake every message of a tokio node pays.
//! - `socket`: one datagram over a Unix socket pair to a thread blocked in `recv` — the kernel
//!   primitive iceoryx2's event service wakes a listener with, and the cheapest wake that
//!   crosses processes and can be polled by a reactor.
//! - `iceoryx2`: iceoryx2 alone, with none of our code: a thread loans, writes and publishes a
//!   slot and notifies the inbox's event; a thread blocked on the listener takes the sample.
//!   The iceoryx2 transport's own cost is its latency above this one.

use super::transport::percentile;
use crate::{LabError, Result};
use iceoryx2::prelude::*;
use serde_json::{Value, json};
use std::time::{Duration, Instant};

fn summary(mut lat: Vec<u64>) -> Value {
    lat.sort_unstable();
    json!({"p50_us": percentile(&lat, 0.5), "p99_us": percentile(&lat, 0.99), "samples": lat.len()})
}

fn since(base: Instant) -> u64 {
    base.elapsed().as_nanos() as u64
}

/// A `std::sync::mpsc` channel (futex wake).
pub(super) fn thread(count: usize, interval: Duration) -> Value {
    #[allow(clippy::disallowed_methods)] // a benchmark owns its clock
    let base = Instant::now();
    let (tx, rx) = std::sync::mpsc::channel::<u64>();
    let waiter = std::thread::spawn(move || {
        let mut lat = Vec::with_capacity(count);
        while let Ok(t) = rx.recv() {
            lat.push(since(base).saturating_sub(t));
        }
        lat
    });
    for _ in 0..count {
        std::thread::sleep(interval);
        if tx.send(since(base)).is_err() {
            break;
        }
    }
    drop(tx);
    summary(waiter.join().unwrap_or_default())
}

/// One current-thread tokio runtime (timer-driven, like the transport bench's sender) waking
/// another, parked on its reactor, through a tokio channel.
///
/// # Errors
/// A runtime could not be built.
pub(super) fn tokio(count: usize, interval: Duration) -> Result<Value> {
    #[allow(clippy::disallowed_methods)] // a benchmark owns its clock
    let base = Instant::now();
    let (tx, mut rx) = tokio::sync::mpsc::channel::<u64>(16);
    let waiter = std::thread::spawn(move || -> Result<Vec<u64>> {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()?;
        Ok(rt.block_on(async move {
            let mut lat = Vec::with_capacity(count);
            while let Ok(Some(t)) = tokio::time::timeout(Duration::from_secs(10), rx.recv()).await {
                lat.push(since(base).saturating_sub(t));
            }
            lat
        }))
    });
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?;
    rt.block_on(async move {
        let mut next = tokio::time::Instant::now();
        for _ in 0..count {
            next += interval;
            tokio::time::sleep_until(next).await;
            if tx.try_send(since(base)).is_err() {
                break;
            }
        }
    });
    let lat = waiter
        .join()
        .map_err(|_| LabError::failed("transport bench", "tokio waiter panicked"))??;
    Ok(summary(lat))
}

/// One datagram over a Unix socket pair to a thread blocked in `recv`.
///
/// # Errors
/// The socket pair could not be made or used.
pub(super) fn socket(count: usize, interval: Duration) -> Result<Value> {
    use std::os::unix::net::UnixDatagram;
    #[allow(clippy::disallowed_methods)] // a benchmark owns its clock
    let base = Instant::now();
    let (tx, rx) = UnixDatagram::pair()?;
    rx.set_read_timeout(Some(Duration::from_secs(10)))?;
    let waiter = std::thread::spawn(move || {
        let mut lat = Vec::with_capacity(count);
        let mut buf = [0u8; 8];
        while lat.len() < count && rx.recv(&mut buf).is_ok() {
            lat.push(since(base).saturating_sub(u64::from_le_bytes(buf)));
        }
        lat
    });
    for _ in 0..count {
        std::thread::sleep(interval);
        tx.send(&since(base).to_le_bytes())?;
    }
    let lat = waiter
        .join()
        .map_err(|_| LabError::failed("transport bench", "socket waiter panicked"))?;
    Ok(summary(lat))
}

type Svc = ipc::Service;

fn iox(what: &str, e: impl std::fmt::Debug) -> LabError {
    LabError::failed("transport bench", format!("iceoryx2 {what}: {e:?}"))
}

/// One side of the iceoryx2 baseline: its node, the inbox and the inbox's event service.
type Side = (
    Node<Svc>,
    iceoryx2::service::port_factory::publish_subscribe::PortFactory<Svc, [u8], ()>,
    iceoryx2::service::port_factory::event::PortFactory<Svc>,
);

/// The node, inbox and event service of one side of the iceoryx2 baseline.
fn iox_service(domain: &str) -> Result<Side> {
    let mut config = Config::default();
    config.global.prefix =
        FileName::new(format!("iox2_{domain}_").as_bytes()).map_err(|e| iox("prefix", e))?;
    let node = NodeBuilder::new()
        .config(&config)
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<Svc>()
        .map_err(|e| iox("node", e))?;
    let name = ServiceName::new("baseline/inbox").map_err(|e| iox("service name", e))?;
    let data = node
        .service_builder(&name)
        .publish_subscribe::<[u8]>()
        .enable_safe_overflow(false)
        .subscriber_max_buffer_size(16)
        .history_size(0)
        .open_or_create()
        .map_err(|e| iox("inbox", e))?;
    let wake = node
        .service_builder(&name)
        .event()
        .open_or_create()
        .map_err(|e| iox("event", e))?;
    Ok((node, data, wake))
}

/// iceoryx2 alone: loan, write, publish and notify on one thread; a thread blocked on the
/// listener takes the sample. Each side has its own iceoryx2 node, as two processes would.
///
/// # Errors
/// An iceoryx2 port could not be made or used.
pub(super) fn iceoryx2(count: usize, interval: Duration) -> Result<Value> {
    #[allow(clippy::disallowed_methods)] // a benchmark owns its clock
    let base = Instant::now();
    let domain = format!("bench-wake-{}", std::process::id());
    let (ready_tx, ready_rx) = std::sync::mpsc::channel::<()>();
    let receiver_domain = domain.clone();
    let waiter = std::thread::spawn(move || -> Result<Vec<u64>> {
        let (_node, data, wake) = iox_service(&receiver_domain)?;
        let sub = data
            .subscriber_builder()
            .create()
            .map_err(|e| iox("subscriber", e))?;
        let listener = wake.listener_builder().create().map_err(|e| iox("listener", e))?;
        let _ = ready_tx.send(());
        let mut lat = Vec::with_capacity(count);
        while lat.len() < count {
            let woke = listener
                .timed_wait(|_| {}, Duration::from_secs(10))
                .map_err(|e| iox("wait", e))?;
            if woke == 0 {
                break;
            }
            while let Some(s) = sub.receive().map_err(|e| iox("receive", e))? {
                if let Some(stamp) = s.payload().get(..8).and_then(|b| <[u8; 8]>::try_from(b).ok()) {
                    lat.push(since(base).saturating_sub(u64::from_le_bytes(stamp)));
                }
            }
        }
        Ok(lat)
    });
    ready_rx
        .recv_timeout(Duration::from_secs(10))
        .map_err(|_| LabError::failed("transport bench", "iceoryx2 baseline receiver did not start"))?;
    let sent = publish_at_rate(&domain, base, count, interval);
    let received = waiter
        .join()
        .map_err(|_| LabError::failed("transport bench", "iceoryx2 waiter panicked"))?;
    // Both nodes are gone: their services with them; the domain's management segment is left.
    remove_domain_files(&domain);
    sent?;
    Ok(summary(received?))
}

/// The sending side of the iceoryx2 baseline: one sample and one notification per interval.
fn publish_at_rate(domain: &str, base: Instant, count: usize, interval: Duration) -> Result<()> {
    let (_node, data, wake) = iox_service(domain)?;
    let publisher = data
        .publisher_builder()
        .initial_max_slice_len(4096)
        .allocation_strategy(AllocationStrategy::Static)
        .create()
        .map_err(|e| iox("publisher", e))?;
    let notifier = wake.notifier_builder().create().map_err(|e| iox("notifier", e))?;
    // The frame size of the transport bench's measurement.
    let mut payload = vec![0u8; 282];
    for _ in 0..count {
        std::thread::sleep(interval);
        payload[..8].copy_from_slice(&since(base).to_le_bytes());
        let sample = publisher
            .loan_slice_uninit(payload.len())
            .map_err(|e| iox("loan", e))?;
        sample
            .write_from_slice(&payload)
            .send()
            .map_err(|e| iox("send", e))?;
        notifier.notify().map_err(|e| iox("notify", e))?;
    }
    Ok(())
}

/// iceoryx2 keeps a management segment per file prefix after its last node is gone.
fn remove_domain_files(domain: &str) {
    let prefix = format!("iox2_{domain}_");
    let Ok(dir) = std::fs::read_dir("/dev/shm") else {
        return;
    };
    for entry in dir.flatten() {
        if entry.file_name().to_string_lossy().starts_with(&prefix) {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}
