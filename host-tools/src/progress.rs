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

/// A counter of `len` `what` (e.g. "simulations") after `prefix`, with a
/// message the caller keeps current (e.g. the best score so far); a
/// spinner on the same line when `len` is not known (a search bounded by
/// wall time). Hidden like [`bar`].
pub fn counter(prefix: &str, what: &str, len: Option<u64>, json: bool) -> ProgressBar {
    if json || !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let counter = match len {
        Some(n) => ProgressBar::with_draw_target(Some(n), ProgressDrawTarget::stderr()),
        None => ProgressBar::new_spinner(),
    };
    let template = format!("{{prefix}} [{{bar:30}}] {{pos}}/{{len}} {what}, {{msg}} ({{elapsed}})");
    if let Ok(style) = ProgressStyle::with_template(&template) {
        counter.set_style(style.progress_chars("=> "));
    }
    counter.set_prefix(prefix.to_string());
    counter
}

/// A line on stderr for a person watching (what a long run is doing
/// now); nothing with `--json` or when stderr is not a terminal.
pub fn note(message: &str, json: bool) {
    if !json && std::io::stderr().is_terminal() {
        eprintln!("{message}");
    }
}
