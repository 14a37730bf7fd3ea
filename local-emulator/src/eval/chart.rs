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
static FONT: &[u8] = include_bytes!("font/DejaVuSansMono.ttf");
const FAMILY: &str = "sans-serif";
const PANEL: (u32, u32) = (560, 460);
/// Series colours, by the method's place in the method list.
const PALETTE: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
];

fn register_font() -> Result<()> {
    static ONCE: Once = Once::new();
    let mut result = Ok(());
    ONCE.call_once(|| {
        result = plotters::style::register_font(FAMILY, FontStyle::Normal, FONT)
            .map_err(|_| anyhow!("the embedded chart font is not a valid font"));
    });
    result
}

/// What one chart shows: its title line per panel and its x axis.
pub struct ChartText<'a> {
    /// Appended to each panel's scene name.
    pub title: &'a str,
    /// The x axis description.
    pub x_desc: &'a str,
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

fn plot_err<E: std::fmt::Debug>(e: E) -> anyhow::Error {
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
    let range = |f: fn(&Point) -> f64| {
        let lo = mine.iter().map(|(_, p)| f(p)).fold(f64::INFINITY, f64::min);
        let hi = mine.iter().map(|(_, p)| f(p)).fold(0.0, f64::max);
        (lo / 1.5)..(hi * 1.5)
    };
    let mut chart = ChartBuilder::on(panel)
        .caption(format!("{scene}: {}", text.title), (FAMILY, 17))
        .margin(12)
        .x_label_area_size(42)
        .y_label_area_size(70)
        .build_cartesian_2d(
            range(|p| p.seconds).log_scale(),
            range(|p| p.errors.rmse).log_scale(),
        )
        .map_err(plot_err)?;
    chart
        .configure_mesh()
        .x_desc(text.x_desc)
        .y_desc("RMSE (linear, vs reference)")
        .label_style((FAMILY, 12))
        .x_label_formatter(&|v| format!("{v:.3}"))
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .draw()
        .map_err(plot_err)?;
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
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(plot_err)?;
    Ok(())
}

/// An 8-bit RGB PNG of `rgb` (row-major, top row first), deterministic (fixed filter and
/// compressor).
fn encode_png(rgb: &[u8], width: u32, height: u32) -> Result<Vec<u8>> {
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
