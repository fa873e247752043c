//! PNG plots of the run-time-versus-error curves (feature `plots`).
//!
//! One chart per curve: wall time on x, total display-space MSE on a log
//! y axis, each point labelled with its setting, the paper's operating point
//! in red. Text needs a TrueType font: DejaVu Sans from Debian's
//! `fonts-dejavu-core` (or the file named by `FOOTLIGHT_FONT`).

use super::Report;
use plotters::prelude::*;
use std::path::Path;

const FONT_PATHS: [&str; 2] =
    ["/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf", "/usr/share/fonts/TTF/DejaVuSans.ttf"];

fn register_font() -> std::io::Result<()> {
    static DONE: std::sync::OnceLock<Result<(), String>> = std::sync::OnceLock::new();
    DONE.get_or_init(|| {
        let path = std::env::var("FOOTLIGHT_FONT")
            .ok()
            .or_else(|| FONT_PATHS.iter().find(|p| Path::new(p).exists()).map(|p| p.to_string()))
            .ok_or("no TrueType font found: install fonts-dejavu-core or set FOOTLIGHT_FONT")?;
        let bytes = std::fs::read(&path).map_err(|e| format!("{path}: {e}"))?;
        // The font must outlive every chart: leak it once per process.
        let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
        plotters::style::register_font("sans-serif", FontStyle::Normal, bytes)
            .map_err(|_| format!("{path}: not a usable font"))
    })
    .clone()
    .map_err(std::io::Error::other)
}

/// Writes `curve-<n>.png` for every curve of the report into `out`.
pub fn write(report: &Report, out: &Path) -> std::io::Result<()> {
    register_font()?;
    for (i, c) in report.curves.iter().enumerate() {
        let file = out.join(format!("curve-{}.png", i + 1));
        let err = |e: String| std::io::Error::other(format!("{}: {e}", file.display()));
        let root = BitMapBackend::new(&file, (800, 500)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
        let total = |p: &super::CurvePoint| p.mse.iter().sum::<f64>().max(1e-12);
        let xmax = c.points.iter().map(|p| p.ms).fold(0.0, f64::max) * 1.1 + 1e-3;
        let ymin = c.points.iter().map(total).fold(f64::INFINITY, f64::min) * 0.5;
        let ymax = c.points.iter().map(total).fold(0.0, f64::max) * 2.0;
        let mut chart = ChartBuilder::on(&root)
            .caption(format!("error vs time: {}", c.name), ("sans-serif", 20))
            .margin(15)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(0.0..xmax, (ymin..ymax).log_scale())
            .map_err(|e| err(e.to_string()))?;
        chart
            .configure_mesh()
            .x_desc("wall time (ms)")
            .y_desc("MSE (R+G+B, display)")
            .y_label_formatter(&|v| format!("{v:.1e}"))
            .draw()
            .map_err(|e| err(e.to_string()))?;
        chart
            .draw_series(LineSeries::new(c.points.iter().map(|p| (p.ms, total(p))), &BLUE))
            .map_err(|e| err(e.to_string()))?;
        for p in &c.points {
            let colour = if p.setting == c.paper_setting { RED } else { BLUE };
            chart
                .draw_series(std::iter::once(Circle::new((p.ms, total(p)), 4, colour.filled())))
                .map_err(|e| err(e.to_string()))?;
            chart
                .draw_series(std::iter::once(Text::new(
                    format!("{}", p.setting),
                    (p.ms, total(p)),
                    ("sans-serif", 13).into_font().color(&BLACK),
                )))
                .map_err(|e| err(e.to_string()))?;
        }
        root.present().map_err(|e| err(e.to_string()))?;
    }
    Ok(())
}
