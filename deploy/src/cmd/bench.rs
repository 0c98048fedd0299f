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
    #[arg(long, default_value_t = 200)]
    pub frames: usize,
    /// CPU to pin to.
    #[arg(long, default_value_t = 0)]
    pub cpu: usize,
}

#[derive(clap::Args, Debug)]
pub struct ScaleArgs {
    /// Print JSON (the only output format; accepted for symmetry with other commands).
    #[arg(long)]
    pub json: bool,
    /// Scale the repetition counts (1.0 = default).
    #[arg(long, default_value_t = 1.0)]
    pub scale: f64,
}

#[derive(clap::Args, Debug)]
pub struct TransportArgs {
    /// Print JSON (the only output format; accepted for symmetry with other commands).
    #[arg(long)]
    pub json: bool,
    /// Messages in the fixed-rate phase.
    #[arg(long, default_value_t = 300)]
    pub rate_messages: usize,
    /// Rate of the fixed-rate phase, Hz.
    #[arg(long, default_value_t = 30.0)]
    pub rate_hz: f64,
    /// Messages in the full-rate phase.
    #[arg(long, default_value_t = 20_000)]
    pub burst_messages: usize,
    /// Iterations per message kind for encode/decode costs.
    #[arg(long, default_value_t = 20_000)]
    pub codec_iterations: usize,
}

fn print(v: &serde_json::Value) -> Result<ExitCode> {
    println!("{}", serde_json::to_string_pretty(v)?);
    Ok(ExitCode::SUCCESS)
}

pub fn camera(a: CameraArgs) -> Result<ExitCode> {
    print(&bench::camera::run(&bench::camera::Options {
        frames: a.frames,
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
        rate_messages: a.rate_messages,
        rate_hz: a.rate_hz,
        burst_messages: a.burst_messages,
        codec_iterations: a.codec_iterations,
    })?)
}

pub fn grid(a: ScaleArgs) -> Result<ExitCode> {
    print(&bench::grid::run(a.scale))
}
