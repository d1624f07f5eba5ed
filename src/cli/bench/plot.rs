//! The PNG of `bench perceive`: the paper's Fig. 5 (a) redrawn from our runs, first-step area
//! against k on the left, total time against k on the right, one line per cloud.

use super::perceive::SweepPoint;
use anyhow::{anyhow, Result};
use plotters::prelude::*;
use std::path::Path;

const COLOURS: [RGBColor; 4] =
    [RGBColor(31, 119, 180), RGBColor(140, 190, 230), RGBColor(214, 39, 40), RGBColor(240, 150, 150)];

/// Draws the sweep `series` (label, points) to `path`.
pub fn fig5(path: &Path, series: &Series) -> Result<()> {
    super::super::ensure_parent(path)?;
    draw(path, series).map_err(|e| anyhow!("cannot draw {}: {e}", path.display()))
}

type Series = [(String, Vec<SweepPoint>)];
type Value = fn(&SweepPoint) -> f64;

fn draw(path: &Path, series: &Series) -> Result<(), Box<dyn std::error::Error>> {
    stairbench::plot_font::register()?;
    let root = BitMapBackend::new(path, (1400, 560)).into_drawing_area();
    root.fill(&WHITE)?;
    let (left, right) = root.split_horizontally(700);
    panel(
        &left,
        "(a) first step: Eq. 3 area p (solid), footprint coverage (thin)",
        "percent of the true step",
        series,
        |q| q.first_area_percent,
        Some(|q| q.first_coverage_percent),
    )?;
    panel(
        &right,
        "(b) whole pipeline, cloud to rectangles",
        "time per frame, ms",
        series,
        |q| q.total_ms,
        None,
    )?;
    root.present()?;
    Ok(())
}

/// One chart against k: a thick line with points per series for `main`, and a thin line for
/// `thin` when given. Non-finite values (step not found) are left out.
fn panel(
    area: &DrawingArea<BitMapBackend, plotters::coord::Shift>,
    caption: &str,
    y_desc: &str,
    series: &Series,
    main: Value,
    thin: Option<Value>,
) -> Result<(), Box<dyn std::error::Error>> {
    let line = |pts: &[SweepPoint], f: Value| -> Vec<(f64, f64)> {
        pts.iter().map(|q| (q.k as f64, f(q))).filter(|(_, v)| v.is_finite()).collect()
    };
    let ks = series.iter().flat_map(|(_, p)| p.iter().map(|q| q.k as f64));
    let (kmin, kmax) = ks.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), k| (a.min(k), b.max(k)));
    let ymax = series.iter().flat_map(|(_, p)| line(p, main)).map(|(_, v)| v).fold(1.0f64, f64::max);
    let mut chart = ChartBuilder::on(area)
        .caption(caption, (stairbench::plot_font::FAMILY, 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d(kmin..kmax, 0.0..ymax * 1.15)?;
    chart.configure_mesh().x_desc("k (neighbours of the normal estimation)").y_desc(y_desc).draw()?;
    for (i, (label, pts)) in series.iter().enumerate() {
        let c = COLOURS[i % COLOURS.len()];
        let m = line(pts, main);
        chart
            .draw_series(LineSeries::new(m.clone(), c.stroke_width(3)))?
            .label(label.as_str())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(3)));
        chart.draw_series(m.iter().map(|&xy| Circle::new(xy, 3, c.filled())))?;
        if let Some(f) = thin {
            chart.draw_series(LineSeries::new(line(pts, f), c.stroke_width(1)))?;
        }
    }
    chart.configure_series_labels().background_style(WHITE.mix(0.8)).border_style(BLACK).draw()?;
    Ok(())
}
