//! Progress bars for runs that take more than a few seconds: drawn on
//! stderr when it is a terminal, hidden when it is not (a pipe, a file, CI)
//! and with `--json` (whose reader is a program).
use std::io::IsTerminal as _;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// A bar of `what` (e.g. "steps") whose length the caller sets; hidden
/// when `json` or when stderr is not a terminal.
pub fn bar(what: &str, json: bool) -> ProgressBar {
    if json || !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr());
    let template = format!(
        "{{elapsed_precise}} [{{bar:30}}] {{human_pos}}/{{human_len}} {what} (eta {{eta}})"
    );
    if let Ok(style) = ProgressStyle::with_template(&template) {
        bar.set_style(style.progress_chars("=> "));
    }
    bar
}

/// A bar that is never drawn (library callers, tests).
pub fn hidden() -> ProgressBar {
    ProgressBar::hidden()
}

/// A spinner with `message` for a phase whose length is not known, ticking
/// on its own; hidden like [`bar`].
pub fn spinner(message: &str, json: bool) -> ProgressBar {
    if json || !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let s = ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr());
    if let Ok(style) = ProgressStyle::with_template("{spinner} {msg} ({elapsed})") {
        s.set_style(style);
    }
    s.set_message(message.to_string());
    s.enable_steady_tick(std::time::Duration::from_millis(200));
    s
}
