//! Scores of perceived steps against ground truth: the paper's estimated-area percentage
//! (Eq. 3), height and corner errors, overlap, and found / false step counts.

use super::PlaneSegment;
use crate::geom2d::{self, P2};
use crate::scene::StepTop;
use nalgebra::Point3;
use serde::Serialize;

/// A true step counts as found when a segment overlaps it with at least this IoU ...
pub const FOUND_IOU: f64 = 0.6;
/// ... and its height is within this, metres.
pub const FOUND_DZ_M: f64 = 0.02;

/// The score of one true step.
#[derive(Debug, Clone, Serialize)]
pub struct StepScore {
    /// Index of the true step (0 = first).
    pub index: usize,
    /// Whether a segment matches it (IoU and height).
    pub found: bool,
    /// Best overlap (IoU in the transverse plane) of any segment.
    pub iou: f64,
    /// Height error of the best-overlapping segment, metres (NaN when none overlaps).
    pub height_error_m: f64,
    /// Mean distance from the segment's corners to the true corners, metres (NaN when none).
    pub corner_error_m: f64,
    /// Where the best-overlapping segment's front edge (the middle of its two nearest
    /// corners along the true ascent) stands against the true nose, metres along the
    /// ascent: negative toward the robot (NaN when none).
    pub front_error_m: f64,
    /// Where its back edge (the middle of its two farthest corners) stands against the true
    /// back (the riser above, or the flight's end), metres along the ascent: positive past
    /// it (NaN when none).
    pub back_error_m: f64,
    /// Eq. 3: p = a/A sum n_i over the segments on this step, percent. Counts voxels, so a
    /// tread lying on a voxel-layer boundary counts twice and p can exceed 100.
    pub area_percent: f64,
    /// Footprint coverage: the part of the true top covered by the segments on this step
    /// (their rectangles clipped to it), percent; at most 100.
    pub coverage_percent: f64,
}

/// Scores of a perception result.
#[derive(Debug, Clone, Serialize)]
pub struct Score {
    /// One per true step.
    pub steps: Vec<StepScore>,
    /// True steps found.
    pub found: usize,
    /// Segments matching no true step.
    pub false_segments: usize,
}

/// The xy corners of a rectangle.
pub fn xy(corners: &[Point3<f64>; 4]) -> Vec<P2> {
    corners.iter().map(|c| P2::new(c.x, c.y)).collect()
}

/// Where the front and back edges of the rectangle `corners` lie along the ascent of the true
/// top `truth` (its front-right to back-right corner), metres from the origin: the middles
/// of its two nearest and two farthest corners (a rectangle turned from the truth reaches
/// past its edges' middles by half its width times the turn's sine at its corners).
fn edges_along(corners: &[Point3<f64>; 4], truth: &[Point3<f64>; 4]) -> [f64; 2] {
    let d = truth[1] - truth[0];
    let u = nalgebra::Vector2::new(d.x, d.y).normalize();
    let mut at = corners.map(|c| c.x * u.x + c.y * u.y);
    at.sort_by(f64::total_cmp);
    [(at[0] + at[1]) / 2.0, (at[2] + at[3]) / 2.0]
}

/// Scores `segments` against the true step tops; `voxel_m` is the voxel edge (Eq. 3's a is
/// its square).
pub fn score(segments: &[PlaneSegment], truth: &[StepTop], voxel_m: f64) -> Score {
    let mut matched = vec![false; segments.len()];
    let steps: Vec<StepScore> = truth
        .iter()
        .map(|t| {
            let txy = xy(&t.corners);
            let best = segments
                .iter()
                .enumerate()
                .map(|(i, s)| (i, geom2d::iou(&xy(s.corners()), &txy)))
                .max_by(|a, b| a.1.total_cmp(&b.1));
            let (iou, dz, corner, edges) = match best {
                Some((i, iou)) if iou > 0.0 => {
                    let s = &segments[i];
                    let corner = s
                        .corners()
                        .iter()
                        .map(|c| t.corners.iter().map(|q| (c - q).norm()).fold(f64::INFINITY, f64::min))
                        .sum::<f64>()
                        / 4.0;
                    let truth = edges_along(&t.corners, &t.corners);
                    let seen = edges_along(s.corners(), &t.corners);
                    (iou, s.height_m() - t.height_m, corner, [seen[0] - truth[0], seen[1] - truth[1]])
                }
                _ => (0.0, f64::NAN, f64::NAN, [f64::NAN; 2]),
            };
            let found = iou >= FOUND_IOU && dz.abs() <= FOUND_DZ_M;
            let (mut voxels, mut covered_m2) = (0, 0.0);
            for (i, s) in segments.iter().enumerate() {
                let c = s.center();
                if t.contains_xy(&c, 0.0) && (s.height_m() - t.height_m).abs() <= FOUND_DZ_M {
                    voxels += s.voxel_count();
                    covered_m2 += geom2d::area(&geom2d::clip_convex(&xy(s.corners()), &txy));
                    matched[i] = true;
                }
            }
            let area_percent = 100.0 * voxels as f64 * voxel_m * voxel_m / t.area_m2();
            // Segments on one step do not overlap (one per plane and cluster); clamp anyway.
            let coverage_percent = (100.0 * covered_m2 / t.area_m2()).min(100.0);
            StepScore {
                index: t.index,
                found,
                iou,
                height_error_m: dz,
                corner_error_m: corner,
                front_error_m: edges[0],
                back_error_m: edges[1],
                area_percent,
                coverage_percent,
            }
        })
        .collect();
    let found = steps.iter().filter(|s| s.found).count();
    Score { steps, found, false_segments: matched.iter().filter(|m| !**m).count() }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    /// A rectangle's edges are scored at their middles: one turned about the true top's
    /// centre scores 0 at both edges (its corners reach 9.8 mm past them on a 1.12 m wide
    /// tread turned 1 deg), one moved 2 cm up the ascent scores +2 cm at both.
    #[test]
    fn edges_are_scored_at_their_middles() {
        let true_top =
            PlaneSegment::new(Point3::new(1.0, 0.0, 0.3), Vector3::x(), 0.3, 1.12, Vector3::z(), 1)
                .expect("valid rectangle");
        let truth =
            [StepTop { index: 0, corners: *true_top.corners(), height_m: 0.3, depth_m: 0.3, width_m: 1.12 }];
        let turn = 1f64.to_radians();
        let turned = PlaneSegment::new(
            Point3::new(1.0, 0.0, 0.3),
            Vector3::new(turn.cos(), turn.sin(), 0.0),
            0.3,
            1.12,
            Vector3::z(),
            1,
        )
        .expect("valid rectangle");
        let moved = true_top.clone().moved(&Vector3::new(0.02, 0.0, 0.0));
        let at = |s: PlaneSegment| {
            let t = &score(&[s], &truth, 0.02).steps[0];
            (t.front_error_m, t.back_error_m)
        };
        let (front, back) = at(turned);
        assert!(front.abs() < 1e-3 && back.abs() < 1e-3, "turned: {front} {back}");
        let (front, back) = at(moved);
        assert!((front - 0.02).abs() < 1e-9 && (back - 0.02).abs() < 1e-9, "moved: {front} {back}");
    }
}
