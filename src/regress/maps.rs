//! Capability maps (plotters): each case as a mark at its two chosen parameters (rise x
//! tread by default), coloured by its verdict (the worst over its noise draws), with the
//! planner's declared limits drawn where they apply.

use super::results::CaseResult;
use super::summary::by_case;
use super::verdict::Verdict;
use plotters::prelude::*;
use std::path::Path;

/// The colour of a verdict class.
fn colour(v: Verdict) -> RGBColor {
    match v {
        Verdict::ClimbedClean => RGBColor(44, 160, 44),
        Verdict::RefusedAsExpected => RGBColor(31, 119, 180),
        Verdict::FalseRefusal => RGBColor(255, 127, 14),
        Verdict::CheckViolated => RGBColor(214, 39, 40),
        Verdict::Fell => RGBColor(0, 0, 0),
        Verdict::SteppedOntoUnclimbable => RGBColor(148, 103, 189),
        Verdict::EstimateStrayed => RGBColor(188, 189, 34),
        Verdict::NoStaircaseFound => RGBColor(140, 86, 75),
        Verdict::Error => RGBColor(227, 119, 194),
        Verdict::Timeout => RGBColor(127, 127, 127),
    }
}

/// A parameter's value as a number (booleans 0/1, a place by its index); none for a case
/// that does not set it.
fn value(r: &CaseResult, key: &str) -> Option<f64> {
    match r.params.get(key)? {
        super::suite::Val::Bool(b) => Some(f64::from(u8::from(*b))),
        super::suite::Val::Text(t) => super::suite::PLACES.iter().position(|p| p == t).map(|i| i as f64),
        v => v.as_f64().filter(|x| x.is_finite()),
    }
}

/// Draws the map of `results` over parameters `x` and `y` to `path`; `limits` are vertical
/// and horizontal lines to draw (a declared limit: axis, value, label).
pub fn draw(
    path: &Path,
    title: &str,
    results: &[CaseResult],
    x: &str,
    y: &str,
    limits: &[(char, f64, String)],
) -> Result<(), String> {
    plot(path, title, results, x, y, limits).map_err(|e| format!("cannot draw {}: {e}", path.display()))
}

fn plot(
    path: &Path,
    title: &str,
    results: &[CaseResult],
    x: &str,
    y: &str,
    limits: &[(char, f64, String)],
) -> Result<(), Box<dyn std::error::Error>> {
    let points: Vec<(f64, f64, Verdict)> = by_case(results)
        .iter()
        .filter_map(|c| {
            let w = c.worst();
            Some((value(w, x)?, value(w, y)?, w.verdict))
        })
        .collect();
    if points.is_empty() {
        return Err(format!("no case has both {x} and {y}").into());
    }
    let span = |f: fn(&(f64, f64, Verdict)) -> f64| {
        let (lo, hi) =
            points.iter().map(f).fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
        let pad = ((hi - lo) * 0.08).max(1e-3);
        (lo - pad)..(hi + pad)
    };
    crate::plot_font::register()?;
    let root = BitMapBackend::new(path, (900, 720)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, (crate::plot_font::FAMILY, 20))
        .margin(14)
        .x_label_area_size(45)
        .y_label_area_size(60)
        .build_cartesian_2d(span(|p| p.0), span(|p| p.1))?;
    chart.configure_mesh().x_desc(x).y_desc(y).draw()?;
    for (axis, at, label) in limits {
        let line: Vec<(f64, f64)> = match axis {
            'x' => vec![(*at, chart.y_range().start), (*at, chart.y_range().end)],
            _ => vec![(chart.x_range().start, *at), (chart.x_range().end, *at)],
        };
        chart
            .draw_series(LineSeries::new(line, BLACK.mix(0.5).stroke_width(2)))?
            .label(label.as_str())
            .legend(|(a, b)| PathElement::new(vec![(a, b), (a + 20, b)], BLACK.mix(0.5).stroke_width(2)));
    }
    for v in Verdict::ALL {
        let mine: Vec<(f64, f64)> = points.iter().filter(|p| p.2 == v).map(|p| (p.0, p.1)).collect();
        if mine.is_empty() {
            continue;
        }
        let c = colour(v);
        chart
            .draw_series(mine.iter().map(|&p| Circle::new(p, 7, c.filled())))?
            .label(format!("{v} ({})", mine.len()))
            .legend(move |(a, b)| Circle::new((a + 10, b), 6, c.filled()));
    }
    chart.configure_series_labels().background_style(WHITE.mix(0.85)).border_style(BLACK).draw()?;
    root.present()?;
    Ok(())
}
