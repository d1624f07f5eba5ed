//! Step rectangles as the planner takes them, from the three places they come from: the
//! perception's [`PlaneSegment`]s (as they are), a scene's ground truth, and a text file in
//! the paper's format (`x,y,z` rows, four corners per step, as in
//! ../shared/paper/exp1/rectangles.txt).

use crate::perception::PlaneSegment;
use crate::scene::geometry::StepTop;
use nalgebra::{Point3, Vector3};

/// Why a rectangles file was refused.
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
pub enum RectanglesError {
    /// A row that is not three finite numbers.
    #[error("line {line}: {reason}")]
    Row {
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// Not a multiple of four corner rows, or no rows.
    #[error("{0} corner rows: a rectangles file has four rows per step")]
    Count(usize),
    /// Four corners that are not a rectangle.
    #[error("step {step} (rows {first}-{last}): {reason}")]
    NotRectangle {
        /// 0-based step in file order.
        step: usize,
        /// First row's line number.
        first: usize,
        /// Last row's line number.
        last: usize,
        /// What is wrong.
        reason: String,
    },
}

/// The rectangles from the lowest up.
pub fn by_height(rects: &[PlaneSegment]) -> Vec<&PlaneSegment> {
    let mut v: Vec<&PlaneSegment> = rects.iter().collect();
    v.sort_by(|a, b| a.height_m().total_cmp(&b.height_m()));
    v
}

/// Each rectangle's rise above the one before it (`sorted` from the lowest up); the first
/// one's rise above `floor_z`, or none without a floor.
pub fn rises_m(sorted: &[&PlaneSegment], floor_z: Option<f64>) -> Vec<f64> {
    let below = floor_z.into_iter().chain(sorted.iter().map(|s| s.height_m()));
    sorted.iter().skip(usize::from(floor_z.is_none())).zip(below).map(|(s, z)| s.height_m() - z).collect()
}

/// Ground truth as rectangles (normal up, ascent along the step's depth).
pub fn from_step_tops(steps: &[StepTop]) -> Vec<PlaneSegment> {
    steps
        .iter()
        .filter_map(|s| {
            let along = s.corners[1] - s.corners[0];
            PlaneSegment::new(s.center(), along, s.depth_m, s.width_m, Vector3::z(), 0)
        })
        .collect()
}

/// Parses the paper's rectangles format. Each step's direction of ascent is the rectangle
/// axis closest to the direction from the lowest step to the highest (+x with one step).
/// Blank lines and lines starting with `#` are skipped; commas or spaces separate numbers.
pub fn parse(text: &str) -> Result<Vec<PlaneSegment>, RectanglesError> {
    let mut rows: Vec<(usize, Point3<f64>)> = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let t = line.trim();
        if t.is_empty() || t.starts_with('#') {
            continue;
        }
        let nums: Vec<f64> = t
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|s| !s.is_empty())
            .map(|s| s.parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|e| RectanglesError::Row { line: i + 1, reason: format!("{e}: {t:?}") })?;
        if nums.len() != 3 || nums.iter().any(|v| !v.is_finite()) {
            return Err(RectanglesError::Row {
                line: i + 1,
                reason: format!("want three finite numbers x,y,z, got {t:?}"),
            });
        }
        rows.push((i + 1, Point3::new(nums[0], nums[1], nums[2])));
    }
    if rows.is_empty() || !rows.len().is_multiple_of(4) {
        return Err(RectanglesError::Count(rows.len()));
    }
    let quads: Vec<&[(usize, Point3<f64>)]> = rows.chunks(4).collect();
    let centre = |q: &[(usize, Point3<f64>)]| {
        Point3::from(q.iter().map(|(_, p)| p.coords).sum::<Vector3<f64>>() / 4.0)
    };
    let lowest = quads.iter().map(|q| centre(q)).min_by(|a, b| a.z.total_cmp(&b.z));
    let highest = quads.iter().map(|q| centre(q)).max_by(|a, b| a.z.total_cmp(&b.z));
    let hint = match (lowest, highest) {
        (Some(a), Some(b)) if quads.len() > 1 => Vector3::new(b.x - a.x, b.y - a.y, 0.0),
        _ => Vector3::x(),
    };
    quads.iter().enumerate().map(|(k, q)| rectangle(k, q, &hint)).collect()
}

fn rectangle(
    step: usize,
    q: &[(usize, Point3<f64>)],
    hint: &Vector3<f64>,
) -> Result<PlaneSegment, RectanglesError> {
    let err = |reason: String| RectanglesError::NotRectangle { step, first: q[0].0, last: q[3].0, reason };
    let p: Vec<Point3<f64>> = q.iter().map(|(_, p)| *p).collect();
    let e0 = Vector3::new(p[1].x - p[0].x, p[1].y - p[0].y, 0.0);
    let e1 = Vector3::new(p[2].x - p[1].x, p[2].y - p[1].y, 0.0);
    let (l0, l1) = (e0.norm(), e1.norm());
    if l0 < 1e-3 || l1 < 1e-3 {
        return Err(err(format!("an edge is shorter than 1 mm ({l0:.4} m, {l1:.4} m)")));
    }
    // Corners in order around the rectangle: consecutive edges perpendicular, opposite equal.
    let cos = e0.dot(&e1) / (l0 * l1);
    let opposite = Vector3::new(p[3].x - p[2].x, p[3].y - p[2].y, 0.0);
    if cos.abs() > 0.05 || (opposite + e0).norm() > 0.02 * l0.max(l1) {
        return Err(err("the corners are not a rectangle in order".into()));
    }
    let centre = Point3::from(p.iter().map(|c| c.coords).sum::<Vector3<f64>>() / 4.0);
    let normal = (p[1] - p[0]).cross(&(p[2] - p[1]));
    let normal = if normal.z < 0.0 { -normal } else { normal };
    let (along, depth, width) =
        if e0.dot(hint).abs() / l0 >= e1.dot(hint).abs() / l1 { (e0, l0, l1) } else { (e1, l1, l0) };
    let along = if along.dot(hint) < 0.0 { -along } else { along };
    PlaneSegment::new(centre, along, depth, width, normal, 0)
        .ok_or_else(|| err("not a finite rectangle".into()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_the_papers_format_and_refuses_garbage() {
        let text = "0,0,0\n0.3,0,0\n0.3,0.5,0\n0,0.5,0\n0.3,0,0.2\n0.6,0,0.2\n0.6,0.5,0.2\n0.3,0.5,0.2\n";
        let r = parse(text).unwrap();
        assert_eq!(r.len(), 2);
        assert!((r[0].depth_m() - 0.3).abs() < 1e-12 && (r[0].width_m() - 0.5).abs() < 1e-12);
        assert!((r[1].along() - Vector3::x()).norm() < 1e-12);
        assert!(matches!(parse("0,0,0\n1,1,1\n"), Err(RectanglesError::Count(2))));
        assert!(matches!(parse("0,0,x\n"), Err(RectanglesError::Row { line: 1, .. })));
        assert!(matches!(parse("0,0,NaN\n"), Err(RectanglesError::Row { line: 1, .. })));
        let skew = "0,0,0\n0.3,0,0\n0.5,0.5,0\n0,0.5,0\n";
        assert!(matches!(parse(skew), Err(RectanglesError::NotRectangle { step: 0, .. })));
    }

    #[test]
    fn rises_above_the_floor_and_each_other() {
        let text = "0.3,0,0.2\n0.6,0,0.2\n0.6,0.5,0.2\n0.3,0.5,0.2\n0,0,0\n0.3,0,0\n0.3,0.5,0\n0,0.5,0\n";
        let r = parse(text).unwrap();
        let sorted = by_height(&r);
        assert_eq!(sorted[0].height_m(), 0.0);
        let with_floor = rises_m(&sorted, Some(-0.25));
        assert!((with_floor[0] - 0.25).abs() < 1e-12 && (with_floor[1] - 0.2).abs() < 1e-12);
        assert_eq!(rises_m(&sorted, None).len(), 1);
    }
}
