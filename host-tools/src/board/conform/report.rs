//! The conformance report as text, JSON (the [`Report`] itself, through
//! `crate::output`) and JUnit XML for CI systems.

use std::fmt::Write as _;

use super::{Outcome, Report};

/// The report as a person reads it: one line per check, then the count.
pub fn text(r: &Report) -> String {
    let mut out = String::new();
    let ratio = r
        .clock_ratio
        .map_or("unmeasured".to_string(), |c| format!("{c:.2}× wall time"));
    let _ = writeln!(
        out,
        "softjoint conform: {} (docs/protocol.md v{}){}; board clock {ratio}",
        r.board,
        firmware::protocol::PROTOCOL_VERSION,
        if r.safe { ", safe mode" } else { "" }
    );
    for c in &r.checks {
        let (tag, detail) = match &c.outcome {
            Outcome::Pass(d) => ("PASS", d),
            Outcome::Fail(d) => ("FAIL", d),
            Outcome::Skip(d) => ("SKIP", d),
        };
        let _ = writeln!(
            out,
            "{tag}  {:<26} {:<16} {:>6.2} s  {}\n      {detail}",
            c.id, c.section, c.seconds, c.title
        );
    }
    let _ = writeln!(
        out,
        "{} passed, {} failed, {} skipped",
        r.passed, r.failed, r.skipped
    );
    out
}

/// `s` with XML's five special characters escaped.
fn xml(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for ch in s.chars() {
        match ch {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            // Control characters other than tab and newlines are not
            // allowed in XML 1.0.
            c if c.is_control() && !matches!(c, '\t' | '\n' | '\r') => out.push(' '),
            c => out.push(c),
        }
    }
    out
}

/// The report as a JUnit XML `testsuite` (one `testcase` per check, its
/// class the section; a skip is `<skipped>`, a failure `<failure>`).
pub fn junit(r: &Report) -> String {
    let total: f64 = r.checks.iter().map(|c| c.seconds).sum();
    let mut out = String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    let _ = writeln!(
        out,
        "<testsuite name=\"softjoint conform: {}\" tests=\"{}\" failures=\"{}\" errors=\"0\" skipped=\"{}\" time=\"{total:.3}\">",
        xml(&r.board),
        r.checks.len(),
        r.failed,
        r.skipped
    );
    for c in &r.checks {
        let _ = write!(
            out,
            "  <testcase classname=\"protocol.md {}\" name=\"{}\" time=\"{:.3}\">",
            xml(c.section),
            xml(c.id),
            c.seconds
        );
        match &c.outcome {
            Outcome::Pass(d) => {
                let _ = write!(out, "<system-out>{}</system-out>", xml(d));
            }
            Outcome::Fail(d) => {
                let _ = write!(
                    out,
                    "<failure message=\"{}\">{}: {}</failure>",
                    xml(d),
                    xml(c.title),
                    xml(d)
                );
            }
            Outcome::Skip(d) => {
                let _ = write!(out, "<skipped message=\"{}\"/>", xml(d));
            }
        }
        out.push_str("</testcase>\n");
    }
    out.push_str("</testsuite>\n");
    out
}
