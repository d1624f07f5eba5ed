//! From RANSAC planes to the staircase's step rectangles (§4.3).
//!
//! 1. Each plane's inliers are split by cluster of supervoxels: a plane segment is one
//!    cluster's part of one plane (a plane through two steps' heights is impossible, since
//!    planes are near-horizontal; a plane at one height may hold several separate surfaces).
//! 2. Segments whose height extent (on their least-squares plane) exceeds epsilon are dropped; parts at one height whose
//!    voxels touch are joined (one tread the clustering cut into strips), and parts smaller
//!    than the sole are dropped (Filter 3's rule).
//! 3. The ground, the surface the robot stands on (the segment under the sensor, else the
//!    lowest segment), and every segment at its height, are set aside: they are the floor.
//!    So is every segment lower: the flight rises from the ground.
//! 4. The remaining segments are clustered by their (depth, width) with single linkage; the
//!    biggest cluster is the staircase (ties: the cluster nearest the sensor); a segment of
//!    another shape that continues the flight by a rise at either end (a top landing) joins
//!    it.
//! 5. The staircase's direction of ascent is the common axis of the segments' minimum-area
//!    rectangles (the flight's, landing included, weighed by size and elongation) that
//!    points up the stairs; each step's rectangle is the extent of its voxels
//!    along and across that direction, so a yawed staircase comes out right.

use super::ransac::Plane;
use super::supervoxel::{Clusters, Supervoxels, UNLABELLED};
use super::voxel::VoxelCloud;
use super::{NoStaircase, PerceptionError, PerceptionParams, PlaneSegment};
use crate::geom2d::{self, P2};
use nalgebra::{Point3, Unit, Vector3};
use rayon::prelude::*;

/// A candidate plane segment.
struct Candidate {
    voxels: Vec<u32>,
    xy: Vec<P2>,
    height: f64,
    normal: Vector3<f64>,
    /// (short side, long side) of the minimum-area rectangle, metres.
    shape: [f64; 2],
    /// Axis of the minimum-area rectangle.
    axis: P2,
    hull: Vec<P2>,
    centroid: P2,
}

/// The steps (lowest first), the number of candidate segments considered, and the ground's
/// height (the candidate under the sensor, else the lowest), metres. `sensor` is where the
/// sensor was at the sweep's end ([`crate::cloud::PointCloud::sensor_at_end`]): where the
/// robot stands, for a sweep taken walking too.
pub fn extract(
    vc: &VoxelCloud,
    sv: &Supervoxels,
    clusters: &Clusters,
    planes: &[Plane],
    sensor: &Point3<f64>,
    gravity: &Unit<Vector3<f64>>,
    p: &PerceptionParams,
) -> Result<(Vec<PlaneSegment>, usize, f64), PerceptionError> {
    let mut members: Vec<Vec<u32>> = vec![Vec::new(); sv.centres.len()];
    for (i, &l) in sv.labels.iter().enumerate() {
        if l != UNLABELLED {
            members[l as usize].push(i as u32);
        }
    }
    let up = -gravity.into_inner();
    let mut parts: Vec<Candidate> = Vec::new();
    for plane in planes {
        let mut by_cluster: Vec<(u32, Vec<u32>)> = Vec::new();
        for &s in &plane.inliers {
            let c = clusters.of_supervoxel[s as usize];
            match by_cluster.iter_mut().find(|e| e.0 == c) {
                Some(e) => e.1.push(s),
                None => by_cluster.push((c, vec![s])),
            }
        }
        for (_, svs) in by_cluster {
            if surface_height_extent_m(&sv.centres, &svs, &up) > p.max_height_extent_m {
                continue;
            }
            let voxels: Vec<u32> = svs.iter().flat_map(|&s| members[s as usize].iter().copied()).collect();
            parts.extend(candidate(vc, voxels, plane.normal.cast(), p));
        }
    }
    from_parts(vc, parts, planes.len(), sensor, gravity, p)
}

/// The steps, as [`extract`] gives them, from surfaces found another way: each a set of
/// `vc`'s voxels with its plane's normal (up), one surface each (a tread may come in
/// several pieces, which are joined as [`extract`] joins a plane's clusters). A surface
/// spanning more than epsilon in height on its own plane is dropped, as a plane's part is.
/// `planes` is how many planes they came from, for the error when none is a surface.
pub fn from_surfaces(
    vc: &VoxelCloud,
    surfaces: Vec<(Vec<u32>, Vector3<f64>)>,
    planes: usize,
    sensor: &Point3<f64>,
    gravity: &Unit<Vector3<f64>>,
    p: &PerceptionParams,
) -> Result<(Vec<PlaneSegment>, usize, f64), PerceptionError> {
    let up = -gravity.into_inner();
    // Each surface on its own (in parallel: the floor's is most of the work).
    let parts = surfaces
        .into_par_iter()
        .filter(|(voxels, _)| surface_height_extent_m(&vc.positions, voxels, &up) <= p.max_height_extent_m)
        .filter_map(|(voxels, normal)| candidate(vc, voxels, normal, p))
        .collect();
    from_parts(vc, parts, planes, sensor, gravity, p)
}

/// Steps 2 (from the joining on) to 5 of the module's doc, on the plane segments `parts`.
fn from_parts(
    vc: &VoxelCloud,
    parts: Vec<Candidate>,
    planes: usize,
    sensor: &Point3<f64>,
    gravity: &Unit<Vector3<f64>>,
    p: &PerceptionParams,
) -> Result<(Vec<PlaneSegment>, usize, f64), PerceptionError> {
    let up = -gravity.into_inner();
    // Filter 3's rule (§4.2) on each joined part too: RANSAC may split a cluster, and a
    // leftover whose footprint is smaller than the sole is not a foothold (a few voxels cut
    // off a tread would be taken for another step, turned), nor are voxels too few to cover
    // their footprint (`min_segment_cover`), nor a part whose own plane is steeper than
    // Filter 1's slope ([`is_surface`]).
    let cands: Vec<Candidate> =
        join_touching(vc, parts, p).into_iter().filter(|c| is_surface(c, &up, p)).collect();
    let n_candidates = cands.len();
    if cands.is_empty() {
        return Err(PerceptionError::NoStaircase(NoStaircase::NoFlatSegment {
            planes,
            epsilon_m: p.max_height_extent_m,
        }));
    }

    // The ground: under the sensor, else the lowest segment (a sloped floor may have failed
    // the epsilon test, as in the paper's own Exp. 1 data; the lowest flat piece is then floor).
    let below = P2::new(sensor.x, sensor.y);
    let ground = cands
        .iter()
        .position(|c| geom2d::contains(&c.hull, &below))
        .or_else(|| (0..cands.len()).min_by(|&a, &b| cands[a].height.total_cmp(&cands[b].height)))
        .unwrap_or(0);
    let ground_h = cands[ground].height;
    // The flight rises from the ground: what lies lower (the floor beside the stairs, seen
    // from a step) is no step of it.
    let steps: Vec<&Candidate> =
        cands.iter().filter(|c| c.height - ground_h > p.max_height_extent_m).collect();
    if steps.is_empty() {
        return Err(PerceptionError::NoStaircase(NoStaircase::OnlyGround {
            segments: n_candidates,
            ground_m: ground_h,
        }));
    }

    // Single-linkage clusters in (depth, width) space.
    let n = steps.len();
    let mut label: Vec<usize> = (0..n).collect();
    for i in 0..n {
        for j in 0..i {
            let d = ((steps[i].shape[0] - steps[j].shape[0]).powi(2)
                + (steps[i].shape[1] - steps[j].shape[1]).powi(2))
            .sqrt();
            if d <= p.shape_tolerance_m && label[i] != label[j] {
                let (from, to) = (label[i], label[j]);
                label.iter_mut().filter(|l| **l == from).for_each(|l| *l = to);
            }
        }
    }
    // Per cluster (labels are indices): its size, counted in heights (a flight rises; like
    // boxes side by side are one height however many, and do not win a tie with the
    // flight's steps as a "staircase": regression `two-boxes-taken-for-the-staircase`), and
    // its segment nearest the sensor.
    let mut heights: Vec<Vec<f64>> = vec![Vec::new(); n];
    let mut nearest = vec![f64::INFINITY; n];
    for (i, &l) in label.iter().enumerate() {
        heights[l].push(steps[i].height);
        nearest[l] = nearest[l].min((steps[i].centroid - below).norm());
    }
    let size: Vec<usize> = heights.iter().map(|h| levels(h, p.max_height_extent_m)).collect();
    let best = (0..n)
        .filter(|&l| size[l] > 0)
        .max_by(|&a, &b| size[a].cmp(&size[b]).then(nearest[b].total_cmp(&nearest[a])))
        .unwrap_or(0);
    let mut stair: Vec<&Candidate> = (0..n).filter(|&i| label[i] == best).map(|i| steps[i]).collect();
    stair.sort_by(|a, b| a.height.total_cmp(&b.height));

    let along = flight(&mut stair, &steps, &below, p);
    let segments = stair
        .iter()
        .filter_map(|c| {
            let left = P2::new(-along.y, along.x);
            let ra = dense_extent(&c.xy, &along, p.voxel_resolution_m, p.min_edge_row_fill);
            let rb = dense_extent(&c.xy, &left, p.voxel_resolution_m, p.min_edge_row_fill);
            let mid = along * (ra[0] + ra[1]) / 2.0 + left * (rb[0] + rb[1]) / 2.0;
            let centre = Point3::new(mid.x, mid.y, c.height);
            let along3 = Vector3::new(along.x, along.y, 0.0);
            PlaneSegment::new(centre, along3, ra[1] - ra[0], rb[1] - rb[0], c.normal, c.voxels.len())
        })
        .collect();
    Ok((segments, n_candidates, ground_h))
}

/// The extent [min, max] of `xy` along `u`, less what lies beyond an empty row at either
/// end: the points there, in rows (strips `row_m` wide across `u`) that hold fewer than
/// `min_fill` of the median row's points, are strays apart from the surface (see
/// `PerceptionParams::min_edge_row_fill`). The sparse rows next to the surface are its own
/// edge, cut by the voxel grid, and stay.
fn dense_extent(xy: &[P2], u: &P2, row_m: f64, min_fill: f64) -> [f64; 2] {
    let along: Vec<f64> = xy.iter().map(|q| q.dot(u)).collect();
    let lo = along.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = along.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if !(hi - lo).is_finite() || hi <= lo {
        return [lo, hi];
    }
    let row = |t: f64| ((t - lo) / row_m) as usize;
    let mut counts = vec![0usize; row(hi) + 1];
    for &t in &along {
        counts[row(t)] += 1;
    }
    let mut filled: Vec<usize> = counts.iter().copied().filter(|&n| n > 0).collect();
    filled.sort_unstable();
    let least = min_fill * filled[filled.len() / 2] as f64;
    let dense = |n: &usize| *n as f64 >= least;
    let (Some(first), Some(last)) = (counts.iter().position(dense), counts.iter().rposition(dense)) else {
        return [lo, hi];
    };
    // The rows kept: from past the last empty row before the first dense one, to before
    // the first empty row after the last dense one.
    let from = counts[..first].iter().rposition(|&n| n == 0).map_or(0, |e| e + 1);
    let to = counts[last..].iter().position(|&n| n == 0).map_or(counts.len(), |e| last + e);
    along
        .iter()
        .filter(|&&t| (from..to).contains(&row(t)))
        .fold([f64::INFINITY, f64::NEG_INFINITY], |[a, b], &t| [a.min(t), b.max(t)])
}

/// Whether a candidate is a surface a sole can use: its own plane, fitted through its
/// voxels, within Filter 1's slope of level (`up`: against gravity), its footprint (convex
/// hull) at least the sole's (Filter 3's rule), and its voxels covering at least
/// `min_segment_cover` of it. The slope is judged again on the segment because Filter 1
/// judged point normals and RANSAC the plane of the supervoxel centres, and both can be
/// noise: on a wall seen from close under 14 mm of range noise, 14 neighbours span less
/// than the noise across the line of sight, a few percent of the wall's normals come within
/// 15 deg of up, and they make a "step" on the wall whose voxels' own plane is far from
/// level (regression `wall-strip-taken-for-a-step`).
fn is_surface(c: &Candidate, up: &Vector3<f64>, p: &PerceptionParams) -> bool {
    let hull_m2 = geom2d::area(&c.hull);
    let cell_m2 = p.voxel_resolution_m * p.voxel_resolution_m;
    let cos_slope = p.normal_distance_threshold - 1.0;
    c.normal.dot(up).abs() >= cos_slope
        && hull_m2 >= p.foot_length_m * p.foot_width_m
        && c.voxels.len() as f64 * cell_m2 >= p.min_segment_cover * hull_m2
}

/// Δz of §4.3, the height a segment spans, measured on the least-squares plane through its
/// supervoxel centres `centres[idx]` (up: `up`) over their footprint: a tilted surface
/// spans its tilt times its size, a level one nothing, whatever the range noise. The
/// centres' own extent grows with the noise and their number: under 15 mm of noise a level
/// tread's centres span more than epsilon (regression
/// `noisy-centres-failed-the-height-extent`). Centres that span no plane are measured as
/// they are.
fn surface_height_extent_m(centres: &[Point3<f32>], idx: &[u32], up: &Vector3<f64>) -> f64 {
    let heights: Vec<f64> = match super::ransac::refit(centres, idx, &up.cast()) {
        Some((n, offset)) if n.cast::<f64>().dot(up) > 1e-3 => {
            let (n, offset) = (n.cast::<f64>(), f64::from(offset));
            let tilt = n - up * n.dot(up);
            // The plane's height above the centre's foot: (offset - tilt . p) / (n . up).
            idx.iter().map(|&i| (offset - tilt.dot(&centres[i as usize].coords.cast())) / n.dot(up)).collect()
        }
        _ => idx.iter().map(|&i| centres[i as usize].coords.cast::<f64>().dot(up)).collect(),
    };
    heights.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
        - heights.iter().cloned().fold(f64::INFINITY, f64::min)
}

/// How many distinct heights `heights` holds: sorted, a new one wherever two neighbours
/// differ by more than `epsilon_m` (0 for none).
fn levels(heights: &[f64], epsilon_m: f64) -> usize {
    let mut h = heights.to_vec();
    h.sort_by(f64::total_cmp);
    h.windows(2).filter(|w| w[1] - w[0] > epsilon_m).count() + usize::from(!h.is_empty())
}

/// Parts at one height (within the RANSAC inlier distance) whose voxels touch (within two
/// voxels) are one surface: the supervoxel clustering cut wide, low treads into strips
/// (pieces of one tread at one height are a rise of 0 and short treads to the planner), and
/// a plane's parts in different clusters were kept apart. Separate surfaces at one height
/// (a box top beside a tread) stay apart.
fn join_touching(vc: &VoxelCloud, parts: Vec<Candidate>, p: &PerceptionParams) -> Vec<Candidate> {
    let g = p.voxel_resolution_m;
    let cell = |v: u32| {
        let q = vc.positions[v as usize];
        ((f64::from(q.x) / g).floor() as i64, (f64::from(q.y) / g).floor() as i64)
    };
    // Each part's cells, built when a pair first passes the cheaper tests.
    let cells: Vec<std::cell::OnceCell<rustc_hash::FxHashSet<(i64, i64)>>> =
        parts.iter().map(|_| std::cell::OnceCell::new()).collect();
    let cells_of = |i: usize| cells[i].get_or_init(|| parts[i].voxels.iter().map(|&v| cell(v)).collect());
    let boxes: Vec<([f64; 2], [f64; 2])> = parts.iter().map(|c| geom2d::extents(&c.hull, &P2::x())).collect();
    let near = |i: usize, j: usize| {
        let ((xi, yi), (xj, yj)) = (boxes[i], boxes[j]);
        let reach = 2.0 * g + 1e-9;
        (parts[i].height - parts[j].height).abs() <= p.ransac_distance_m
            && xi[0] - reach <= xj[1]
            && xj[0] - reach <= xi[1]
            && yi[0] - reach <= yj[1]
            && yj[0] - reach <= yi[1]
            && cells_of(j)
                .iter()
                .any(|&(x, y)| (-2..=2).any(|dx| (-2..=2).any(|dy| cells_of(i).contains(&(x + dx, y + dy)))))
    };
    let n = parts.len();
    let mut label: Vec<usize> = (0..n).collect();
    for i in 0..n {
        for j in 0..i {
            if label[i] != label[j] && near(i, j) {
                let (from, to) = (label[i], label[j]);
                label.iter_mut().filter(|l| **l == from).for_each(|l| *l = to);
            }
        }
    }
    let mut groups: Vec<Vec<Candidate>> = (0..n).map(|_| Vec::new()).collect();
    for (c, l) in parts.into_iter().zip(label) {
        groups[l].push(c);
    }
    groups
        .into_iter()
        .flat_map(|group| match group.len() {
            0 => Vec::new(),
            1 => group,
            // A chain of pairs each within the RANSAC distance may span more than epsilon:
            // such a group stays in its parts.
            _ if group.iter().map(|c| c.height).fold(f64::NEG_INFINITY, f64::max)
                - group.iter().map(|c| c.height).fold(f64::INFINITY, f64::min)
                > p.max_height_extent_m =>
            {
                group
            }
            _ => {
                let normal = group.iter().map(|c| c.normal * c.voxels.len() as f64).sum::<Vector3<f64>>();
                let voxels: Vec<u32> = group.into_iter().flat_map(|c| c.voxels).collect();
                candidate(vc, voxels, normal.normalize(), p).into_iter().collect()
            }
        })
        .collect()
}

/// A segment of `voxels`, its normal fitted to them by least squares (`normal`, the
/// plane's, when they do not span a plane). RANSAC's plane is fitted to supervoxel centres,
/// a few dozen for a tread, and under 15 mm of range noise it can come out tilted by
/// degrees where the plane of the tread's hundreds of voxels is within half a degree
/// (regression `tilted-tread-and-sunk-landing`).
fn candidate(
    vc: &VoxelCloud,
    voxels: Vec<u32>,
    normal: Vector3<f64>,
    p: &PerceptionParams,
) -> Option<Candidate> {
    // The plane and height beside the footprint (a floor's thousands of voxels take
    // milliseconds each).
    let ((normal, height), footprint) = rayon::join(
        || {
            let up = normal.cast::<f32>();
            let normal = super::ransac::refit(&vc.positions, &voxels, &up).map_or(normal, |(n, _)| n.cast());
            let sum_m = voxels.iter().map(|&v| vc.positions[v as usize].z as f64).sum::<f64>();
            (normal, sum_m / voxels.len() as f64)
        },
        || {
            let xy: Vec<P2> =
                voxels.iter().map(|&v| vc.positions[v as usize].xy().coords.cast::<f64>()).collect();
            let hull = geom2d::convex_hull(&xy);
            let (axis, _, _) = geom2d::min_area_rect_of_hull(&hull)?;
            // The shape compared with other segments' is that of the rectangle the segment
            // would give as a step: without strays beyond an empty row ([`dense_extent`]). A
            // stray column past a tread's side made it a shape apart from its like steps, and
            // a level of clutter was taken for the staircase (test
            // `a_stray_column_does_not_split_the_flight`).
            let (v, fill) = (p.voxel_resolution_m, p.min_edge_row_fill);
            let (ra, rb) = rayon::join(
                || dense_extent(&xy, &axis, v, fill),
                || dense_extent(&xy, &P2::new(-axis.y, axis.x), v, fill),
            );
            let centroid = xy.iter().sum::<P2>() / xy.len() as f64;
            Some((xy, hull, axis, ra[1] - ra[0], rb[1] - rb[0], centroid))
        },
    );
    let (xy, hull, axis, a, b, centroid) = footprint?;
    Some(Candidate { voxels, xy, height, normal, shape: [a.min(b), a.max(b)], axis, hull, centroid })
}

/// §4.3 takes the steps as the biggest cluster of like-shaped segments, so a tread of
/// another depth at an end of the flight (a top landing, a deeper first step) was left out:
/// from the floor the loop never saw the landing, and from the last step it saw it with its
/// nose hidden under the sensor, 11 cm too far, and walked into its riser. A segment is
/// kept as the flight's continuation when it rises from the flight's top step (or drops to
/// its bottom one) by more than epsilon and at most `flight_max_rise_m`, its near edge is
/// within `flight_gap_m` of that step's far edge along the ascent (read again over the
/// flight as it grows: a strip of a step seen in part may be turned), and across it
/// overlaps that step by half the narrower width. A step seen in part, of another shape
/// than its neighbours, between two of the flight's steps is kept the same way, rising from
/// the one below (left out, it leaves a step missing to the planner: regression
/// `tread-split-in-two-under-20mm`). Repeated while one is added.
fn extend_flight<'a>(
    stair: &mut Vec<&'a Candidate>,
    others: &[&'a Candidate],
    sensor: &P2,
    p: &PerceptionParams,
) {
    let continues = |along: &P2, end: &Candidate, c: &Candidate, up: bool| {
        let rise = if up { c.height - end.height } else { end.height - c.height };
        let (ea, eb) = geom2d::extents(&end.xy, along);
        let (ca, cb) = geom2d::extents(&c.xy, along);
        let gap = if up { ca[0] - ea[1] } else { ea[0] - ca[1] };
        let overlap = eb[1].min(cb[1]) - eb[0].max(cb[0]);
        rise > p.max_height_extent_m
            && rise <= p.flight_max_rise_m
            && gap.abs() <= p.flight_gap_m
            && overlap >= 0.5 * (eb[1] - eb[0]).min(cb[1] - cb[0])
    };
    loop {
        let (Some(&top), Some(&bottom)) = (stair.last(), stair.first()) else { return };
        let along = &ascent_direction(stair, sensor, p);
        let continues = |end: &Candidate, c: &Candidate, up: bool| continues(along, end, c, up);
        let fresh = |c: &&&Candidate| !stair.iter().any(|s| std::ptr::eq(*s, **c));
        if let Some(c) = others.iter().filter(fresh).find(|c| continues(top, c, true)) {
            stair.push(c);
        } else if let Some(c) = others.iter().filter(fresh).find(|c| continues(bottom, c, false)) {
            stair.insert(0, c);
        } else if let Some((k, c)) = stair.windows(2).enumerate().find_map(|(k, w)| {
            others
                .iter()
                .filter(fresh)
                .find(|c| continues(w[0], c, true) && w[1].height - c.height > p.max_height_extent_m)
                .map(|c| (k, *c))
        }) {
            stair.insert(k + 1, c);
        } else {
            return;
        }
    }
}

/// The flight from its cluster `stair` (sorted by height): extended by the `others` that
/// continue it ([`extend_flight`]), and its direction of ascent over the whole flight: the
/// cluster alone may be one step seen in part, a strip whose turned axis would turn every
/// rectangle drawn along it (regression `strip-of-step-1-set-the-axis`).
fn flight<'a>(
    stair: &mut Vec<&'a Candidate>,
    others: &[&'a Candidate],
    sensor: &P2,
    p: &PerceptionParams,
) -> P2 {
    extend_flight(stair, others, sensor, p);
    ascent_direction(stair, sensor, p)
}

/// Unit horizontal direction of ascent of a staircase (steps sorted by height): the
/// rectangles' axes ([`rectangle_axes`]), turned toward the line through the steps' middles
/// as far as that line is surer ([`through_the_middles`]).
fn ascent_direction(stair: &[&Candidate], sensor: &P2, p: &PerceptionParams) -> P2 {
    let axes = rectangle_axes(stair, sensor);
    through_the_middles(stair, axes, p)
}

/// The direction of ascent `axes` turned toward the line through the middles (across) of
/// the steps in `stair` as wide as the flight, weighing the two by their variances.
///
/// A segment's minimum-area rectangle is drawn on its hull, the ragged outline that range
/// noise, dropouts and the world-aligned voxel grid leave (a stray voxel at a corner turns
/// it) by degrees, and so does their weighed mean, one axis for every step of a view; a
/// foot keeping its lane along it drifts sideways a step at a time until a landing is
/// refused as overhung (regression `rectangle-axes-drifted-the-lanes`). The steps' middles
/// across lie on the flight's axis however the grid falls: each is within about a quarter
/// voxel (its two side edges, each half a voxel, averaged), so over steps spread along the
/// flight their line's direction is known to `voxel / 2 / spread`, where a rectangle's axis
/// is known to about `voxel / its long side`. Steps narrower than the flight (a step seen
/// in part across, a landing of another width) are left out of the line. A step's middle
/// and width are those of the rectangle it will give ([`dense_extent`]), not its hull's:
/// a wall beside the flight returns a few points at a tread's height, a gap past its side,
/// and one such column widens the hull by the gap, moves its middle by half of it, and on
/// steps where it fell on alternate sides turned the line by degrees (regression
/// `wall-column-turned-the-flight`, the cell method).
fn through_the_middles(stair: &[&Candidate], axes: P2, p: &PerceptionParams) -> P2 {
    let across = P2::new(-axes.y, axes.x);
    let spans: Vec<(f64, f64, f64)> = stair
        .iter()
        .map(|c| {
            let ra = dense_extent(&c.xy, &axes, p.voxel_resolution_m, p.min_edge_row_fill);
            let rb = dense_extent(&c.xy, &across, p.voxel_resolution_m, p.min_edge_row_fill);
            ((ra[0] + ra[1]) / 2.0, (rb[0] + rb[1]) / 2.0, rb[1] - rb[0])
        })
        .collect();
    let widest = spans.iter().map(|s| s.2).fold(0.0, f64::max);
    let like: Vec<(f64, f64)> =
        spans.iter().filter(|s| s.2 >= widest - p.shape_tolerance_m / 2.0).map(|s| (s.0, s.1)).collect();
    if like.len() < 2 {
        return axes;
    }
    let n = like.len() as f64;
    let (mean_a, mean_b) = like.iter().fold((0.0, 0.0), |(a, b), s| (a + s.0 / n, b + s.1 / n));
    let spread_m2: f64 = like.iter().map(|s| (s.0 - mean_a).powi(2)).sum();
    if spread_m2 <= 0.0 {
        return axes;
    }
    let slope = like.iter().map(|s| (s.0 - mean_a) * (s.1 - mean_b)).sum::<f64>() / spread_m2;
    let v = p.voxel_resolution_m;
    let var_middles = (v / 4.0).powi(2) / spread_m2;
    let var_axes = (v / widest.max(v)).powi(2);
    let turn_rad = slope.atan() * var_axes / (var_axes + var_middles);
    let (s, c) = turn_rad.sin_cos();
    axes * c + across * s
}

/// The direction of ascent from the segments' rectangle axes (steps sorted by height).
fn rectangle_axes(stair: &[&Candidate], sensor: &P2) -> P2 {
    // The segments' rectangle axes, folded to [0, 90) degrees, averaged on the doubled
    // circle of period 90 degrees (angle x 4), weighted by segment size and by how long the
    // rectangle is against its width: a near-square one (a deep landing seen in part, often
    // the biggest segment in view: regression `strip-of-step-1-set-the-axis`) says little
    // of its axis.
    let (mut s, mut c) = (0.0, 0.0);
    for seg in stair {
        let a = seg.axis.y.atan2(seg.axis.x);
        let elongation = 1.0 - seg.shape[0] / seg.shape[1].max(1e-9);
        let w = seg.voxels.len() as f64 * elongation;
        s += w * (4.0 * a).sin();
        c += w * (4.0 * a).cos();
    }
    let a = s.atan2(c) / 4.0;
    let axes = [P2::new(a.cos(), a.sin()), P2::new(-a.sin(), a.cos())];
    // Which axis, and which way: up the stairs (lowest to highest step), or, for a single
    // step, away from the sensor. Between steps, from middle to middle of their outlines,
    // not from centroid to centroid: the voxels of a step seen in part crowd where the view
    // is open (the legs hide one side of the next step, its centroid lies far off its
    // middle across, and the flight's width may be taken for its ascent: regression
    // `crowded-centroid-turned-the-ascent`).
    let middle = |c: &Candidate| {
        let (ra, rb) = geom2d::extents(&c.hull, &axes[0]);
        axes[0] * ((ra[0] + ra[1]) / 2.0) + axes[1] * ((rb[0] + rb[1]) / 2.0)
    };
    let way = match (stair.first(), stair.last()) {
        (Some(lo), Some(hi)) if stair.len() >= 2 => middle(hi) - middle(lo),
        (Some(only), _) => only.centroid - sensor,
        _ => P2::x(),
    };
    let pick = if axes[0].dot(&way).abs() >= axes[1].dot(&way).abs() { axes[0] } else { axes[1] };
    if pick.dot(&way) < 0.0 {
        -pick
    } else {
        pick
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A level patch's centres with a height noise of +-2 cm (beyond epsilon's 3 cm from
    /// top to bottom), and a 10 deg ramp: the level one spans nothing, the ramp its tilt.
    #[test]
    fn a_surface_spans_its_tilt_not_its_noise() {
        let up = Vector3::z();
        let grid = |z: &dyn Fn(f32, f32, usize) -> f32| -> Vec<Point3<f32>> {
            (0..100)
                .map(|i| {
                    let (x, y) = ((i % 10) as f32 * 0.05, (i / 10) as f32 * 0.03);
                    Point3::new(x, y, z(x, y, i))
                })
                .collect()
        };
        let idx: Vec<u32> = (0..100).collect();
        // A deterministic +-2 cm scatter whose mean plane is level.
        let noisy =
            grid(&|_, _, i| 0.3 + if (i * 7919) % 13 < 6 { 0.02 } else { -0.02 } * ((i % 3) as f32 - 1.0));
        let raw = noisy.iter().map(|c| c.z).fold(f32::MIN, f32::max)
            - noisy.iter().map(|c| c.z).fold(f32::MAX, f32::min);
        assert!(f64::from(raw) > 0.03, "the centres themselves span {raw}");
        let level = surface_height_extent_m(&noisy, &idx, &up);
        assert!(level < 0.01, "a level patch spans {level}");
        let slope = 10f32.to_radians().tan();
        let ramp = grid(&|x, _, _| 0.3 + slope * x);
        let span = surface_height_extent_m(&ramp, &idx, &up);
        assert!((span - 0.45 * f64::from(slope)).abs() < 1e-4, "a 10 deg ramp 0.45 m long spans {span}");
        assert!(span > 0.03);
    }

    /// Voxels at `xy` (z = 0.3), as a candidate.
    fn candidate_of(xy: &[(f32, f32)]) -> Candidate {
        candidate_at(xy, 0.3)
    }

    /// Voxels at `xy` and height `z`, as a candidate.
    fn candidate_at(xy: &[(f32, f32)], z: f32) -> Candidate {
        let at: Vec<Point3<f32>> = xy.iter().map(|&(x, y)| Point3::new(x, y, z)).collect();
        candidate_on(&at)
    }

    /// Voxels at `at`, as a candidate (normal hint: up).
    fn candidate_on(at: &[Point3<f32>]) -> Candidate {
        let vc = voxel_cloud(at.to_vec());
        candidate(&vc, (0..at.len() as u32).collect(), Vector3::z(), &PerceptionParams::default())
            .expect("a candidate")
    }

    /// 2 cm voxels at `positions`, their normals up.
    fn voxel_cloud(positions: Vec<Point3<f32>>) -> VoxelCloud {
        let n = positions.len();
        VoxelCloud {
            resolution_m: 0.02,
            keys: vec![[0, 0, 0]; n],
            positions,
            normals: vec![Vector3::z(); n],
            counts: vec![1; n],
            adjacency: vec![1; n],
        }
    }

    /// A tread 0.3 by 1 m, every voxel seen or one row in two and one in three across (a
    /// far view's sampling), and a 5 cm strip of it, are surfaces; the stray of regression
    /// `scattered-floor-voxels-joined-the-flight`, 4 voxels at the corners of such a tread,
    /// is not, nor is a patch smaller than the sole.
    #[test]
    fn scattered_voxels_are_not_a_surface() {
        let p = PerceptionParams::default();
        let grid = |dx: usize, dy: usize, depth: f32| -> Vec<(f32, f32)> {
            let (nx, ny) = ((depth / 0.02) as usize, 50);
            (0..=nx)
                .step_by(dx)
                .flat_map(|i| (0..ny).step_by(dy).map(move |j| (i as f32 * 0.02, j as f32 * 0.02)))
                .collect()
        };
        assert!(is_surface(&candidate_of(&grid(1, 1, 0.3)), &Vector3::z(), &p));
        assert!(is_surface(&candidate_of(&grid(2, 3, 0.3)), &Vector3::z(), &p));
        assert!(is_surface(&candidate_of(&grid(1, 1, 0.05)), &Vector3::z(), &p));
        assert!(!is_surface(
            &candidate_of(&[(0.0, 0.0), (0.3, 0.0), (0.0, 1.0), (0.3, 1.0)]),
            &Vector3::z(),
            &p
        ));
        let small: Vec<(f32, f32)> =
            (0..50).map(|i| ((i % 10) as f32 * 0.02, (i / 10) as f32 * 0.02)).collect();
        assert!(
            !is_surface(&candidate_of(&small), &Vector3::z(), &p),
            "0.18 by 0.08 m: smaller than the sole"
        );
    }

    /// Regression `wall-strip-taken-for-a-step`: a strip 6 cm by 1.2 m on a wall, its
    /// voxels' plane 54.5 deg from level, is no surface, though its footprint holds a
    /// sole's area and its voxels cover it; the same strip level, or tilted 10 deg, is one,
    /// and tilted 20 deg (past Filter 1's 15) is not.
    #[test]
    fn a_strip_of_a_wall_is_not_a_surface() {
        let p = PerceptionParams::default();
        let strip = |tilt_deg: f32| -> Candidate {
            let slope = tilt_deg.to_radians().tan();
            let at: Vec<Point3<f32>> = (0..4)
                .flat_map(|i| (0..60).map(move |j| (i as f32 * 0.02, j as f32 * 0.02)))
                .map(|(x, y)| Point3::new(3.11 + x, y, 1.496 + slope * x))
                .collect();
            candidate_on(&at)
        };
        let wall = strip(54.5);
        assert!(geom2d::area(&wall.hull) >= p.foot_length_m * p.foot_width_m, "the footprint is a sole's");
        assert!(!is_surface(&wall, &Vector3::z(), &p), "a wall's strip taken for a surface");
        assert!(is_surface(&strip(0.0), &Vector3::z(), &p));
        assert!(is_surface(&strip(10.0), &Vector3::z(), &p));
        assert!(!is_surface(&strip(20.0), &Vector3::z(), &p), "a 20 deg ramp taken for a surface");
    }

    /// A tread of `depth_m` by `width_m` from `front_m` along x, turned `yaw_deg`, every
    /// 2 cm, at height `z`.
    fn tread(front_m: f32, depth_m: f32, width_m: f32, yaw_deg: f32, z: f32) -> Candidate {
        tread_seen(front_m, depth_m, width_m, yaw_deg, z, |_, _| true)
    }

    /// The voxels of [`tread`] that `seen(along_m, across_m)` keeps (tread coordinates
    /// from its front's middle).
    fn tread_seen(
        front_m: f32,
        depth_m: f32,
        width_m: f32,
        yaw_deg: f32,
        z: f32,
        seen: impl Fn(f32, f32) -> bool,
    ) -> Candidate {
        let (s, c) = yaw_deg.to_radians().sin_cos();
        let (nx, ny) = ((depth_m / 0.02) as usize, (width_m / 0.02) as usize);
        let xy: Vec<(f32, f32)> = (0..=nx)
            .flat_map(|i| (0..=ny).map(move |j| (i as f32 * 0.02, j as f32 * 0.02 - width_m / 2.0)))
            .filter(|&(a, b)| seen(a, b))
            .map(|(a, b)| ((front_m + a) * c - b * s, (front_m + a) * s + b * c))
            .collect();
        candidate_at(&xy, z)
    }

    /// Regression `riser-strays-moved-a-front-edge`, step 6 under 15 mm of range noise:
    /// rows of 2, 0 and 7 voxels ahead of its rows of 28 or more (the riser's top,
    /// scattered along the rays). What lies beyond the empty row is not tread; the sparse
    /// row next to it may be its edge cut by the grid and stays (Exp. 1's treads end in
    /// rows of 5 and 1 after rows of 20). A tread seen one row in two from afar keeps its
    /// whole depth.
    #[test]
    fn sparse_rows_beyond_a_gap_ahead_of_a_nose_are_not_tread() {
        let p = PerceptionParams::default();
        let v = p.voxel_resolution_m;
        let row = |along_m: f64, n: usize| (0..n).map(move |j| P2::new(along_m, j as f64 * v));
        // The tread from 0 to 0.26 m along x, 30 voxels a row; strays at -0.061 and -0.02 (off
        // the rows' bounds: the rows start at the lowest point).
        let tread: Vec<P2> = (0..=13).flat_map(|i| row(i as f64 * v, 30)).collect();
        let with_strays: Vec<P2> = row(-0.061, 2).chain(row(-0.02, 7)).chain(tread.iter().copied()).collect();
        let [front, back] = dense_extent(&with_strays, &P2::x(), v, p.min_edge_row_fill);
        assert!(
            (front + 0.02).abs() < 1e-9 && (back - 0.26).abs() < 1e-9,
            "the tread spans {front:.3}..{back:.3} m"
        );
        // Sparse edge rows with no gap: kept, at both ends.
        let cut: Vec<P2> =
            row(-0.041, 1).chain(row(-0.02, 5)).chain(tread.iter().copied()).chain(row(0.28, 2)).collect();
        assert_eq!(dense_extent(&cut, &P2::x(), v, p.min_edge_row_fill), [-0.041, 0.28]);
        // A stray row beyond an empty one at the back: dropped.
        let behind: Vec<P2> = tread.iter().copied().chain(row(0.30, 2)).collect();
        assert!((dense_extent(&behind, &P2::x(), v, p.min_edge_row_fill)[1] - 0.26).abs() < 1e-9);
        // One row in two seen: the whole depth.
        let sparse: Vec<P2> = (0..=13).step_by(2).flat_map(|i| row(i as f64 * v, 30)).collect();
        let [a, b] = dense_extent(&sparse, &P2::x(), v, p.min_edge_row_fill);
        assert!(a.abs() < 1e-9 && (b - 0.24).abs() < 1e-9, "{a}..{b}");
    }

    /// Regression `crowded-centroid-turned-the-ascent`, the view from step 3 of a flight
    /// yawed -19 degrees: the legs hide most of step 4 but its left side and a row along
    /// its back (its outline whole, its voxels crowded to one side: their centroid 0.35 m
    /// off its middle across); step 5 whole. The ascent is read from the steps' middles,
    /// not taken across the flight.
    #[test]
    fn a_step_seen_on_one_side_does_not_turn_the_flight() {
        let p = PerceptionParams::default();
        let yaw_deg = -19.3;
        let step_4 = tread_seen(0.0, 0.26, 1.44, yaw_deg, 0.64, |a, b| b > 0.1 || a > 0.24);
        let step_5 = tread(0.274, 0.27, 1.44, yaw_deg, 0.80);
        let sensor = P2::new(-0.5, 0.2);
        let along = ascent_direction(&[&step_4, &step_5], &sensor, &p);
        let off_deg = along.y.atan2(along.x).to_degrees() - f64::from(yaw_deg);
        assert!(off_deg.abs() < 2.0, "the flight's ascent is {off_deg:.1} deg off");
    }

    /// Regression `strip-of-step-1-set-the-axis`, the view from the foot of the flight: the
    /// cluster is a 13 cm strip of step 1 whose rectangle is turned 5 deg; step 2 and a
    /// deep landing continue it. The flight's ascent is read over all three (the strip
    /// still pulls it 1.4 deg), and step 2's rectangle along it is within 4 cm of its
    /// depth.
    #[test]
    fn a_strip_of_a_step_does_not_set_the_flights_axis() {
        let p = PerceptionParams::default();
        // Step 1's back 13 cm (its front hidden under the sensor), step 2, the landing.
        let strip = tread(0.132, 0.13, 1.13, 5.0, 0.187);
        let step_2 = tread(0.262, 0.262, 1.31, 0.0, 0.374);
        let landing = tread(0.524, 1.26, 1.31, 0.0, 0.561);
        let mut stair = vec![&strip];
        let others = [&strip, &step_2, &landing];
        let along = flight(&mut stair, &others, &P2::new(-0.9, 0.0), &p);
        assert_eq!(stair.len(), 3, "step 2 and the landing continue the strip");
        let off_deg = along.y.atan2(along.x).to_degrees();
        assert!(off_deg.abs() < 2.0, "the flight's ascent is {off_deg:.2} deg off");
        // Step 2's rectangle along it (along the strip's axis: 0.375 m on its 0.262 m).
        let (ra, _) = geom2d::extents(&step_2.xy, &along);
        assert!((ra[1] - ra[0] - 0.262).abs() < 0.04, "step 2 comes out {:.3} m deep", ra[1] - ra[0]);
    }

    /// A tread as the voxel grid sees it under noise: its surface every 5 mm, each point in
    /// the world-aligned 2 cm voxel it falls in (one voxel, at the cell's centre, per cell),
    /// its outline ragged as range noise and dropouts leave it: the cells within 3 cm inside
    /// its edges seen one in two, the cells up to 3 cm outside (stray returns) one in ten,
    /// at random (`draw`: a seeded draw in 0..1).
    fn ragged_tread(
        front_m: f64,
        depth_m: f64,
        width_m: f64,
        yaw_deg: f64,
        z: f32,
        draw: &mut impl FnMut() -> f64,
    ) -> Candidate {
        let (s, c) = yaw_deg.to_radians().sin_cos();
        let band_m = 0.03;
        let mut cells: Vec<(i64, i64, f64)> = Vec::new();
        let (nx, ny) =
            (((depth_m + 2.0 * band_m) / 0.005) as usize, ((width_m + 2.0 * band_m) / 0.005) as usize);
        for i in 0..=nx {
            for j in 0..=ny {
                let (a, b) = (i as f64 * 0.005 - band_m, j as f64 * 0.005 - band_m);
                // Signed distance inside the outline (negative: outside).
                let inside = a.min(depth_m - a).min(b).min(width_m - b);
                let seen = if inside < 0.0 {
                    0.1
                } else if inside < band_m {
                    0.5
                } else {
                    1.0
                };
                let (a, b) = (front_m + a, b - width_m / 2.0);
                let (x, y) = (a * c - b * s, a * s + b * c);
                cells.push(((x / 0.02).floor() as i64, (y / 0.02).floor() as i64, seen));
            }
        }
        // A cell is as likely seen as its most inside point.
        cells.sort_unstable_by(|p, q| (p.0, p.1).cmp(&(q.0, q.1)).then(q.2.total_cmp(&p.2)));
        cells.dedup_by_key(|c| (c.0, c.1));
        let xy: Vec<(f32, f32)> = cells
            .iter()
            .filter(|c| draw() < c.2)
            .map(|&(x, y, _)| ((x as f32 + 0.5) * 0.02, (y as f32 + 0.5) * 0.02))
            .collect();
        candidate_at(&xy, z)
    }

    /// Regression `rectangle-axes-drifted-the-lanes`: a flight of 0.338 m by 0.80 m treads
    /// yawed 9.5 degrees, 12 mm of range noise. Each tread's minimum-area rectangle is
    /// drawn on its ragged outline on the world-aligned voxel grid, and the rectangles'
    /// axes came out at 6.4-9.4 degrees: the feet keeping their lanes along them drifted
    /// sideways until a landing "would overhang its side". The line through the steps'
    /// middles knows the axis better: a third less off.
    #[test]
    fn the_flights_axis_is_read_through_the_steps_middles() {
        let p = PerceptionParams::default();
        let mut seed = 12345u64;
        let mut draw = move || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let sensor = P2::new(-1.0, 0.0);
        let (mut rect_deg2, mut flight_deg2) = (0.0, 0.0);
        let n = 40;
        for k in 0..n {
            let yaw_deg = 2.0 + 0.4 * k as f64;
            let treads: Vec<Candidate> = (0..5)
                .map(|i| {
                    ragged_tread(0.338 * i as f64, 0.338, 0.80, yaw_deg, 0.16 * (i + 1) as f32, &mut draw)
                })
                .collect();
            let stair: Vec<&Candidate> = treads.iter().collect();
            let off = |d: P2| (d.y.atan2(d.x).to_degrees() - yaw_deg).powi(2) / n as f64;
            rect_deg2 += off(rectangle_axes(&stair, &sensor));
            flight_deg2 += off(ascent_direction(&stair, &sensor, &p));
        }
        let (rect_deg, flight_deg): (f64, f64) = (rect_deg2.sqrt(), flight_deg2.sqrt());
        assert!(
            rect_deg > 0.4,
            "the rectangles' axes are {rect_deg:.2} deg off (rms): the case is not shown"
        );
        assert!(
            flight_deg < 0.67 * rect_deg,
            "the flight's ascent is {flight_deg:.2} deg off (rms), the rectangles' {rect_deg:.2}"
        );
    }

    /// Regression `wall-column-turned-the-flight`, the cell method's view from the floor of
    /// a flight 0.81 m wide yawed 17 deg between stairwell walls 6 cm past its sides: a
    /// wall's return at a tread's height joined steps 2 and 3 on the left and step 4 on
    /// the right, one column each. The flight's ascent stays within half a degree.
    #[test]
    fn a_wall_column_beside_a_tread_does_not_turn_the_flight() {
        let p = PerceptionParams::default();
        let yaw_deg = 17.0f32;
        let (s, c) = yaw_deg.to_radians().sin_cos();
        let stair: Vec<Candidate> = [1.0f32, 1.0, -1.0]
            .iter()
            .enumerate()
            .map(|(i, &side)| {
                let (front, z) = (0.37 * i as f32, 0.114 * (i + 2) as f32);
                let mut xy = tread(front, 0.36, 0.80, yaw_deg, z).xy;
                // The wall's column, at the tread's middle along it, 6 cm past its side.
                let (a, b) = (front + 0.18, side * (0.40 + 0.06));
                xy.push(P2::new(f64::from(a * c - b * s), f64::from(a * s + b * c)));
                let at: Vec<(f32, f32)> = xy.iter().map(|q| (q.x as f32, q.y as f32)).collect();
                candidate_at(&at, z)
            })
            .collect();
        let refs: Vec<&Candidate> = stair.iter().collect();
        let along = ascent_direction(&refs, &P2::new(-1.0, -0.3), &p);
        let off_deg = along.y.atan2(along.x).to_degrees() - f64::from(yaw_deg);
        assert!(off_deg.abs() < 0.5, "the flight's ascent is {off_deg:.2} deg off");
    }

    /// Voxels every 2 cm over `x0..x1`, `y0..y1` at height `z`.
    fn patch(x0: f32, x1: f32, y0: f32, y1: f32, z: f32) -> Vec<Point3<f32>> {
        let g = 0.02f32;
        let (nx, ny) = (((x1 - x0) / g).round() as usize, ((y1 - y0) / g).round() as usize);
        (0..nx)
            .flat_map(|i| {
                (0..ny).map(move |j| Point3::new(x0 + (i as f32 + 0.5) * g, y0 + (j as f32 + 0.5) * g, z))
            })
            .collect()
    }

    /// [`from_surfaces`] on `surfaces` (one level surface each), seen from `sensor`.
    fn on_surfaces(
        surfaces: &[Vec<Point3<f32>>],
        sensor: &Point3<f64>,
        p: &PerceptionParams,
    ) -> Result<(Vec<PlaneSegment>, usize, f64), PerceptionError> {
        let mut positions = Vec::new();
        let mut parts = Vec::new();
        for s in surfaces {
            let first = positions.len() as u32;
            positions.extend_from_slice(s);
            parts.push(((first..positions.len() as u32).collect::<Vec<u32>>(), Vector3::z()));
        }
        let gravity = Unit::new_normalize(-Vector3::z());
        from_surfaces(&voxel_cloud(positions), parts, surfaces.len(), sensor, &gravity, p)
    }

    /// `regress wide` case wide-0035 with the cell method, the loop's first view (not in
    /// the `regressions` suite, which runs the default method): step 2 carried one column
    /// 12 cm past the flight's side, step 3 was half hidden, and with the shapes taken from the hulls the
    /// three steps were three shapes apart; two clutter boxes beside the robot, one level,
    /// tied with them and were nearer, and the clutter's top (0.557 m) was taken for the
    /// staircase. The shapes compared are those of the steps' rectangles, strays left out.
    #[test]
    fn a_stray_column_does_not_split_the_flight() {
        let p = PerceptionParams::default();
        let mut step_2 = patch(1.28, 1.56, -0.84, 0.84, 0.342);
        step_2.extend([Point3::new(1.41, 0.97, 0.342)]);
        let surfaces = [
            patch(-1.0, 0.9, -1.0, 1.0, 0.0),
            patch(1.0, 1.28, -0.84, 0.84, 0.171),
            step_2,
            patch(1.56, 1.84, -0.84, 0.67, 0.514),
            patch(-0.4, 0.3, 0.6, 1.16, 0.557),
            patch(-0.4, 0.3, -1.22, -0.66, 0.557),
        ];
        let (steps, _, _) = on_surfaces(&surfaces, &Point3::new(0.0, 0.0, 1.5), &p).expect("steps");
        let heights: Vec<f64> = steps.iter().map(|s| (s.height_m() * 1000.0).round() / 1000.0).collect();
        assert_eq!(heights, [0.171, 0.342, 0.514], "the staircase found");
    }

    /// A robot on step 1 (its sensor above that tread), the floor beside the flight in sight
    /// past the handrail: a strip of it the steps' shape, lower than the ground. It is no
    /// step of the flight up from where the robot stands; taken for one (a sweep taken
    /// walking, `real-0001`'s seventh view), it turned the flight by 90 deg ("not a straight
    /// staircase").
    #[test]
    fn a_surface_lower_than_the_ground_is_no_step() {
        let p = PerceptionParams::default();
        let mut surfaces: Vec<Vec<Point3<f32>>> = (0..5)
            .map(|k| patch(1.2 + 0.26 * k as f32, 1.46 + 0.26 * k as f32, -0.62, 0.62, 0.19 * (k + 1) as f32))
            .collect();
        surfaces.push(patch(2.0, 3.2, -1.76, -1.46, 0.0));
        let sensor = Point3::new(1.34, 0.0, 1.7);
        let (steps, _, ground_m) = on_surfaces(&surfaces, &sensor, &p).expect("steps");
        let heights: Vec<f64> = steps.iter().map(|s| (s.height_m() * 100.0).round() / 100.0).collect();
        assert!((ground_m - 0.19).abs() < 1e-3, "the ground at {ground_m} m");
        assert_eq!(heights, [0.38, 0.57, 0.76, 0.95], "the flight found");
        for s in &steps {
            let off_deg = s.along().y.atan2(s.along().x).to_degrees();
            assert!(off_deg.abs() < 1.0, "a step turned {off_deg:.1} deg");
        }
    }

    #[test]
    fn levels_count_distinct_heights() {
        assert_eq!(levels(&[], 0.03), 0);
        assert_eq!(levels(&[0.377, 0.377], 0.03), 1);
        assert_eq!(levels(&[0.354, 0.178, 0.18], 0.03), 2);
    }
}
