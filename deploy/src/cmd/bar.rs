//! Progress bars for long commands (`sim`, `experiment`): drawn on standard error only when it
//! is a terminal, so piped or redirected output stays quiet.

use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::sync::Mutex;

/// Whether bars are shown at all: standard error is a terminal.
fn shown() -> bool {
    std::io::stderr().is_terminal()
}

/// A bar over `total` simulated seconds, or `None` when not on a terminal.
pub fn simulated_seconds(total: f64) -> Option<ProgressBar> {
    if !shown() || !total.is_finite() {
        return None;
    }
    let bar = ProgressBar::new(total.ceil() as u64);
    bar.set_style(
        ProgressStyle::with_template("{elapsed_precise} [{bar:30}] {pos}/{len} simulated s, {eta} left")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    Some(bar)
}

/// A counter of finished simulated runs (every experiment's methods and seeds), fed by
/// `lab::progress`; hidden when not on a terminal. Call once, before the study.
pub fn study_runs(label: &str) -> Option<ProgressBar> {
    if !shown() {
        return None;
    }
    let bar = ProgressBar::new_spinner();
    bar.set_style(
        ProgressStyle::with_template("{elapsed_precise} {spinner} {prefix}: {pos} runs done, last {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_spinner()),
    );
    bar.set_prefix(label.to_string());
    bar.enable_steady_tick(std::time::Duration::from_millis(200));
    let shared = Mutex::new(bar.clone());
    lab::progress::observe(move |step| {
        let lab::progress::Step::Run { method, seed } = step;
        if let Ok(bar) = shared.lock() {
            bar.set_message(format!("{method} (seed {seed})"));
            bar.inc(1);
        }
    });
    Some(bar)
}
