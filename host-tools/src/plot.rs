//! The one plotting module: every picture `softjoint` writes is SVG built
//! here.
//!
//! Hand-written rather than `plotters`: plotters lays text out with a font
//! backend (system fonts through fontconfig, or a font file compiled in),
//! while an SVG can leave text to the viewer, so this writer needs neither
//! fonts nor system libraries, and the pictures stay a few kB of readable
//! XML.
//!
//! - [`Svg`]: a document in pixel coordinates with the few primitives the
//!   pictures use. Non-finite coordinates (and finite ones beyond a
//!   million pixels, an exploding simulation's) never reach the file: a
//!   polyline lifts its pen at them, a polygon with one is left out (and
//!   counted in [`Svg::skipped`]), text is escaped.
//! - [`line_charts`]: stacked charts of series against an x axis, each with
//!   its own axis labels and legend (time series, μ(F) per generation, fit
//!   curves).
//! - [`shape_panels`]: outlines and point sets drawn to one equal-aspect
//!   scale in a grid of panels (contours of tracked objects and their
//!   fits, frame by frame).
//! - [`false_colour`]: the colour ramp of the seed 002 damping images.
//! - [`panel_grid`]: a grid of equal-aspect 2D views sharing one scale
//!   (projected 3D shapes, animation frame strips), each drawn in painter's
//!   order so that a rope's upper strand hides the lower one at a crossing.
use std::fmt::Write as _;

/// An SVG document under construction, in pixels, origin top left.
pub struct Svg {
    body: String,
    width: f64,
    height: f64,
    skipped: usize,
}

/// How a line is drawn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stroke<'a> {
    /// Colour (CSS).
    pub colour: &'a str,
    /// Width (px).
    pub width: f64,
    /// Dashed.
    pub dashed: bool,
}

impl<'a> Stroke<'a> {
    /// A solid line.
    pub fn solid(colour: &'a str, width: f64) -> Self {
        Self {
            colour,
            width,
            dashed: false,
        }
    }
    /// A dashed line.
    pub fn dashed(colour: &'a str, width: f64) -> Self {
        Self {
            colour,
            width,
            dashed: true,
        }
    }
    fn attributes(&self) -> String {
        let dash = if self.dashed {
            r#" stroke-dasharray="6,4""#
        } else {
            ""
        };
        format!(
            r#"stroke="{}" stroke-width="{}"{dash}"#,
            escape(self.colour),
            self.width
        )
    }
}

/// Horizontal anchoring of a text.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Anchor {
    /// Text starts at x.
    Start,
    /// Text is centred on x.
    Middle,
    /// Text ends at x.
    End,
}

/// Escapes text for SVG.
fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Largest |coordinate| drawn (px): beyond it a point is left out like a
/// non-finite one. An exploding simulation gives finite coordinates of
/// 1e200 px, which viewers cannot render and no page can show; a million
/// pixels is far outside any picture here (estimate).
const MAX_COORDINATE_PX: f64 = 1e6;

fn drawable(v: f64) -> bool {
    v.is_finite() && v.abs() <= MAX_COORDINATE_PX
}

fn finite(p: &(f64, f64)) -> bool {
    drawable(p.0) && drawable(p.1)
}

impl Svg {
    /// An empty white page of `width` × `height` px.
    pub fn new(width: f64, height: f64) -> Self {
        let mut body = String::new();
        let _ = writeln!(body, r#"<rect width="100%" height="100%" fill="white"/>"#);
        Self {
            body,
            width,
            height,
            skipped: 0,
        }
    }

    /// Shapes left out because a coordinate was not finite.
    pub fn skipped(&self) -> usize {
        self.skipped
    }

    /// A text at (x, y) of `size` px.
    pub fn text(&mut self, x: f64, y: f64, size: f64, anchor: Anchor, text: &str) {
        self.text_styled(x, y, size, anchor, "", text);
    }

    /// A text with extra SVG attributes (`fill="…"`, `font-weight="…"`).
    pub fn text_styled(
        &mut self,
        x: f64,
        y: f64,
        size: f64,
        anchor: Anchor,
        style: &str,
        text: &str,
    ) {
        if !finite(&(x, y)) {
            self.skipped += 1;
            return;
        }
        let anchor = match anchor {
            Anchor::Start => "start",
            Anchor::Middle => "middle",
            Anchor::End => "end",
        };
        let _ = writeln!(
            self.body,
            r#"<text x="{x:.1}" y="{y:.1}" font-size="{size}" text-anchor="{anchor}" {style}>{}</text>"#,
            escape(text)
        );
    }

    /// A text rotated 90° anticlockwise about (x, y) (a y-axis label).
    pub fn vertical_text(&mut self, x: f64, y: f64, size: f64, text: &str) {
        let _ = writeln!(
            self.body,
            r#"<text transform="translate({x:.1},{y:.1}) rotate(-90)" font-size="{size}" text-anchor="middle">{}</text>"#,
            escape(text)
        );
    }

    /// A straight line.
    pub fn line(&mut self, from: (f64, f64), to: (f64, f64), stroke: Stroke<'_>) {
        if !(finite(&from) && finite(&to)) {
            self.skipped += 1;
            return;
        }
        let _ = writeln!(
            self.body,
            r#"<line x1="{:.1}" y1="{:.1}" x2="{:.1}" y2="{:.1}" {}/>"#,
            from.0,
            from.1,
            to.0,
            to.1,
            stroke.attributes()
        );
    }

    /// An open polyline; the pen lifts at every non-finite point.
    pub fn polyline(&mut self, points: impl IntoIterator<Item = (f64, f64)>, stroke: Stroke<'_>) {
        let mut d = String::new();
        let mut pen_up = true;
        for p in points {
            if !finite(&p) {
                pen_up = true;
                continue;
            }
            let _ = write!(
                d,
                "{}{:.1},{:.1} ",
                if pen_up { "M" } else { "L" },
                p.0,
                p.1
            );
            pen_up = false;
        }
        if !d.is_empty() {
            // Thick lines (a rope drawn at its diameter) get round joins
            // and caps so consecutive pieces join without notches.
            let round = if stroke.width >= 4.0 {
                r#" stroke-linecap="round" stroke-linejoin="round""#
            } else {
                ""
            };
            let _ = writeln!(
                self.body,
                r#"<path d="{}" fill="none" {}{round}/>"#,
                d.trim_end(),
                stroke.attributes()
            );
        }
    }

    /// Line segments drawn as one path (a mesh's edges).
    pub fn segments(
        &mut self,
        segments: impl IntoIterator<Item = ((f64, f64), (f64, f64))>,
        stroke: Stroke<'_>,
    ) {
        let mut d = String::new();
        for (a, b) in segments {
            if finite(&a) && finite(&b) {
                let _ = write!(d, "M{:.1},{:.1}L{:.1},{:.1}", a.0, a.1, b.0, b.1);
            } else {
                self.skipped += 1;
            }
        }
        if !d.is_empty() {
            let _ = writeln!(
                self.body,
                r#"<path d="{d}" fill="none" {}/>"#,
                stroke.attributes()
            );
        }
    }

    /// A closed, filled polygon; left out if any point is not finite.
    pub fn polygon(&mut self, points: &[(f64, f64)], fill: &str, stroke: Stroke<'_>) {
        if points.is_empty() || !points.iter().all(finite) {
            self.skipped += 1;
            return;
        }
        let pts: Vec<String> = points
            .iter()
            .map(|(x, y)| format!("{x:.1},{y:.1}"))
            .collect();
        let _ = writeln!(
            self.body,
            r#"<polygon points="{}" fill="{}" {}/>"#,
            pts.join(" "),
            escape(fill),
            stroke.attributes()
        );
    }

    /// A circle outline.
    pub fn circle(&mut self, centre: (f64, f64), radius: f64, stroke: Stroke<'_>) {
        if !(finite(&centre) && drawable(radius)) {
            self.skipped += 1;
            return;
        }
        let _ = writeln!(
            self.body,
            r#"<circle cx="{:.1}" cy="{:.1}" r="{radius:.1}" fill="none" {}/>"#,
            centre.0,
            centre.1,
            stroke.attributes()
        );
    }

    /// An arrow from `from` to `to` with a head of `head` px (vector
    /// fields); left out if a coordinate is not finite, drawn as a dot when
    /// shorter than a pixel.
    pub fn arrow(&mut self, from: (f64, f64), to: (f64, f64), head: f64, stroke: Stroke<'_>) {
        if !(finite(&from) && finite(&to) && head.is_finite()) {
            self.skipped += 1;
            return;
        }
        let (dx, dy) = (to.0 - from.0, to.1 - from.1);
        let len = (dx * dx + dy * dy).sqrt();
        if len < 1.0 {
            let _ = writeln!(
                self.body,
                r#"<circle cx="{:.1}" cy="{:.1}" r="{:.1}" fill="{}"/>"#,
                from.0,
                from.1,
                0.5 * stroke.width.max(1.0),
                escape(stroke.colour)
            );
            return;
        }
        let (ux, uy) = (dx / len, dy / len);
        let h = head.min(0.5 * len);
        let left = (to.0 - h * (ux + 0.5 * uy), to.1 - h * (uy - 0.5 * ux));
        let right = (to.0 - h * (ux - 0.5 * uy), to.1 - h * (uy + 0.5 * ux));
        let _ = writeln!(
            self.body,
            r#"<path d="M{:.1},{:.1}L{:.1},{:.1}M{:.1},{:.1}L{:.1},{:.1}L{:.1},{:.1}" fill="none" {}/>"#,
            from.0,
            from.1,
            to.0,
            to.1,
            left.0,
            left.1,
            to.0,
            to.1,
            right.0,
            right.1,
            stroke.attributes()
        );
    }

    /// A filled circle (a marker).
    pub fn dot(&mut self, centre: (f64, f64), radius: f64, fill: &str) {
        if !(finite(&centre) && radius.is_finite()) {
            self.skipped += 1;
            return;
        }
        let _ = writeln!(
            self.body,
            r#"<circle cx="{:.1}" cy="{:.1}" r="{radius:.1}" fill="{}"/>"#,
            centre.0,
            centre.1,
            escape(fill)
        );
    }

    /// A rectangle.
    pub fn rect(&mut self, x: f64, y: f64, w: f64, h: f64, fill: &str, stroke: Option<Stroke<'_>>) {
        if ![x, y, w, h].into_iter().all(drawable) {
            self.skipped += 1;
            return;
        }
        let stroke = stroke.map(|s| s.attributes()).unwrap_or_default();
        let _ = writeln!(
            self.body,
            r#"<rect x="{x:.1}" y="{y:.1}" width="{w:.1}" height="{h:.1}" fill="{}" {stroke}/>"#,
            escape(fill)
        );
    }

    /// The document.
    pub fn finish(self) -> String {
        format!(
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w:.0}\" height=\"{h:.0}\" viewBox=\"0 0 {w:.0} {h:.0}\" font-family=\"sans-serif\">\n{}</svg>\n",
            self.body,
            w = self.width,
            h = self.height
        )
    }
}

/// One line of a chart.
pub struct Series {
    /// Legend text.
    pub label: String,
    /// Colour (CSS).
    pub colour: &'static str,
    /// Dashed line.
    pub dashed: bool,
    /// (x, y) points; non-finite ones break the line.
    pub points: Vec<(f64, f64)>,
}

impl Series {
    /// A series of `y` values against shared `x` values.
    pub fn over(
        label: impl Into<String>,
        colour: &'static str,
        dashed: bool,
        x: &[f64],
        y: &[f64],
    ) -> Self {
        Self {
            label: label.into(),
            colour,
            dashed,
            points: x.iter().copied().zip(y.iter().copied()).collect(),
        }
    }
}

/// One chart: a title, axis labels that say what is plotted, and series.
pub struct Chart {
    /// Title.
    pub title: String,
    /// What the x axis is, with its unit (`time (s)`, `generation`).
    pub x_label: String,
    /// What the y axis is, with its unit.
    pub y_label: String,
    /// Lines.
    pub series: Vec<Series>,
}

const CHART_W: f64 = 960.0;
const CHART_H: f64 = 300.0;
const ML: f64 = 70.0;
const MR: f64 = 190.0;
const MT: f64 = 30.0;
const MB: f64 = 42.0;

/// Round tick values covering `lo..=hi`, about `n` of them.
pub fn nice_ticks(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    if !(lo.is_finite() && hi.is_finite()) || n == 0 {
        return Vec::new();
    }
    let span = (hi - lo).max(1e-12);
    let raw = span / n as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|s| span / s <= n as f64)
        .unwrap_or(10.0 * mag);
    let mut out = Vec::new();
    let mut k = (lo / step).ceil();
    while k * step <= hi + step * 1e-9 && out.len() < 4 * n + 2 {
        out.push(k * step);
        k += 1.0;
    }
    out
}

fn format_tick(v: f64) -> String {
    let a = v.abs();
    if a < 1e-12 {
        "0".into()
    } else if !(1e-3..1e6).contains(&a) {
        format!("{v:.1e}")
    } else if v.fract().abs() < 1e-9 {
        format!("{v:.0}")
    } else {
        format!("{v:.3}")
            .trim_end_matches('0')
            .trim_end_matches('.')
            .to_string()
    }
}

/// The finite range of `values`, padded by 5 %; (0, 1) when there is none.
fn range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
            (l.min(v), h.max(v))
        });
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    let pad = ((hi - lo) * 0.05)
        .max(1e-9 * lo.abs().max(hi.abs()))
        .max(1e-12);
    (lo - pad, hi + pad)
}

/// Charts stacked vertically, one per row, each over its own x range.
pub fn line_charts(charts: &[Chart]) -> Svg {
    let mut svg = Svg::new(CHART_W, CHART_H * charts.len().max(1) as f64);
    for (ci, chart) in charts.iter().enumerate() {
        let oy = ci as f64 * CHART_H;
        let points = || chart.series.iter().flat_map(|s| s.points.iter());
        let (x0, x1) = range(points().map(|p| p.0));
        let (y0, y1) = range(points().map(|p| p.1));
        let (pw, ph) = (CHART_W - ML - MR, CHART_H - MT - MB);
        let px = |x: f64| ML + (x - x0) / (x1 - x0) * pw;
        let py = |y: f64| oy + MT + (y1 - y) / (y1 - y0) * ph;
        svg.text_styled(
            ML,
            oy + 18.0,
            14.0,
            Anchor::Start,
            r#"font-weight="bold""#,
            &chart.title,
        );
        let grid = Stroke::solid("#e0e0e0", 1.0);
        for y in nice_ticks(y0, y1, 6) {
            svg.line((ML, py(y)), (ML + pw, py(y)), grid);
            svg.text(ML - 6.0, py(y) + 4.0, 12.0, Anchor::End, &format_tick(y));
        }
        for x in nice_ticks(x0, x1, 10) {
            svg.line((px(x), oy + MT), (px(x), oy + MT + ph), grid);
            svg.text(
                px(x),
                oy + MT + ph + 16.0,
                12.0,
                Anchor::Middle,
                &format_tick(x),
            );
        }
        svg.rect(
            ML,
            oy + MT,
            pw,
            ph,
            "none",
            Some(Stroke::solid("#333", 1.0)),
        );
        svg.text(
            ML + pw / 2.0,
            oy + CHART_H - 6.0,
            12.0,
            Anchor::Middle,
            &chart.x_label,
        );
        svg.vertical_text(16.0, oy + MT + ph / 2.0, 12.0, &chart.y_label);
        for (li, s) in chart.series.iter().enumerate() {
            let stroke = Stroke {
                colour: s.colour,
                width: 1.4,
                dashed: s.dashed,
            };
            svg.polyline(s.points.iter().map(|&(x, y)| (px(x), py(y))), stroke);
            let ly = oy + MT + 14.0 + 18.0 * li as f64;
            svg.line(
                (ML + pw + 10.0, ly),
                (ML + pw + 34.0, ly),
                Stroke {
                    width: 2.0,
                    ..stroke
                },
            );
            svg.text(ML + pw + 40.0, ly + 4.0, 12.0, Anchor::Start, &s.label);
        }
    }
    svg
}

/// How a [`Shape`] is drawn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ShapeStyle {
    /// A closed outline.
    Closed {
        /// Line width, px.
        width: f64,
        /// Dashed.
        dashed: bool,
    },
    /// An open polyline.
    Open {
        /// Line width, px.
        width: f64,
        /// Dashed.
        dashed: bool,
    },
    /// One dot per point.
    Dots {
        /// Dot radius, px.
        radius: f64,
    },
}

/// Points drawn in a panel, in data coordinates.
pub struct Shape {
    /// The points.
    pub points: Vec<(f64, f64)>,
    /// Colour (CSS).
    pub colour: &'static str,
    /// How.
    pub style: ShapeStyle,
}

/// One panel of [`shape_panels`].
pub struct Panel {
    /// Caption under the panel.
    pub caption: String,
    /// What to draw, in order (later on top).
    pub shapes: Vec<Shape>,
}

/// Width of one shape panel, px.
const PANEL_W: f64 = 240.0;

/// Panels in a grid of up to `columns` columns, all drawn to one
/// equal-aspect scale fitted to every finite point; `y_up` puts +y at the
/// top (physics) rather than the bottom (image rows). `legend` is written
/// at the foot.
pub fn shape_panels(
    title: &str,
    panels: &[Panel],
    columns: usize,
    y_up: bool,
    legend: &str,
) -> Svg {
    let pts = || {
        panels
            .iter()
            .flat_map(|p| p.shapes.iter().flat_map(|s| s.points.iter()))
            .filter(|p| finite(p))
    };
    let (x0, x1) = range(pts().map(|p| p.0));
    let (y0, y1) = range(pts().map(|p| p.1));
    let scale = (PANEL_W / (x1 - x0)).min(PANEL_W / (y1 - y0));
    let panel_h = (y1 - y0) * scale;
    let cols = columns.clamp(1, panels.len().max(1));
    let rows = panels.len().div_ceil(cols).max(1);
    let (top, gap, caption) = (36.0, 12.0, 20.0);
    let width = gap + cols as f64 * (PANEL_W + gap);
    let height = top + rows as f64 * (panel_h + caption + gap) + 24.0;
    let mut svg = Svg::new(width.max(480.0), height);
    svg.text_styled(
        gap,
        22.0,
        14.0,
        Anchor::Start,
        r#"font-weight="bold""#,
        title,
    );
    for (k, panel) in panels.iter().enumerate() {
        let ox = gap + (k % cols) as f64 * (PANEL_W + gap);
        let oy = top + (k / cols) as f64 * (panel_h + caption + gap);
        let tx = |p: &(f64, f64)| {
            let y = if y_up { y1 - p.1 } else { p.1 - y0 };
            (ox + (p.0 - x0) * scale, oy + y * scale)
        };
        svg.rect(
            ox,
            oy,
            PANEL_W,
            panel_h,
            "none",
            Some(Stroke::solid("#ccc", 1.0)),
        );
        for shape in &panel.shapes {
            let screen: Vec<(f64, f64)> = shape.points.iter().map(tx).collect();
            match shape.style {
                ShapeStyle::Closed { width, dashed } => {
                    let mut closed = screen.clone();
                    if let Some(&first) = screen.first() {
                        closed.push(first);
                    }
                    svg.polyline(
                        closed,
                        Stroke {
                            colour: shape.colour,
                            width,
                            dashed,
                        },
                    );
                }
                ShapeStyle::Open { width, dashed } => {
                    svg.polyline(
                        screen,
                        Stroke {
                            colour: shape.colour,
                            width,
                            dashed,
                        },
                    );
                }
                ShapeStyle::Dots { radius } => {
                    for p in screen {
                        svg.dot(p, radius, shape.colour);
                    }
                }
            }
        }
        svg.text(ox, oy + panel_h + 15.0, 12.0, Anchor::Start, &panel.caption);
    }
    svg.text_styled(
        gap,
        height - 8.0,
        12.0,
        Anchor::Start,
        r##"fill="#555""##,
        legend,
    );
    svg
}

/// Blue (0) → cyan → green → yellow → red (1), the seed 002 Fig. 9 ramp;
/// non-finite values are blue.
pub fn false_colour(t: f64) -> (u8, u8, u8) {
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let ramp = |x: f64| (255.0 * x.clamp(0.0, 1.0)).round() as u8;
    (
        ramp(2.0 * t - 1.0),
        ramp(1.0 - (2.0 * t - 1.0).abs()),
        ramp(1.0 - 2.0 * t),
    )
}

/// One stroke of a [`ViewPanel`], in world units.
#[derive(Debug, Clone, PartialEq)]
pub struct PanelStroke {
    /// Polyline, world coordinates (x right, y up).
    pub points: Vec<(f64, f64)>,
    /// Colour (CSS).
    pub colour: String,
    /// Line width in world units (a rope's diameter), or in px if
    /// `width_in_px`.
    pub width: f64,
    pub width_in_px: bool,
    /// Draw a white halo under the line (crossings read as over/under).
    pub halo: bool,
}

/// One view of a [`panel_grid`].
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ViewPanel {
    pub title: String,
    /// Axis names, e.g. ("x (m)", "y (m)").
    pub axes: (String, String),
    /// Drawn in order: later strokes on top.
    pub strokes: Vec<PanelStroke>,
    /// Markers: position, colour, label.
    pub markers: Vec<((f64, f64), String, String)>,
}

/// A panel title's font size: 13 px, or smaller so that the title stays
/// within `width_px` (bold sans-serif glyphs average about 0.6 em), so a
/// long title (a shape marked UNVERIFIED, say) never runs into the next
/// panel's.
fn title_font_px(title: &str, width_px: f64) -> f64 {
    let chars = title.chars().count().max(1) as f64;
    (width_px / (0.6 * chars)).clamp(8.0, 13.0)
}

/// Panels in a grid of `columns`, each `size_px` square, all at one scale
/// (the largest extent of any panel, padded), equal aspect; a scale bar
/// says how long `scale_bar` world units are.
pub fn panel_grid(
    panels: &[ViewPanel],
    columns: usize,
    size_px: f64,
    scale_bar: (f64, &str),
    shared_window: bool,
) -> Svg {
    let columns = columns.max(1);
    let rows = panels.len().div_ceil(columns).max(1);
    let head = 22.0;
    let foot = 18.0;
    let (w, h) = (
        size_px * columns as f64,
        (size_px + head + foot) * rows as f64 + 24.0,
    );
    let mut svg = Svg::new(w, h);
    let (extent, centres) = view_windows(panels, shared_window);
    let scale = (size_px - 30.0) / (extent * 1.08);
    for (k, (p, &centre)) in panels.iter().zip(&centres).enumerate() {
        let (col, row) = (k % columns, k / columns);
        let frame = ViewFrame {
            ox: col as f64 * size_px,
            oy: row as f64 * (size_px + head + foot),
            size_px,
            head,
            scale,
            centre,
        };
        frame.draw(&mut svg, p);
    }
    let (len, label) = scale_bar;
    if len.is_finite() && len > 0.0 {
        let y = h - 10.0;
        svg.line(
            (10.0, y),
            (10.0 + len * scale, y),
            Stroke::solid("#333", 2.0),
        );
        svg.text(16.0 + len * scale, y + 4.0, 11.0, Anchor::Start, label);
    }
    svg
}

/// The bounding box `(x0, x1, y0, y1)` of the finite `points`; none when
/// there is no finite point.
fn finite_bounds<'a>(points: impl Iterator<Item = &'a (f64, f64)>) -> Option<(f64, f64, f64, f64)> {
    let (mut x0, mut x1, mut y0, mut y1) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for q in points.filter(|q| finite(q)) {
        x0 = x0.min(q.0);
        x1 = x1.max(q.0);
        y0 = y0.min(q.1);
        y1 = y1.max(q.1);
    }
    x0.is_finite().then_some((x0, x1, y0, y1))
}

/// The windows of a [`panel_grid`]: one extent for all (world units; the
/// largest of any panel) and each panel's centre, that of its own strokes
/// and markers (the unit square for an empty panel). With
/// `shared_window`, every panel is centred on the union of all strokes,
/// and the extent is that union's.
fn view_windows(panels: &[ViewPanel], shared_window: bool) -> (f64, Vec<(f64, f64)>) {
    let mut extent: f64 = 1e-9;
    let mut centres = Vec::new();
    for p in panels {
        let pts = p
            .strokes
            .iter()
            .flat_map(|s| s.points.iter())
            .chain(p.markers.iter().map(|m| &m.0));
        let (x0, x1, y0, y1) = finite_bounds(pts).unwrap_or((0.0, 1.0, 0.0, 1.0));
        extent = extent.max(x1 - x0).max(y1 - y0);
        centres.push((0.5 * (x0 + x1), 0.5 * (y0 + y1)));
    }
    if shared_window {
        let strokes = panels
            .iter()
            .flat_map(|p| p.strokes.iter().flat_map(|s| s.points.iter()));
        if let Some((x0, x1, y0, y1)) = finite_bounds(strokes) {
            extent = (x1 - x0).max(y1 - y0);
            centres.fill((0.5 * (x0 + x1), 0.5 * (y0 + y1)));
        }
    }
    (extent, centres)
}

/// Where one [`ViewPanel`] of a [`panel_grid`] goes: its top-left corner
/// (px), its square's side and the title band above it (px), the grid's
/// scale (px per world unit) and the world point at the square's centre.
struct ViewFrame {
    ox: f64,
    oy: f64,
    size_px: f64,
    head: f64,
    scale: f64,
    centre: (f64, f64),
}

impl ViewFrame {
    /// World point `q` on the page (y up in the world, down on the page).
    fn px(&self, q: (f64, f64)) -> (f64, f64) {
        let (cx, cy) = self.centre;
        (
            self.ox + self.size_px / 2.0 + (q.0 - cx) * self.scale,
            self.oy + self.head + self.size_px / 2.0 - (q.1 - cy) * self.scale,
        )
    }

    /// The panel: its frame, title and axis names, then its strokes and
    /// markers.
    fn draw(&self, svg: &mut Svg, p: &ViewPanel) {
        let (ox, oy, size_px, head) = (self.ox, self.oy, self.size_px, self.head);
        svg.rect(
            ox + 2.0,
            oy + head,
            size_px - 4.0,
            size_px,
            "none",
            Some(Stroke::solid("#ccc", 1.0)),
        );
        svg.text_styled(
            ox + 6.0,
            oy + 16.0,
            title_font_px(&p.title, size_px - 10.0),
            Anchor::Start,
            r#"font-weight="bold""#,
            &p.title,
        );
        svg.text(
            ox + size_px / 2.0,
            oy + head + size_px + 14.0,
            11.0,
            Anchor::Middle,
            &format!("→ {}   ↑ {}", p.axes.0, p.axes.1),
        );
        for s in &p.strokes {
            self.draw_stroke(svg, s);
        }
        for (q, colour, label) in &p.markers {
            let c = self.px(*q);
            svg.circle(c, 5.0, Stroke::solid(colour, 2.5));
            if !label.is_empty() {
                svg.text(c.0 + 7.0, c.1 - 7.0, 11.0, Anchor::Start, label);
            }
        }
    }

    /// One stroke, on its halo if it has one.
    fn draw_stroke(&self, svg: &mut Svg, s: &PanelStroke) {
        let width = if s.width_in_px {
            s.width
        } else {
            (s.width * self.scale).max(1.0)
        };
        let pts: Vec<(f64, f64)> = s.points.iter().map(|&q| self.px(q)).collect();
        if s.halo && pts.len() == 2 {
            // The halo covers the middle of a piece only, so that
            // consecutive pieces join without gaps while an upper
            // strand still cuts the one below.
            let (a, b) = (pts[0], pts[1]);
            let at = |t: f64| (a.0 + (b.0 - a.0) * t, a.1 + (b.1 - a.1) * t);
            svg.polyline([at(0.2), at(0.8)], Stroke::solid("white", width + 4.0));
        } else if s.halo && pts.len() > 2 {
            svg.polyline(
                pts[1..pts.len() - 1].iter().copied(),
                Stroke::solid("white", width + 4.0),
            );
        }
        svg.polyline(pts, Stroke::solid(&s.colour, width));
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_long_panel_title_shrinks_to_its_panel_and_a_short_one_keeps_13_px() {
        let short = "0.60L one-knot ∥y 3.55e-2 J ✓";
        assert_eq!(title_font_px(short, 270.0), 13.0);
        let long = "0.10L knot-free ∥y 3.65e-2 J UNVERIFIED";
        let px = title_font_px(long, 270.0);
        assert!(
            px < 13.0 && px * 0.6 * long.chars().count() as f64 <= 270.0 + 1e-9,
            "{px}"
        );
    }

    use super::*;

    #[test]
    fn non_finite_coordinates_never_reach_the_file() {
        let mut svg = Svg::new(100.0, 100.0);
        svg.polyline(
            [
                (0.0, 0.0),
                (f64::NAN, 1.0),
                (2.0, 2.0),
                (3.0, f64::INFINITY),
                (4.0, 1e200),
            ],
            Stroke::solid("red", 1.0),
        );
        svg.polygon(
            &[(0.0, 0.0), (1.0, f64::NAN), (2.0, 0.0)],
            "blue",
            Stroke::solid("black", 1.0),
        );
        svg.line((0.0, 0.0), (f64::NAN, 0.0), Stroke::solid("black", 1.0));
        svg.text(f64::INFINITY, 0.0, 12.0, Anchor::Start, "x");
        let skipped = svg.skipped();
        let out = svg.finish();
        assert!(!out.contains("NaN") && !out.contains("inf"), "{out}");
        assert_eq!(skipped, 3);
        assert!(out.contains(r#"d="M0.0,0.0 M2.0,2.0""#), "{out}");
    }

    #[test]
    fn charts_label_their_axes_and_escape_text() {
        let x = [0.0, 1.0, 2.0];
        let out = line_charts(&[Chart {
            title: "a < b & c".into(),
            x_label: "generation".into(),
            y_label: "μ(F)".into(),
            series: vec![Series::over("best", "#d22", false, &x, &[0.5, 0.9, 0.95])],
        }])
        .finish();
        assert!(out.contains(">generation<") && out.contains(">μ(F)<"));
        assert!(out.contains("a &lt; b &amp; c"));
        assert!(!out.contains("time (s)"));
    }

    #[test]
    fn shape_panels_share_one_scale_and_skip_non_finite_points() {
        let square = vec![(0.0, 0.0), (2.0, 0.0), (2.0, 1.0), (0.0, 1.0)];
        let panels = vec![
            Panel {
                caption: "a".into(),
                shapes: vec![Shape {
                    points: square.clone(),
                    colour: "#d22",
                    style: ShapeStyle::Closed {
                        width: 1.0,
                        dashed: false,
                    },
                }],
            },
            Panel {
                caption: "b & c".into(),
                shapes: vec![Shape {
                    points: vec![(1.0, 0.5), (f64::NAN, 0.0)],
                    colour: "#1f5fbf",
                    style: ShapeStyle::Dots { radius: 2.0 },
                }],
            },
        ];
        let svg = shape_panels("t", &panels, 2, true, "legend");
        assert_eq!(svg.skipped(), 1);
        let out = svg.finish();
        assert!(out.contains("b &amp; c") && out.contains("<circle") && !out.contains("NaN"));
        // The closed outline returns to its first point.
        let path = out.lines().find(|l| l.starts_with("<path")).unwrap();
        let d = path.split('"').nth(1).unwrap();
        let first = d.trim_start_matches('M').split(' ').next().unwrap();
        let last = d.rsplit('L').next().unwrap();
        assert_eq!(first, last, "{path}");
        // Equal aspect: the 2 × 1 square is twice as wide as high.
        let xs: Vec<f64> = d
            .split([' ', 'M', 'L'])
            .filter(|t| !t.is_empty())
            .map(|t| t.split(',').next().unwrap().parse().unwrap())
            .collect();
        let ys: Vec<f64> = d
            .split([' ', 'M', 'L'])
            .filter(|t| !t.is_empty())
            .map(|t| t.split(',').nth(1).unwrap().parse().unwrap())
            .collect();
        let w = xs.iter().cloned().fold(f64::MIN, f64::max)
            - xs.iter().cloned().fold(f64::MAX, f64::min);
        let h = ys.iter().cloned().fold(f64::MIN, f64::max)
            - ys.iter().cloned().fold(f64::MAX, f64::min);
        assert!((w / h - 2.0).abs() < 0.01, "{w} × {h}");
    }

    #[test]
    fn ticks_are_round_and_cover_the_range() {
        let t = nice_ticks(0.0, 1.0, 5);
        assert_eq!(t.len(), 6);
        for (v, want) in t.iter().zip([0.0, 0.2, 0.4, 0.6, 0.8, 1.0]) {
            assert!((v - want).abs() < 1e-12, "{t:?}");
        }
        assert!(nice_ticks(f64::NAN, 1.0, 5).is_empty());
        let t = nice_ticks(-3.3, 7.9, 10);
        assert!(t.first().unwrap() >= &-3.3 && t.last().unwrap() <= &7.9 && t.len() >= 5);
    }
}
