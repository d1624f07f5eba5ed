//! Beyond the paper: a tread's front edge placed on the riser below it.
//!
//! §4 finds the treads as level segments, and a rectangle's edges come from its voxels. Under
//! range noise those edges err by centimetres: the nose's returns scatter along the rays, and
//! the voxels of a tread's edge mix with its riser's (by up to about 1 cm at 10 mm of noise,
//! 3 cm at 20-25 mm: regression `tread-edge-mixed-with-its-riser`). The riser under a nose
//! is a vertical surface facing the sensor, seen by hundreds of returns from the floor and
//! the treads below: whatever their scatter along the rays, they lie about the nose's
//! distance along the ascent, and their median places the nose within millimetres. Filter 1
//! drops those returns (their
//! normals are level), so they are taken from the whole cloud, in a band below the tread's
//! top and a window about its front edge as the segment has it (its place from the band's
//! lower half: a nosing's face stands in the upper); a riser seen in part (its returns all
//! in the upper or the lower half of the band, where a nosing's face stands for its
//! shadowed top: a view over the nose, or a partial view of the floor below it) leaves the
//! edge as it was. A tread whose own returns
//! run on past its riser has a nosing: its front is then the nose, not the riser (a foot on
//! the tread below keeps its toes behind the nose, not under it).

use super::PlaneSegment;
use crate::stats::median;
use nalgebra::{Point3, Vector3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Where a tread's riser is looked for and when it is believed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RiserParams {
    /// Whether the fronts are placed on the risers (`false`: the rectangles as §4 gives
    /// them).
    pub enabled: bool,
    /// Half the window, along the ascent about the segment's front edge, in which the riser
    /// is looked for, metres: the edges err by up to about 4 cm under 25 mm of noise.
    pub half_window_m: f64,
    /// The band below the tread's top in which a return may be the riser's, metres below
    /// the top: [nearest, farthest]. Its near end keeps the tread's own returns out (they
    /// scatter about 1-2 cm in height under 10-25 mm of noise), its far end the tread or
    /// floor below (a rise is 10 cm or more: building codes, the generated suites); for a
    /// step with a tread below it the band also ends `band_m[0]` above that tread.
    pub band_m: [f64; 2],
    /// Returns this far inside the segment's sides only, metres (a wall or a rail beside
    /// the flight is no riser).
    pub side_margin_m: f64,
    /// Least returns on the riser (about the median) for it to place the front.
    pub min_returns: usize,
    /// Least share of those returns in each half of the band (upper, lower): a riser seen
    /// whole. A riser seen in part, a strip of returns at one height, is not believed.
    pub min_half_share: f64,
}

impl Default for RiserParams {
    fn default() -> Self {
        Self {
            enabled: true,
            half_window_m: 0.05,
            band_m: [0.02, 0.08],
            side_margin_m: 0.05,
            min_returns: 30,
            min_half_share: 0.3,
        }
    }
}

impl RiserParams {
    /// Why the parameters are unusable, naming the field; `None` when they are fine.
    pub fn invalid(&self) -> Option<(&'static str, &'static str)> {
        let pos = |v: f64| v.is_finite() && v > 0.0;
        if !pos(self.half_window_m) {
            return Some(("riser.half_window_m", "must be > 0"));
        }
        if !(pos(self.band_m[0]) && self.band_m[1].is_finite() && self.band_m[1] > self.band_m[0]) {
            return Some(("riser.band_m", "must be [near, far] with 0 < near < far"));
        }
        if !(self.side_margin_m.is_finite() && self.side_margin_m >= 0.0) {
            return Some(("riser.side_margin_m", "must be >= 0"));
        }
        if !(self.min_half_share.is_finite() && (0.0..=0.5).contains(&self.min_half_share)) {
            return Some(("riser.min_half_share", "must be in [0, 0.5]"));
        }
        None
    }
}

/// Places each segment's front edge (its end against its ascent, facing `viewpoint`) on the
/// riser below it where `points` show one whole (see the module's doc); the segment keeps
/// its back edge, width, height and normal, and is marked [`PlaneSegment::front_on_riser`].
/// `ground_m` is the height of the surface the sensor stands over (the floor, or the tread
/// under the robot), which bounds the band of the lowest segment as a tread below does;
/// `noise_m`, the sweep's measured range noise, sets the least nosing believed.
/// Left as they are: a segment whose front does not face the sensor (the sensor past its
/// middle: a tread under or behind the robot), and a lone segment deeper than wide (with
/// no flight to give its ascent, its "front" may be a side: the step's side face or a
/// wall would be taken for its riser). Returns how many fronts moved.
pub fn place_fronts(
    segments: &mut [PlaneSegment],
    points: &[Point3<f32>],
    viewpoint: &Point3<f64>,
    ground_m: Option<f64>,
    noise_m: Option<f64>,
    p: &RiserParams,
) -> usize {
    if !p.enabled {
        return 0;
    }
    let heights: Vec<f64> = segments.iter().map(|s| s.height_m()).chain(ground_m).collect();
    let lone = segments.len() == 1;
    let least_m = NOSING_MIN_M.max(NOSING_NOISE_FACTOR * noise_m.unwrap_or(0.0));
    // Each segment's riser, and how far its nose projects past it where a nosing is seen.
    let found: Vec<Option<(f64, Option<f64>)>> = segments
        .par_iter()
        .map(|s| {
            if (viewpoint - s.center()).dot(&s.along()) >= 0.0 || (lone && s.depth_m() > s.width_m()) {
                return None;
            }
            let top = s.height_m();
            // The highest tread below this one (a rise of more than twice the band's near end).
            let below = heights
                .iter()
                .copied()
                .filter(|&h| h < top - 2.0 * p.band_m[0])
                .fold(f64::NEG_INFINITY, f64::max);
            let band = [(top - p.band_m[1]).max(below + p.band_m[0]), top - p.band_m[0]];
            let riser = riser_along(s, points, band, p)?;
            Some((riser, nosing_ahead(s, points, riser, least_m, p).map(|nose| nose - riser)))
        })
        .collect();
    // A flight's treads have one nosing (building codes: within a few millimetres): where
    // at least half the risers found show one, every front goes that far past its riser (the
    // median); else none does. Mixed, a tread whose nosing went unseen would keep its front
    // on the riser while the next one's moved to its nose, and the span between them lose a
    // nosing's depth.
    let risers = found.iter().flatten().count();
    let seen: Vec<f64> = found.iter().flatten().filter_map(|(_, n)| *n).collect();
    let nosing_m =
        if !seen.is_empty() && 2 * seen.len() >= risers { median(seen).unwrap_or(0.0) } else { 0.0 };
    let mut moved = 0;
    for (s, f) in segments.iter_mut().zip(found) {
        if let Some(placed) = f.and_then(|(riser, _)| with_front(s, riser + nosing_m)) {
            *s = placed.with_nosing_m(nosing_m);
            moved += 1;
        }
    }
    moved
}

/// The riser's distance from `s`'s centre toward its front (against its ascent), metres,
/// when the returns in `band` (heights) and the window about the front show one whole.
fn riser_along(s: &PlaneSegment, points: &[Point3<f32>], band: [f64; 2], p: &RiserParams) -> Option<f64> {
    if band[1] - band[0] < p.band_m[0] {
        return None;
    }
    let out = -s.along();
    let side = Vector3::new(-out.y, out.x, 0.0);
    let c = s.center();
    let front = s.depth_m() / 2.0;
    let half_width = s.width_m() / 2.0 - p.side_margin_m;
    // (distance toward the front from the centre, height) of each return in the box.
    let near: Vec<(f64, f64)> = points
        .iter()
        .map(|q| q.cast::<f64>())
        .filter(|q| q.z > band[0] && q.z < band[1])
        .map(|q| (q - c, q.z))
        .filter(|(d, _)| d.dot(&side).abs() < half_width)
        .map(|(d, z)| (d.dot(&out), z))
        .filter(|(t, _)| (t - front).abs() < p.half_window_m && t.is_finite())
        .collect();
    if near.len() < p.min_returns {
        return None;
    }
    // The median of the band's lower half, twice again over its returns within a halved
    // window about it: the riser's returns are a dense peak, the treads' strays a thin spread
    // on either side. Not the upper half: a nosing's face (as deep as the tread's thickness,
    // 25-40 mm) stands there a nosing's depth before the riser, and from near the flight it
    // shadows the riser's top; mixed in, its returns pull the riser out toward the nose
    // (regression `nosing-face-pulled-the-riser-out`).
    let mid = (band[0] + band[1]) / 2.0;
    let lower: Vec<f64> = near.iter().filter(|r| r.1 < mid).map(|r| r.0).collect();
    let mut at = median(lower.iter().copied())?;
    for w in [p.half_window_m / 2.0, p.half_window_m / 4.0] {
        at = median(lower.iter().copied().filter(|t| (t - at).abs() < w))?;
    }
    // Seen whole: returns about it in the band's lower half, and in its upper half either
    // its own or a nosing's face before it (which shadows the riser's top from near:
    // regression `riser-under-a-nosing-not-believed`).
    let at_riser = |t: f64| (t - at).abs() < p.half_window_m / 4.0;
    let lower = near.iter().filter(|r| r.1 < mid && at_riser(r.0)).count();
    let upper = near.iter().filter(|r| r.1 >= mid && (at_riser(r.0) || r.0 > at)).count();
    let least = (p.min_half_share * (lower + upper) as f64).ceil() as usize;
    let whole = lower + upper >= p.min_returns && upper >= least && lower >= least;
    whole.then_some(at)
}

/// The nose of a tread that projects past its riser (a nosing: IRC R311.7.5.3 asks for 19
/// to 32 mm on short treads), as a distance toward the front from `s`'s centre, the riser
/// being at `riser_m`: where the tread's own returns (within `band_m[0]` of its top) run on
/// past the riser, at least `min_returns` of them in the window's half beyond it, the nose
/// is the 70th percentile of the returns past the riser, at most the segment's own front. `None` for a riser under a plain nose: past it, at the top's height,
/// is air, and the segment's voxel front stands on or behind it.
fn nosing_ahead(
    s: &PlaneSegment,
    points: &[Point3<f32>],
    riser_m: f64,
    least_m: f64,
    p: &RiserParams,
) -> Option<f64> {
    let out = -s.along();
    let side = Vector3::new(-out.y, out.x, 0.0);
    let c = s.center();
    let top = s.height_m();
    let half_width = s.width_m() / 2.0 - p.side_margin_m;
    let top_returns: Vec<f64> = points
        .iter()
        .map(|q| q.cast::<f64>())
        .filter(|q| (q.z - top).abs() < p.band_m[0])
        .map(|q| q - c)
        .filter(|d| d.dot(&side).abs() < half_width)
        .map(|d| d.dot(&out) - riser_m)
        .collect();
    let ahead = top_returns.iter().filter(|t| **t > least_m && **t < p.half_window_m).count();
    // A nosing's top and face give past its least projection at least `NOSING_SHARE` of
    // the returns of a strip of the tread `NOSING_STRIP_M` deep behind the riser; a plain
    // nose's strays under range noise are a thin spread by the edge. And the segment's own
    // front, from its voxels, stands past the riser too: a plain tread's voxel front comes
    // back onto the tread under noise, rarely out past it.
    let behind = top_returns.iter().filter(|t| **t < 0.0 && **t > -NOSING_STRIP_M).count();
    let voxel_front_m = s.depth_m() / 2.0 - riser_m;
    if ahead < p.min_returns || (ahead as f64) < NOSING_SHARE * behind as f64 || voxel_front_m < least_m {
        return None;
    }
    // The nose: the 70th percentile of every return past the riser (the test above counts
    // only those past the least projection, which under noise lie past a short nosing's
    // nose): short of the nose by a few millimetres on its top's spread, past it by about as
    // much where its face's returns stray, at most the segment's own front.
    let mut past: Vec<f64> = top_returns.into_iter().filter(|t| *t > 0.0 && *t < p.half_window_m).collect();
    past.sort_by(f64::total_cmp);
    let k = ((past.len() - 1) as f64 * NOSE_QUANTILE).round() as usize;
    Some(riser_m + past[k].min(voxel_front_m))
}

/// Least projection past the riser of a nosing's returns, and of the tread's voxel front,
/// metres: IRC's least nosing is 19 mm, and under 20 mm of range noise a plain nose's voxel
/// front and a few dozen of its returns stray up to about 15 mm past the riser (the Exp. 1
/// flight's fronts, `tests/perception.rs`).
const NOSING_MIN_M: f64 = 0.015;

/// ... and at least this many times the sweep's measured range noise: at grazing incidence
/// a range error moves a return almost wholly along the tread, and under 20 mm of noise a
/// far plain nose's voxel front and returns stray past 15 mm (the Exp. 1 flight's top step,
/// `tests/perception.rs`). A nosing shorter than that under such noise is left on its
/// riser.
const NOSING_NOISE_FACTOR: f64 = 1.5;

/// The strip of a tread behind its riser that a nosing's returns are weighed against,
/// metres, and the share of its returns a nosing shows past `NOSING_MIN_M` (see
/// [`nosing_ahead`]).
const NOSING_STRIP_M: f64 = 0.035;
const NOSING_SHARE: f64 = 0.25;
/// The quantile of a nosing's returns past its riser taken for its nose.
const NOSE_QUANTILE: f64 = 0.7;

/// `s` with its front `front_m` from its old centre against its ascent, its back kept;
/// `None` when that leaves no depth.
fn with_front(s: &PlaneSegment, front_m: f64) -> Option<PlaneSegment> {
    let out = -s.along();
    let back_m = -s.depth_m() / 2.0;
    let depth_m = front_m - back_m;
    if depth_m <= 0.0 {
        return None;
    }
    let centre = s.center() + out * (front_m + back_m) / 2.0;
    PlaneSegment::new(centre, s.along(), depth_m, s.width_m(), s.normal().into_inner(), s.voxel_count())
        .map(|placed| placed.with_front_on_riser(true))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A level tread 1 m wide ascending along x, its nose at `front`, its top at `z`.
    fn tread(front: f64, z: f64, depth: f64) -> PlaneSegment {
        PlaneSegment::level_along_x(front, z, depth)
    }

    /// Returns on a vertical plane at x from z0 to z1 (every 5 mm), across |y| < 0.4.
    fn wall(x: f64, z0: f64, z1: f64) -> Vec<Point3<f32>> {
        let mut v = Vec::new();
        let mut z = z0;
        while z < z1 {
            for k in 0..40 {
                v.push(Point3::new(x as f32, (-0.4 + 0.02 * k as f64) as f32, z as f32));
            }
            z += 0.005;
        }
        v
    }

    /// Returns on a level patch at height z from x0 to x1 (every 2.5 mm), across |y| < 0.4.
    fn patch(x0: f64, x1: f64, z: f64) -> Vec<Point3<f32>> {
        let n = ((x1 - x0) / 0.0025).round() as usize;
        (0..=n)
            .flat_map(|i| {
                (0..40).map(move |k| {
                    Point3::new((x0 + 0.0025 * i as f64) as f32, (-0.4 + 0.02 * k as f64) as f32, z as f32)
                })
            })
            .collect()
    }

    #[test]
    fn a_nosing_past_its_riser_is_the_front_not_the_riser() {
        let eye = Point3::new(0.0, 0.0, 1.4);
        let p = RiserParams::default();
        // A tread 0.3 m up whose nose stands 25 mm before its riser (at 1.025 m); the
        // segment's front from voxels at 1.003.
        let seg = tread(1.003, 0.3, 0.297);
        let mut cloud = wall(1.025, 0.15, 0.27);
        cloud.extend(patch(1.0, 1.3, 0.3));
        let mut one = [seg.clone()];
        assert_eq!(place_fronts(&mut one, &cloud, &eye, None, None, &p), 1);
        let front = one[0].center().x - one[0].depth_m() / 2.0;
        // On the nose at 1.0, not the riser at 1.025: short of it by at most a centimetre
        // (the 70th percentile of its top's returns), never past it.
        assert!((1.0..1.01).contains(&front), "the front on the nose at 1.0, not the riser: {front:.4}");
        assert!(one[0].front_on_riser());
        // The same riser under a plain nose: the front on the riser.
        let mut plain = wall(1.025, 0.15, 0.3);
        plain.extend(patch(1.025, 1.3, 0.3));
        let mut one = [seg.clone()];
        assert_eq!(place_fronts(&mut one, &plain, &eye, None, None, &p), 1);
        let front = one[0].center().x - one[0].depth_m() / 2.0;
        assert!((front - 1.025).abs() < 1e-3, "{front:.4}");
    }

    #[test]
    fn a_nosings_face_does_not_pull_the_riser_out() {
        // A tread 0.3 m up, 30 mm thick, its nose 25 mm before its riser at 1.025 m, seen
        // from near: the face's returns (1.0 m, 0.27-0.3 m up) outnumber the riser's, whose
        // top the nosing shadows; both scattered 10 mm along the rays.
        let p = RiserParams::default();
        let seg = tread(1.003, 0.3, 0.297);
        let spread = |pts: Vec<Point3<f32>>| -> Vec<Point3<f32>> {
            pts.iter()
                .flat_map(|q| (-2..=2).map(move |k| Point3::new(q.x + 0.005 * k as f32, q.y, q.z)))
                .collect()
        };
        let mut cloud = spread(wall(1.025, 0.15, 0.265));
        // Its top shadowed to 0.245 m: the band's upper half holds the face alone.
        let mut shadowed = spread(wall(1.025, 0.15, 0.245));
        for _ in 0..3 {
            cloud.extend(spread(wall(1.0, 0.27, 0.3)));
            shadowed.extend(spread(wall(1.0, 0.27, 0.3)));
        }
        let band = [0.3 - p.band_m[1], 0.3 - p.band_m[0]];
        for pts in [cloud, shadowed] {
            let riser = riser_along(&seg, &pts, band, &p).expect("a riser seen whole");
            let at_x = seg.center().x - riser;
            assert!((at_x - 1.025).abs() < 2e-3, "the riser at {at_x:.4}, not 1.025");
        }
    }

    #[test]
    fn a_front_moves_onto_a_riser_seen_whole_and_only_then() {
        let eye = Point3::new(0.0, 0.0, 1.4);
        let p = RiserParams::default();
        // The segment's front 2.5 cm short of the true nose at 1.0 m, its back at 1.3 m.
        let seg = tread(1.025, 0.3, 0.275);
        let mut one = [seg.clone()];
        // Step 1's riser from the floor (z 0.15 below it) to its nose, plus strays of the
        // tread ahead of and behind the window.
        let mut riser = wall(1.0, 0.15, 0.3);
        riser.extend(wall(1.2, 0.285, 0.3));
        assert_eq!(place_fronts(&mut one, &riser, &eye, None, None, &p), 1);
        let front = one[0].center().x - one[0].depth_m() / 2.0;
        assert!((front - 1.0).abs() < 1e-3, "front at {front:.4}");
        assert!((one[0].center().x + one[0].depth_m() / 2.0 - 1.3).abs() < 1e-9, "the back kept");
        assert_eq!(one[0].height_m(), 0.3);
        assert!(one[0].front_on_riser());
        // A riser seen only in its upper part (a view over the nose): not believed.
        let mut part = [seg.clone()];
        assert_eq!(place_fronts(&mut part, &wall(1.0, 0.25, 0.3), &eye, None, None, &p), 0);
        assert_eq!(part[0], seg);
        // Nothing within the window (the true nose 10 cm off): not believed.
        let mut far = [seg.clone()];
        assert_eq!(place_fronts(&mut far, &wall(0.9, 0.15, 0.3), &eye, None, None, &p), 0);
        // Disabled: the rectangles as §4 gives them.
        let mut off = [seg.clone()];
        assert_eq!(
            place_fronts(&mut off, &riser, &eye, None, None, &RiserParams { enabled: false, ..p.clone() }),
            0
        );
        // Seen from past its middle (a tread under or behind the robot), its front does not
        // face the sensor: left as it is, whatever stands under its back edge.
        let mut back = [seg.clone()];
        let behind = Point3::new(1.2, 0.0, 1.4);
        assert_eq!(place_fronts(&mut back, &riser, &behind, None, None, &p), 0);
        assert_eq!(back[0], seg);
        // A lone segment deeper than wide may have its axes swapped: left as it is.
        let deep = PlaneSegment::new(Point3::new(1.5, 0.0, 0.3), Vector3::x(), 1.0, 0.4, Vector3::z(), 100)
            .expect("valid rectangle");
        let mut lone = [deep.clone()];
        assert_eq!(place_fronts(&mut lone, &wall(1.0, 0.15, 0.3), &eye, None, None, &p), 0);
        assert_eq!(lone[0], deep);
    }

    #[test]
    fn the_band_stops_above_the_tread_below() {
        // Treads 8 cm apart in height: the upper's band is 2-6 cm under its top, and the
        // lower tread's returns, scattered up to 1.5 cm above it, stay out of it (with the
        // band 2-8 cm under the top they outnumber the riser's and it is not believed).
        let eye = Point3::new(0.0, 0.0, 1.4);
        let p = RiserParams::default();
        let mut segs = [tread(0.5, 0.22, 0.3), tread(0.825, 0.30, 0.3)];
        let mut pts = wall(0.8, 0.22, 0.30);
        for k in 0..12 {
            for z in [0.225, 0.23, 0.235] {
                pts.extend(wall(0.776 + 0.002 * k as f64, z, z + 0.001));
            }
        }
        place_fronts(&mut segs, &pts, &eye, None, None, &p);
        let front = segs[1].center().x - segs[1].depth_m() / 2.0;
        assert!((front - 0.8).abs() < 1e-3, "front at {front:.4}");
        // The same with the lower tread known only as the ground under the sensor (the
        // floor, or the tread the robot stands on).
        let mut upper = [tread(0.825, 0.30, 0.3)];
        place_fronts(&mut upper, &pts, &eye, Some(0.22), None, &p);
        let front = upper[0].center().x - upper[0].depth_m() / 2.0;
        assert!((front - 0.8).abs() < 1e-3, "front at {front:.4}");
        let mut unbounded = [tread(0.825, 0.30, 0.3)];
        assert_eq!(
            place_fronts(&mut unbounded, &pts, &eye, None, None, &p),
            0,
            "the strays outnumber the riser"
        );
    }
}
