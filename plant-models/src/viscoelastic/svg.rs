//! Minimal SVG output: the fit plot (measured vs fitted force) and the
//! false-colour image of a per-vertex value over the mesh (the seed's
//! Fig. 9: red high, blue low). Hand-written, no dependency.
use super::mesh::{cross, dot, sub, SurfaceMesh};
use std::fmt::Write as _;

/// Blue (0) → cyan → green → yellow → red (1).
pub fn false_colour(t: f64) -> (u8, u8, u8) {
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let ramp = |x: f64| (255.0 * x.clamp(0.0, 1.0)).round() as u8;
    let r = ramp(2.0 * t - 1.0);
    let g = ramp(1.0 - (2.0 * t - 1.0).abs());
    let b = ramp(1.0 - 2.0 * t);
    (r, g, b)
}

/// Plot of measured and fitted force against time, with a caption.
pub fn fit_plot(time_s: &[f64], measured_n: &[f64], fitted_n: &[f64], caption: &str) -> String {
    let (w, h, m) = (720.0, 420.0, 50.0);
    let t0 = time_s.first().copied().unwrap_or(0.0);
    let t1 = time_s.last().copied().unwrap_or(1.0).max(t0 + 1e-12);
    let all = measured_n.iter().chain(fitted_n);
    let fmin = all.clone().copied().fold(f64::INFINITY, f64::min).min(0.0);
    let fmax = all
        .copied()
        .fold(f64::NEG_INFINITY, f64::max)
        .max(fmin + 1e-12);
    let x = |t: f64| m + (t - t0) / (t1 - t0) * (w - 2.0 * m);
    let y = |f: f64| h - m - (f - fmin) / (fmax - fmin) * (h - 2.0 * m);
    let path = |v: &[f64]| {
        let mut s = String::new();
        for (k, (&t, &f)) in time_s.iter().zip(v).enumerate() {
            let _ = write!(
                s,
                "{}{:.2},{:.2} ",
                if k == 0 { "M" } else { "L" },
                x(t),
                y(f)
            );
        }
        s
    };
    let mut s = String::new();
    let _ = writeln!(
        s,
        r##"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}">"##
    );
    let _ = writeln!(s, r##"<rect width="100%" height="100%" fill="white"/>"##);
    let _ = writeln!(
        s,
        r##"<path d="M{m},{m} L{m},{} L{},{}" fill="none" stroke="black"/>"##,
        h - m,
        w - m,
        h - m
    );
    let _ = writeln!(
        s,
        r##"<path d="{}" fill="none" stroke="#888" stroke-width="1"/>"##,
        path(measured_n)
    );
    let _ = writeln!(
        s,
        r##"<path d="{}" fill="none" stroke="#d00" stroke-width="2"/>"##,
        path(fitted_n)
    );
    let _ = writeln!(
        s,
        r##"<text x="{m}" y="20" font-family="sans-serif" font-size="13">{}</text>"##,
        escape(caption)
    );
    let _ = writeln!(
        s,
        r##"<text x="{}" y="{}" font-family="sans-serif" font-size="12" text-anchor="middle">time (s): {t0:.3} … {t1:.3}</text>"##,
        w / 2.0,
        h - 15.0
    );
    let _ = writeln!(
        s,
        r##"<text x="12" y="{}" font-family="sans-serif" font-size="12" transform="rotate(-90 12 {})" text-anchor="middle">force (N): {fmin:.3} … {fmax:.3}</text>"##,
        h / 2.0,
        h / 2.0
    );
    let _ = writeln!(
        s,
        r##"<text x="{}" y="40" font-family="sans-serif" font-size="12" fill="#888">measured</text><text x="{}" y="56" font-family="sans-serif" font-size="12" fill="#d00">fitted</text>"##,
        w - 130.0,
        w - 130.0
    );
    s.push_str("</svg>\n");
    s
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// False-colour image of `value` (one per mesh vertex) over the mesh,
/// orthographic view from `view_dir` (towards the object), painter's
/// algorithm, back faces culled. Colour scale from 0 to the maximum value.
pub fn false_colour_mesh(
    mesh: &SurfaceMesh,
    value: &[f64],
    view_dir: [f64; 3],
    caption: &str,
) -> String {
    let (w, h) = (640.0, 520.0);
    let d = {
        let l = dot(view_dir, view_dir).sqrt().max(1e-12);
        [view_dir[0] / l, view_dir[1] / l, view_dir[2] / l]
    };
    // Screen axes: right = d × z (or x if looking along z), up = right × d.
    let mut right = cross(d, [0.0, 0.0, 1.0]);
    if dot(right, right) < 1e-12 {
        right = [1.0, 0.0, 0.0];
    }
    let rl = dot(right, right).sqrt();
    let right = [right[0] / rl, right[1] / rl, right[2] / rl];
    let up = cross(right, d);
    let proj: Vec<(f64, f64, f64)> = mesh
        .vertices_m
        .iter()
        .map(|p| (dot(*p, right), dot(*p, up), dot(*p, d)))
        .collect();
    let (mut xmin, mut xmax, mut ymin, mut ymax) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for &(x, y, _) in &proj {
        xmin = xmin.min(x);
        xmax = xmax.max(x);
        ymin = ymin.min(y);
        ymax = ymax.max(y);
    }
    let scale = ((w - 80.0) / (xmax - xmin).max(1e-12)).min((h - 120.0) / (ymax - ymin).max(1e-12));
    let sx = |x: f64| 40.0 + (x - xmin) * scale;
    let sy = |y: f64| h - 80.0 - (y - ymin) * scale;
    let vmax = value
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    let mut tris: Vec<(f64, usize)> = mesh
        .triangles
        .iter()
        .enumerate()
        .filter(|(_, t)| {
            let [a, b, c] = t.map(|i| mesh.vertices_m[i]);
            dot(cross(sub(b, a), sub(c, a)), d) < 0.0 // facing the viewer
        })
        .map(|(k, t)| (t.iter().map(|&i| proj[i].2).sum::<f64>(), k))
        .collect();
    tris.sort_by(|a, b| b.0.total_cmp(&a.0)); // far first
    let mut s = String::new();
    let _ = writeln!(
        s,
        r##"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}">"##
    );
    let _ = writeln!(s, r##"<rect width="100%" height="100%" fill="white"/>"##);
    for (_, k) in tris {
        let t = mesh.triangles[k];
        let v = t
            .iter()
            .map(|&i| value.get(i).copied().unwrap_or(0.0))
            .sum::<f64>()
            / 3.0;
        let (r, g, b) = false_colour(if vmax > 0.0 { v / vmax } else { 0.0 });
        let pts: Vec<String> = t
            .iter()
            .map(|&i| format!("{:.1},{:.1}", sx(proj[i].0), sy(proj[i].1)))
            .collect();
        let _ = writeln!(
            s,
            r##"<polygon points="{}" fill="rgb({r},{g},{b})" stroke="#333" stroke-width="0.3"/>"##,
            pts.join(" ")
        );
    }
    for k in 0..10 {
        let (r, g, b) = false_colour(k as f64 / 9.0);
        let _ = writeln!(
            s,
            r##"<rect x="{}" y="{}" width="30" height="14" fill="rgb({r},{g},{b})"/>"##,
            40.0 + 30.0 * k as f64,
            h - 50.0
        );
    }
    let _ = writeln!(
        s,
        r##"<text x="40" y="{}" font-family="sans-serif" font-size="12">0</text><text x="340" y="{}" font-family="sans-serif" font-size="12">{vmax:.4e}</text>"##,
        h - 22.0,
        h - 22.0
    );
    let _ = writeln!(
        s,
        r##"<text x="40" y="24" font-family="sans-serif" font-size="14">{}</text>"##,
        escape(caption)
    );
    s.push_str("</svg>\n");
    s
}
