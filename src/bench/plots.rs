//! SVG plots of the run-time-versus-error curves, written by every
//! `footlight bench` run (`curve-<n>.svg` beside `report.md`).
//!
//! One chart per curve: wall time on x, total display-space MSE (R+G+B) on a
//! log y axis, each point labelled with its setting, the paper's operating
//! point in red. Written by hand rather than with plotters: a chart is one
//! polyline, a few circles and text elements, and SVG text is drawn by the
//! viewer, so no font file is needed at run time (plotters' bitmap backend
//! needed a TrueType font on the machine).

use super::{CurvePoint, Report};
use std::fmt::Write as _;
use std::path::Path;

const WIDTH: f64 = 800.0;
const HEIGHT: f64 = 500.0;
/// Plot area margins: left, right, top, bottom.
const MARGIN: (f64, f64, f64, f64) = (90.0, 30.0, 50.0, 60.0);

/// Total MSE of a point, floored so the log axis stays finite.
fn total(p: &CurvePoint) -> f64 {
    p.mse.iter().sum::<f64>().max(1e-12)
}

/// Escapes text for an SVG text node.
fn escape(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

/// One curve as a standalone SVG document.
pub fn curve_svg(c: &super::sweeps::Curve) -> String {
    let (l, r, t, b) = MARGIN;
    let (pw, ph) = (WIDTH - l - r, HEIGHT - t - b);
    let xmax = c.points.iter().map(|p| p.ms).filter(|v| v.is_finite()).fold(0.0, f64::max) * 1.1 + 1e-3;
    let lo = c.points.iter().map(total).filter(|v| v.is_finite()).fold(f64::INFINITY, f64::min);
    let hi = c.points.iter().map(total).filter(|v| v.is_finite()).fold(0.0, f64::max);
    let (lo, hi) = if lo.is_finite() && hi > 0.0 { (lo, hi) } else { (1e-6, 1.0) };
    // Whole decades around the data.
    let (d0, d1) = ((lo * 0.8).log10().floor(), (hi * 1.25).log10().ceil().max((lo * 0.8).log10().floor() + 1.0));
    let x = |ms: f64| l + pw * (ms / xmax).clamp(0.0, 1.0);
    let y = |mse: f64| t + ph * (1.0 - ((mse.log10() - d0) / (d1 - d0)).clamp(0.0, 1.0));
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" height="{HEIGHT}" viewBox="0 0 {WIDTH} {HEIGHT}" font-family="sans-serif">"#
    );
    let _ = writeln!(s, r#"<rect width="100%" height="100%" fill="white"/>"#);
    let _ = writeln!(
        s,
        r#"<text x="{}" y="28" font-size="18" text-anchor="middle">error vs time: {}</text>"#,
        WIDTH / 2.0,
        escape(&c.name)
    );
    // Axes, decade grid lines and labels.
    let _ = writeln!(s, r#"<rect x="{l}" y="{t}" width="{pw}" height="{ph}" fill="none" stroke="black"/>"#);
    for d in (d0 as i32)..=(d1 as i32) {
        let yy = y(10f64.powi(d));
        y_tick(&mut s, yy, &format!("1e{d}"));
    }
    for i in 0..=5 {
        let ms = xmax * i as f64 / 5.0;
        let xx = x(ms);
        x_tick(&mut s, xx, &format!("{ms:.0}"));
    }
    let _ = writeln!(
        s,
        r#"<text x="{}" y="{}" font-size="14" text-anchor="middle">wall time (ms)</text>"#,
        l + pw / 2.0,
        HEIGHT - 15.0
    );
    let _ = writeln!(
        s,
        r#"<text x="20" y="{0}" font-size="14" text-anchor="middle" transform="rotate(-90 20 {0})">MSE (R+G+B, display)</text>"#,
        t + ph / 2.0
    );
    let line: Vec<String> = c
        .points
        .iter()
        .filter(|p| p.ms.is_finite() && total(p).is_finite())
        .map(|p| format!("{:.1},{:.1}", x(p.ms), y(total(p))))
        .collect();
    let _ = writeln!(s, r#"<polyline points="{}" fill="none" stroke="blue" stroke-width="2"/>"#, line.join(" "));
    for p in c.points.iter().filter(|p| p.ms.is_finite() && total(p).is_finite()) {
        let colour = if p.setting == c.paper_setting { "red" } else { "blue" };
        let (px, py) = (x(p.ms), y(total(p)));
        let _ = writeln!(
            s,
            r#"<circle cx="{px:.1}" cy="{py:.1}" r="4" fill="{colour}"/><text x="{:.1}" y="{:.1}" font-size="12">{}</text>"#,
            px + 6.0,
            py - 6.0,
            p.setting
        );
    }
    let _ = writeln!(
        s,
        r#"<text x="{}" y="{}" font-size="12" fill="red" text-anchor="end">red: the paper's operating point ({} = {})</text>"#,
        l + pw - 6.0,
        t + 16.0,
        escape(&c.setting),
        c.paper_setting
    );
    s += "</svg>\n";
    s
}

/// One line of a [`series_svg`] chart.
pub struct Series {
    /// Its name in the legend.
    pub name: String,
    /// Its SVG colour.
    pub colour: String,
    /// (x, y) points in x order.
    pub points: Vec<(f64, f64)>,
}

/// Lines against a linear x and y (y from 0 to `y_max`, drawn dashed in
/// grey as the goal), with a legend: the festival section's emitters
/// ready over time.
pub fn series_svg(title: &str, x_label: &str, y_label: &str, y_max: f64, series: &[Series]) -> String {
    let (l, r, t, b) = MARGIN;
    let (pw, ph) = (WIDTH - l - r, HEIGHT - t - b);
    let finite = |v: &f64| v.is_finite();
    let xmax = series.iter().flat_map(|s| s.points.iter().map(|p| p.0)).filter(finite).fold(0.0, f64::max).max(1e-3);
    let ymax =
        series.iter().flat_map(|s| s.points.iter().map(|p| p.1)).filter(finite).fold(y_max, f64::max).max(1.0) * 1.05;
    let x = |v: f64| l + pw * (v / xmax).clamp(0.0, 1.0);
    let y = |v: f64| t + ph * (1.0 - (v / ymax).clamp(0.0, 1.0));
    let mut s = open_chart(title);
    for i in 0..=5 {
        let (xv, yv) = (xmax * i as f64 / 5.0, ymax * i as f64 / 5.0);
        let (xx, yy) = (x(xv), y(yv));
        x_tick(&mut s, xx, &format!("{xv:.0}"));
        y_tick(&mut s, yy, &format!("{yv:.0}"));
    }
    axis_titles(&mut s, x_label, y_label);
    let _ = writeln!(
        s,
        r#"<line x1="{l}" y1="{0:.1}" x2="{1}" y2="{0:.1}" stroke="grey" stroke-dasharray="6 4"/>"#,
        y(y_max),
        l + pw
    );
    for (i, se) in series.iter().enumerate() {
        let line: Vec<String> = se
            .points
            .iter()
            .filter(|p| p.0.is_finite() && p.1.is_finite())
            .map(|p| format!("{:.1},{:.1}", x(p.0), y(p.1)))
            .collect();
        let _ = writeln!(
            s,
            r#"<polyline points="{}" fill="none" stroke="{}" stroke-width="2"/>"#,
            line.join(" "),
            escape(&se.colour)
        );
        let ly = t + 18.0 + 16.0 * i as f64;
        let _ = writeln!(
            s,
            r#"<line x1="{0}" y1="{ly:.1}" x2="{1}" y2="{ly:.1}" stroke="{2}" stroke-width="3"/><text x="{3}" y="{4:.1}" font-size="12">{5}</text>"#,
            l + 10.0,
            l + 34.0,
            escape(&se.colour),
            l + 40.0,
            ly + 4.0,
            escape(&se.name)
        );
    }
    s += "</svg>\n";
    s
}

/// Writes `curve-<n>.svg` for every curve of the report into `out`.
pub fn write(report: &Report, out: &Path) -> std::io::Result<()> {
    for (i, c) in report.curves.iter().enumerate() {
        let file = out.join(format!("curve-{}.svg", i + 1));
        std::fs::write(&file, curve_svg(c)).map_err(|e| std::io::Error::other(format!("{}: {e}", file.display())))?;
    }
    Ok(())
}

/// Lines on log x and log y axes (decades gridded), with a legend and an
/// optional goal drawn dashed in grey: the error-against-time curves.
pub fn log_log_svg(title: &str, x_label: &str, y_label: &str, goal: Option<f64>, series: &[Series]) -> String {
    let (l, r, t, b) = MARGIN;
    let (pw, ph) = (WIDTH - l - r, HEIGHT - t - b);
    let points = || {
        series
            .iter()
            .flat_map(|s| s.points.iter())
            .filter(|p| p.0 > 0.0 && p.1 > 0.0 && p.0.is_finite() && p.1.is_finite())
    };
    let decade = |v: f64, up: bool| if up { v.log10().ceil() } else { v.log10().floor() };
    let (mut x0, mut x1) =
        (points().map(|p| p.0).fold(f64::INFINITY, f64::min), points().map(|p| p.0).fold(0.0, f64::max));
    let (mut y0, mut y1) =
        (points().map(|p| p.1).fold(f64::INFINITY, f64::min), points().map(|p| p.1).fold(0.0, f64::max));
    if let Some(g) = goal.filter(|g| *g > 0.0) {
        (y0, y1) = (y0.min(g), y1.max(g));
    }
    if !(x1 > 0.0 && x0.is_finite()) {
        (x0, x1) = (0.1, 10.0);
    }
    if !(y1 > 0.0 && y0.is_finite()) {
        (y0, y1) = (1e-5, 1e-1);
    }
    let (dx0, dx1) = (decade(x0, false), decade(x1, true).max(decade(x0, false) + 1.0));
    let (dy0, dy1) = (decade(y0, false), decade(y1, true).max(decade(y0, false) + 1.0));
    let x = |v: f64| l + pw * ((v.log10() - dx0) / (dx1 - dx0)).clamp(0.0, 1.0);
    let y = |v: f64| t + ph * (1.0 - ((v.log10() - dy0) / (dy1 - dy0)).clamp(0.0, 1.0));
    let mut s = open_chart(title);
    for d in (dx0 as i32)..=(dx1 as i32) {
        let xx = x(10f64.powi(d));
        x_tick(&mut s, xx, &format!("1e{d}"));
    }
    for d in (dy0 as i32)..=(dy1 as i32) {
        let yy = y(10f64.powi(d));
        y_tick(&mut s, yy, &format!("1e{d}"));
    }
    axis_titles(&mut s, x_label, y_label);
    if let Some(g) = goal.filter(|g| *g > 0.0) {
        let _ = writeln!(
            s,
            r#"<line x1="{l}" y1="{0:.1}" x2="{1}" y2="{0:.1}" stroke="grey" stroke-dasharray="6 4"/>"#,
            y(g),
            l + pw
        );
    }
    for (i, se) in series.iter().enumerate() {
        let kept: Vec<&(f64, f64)> =
            se.points.iter().filter(|p| p.0 > 0.0 && p.1 > 0.0 && p.0.is_finite() && p.1.is_finite()).collect();
        let line: Vec<String> = kept.iter().map(|p| format!("{:.1},{:.1}", x(p.0), y(p.1))).collect();
        let colour = escape(&se.colour);
        let _ =
            writeln!(s, r#"<polyline points="{}" fill="none" stroke="{colour}" stroke-width="2"/>"#, line.join(" "));
        for p in &kept {
            let _ = writeln!(s, r#"<circle cx="{:.1}" cy="{:.1}" r="3" fill="{colour}"/>"#, x(p.0), y(p.1));
        }
        let ly = t + 18.0 + 16.0 * i as f64;
        let _ = writeln!(
            s,
            r#"<line x1="{0}" y1="{ly:.1}" x2="{1}" y2="{ly:.1}" stroke="{colour}" stroke-width="3"/><text x="{2}" y="{3:.1}" font-size="12">{4}</text>"#,
            l + pw - 250.0,
            l + pw - 226.0,
            l + pw - 220.0,
            ly + 4.0,
            escape(&se.name)
        );
    }
    s += "</svg>\n";
    s
}

/// The plot area every chart draws in: (left, top, width, height).
fn plot_area() -> (f64, f64, f64, f64) {
    let (l, r, t, b) = MARGIN;
    (l, t, WIDTH - l - r, HEIGHT - t - b)
}

/// A chart's opening: the svg element, a white page, the title and the
/// frame of the plot area.
fn open_chart(title: &str) -> String {
    let (l, t, pw, ph) = plot_area();
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" height="{HEIGHT}" viewBox="0 0 {WIDTH} {HEIGHT}" font-family="sans-serif">"#
    );
    let _ = writeln!(s, r#"<rect width="100%" height="100%" fill="white"/>"#);
    let _ =
        writeln!(s, r#"<text x="{}" y="28" font-size="18" text-anchor="middle">{}</text>"#, WIDTH / 2.0, escape(title));
    let _ = writeln!(s, r#"<rect x="{l}" y="{t}" width="{pw}" height="{ph}" fill="none" stroke="black"/>"#);
    s
}

/// A vertical grid line at `xx` with its label under the plot area.
fn x_tick(s: &mut String, xx: f64, label: &str) {
    let (_, t, _, ph) = plot_area();
    let _ = writeln!(
        s,
        r##"<line x1="{xx:.1}" y1="{t}" x2="{xx:.1}" y2="{}" stroke="#ddd"/><text x="{xx:.1}" y="{}" font-size="12" text-anchor="middle">{label}</text>"##,
        t + ph,
        t + ph + 18.0
    );
}

/// A horizontal grid line at `yy` with its label left of the plot area.
fn y_tick(s: &mut String, yy: f64, label: &str) {
    let (l, _, pw, _) = plot_area();
    let _ = writeln!(
        s,
        r##"<line x1="{l}" y1="{yy:.1}" x2="{}" y2="{yy:.1}" stroke="#ddd"/><text x="{}" y="{:.1}" font-size="12" text-anchor="end">{label}</text>"##,
        l + pw,
        l - 6.0,
        yy + 4.0
    );
}

/// The axes' titles: `x_label` under the plot area, `y_label` turned along its left side.
fn axis_titles(s: &mut String, x_label: &str, y_label: &str) {
    let (l, t, pw, ph) = plot_area();
    let _ = writeln!(
        s,
        r#"<text x="{}" y="{}" font-size="14" text-anchor="middle">{}</text>"#,
        l + pw / 2.0,
        HEIGHT - 15.0,
        escape(x_label)
    );
    let _ = writeln!(
        s,
        r#"<text x="20" y="{0}" font-size="14" text-anchor="middle" transform="rotate(-90 20 {0})">{1}</text>"#,
        t + ph / 2.0,
        escape(y_label)
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bench::sweeps::Curve;

    #[test]
    fn svg_has_one_point_per_setting_and_marks_the_paper() {
        let points = [(1.0, 10.0, 1e-2), (2.0, 20.0, 1e-3), (4.0, 40.0, 2e-4)]
            .map(|(setting, ms, m)| CurvePoint { setting, ms, mse: [m, 0.0, 0.0] })
            .to_vec();
        let svg = curve_svg(&Curve::new("a <test>", "passes", 2.0, points));
        assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
        assert_eq!(svg.matches("<circle").count(), 3);
        assert_eq!(svg.matches(r#"fill="red""#).count(), 1 + 1, "one red point and the red legend");
        assert!(svg.contains("a &lt;test&gt;"));
        // Larger error is higher on the page (SVG's y grows downward).
        let ys: Vec<f64> = svg
            .lines()
            .filter(|l| l.starts_with("<circle"))
            .map(|l| l.split("cy=\"").nth(1).unwrap().split('"').next().unwrap().parse().unwrap())
            .collect();
        assert!(ys[0] < ys[1] && ys[1] < ys[2], "{ys:?}");
    }

    #[test]
    fn series_svg_has_a_line_per_series_and_scales_y_from_zero() {
        let a = Series { name: "a & b".into(), colour: "red".into(), points: vec![(0.0, 0.0), (10.0, 50.0)] };
        let b = Series { name: "c".into(), colour: "blue".into(), points: vec![(0.0, 100.0), (10.0, 100.0)] };
        let svg = series_svg("t", "x", "y", 100.0, &[a, b]);
        assert_eq!(svg.matches("<polyline").count(), 2);
        assert!(svg.contains("a &amp; b"));
        let coords = |n: usize| -> Vec<(f64, f64)> {
            let l = svg.lines().filter(|l| l.starts_with("<polyline")).nth(n).unwrap();
            l.split('"')
                .nth(1)
                .unwrap()
                .split(' ')
                .map(|p| {
                    let (x, y) = p.split_once(',').unwrap();
                    (x.parse().unwrap(), y.parse().unwrap())
                })
                .collect()
        };
        let (a, b) = (coords(0), coords(1));
        // y = 0 at the plot's bottom edge, larger y higher on the page; x from the left edge.
        assert_eq!(a[0], (MARGIN.0, HEIGHT - MARGIN.3));
        assert!(b[0].1 < a[1].1 && a[1].1 < a[0].1);
        assert_eq!(a[1].0, WIDTH - MARGIN.1);
    }
}
