//! `ocelli deploy [SCENARIO] --out DIR`: render per-host configuration (scenario, systemd
//! units, `sysusers.d` snippet, `nodes.txt`, and over TCP the cluster's certificates) for
//! installing a scenario on real machines.

use super::common::ScenarioArg;
use crate::deploy::{Options, certs, render, uses_tls, write_plan};
use anyhow::{Context, Result};
use proto::scenario::{DEFAULT_SCENARIO_TOML, Scenario};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub scenario: ScenarioArg,
    /// Output directory: one subdirectory per host.
    #[arg(long)]
    pub out: PathBuf,
    /// `--source` for every camera unit, e.g. `v4l2:/dev/video0` on Pis with a camera.
    #[arg(long, default_value = "synthetic")]
    pub camera_source: String,
}

pub fn run(args: Args) -> Result<ExitCode> {
    let (scenario, text) = match &args.scenario.scenario {
        Some(p) => {
            let scenario = Scenario::load(p)?;
            let text = std::fs::read_to_string(p).with_context(|| format!("reading {}", p.display()))?;
            (scenario, text)
        }
        None => (Scenario::default_scenario(), DEFAULT_SCENARIO_TOML.to_string()),
    };
    let opts = Options {
        camera_source: args.camera_source,
    };
    let plan = render(&scenario, &text, &opts)?;
    write_plan(&plan, &args.out).with_context(|| format!("writing under {}", args.out.display()))?;
    if uses_tls(&scenario, plan.transport) {
        let issued = certs::issue(&scenario, &plan, &args.out)?;
        println!(
            "TLS: {} node certificate(s) from the CA in {} ({}); keep its ca.key off the nodes",
            issued.certificates,
            issued.ca_dir.display(),
            if issued.reused_ca {
                "existing CA reused"
            } else {
                "new CA"
            }
        );
    } else if plan.transport == proto::scenario::TransportKind::Tcp {
        tracing::warn!("the scenario says `insecure = true`: plain TCP between hosts, no certificates");
    }
    for host in &plan.hosts {
        let units = host
            .files
            .iter()
            .filter(|(p, _)| p.extension().is_some_and(|e| e == "service"))
            .count();
        println!(
            "{}: {} unit(s) in {}",
            host.host,
            units,
            args.out.join(&host.host).display()
        );
    }
    Ok(ExitCode::SUCCESS)
}
