//! The PNG of `bench perceive`: the paper's Fig. 5 (a) redrawn from our runs, first-step area
//! against k on the left, total time against k on the right, one line per cloud.

use super::perceive::SweepPoint;
use anyhow::{anyhow, Result};
use plotters::prelude::*;
use std::path::Path;

const COLOURS: [RGBColor; 4] =
    [RGBColor(31, 119, 180), RGBColor(140, 190, 230), RGBColor(214, 39, 40), RGBColor(240, 150, 150)];

/// Draws the sweep `series` (label, points) to `path`.
pub fn fig5(path: &Path, series: &[(String, Vec<SweepPoint>)]) -> Result<()> {
    super::super::ensure_parent(path)?;
    draw(path, series).map_err(|e| anyhow!("cannot draw {}: {e}", path.display()))
}

fn draw(path: &Path, series: &[(String, Vec<SweepPoint>)]) -> Result<(), Box<dyn std::error::Error>> {
    let root = BitMapBackend::new(path, (1400, 560)).into_drawing_area();
    root.fill(&WHITE)?;
    let (left, right) = root.split_horizontally(700);
    let ks = series.iter().flat_map(|(_, p)| p.iter().map(|q| q.k as f64));
    let (kmin, kmax) = ks.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), k| (a.min(k), b.max(k)));
    let finite = |v: f64| v.is_finite().then_some(v);
    let pmax = series
        .iter()
        .flat_map(|(_, p)| p.iter().filter_map(|q| finite(q.first_area_percent)))
        .fold(100.0f64, f64::max);
    let tmax = series.iter().flat_map(|(_, p)| p.iter().map(|q| q.total_ms)).fold(1.0f64, f64::max);

    let mut a = ChartBuilder::on(&left)
        .caption("(a) first step: Eq. 3 area p (solid), footprint coverage (thin)", ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d(kmin..kmax, 0.0..pmax * 1.1)?;
    a.configure_mesh()
        .x_desc("k (neighbours of the normal estimation)")
        .y_desc("percent of the true step")
        .draw()?;
    for (i, (label, pts)) in series.iter().enumerate() {
        let c = COLOURS[i % COLOURS.len()];
        let p: Vec<(f64, f64)> =
            pts.iter().filter_map(|q| finite(q.first_area_percent).map(|v| (q.k as f64, v))).collect();
        a.draw_series(LineSeries::new(p.clone(), c.stroke_width(3)))?
            .label(label.as_str())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(3)));
        a.draw_series(p.iter().map(|&xy| Circle::new(xy, 3, c.filled())))?;
        let cov: Vec<(f64, f64)> =
            pts.iter().filter_map(|q| finite(q.first_coverage_percent).map(|v| (q.k as f64, v))).collect();
        a.draw_series(LineSeries::new(cov, c.stroke_width(1)))?;
    }
    a.configure_series_labels().background_style(WHITE.mix(0.8)).border_style(BLACK).draw()?;

    let mut b = ChartBuilder::on(&right)
        .caption("(b) whole pipeline, cloud to rectangles", ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d(kmin..kmax, 0.0..tmax * 1.15)?;
    b.configure_mesh()
        .x_desc("k (neighbours of the normal estimation)")
        .y_desc("time per frame, ms")
        .draw()?;
    for (i, (label, pts)) in series.iter().enumerate() {
        let c = COLOURS[i % COLOURS.len()];
        let t: Vec<(f64, f64)> = pts.iter().map(|q| (q.k as f64, q.total_ms)).collect();
        b.draw_series(LineSeries::new(t.clone(), c.stroke_width(2)))?
            .label(label.as_str())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2)));
        b.draw_series(t.iter().map(|&xy| Circle::new(xy, 3, c.filled())))?;
    }
    b.configure_series_labels().background_style(WHITE.mix(0.8)).border_style(BLACK).draw()?;
    root.present()?;
    Ok(())
}
