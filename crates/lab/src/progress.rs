//! Progress of long commands (reports, dataset generation, benchmarks): a bar on stderr when
//! stderr is a terminal, nothing at all when it is piped or redirected, so logs and JSON output
//! stay clean.

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::time::Duration;

fn target() -> ProgressDrawTarget {
    target_for(std::io::stderr().is_terminal())
}

fn target_for(terminal: bool) -> ProgressDrawTarget {
    if terminal {
        ProgressDrawTarget::stderr()
    } else {
        ProgressDrawTarget::hidden()
    }
}

/// A bar over `len` steps of `what`; call `inc(1)` per step and `finish_and_clear()` at the end.
pub fn bar(len: u64, what: &str) -> ProgressBar {
    let pb = ProgressBar::with_draw_target(Some(len), target());
    if let Ok(style) =
        ProgressStyle::with_template("{msg} [{bar:32}] {pos}/{len} ({elapsed}, eta {eta})")
    {
        pb.set_style(style.progress_chars("=> "));
    }
    pb.set_message(what.to_string());
    pb
}

/// A spinner for work without a known length (redrawn a few times a second).
pub fn spinner(what: &str) -> ProgressBar {
    let pb = ProgressBar::with_draw_target(None, target());
    if let Ok(style) = ProgressStyle::with_template("{spinner} {msg} ({elapsed})") {
        pb.set_style(style);
    }
    pb.set_message(what.to_string());
    if !pb.is_hidden() {
        pb.enable_steady_tick(Duration::from_millis(200));
    }
    pb
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn drawn_on_a_terminal_only() {
        assert!(target_for(false).is_hidden());
        // (A terminal target is hidden too when the process has no terminal; that one is
        // checked end to end by tests/progress.rs with piped output.)
    }
}
