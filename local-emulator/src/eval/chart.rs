//! The charts of `hort eval`: time against RMSE on log-log axes, one panel per scene, one series
//! per method, the Pareto front ringed in black and joined by a thin black line.
//!
//! Drawn by `plotters` into an RGB buffer (pure Rust: its bitmap backend and `ab_glyph` with the
//! embedded DejaVu Sans Mono, `font/LICENSE`), then encoded as an 8-bit PNG by the `png` crate.
//! The same points give the same bytes.

use super::Point;
use anyhow::{Result, anyhow};
use plotters::prelude::*;
use std::sync::Once;

/// DejaVu Sans Mono (Bitstream Vera licence, `font/LICENSE`).
pub(crate) static FONT: &[u8] = include_bytes!("font/DejaVuSansMono.ttf");
pub(crate) const FAMILY: &str = "sans-serif";
const PANEL: (u32, u32) = (560, 460);
/// Series colours, by the method's place in the method list.
pub(crate) const PALETTE: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
];

pub(crate) fn register_font() -> Result<()> {
    static ONCE: Once = Once::new();
    let mut result = Ok(());
    ONCE.call_once(|| {
        result = plotters::style::register_font(FAMILY, FontStyle::Normal, FONT)
            .map_err(|_| anyhow!("the embedded chart font is not a valid font"));
    });
    result
}

/// What one chart shows: its title line per panel, its x axis, and the references' floors.
pub struct ChartText<'a> {
    /// Appended to each panel's scene name.
    pub title: &'a str,
    /// The x axis description.
    pub x_desc: &'a str,
    /// Per scene, the reference's own RMSE, drawn as a grey horizontal line when given.
    pub floors: &'a [(String, f64)],
}

/// The PNG of one panel per scene (in `scenes` order) of `points` (seconds against RMSE), the
/// series in `methods` order, `front[i]` marking `points[i]` on its scene's Pareto front.
/// Points of other scenes or methods are ignored; a scene without points is an error.
pub fn draw(
    text: &ChartText,
    scenes: &[String],
    methods: &[String],
    points: &[Point],
    front: &[bool],
) -> Result<Vec<u8>> {
    register_font()?;
    let (w, h) = (PANEL.0 * scenes.len().max(1) as u32, PANEL.1);
    let mut buffer = vec![0u8; w as usize * h as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut buffer, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let panels = root.split_evenly((1, scenes.len().max(1)));
        for (panel, scene) in panels.iter().zip(scenes) {
            draw_panel(panel, text, scene, methods, points, front)?;
        }
        root.present().map_err(plot_err)?;
    }
    encode_png(&buffer, w, h)
}

pub(crate) fn plot_err<E: std::fmt::Debug>(e: E) -> anyhow::Error {
    anyhow!("drawing the chart: {e:?}")
}

fn draw_panel(
    panel: &DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>,
    text: &ChartText,
    scene: &str,
    methods: &[String],
    points: &[Point],
    front: &[bool],
) -> Result<()> {
    let mine: Vec<(usize, &Point)> = points
        .iter()
        .enumerate()
        .filter(|(_, p)| p.scene == scene && p.errors.rmse > 0.0 && p.seconds > 0.0)
        .collect();
    if mine.is_empty() {
        return Err(anyhow!("no points to chart for scene {scene}"));
    }
    let floor = text
        .floors
        .iter()
        .find(|(s, _)| s == scene)
        .map(|&(_, rmse)| rmse);
    // Whole decades, so every axis has at least two labelled ticks.
    let range = |f: &dyn Fn(&Point) -> f64, extra: Option<f64>| {
        let values = mine.iter().map(|(_, p)| f(p)).chain(extra);
        let lo = values.clone().fold(f64::INFINITY, f64::min);
        let hi = values.fold(0.0, f64::max);
        10f64.powf(lo.log10().floor())..10f64.powf(hi.log10().ceil())
    };
    let mut chart = ChartBuilder::on(panel)
        .caption(format!("{scene}: {}", text.title), (FAMILY, 17))
        .margin(12)
        .x_label_area_size(42)
        .y_label_area_size(70)
        .build_cartesian_2d(
            range(&|p| p.seconds, None).log_scale(),
            range(&|p| p.errors.rmse, floor).log_scale(),
        )
        .map_err(plot_err)?;
    chart
        .configure_mesh()
        .x_desc(text.x_desc)
        .y_desc("RMSE (linear, vs reference)")
        .label_style((FAMILY, 12))
        .x_label_formatter(&|v| tick(*v))
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .draw()
        .map_err(plot_err)?;
    if let Some(rmse) = floor {
        let (x0, x1) = (chart.x_range().start, chart.x_range().end);
        let grey = RGBColor(150, 150, 150);
        chart
            .draw_series(LineSeries::new(
                vec![(x0, rmse), (x1, rmse)],
                grey.stroke_width(2),
            ))
            .map_err(plot_err)?
            .label("reference's own error")
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], grey.stroke_width(2))
            });
    }
    let mut on_front: Vec<(f64, f64)> = mine
        .iter()
        .filter(|(i, _)| front[*i])
        .map(|(_, p)| (p.seconds, p.errors.rmse))
        .collect();
    on_front.sort_by(|a, b| a.0.total_cmp(&b.0));
    chart
        .draw_series(LineSeries::new(on_front.clone(), BLACK.stroke_width(1)))
        .map_err(plot_err)?
        .label("Pareto front")
        .legend(|(x, y)| Circle::new((x + 10, y), 6, BLACK.stroke_width(2)));
    chart
        .draw_series(
            on_front
                .iter()
                .map(|&p| Circle::new(p, 7, BLACK.stroke_width(2))),
        )
        .map_err(plot_err)?;
    for (m, method) in methods.iter().enumerate() {
        let colour = PALETTE[m % PALETTE.len()];
        let mut series: Vec<(f64, f64)> = mine
            .iter()
            .filter(|(_, p)| &p.method == method)
            .map(|(_, p)| (p.seconds, p.errors.rmse))
            .collect();
        if series.is_empty() {
            continue;
        }
        series.sort_by(|a, b| a.0.total_cmp(&b.0));
        chart
            .draw_series(LineSeries::new(series.clone(), colour.stroke_width(2)))
            .map_err(plot_err)?
            .label(method.as_str())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(3))
            });
        chart
            .draw_series(series.iter().map(|&p| Circle::new(p, 3, colour.filled())))
            .map_err(plot_err)?;
    }
    chart
        .configure_series_labels()
        .label_font((FAMILY, 13))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::LowerLeft)
        .draw()
        .map_err(plot_err)?;
    Ok(())
}

/// A log axis label: the value when its leading digit is 1, 2 or 5, else nothing (so ticks
/// within one decade do not collide), with as many decimals as its magnitude needs.
pub(crate) fn tick(v: f64) -> String {
    if v.is_nan() || v <= 0.0 {
        return String::new();
    }
    let decade = v.log10().floor();
    let mantissa = v / 10f64.powf(decade);
    if [1.0, 2.0, 5.0].iter().any(|m| (mantissa - m).abs() < 1e-6) {
        format!("{v:.*}", (-decade).max(0.0) as usize)
    } else {
        String::new()
    }
}

/// The ticks of a log axis over `range`: every value 1, 2 or 5 times a power of ten in it
/// (ends included), each of which [`tick`] labels. Over whole decades (as the charts' axes
/// are) that is at least 4 ticks (1, 2, 5, 10 of the one decade).
pub(crate) fn ticks_125(range: std::ops::Range<f64>) -> Vec<f64> {
    let (lo, hi) = (range.start, range.end);
    if !(lo > 0.0 && hi >= lo && hi.is_finite()) {
        return Vec::new();
    }
    let slack = 1e-9;
    let mut ticks = Vec::new();
    for decade in (lo.log10().floor() as i32)..=(hi.log10().ceil() as i32) {
        for m in [1.0, 2.0, 5.0] {
            // Decimal text back to a number, so 2e-3 is the double nearest 0.002 and `tick`
            // labels it.
            let v: f64 = format!("{m}e{decade}").parse().unwrap_or(f64::NAN);
            if v >= lo * (1.0 - slack) && v <= hi * (1.0 + slack) {
                ticks.push(v);
            }
        }
    }
    ticks
}

/// An 8-bit RGB PNG of `rgb` (row-major, top row first), deterministic (fixed filter and
/// compressor).
pub(crate) fn encode_png(rgb: &[u8], width: u32, height: u32) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    let mut encoder = png::Encoder::new(&mut out, width, height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
    encoder.set_deflate_compression(png::DeflateCompression::FdeflateUltraFast);
    encoder.set_filter(png::Filter::Paeth);
    let mut writer = encoder.write_header()?;
    writer.write_image_data(rgb)?;
    writer.finish()?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::{tick, ticks_125};

    #[test]
    fn ticks_label_1_2_5_only() {
        assert_eq!(tick(0.01), "0.01");
        assert_eq!(tick(0.02), "0.02");
        assert_eq!(tick(0.03), "");
        assert_eq!(tick(5.0), "5");
        assert_eq!(tick(10.0), "10");
        assert_eq!(tick(0.0), "");
    }

    /// The axes of `hort plan --chart` as drawn for docs/plan/projection.png (whole decades
    /// around $0.0040 to $0.047, and 1.2 to 600 s): every 1-2-5 value is a labelled tick.
    #[test]
    fn log_axes_get_a_labelled_tick_at_every_1_2_5_value() {
        let labels = |lo, hi| -> Vec<String> { ticks_125(lo..hi).into_iter().map(tick).collect() };
        assert_eq!(
            labels(0.001, 0.1),
            ["0.001", "0.002", "0.005", "0.01", "0.02", "0.05", "0.1"]
        );
        assert_eq!(labels(0.001, 0.01), ["0.001", "0.002", "0.005", "0.01"]);
        assert_eq!(
            labels(1.0, 1000.0),
            ["1", "2", "5", "10", "20", "50", "100", "200", "500", "1000"]
        );
        // Not on whole decades: the 1-2-5 values inside.
        assert_eq!(labels(0.003, 0.03), ["0.005", "0.01", "0.02"]);
        assert_eq!(labels(0.0, 1.0), Vec::<String>::new());
    }
}
