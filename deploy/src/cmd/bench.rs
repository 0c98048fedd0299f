//! `ocelli bench camera|head|server|transport|grid`: the lab's benchmarks (`lab::bench`), printed as
//! JSON on standard output.

use anyhow::Result;
use lab::bench;
use std::process::ExitCode;

#[derive(clap::Args, Debug)]
pub struct CameraArgs {
    /// Print JSON (the only output format; accepted for symmetry with other commands).
    #[arg(long)]
    pub json: bool,
    /// Frames timed per configuration (after a warm-up of 20).
    #[arg(long, default_value_t = 200, value_parser = clap::value_parser!(u64).range(1..=1_000_000))]
    pub frames: u64,
    /// CPU to pin to.
    #[arg(long, default_value_t = 0)]
    pub cpu: usize,
}

#[derive(clap::Args, Debug)]
pub struct ScaleArgs {
    /// Print JSON (the only output format; accepted for symmetry with other commands).
    #[arg(long)]
    pub json: bool,
    /// Scale the repetition counts (1.0 = default), in (0, 1000].
    #[arg(long, default_value_t = 1.0, value_parser = scale)]
    pub scale: f64,
}

#[derive(clap::Args, Debug)]
pub struct TransportArgs {
    /// Print JSON (the only output format; accepted for symmetry with other commands).
    #[arg(long)]
    pub json: bool,
    /// Messages in the fixed-rate phase.
    #[arg(long, default_value_t = 300, value_parser = clap::value_parser!(u64).range(1..=10_000_000))]
    pub rate_messages: u64,
    /// Rate of the fixed-rate phase, Hz.
    #[arg(long, default_value_t = 30.0, value_parser = super::common::positive)]
    pub rate_hz: f64,
    /// Messages in the full-rate phase.
    #[arg(long, default_value_t = 20_000, value_parser = clap::value_parser!(u64).range(1..=10_000_000))]
    pub burst_messages: u64,
    /// Iterations per message kind for encode/decode costs.
    #[arg(long, default_value_t = 20_000, value_parser = clap::value_parser!(u64).range(1..=10_000_000))]
    pub codec_iterations: u64,
}

fn scale(s: &str) -> Result<f64, String> {
    let x = super::common::positive(s)?;
    if x <= 1000.0 {
        Ok(x)
    } else {
        Err(format!("expected a scale in (0, 1000], got {x}"))
    }
}

fn print(v: &serde_json::Value) -> Result<ExitCode> {
    println!("{}", serde_json::to_string_pretty(v)?);
    Ok(ExitCode::SUCCESS)
}

pub fn camera(a: CameraArgs) -> Result<ExitCode> {
    print(&bench::camera::run(&bench::camera::Options {
        frames: a.frames as usize,
        cpu: a.cpu,
    })?)
}

pub fn head(a: ScaleArgs) -> Result<ExitCode> {
    print(&bench::head::run(&bench::head::Options { scale: a.scale })?)
}

pub fn server(a: ScaleArgs) -> Result<ExitCode> {
    print(&bench::server::run(&bench::server::Options { scale: a.scale })?)
}

pub fn transport(a: TransportArgs) -> Result<ExitCode> {
    print(&bench::transport::run(&bench::transport::Options {
        rate_messages: a.rate_messages as usize,
        rate_hz: a.rate_hz,
        burst_messages: a.burst_messages as usize,
        codec_iterations: a.codec_iterations as usize,
    })?)
}

pub fn fuse(a: ScaleArgs) -> Result<ExitCode> {
    print(&bench::fuse::run(&bench::fuse::Options { scale: a.scale })?)
}

pub fn grid(a: ScaleArgs) -> Result<ExitCode> {
    print(&bench::grid::run(a.scale))
}
