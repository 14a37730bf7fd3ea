//! `hort plan --chart`: projected wall time and dollars against the function count, one series
//! per scene, on log-log axes (two panels side by side), drawn like `hort eval`'s charts (the
//! same embedded font and palette). The same projections give the same bytes.

use crate::eval::chart::{FAMILY, PALETTE, encode_png, plot_err, register_font, tick, ticks_125};
use anyhow::{Result, bail};
use hort_core::predict::Projection;
use plotters::prelude::*;

/// The function counts a chart sweeps: 1, 2 and 5 per decade from 1 to 10,000.
pub const CHART_SWEEP: [u32; 13] = [
    1, 2, 5, 10, 20, 50, 100, 200, 500, 1_000, 2_000, 5_000, 10_000,
];

const PANEL: (u32, u32) = (620, 460);

/// One scene's line: its label and its projections over [`CHART_SWEEP`].
pub struct SceneSeries {
    /// The legend label (scene name, size and triangle count).
    pub label: String,
    /// Projections, fewest functions first.
    pub points: Vec<Projection>,
}

/// The PNG: wall seconds (left) and dollars (right) against functions, `subtitle` under each
/// panel's title (the target and image settings). Errors when there is nothing to draw.
pub fn draw(subtitle: &str, series: &[SceneSeries]) -> Result<Vec<u8>> {
    if series.iter().all(|s| s.points.is_empty()) {
        bail!("no projections to chart");
    }
    register_font()?;
    let (w, h) = (PANEL.0 * 2, PANEL.1);
    let mut buffer = vec![0u8; w as usize * h as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut buffer, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let panels = root.split_evenly((1, 2));
        let seconds = |p: &Projection| p.seconds;
        let dollars = |p: &Projection| p.dollars;
        let plain = |v: f64| tick(v);
        let usd = |v: f64| match tick(v) {
            t if t.is_empty() => t,
            t => format!("${t}"),
        };
        let time = (
            "wall time",
            "seconds",
            &seconds as &dyn Fn(&Projection) -> f64,
            &plain as &dyn Fn(f64) -> String,
        );
        let cost = (
            "cost",
            "dollars",
            &dollars as &dyn Fn(&Projection) -> f64,
            &usd as &dyn Fn(f64) -> String,
        );
        panel(&panels[0], time, subtitle, series)?;
        panel(&panels[1], cost, subtitle, series)?;
        root.present().map_err(plot_err)?;
    }
    encode_png(&buffer, w, h)
}

/// What a panel shows: its name, its unit, the value of a projection, and its tick labels.
type Measure<'a> = (
    &'a str,
    &'a str,
    &'a dyn Fn(&Projection) -> f64,
    &'a dyn Fn(f64) -> String,
);

fn panel(
    area: &DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>,
    (what, unit, value, label): Measure<'_>,
    subtitle: &str,
    series: &[SceneSeries],
) -> Result<()> {
    let values = series
        .iter()
        .flat_map(|s| s.points.iter().map(value))
        .filter(|v| *v > 0.0);
    let lo = values.clone().fold(f64::INFINITY, f64::min);
    let hi = values.fold(0.0, f64::max);
    // Whole decades, ticked at every 1-2-5 value (plotters' own log ticks fall between them,
    // so one decade had a single label): at least 4 labelled ticks.
    let y = 10f64.powf(lo.log10().floor())..10f64.powf(hi.log10().ceil());
    let y_ticks = ticks_125(y.clone());
    let x = 1.0..f64::from(CHART_SWEEP[CHART_SWEEP.len() - 1]);
    let mut chart = ChartBuilder::on(area)
        .caption(
            format!("{what} against functions, {subtitle}"),
            (FAMILY, 15),
        )
        .margin(12)
        .x_label_area_size(42)
        .y_label_area_size(70)
        .build_cartesian_2d(x.log_scale(), y.log_scale().with_key_points(y_ticks))
        .map_err(plot_err)?;
    chart
        .configure_mesh()
        .x_desc("functions")
        .y_desc(unit)
        .label_style((FAMILY, 12))
        .x_label_formatter(&|v| tick(*v))
        .y_label_formatter(&|v| label(*v))
        .draw()
        .map_err(plot_err)?;
    for (i, s) in series.iter().enumerate() {
        let colour = PALETTE[i % PALETTE.len()];
        let line: Vec<(f64, f64)> = s
            .points
            .iter()
            .map(|p| (f64::from(p.functions), value(p)))
            .filter(|(_, v)| *v > 0.0)
            .collect();
        chart
            .draw_series(LineSeries::new(line.clone(), colour.stroke_width(2)))
            .map_err(plot_err)?
            .label(s.label.as_str())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(3))
            });
        chart
            .draw_series(line.iter().map(|&p| Circle::new(p, 3, colour.filled())))
            .map_err(plot_err)?;
    }
    chart
        .configure_series_labels()
        .label_font((FAMILY, 12))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(plot_err)?;
    Ok(())
}
