//! A small SVG line-chart writer: stacked charts sharing a time axis.
//! Hand-written because the plots are simple and an SVG needs no fonts or
//! system libraries.
use std::fmt::Write as _;

/// One line.
pub struct Series {
    /// Legend text.
    pub label: String,
    /// Stroke colour.
    pub colour: &'static str,
    /// Dashed line.
    pub dashed: bool,
    /// Values, one per time point (non-finite values break the line).
    pub values: Vec<f64>,
}

impl Series {
    /// A series.
    pub fn new(label: String, colour: &'static str, dashed: bool, values: Vec<f64>) -> Self {
        Self {
            label,
            colour,
            dashed,
            values,
        }
    }
}

/// One chart.
pub struct Chart {
    /// Title.
    pub title: String,
    /// Y axis label.
    pub y_label: String,
    /// Lines.
    pub series: Vec<Series>,
}

const W: f64 = 960.0;
const H: f64 = 300.0;
const ML: f64 = 70.0;
const MR: f64 = 170.0;
const MT: f64 = 30.0;
const MB: f64 = 40.0;

fn nice_ticks(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    let span = (hi - lo).max(1e-9);
    let raw = span / n as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|s| span / s <= n as f64)
        .unwrap_or(10.0 * mag);
    let mut v = (lo / step).ceil() * step;
    let mut out = Vec::new();
    while v <= hi + 1e-9 {
        out.push(v);
        v += step;
    }
    out
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// Renders the charts stacked vertically over the common time axis `t`.
pub fn render(t: &[f64], charts: &[Chart]) -> String {
    let total_h = H * charts.len() as f64;
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{total_h}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(s, r#"<rect width="100%" height="100%" fill="white"/>"#);
    let (t0, t1) = (
        t.first().copied().unwrap_or(0.0),
        t.last().copied().unwrap_or(1.0).max(1e-9),
    );
    for (ci, chart) in charts.iter().enumerate() {
        let oy = ci as f64 * H;
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for v in chart
            .series
            .iter()
            .flat_map(|s| s.values.iter())
            .filter(|v| v.is_finite())
        {
            lo = lo.min(*v);
            hi = hi.max(*v);
        }
        if !lo.is_finite() {
            (lo, hi) = (0.0, 1.0);
        }
        let pad = ((hi - lo) * 0.05).max(0.1);
        (lo, hi) = (lo - pad, hi + pad);
        let px = |x: f64| ML + (x - t0) / (t1 - t0).max(1e-9) * (W - ML - MR);
        let py = |y: f64| oy + MT + (hi - y) / (hi - lo) * (H - MT - MB);
        let _ = writeln!(
            s,
            r#"<text x="{ML}" y="{}" font-size="14" font-weight="bold">{}</text>"#,
            oy + 18.0,
            escape(&chart.title)
        );
        for y in nice_ticks(lo, hi, 6) {
            let (x2, yy, tx) = (W - MR, py(y), ML - 6.0);
            let _ = writeln!(
                s,
                r##"<line x1="{ML}" x2="{x2}" y1="{yy:.1}" y2="{yy:.1}" stroke="#e0e0e0"/><text x="{tx}" y="{:.1}" text-anchor="end">{}</text>"##,
                yy + 4.0,
                format_tick(y)
            );
        }
        for x in nice_ticks(t0, t1, 10) {
            let _ = writeln!(
                s,
                r##"<line x1="{0:.1}" x2="{0:.1}" y1="{1}" y2="{2}" stroke="#e0e0e0"/><text x="{0:.1}" y="{3}" text-anchor="middle">{4}</text>"##,
                px(x),
                oy + MT,
                oy + H - MB,
                oy + H - MB + 16.0,
                format_tick(x)
            );
        }
        let _ = writeln!(
            s,
            r##"<rect x="{ML}" y="{}" width="{}" height="{}" fill="none" stroke="#333"/>"##,
            oy + MT,
            W - ML - MR,
            H - MT - MB
        );
        let _ = writeln!(
            s,
            r#"<text x="{}" y="{}" text-anchor="middle">time (s)</text>"#,
            ML + (W - ML - MR) / 2.0,
            oy + H - 6.0
        );
        let _ = writeln!(
            s,
            r#"<text transform="translate(16,{}) rotate(-90)" text-anchor="middle">{}</text>"#,
            oy + H / 2.0,
            escape(&chart.y_label)
        );
        for (li, series) in chart.series.iter().enumerate() {
            let mut d = String::new();
            let mut pen_up = true;
            for (x, y) in t.iter().zip(series.values.iter()) {
                if !y.is_finite() {
                    pen_up = true;
                    continue;
                }
                let _ = write!(
                    d,
                    "{}{:.1},{:.1} ",
                    if pen_up { "M" } else { "L" },
                    px(*x),
                    py(*y)
                );
                pen_up = false;
            }
            let dash = if series.dashed {
                r#" stroke-dasharray="6,4""#
            } else {
                ""
            };
            let _ = writeln!(
                s,
                r#"<path d="{d}" fill="none" stroke="{}" stroke-width="1.4"{dash}/>"#,
                series.colour
            );
            let ly = oy + MT + 14.0 + 18.0 * li as f64;
            let _ = writeln!(
                s,
                r#"<line x1="{0}" x2="{1}" y1="{ly}" y2="{ly}" stroke="{2}" stroke-width="2"{dash}/><text x="{3}" y="{4}">{5}</text>"#,
                W - MR + 10.0,
                W - MR + 34.0,
                series.colour,
                W - MR + 40.0,
                ly + 4.0,
                escape(&series.label)
            );
        }
    }
    s.push_str("</svg>\n");
    s
}

fn format_tick(v: f64) -> String {
    if v.abs() < 1e-9 {
        "0".into()
    } else if v.fract().abs() < 1e-9 {
        format!("{v:.0}")
    } else {
        format!("{v:.2}")
            .trim_end_matches('0')
            .trim_end_matches('.')
            .to_string()
    }
}
