//! The step map: the steps known so far, updated by each new view, and what the planner gets
//! next. The paper re-estimates the upper steps as the robot climbs (§5, §6.4); a step under
//! the lidar's blind spot stays as last seen. [`StepMap::next_input`] is the one function
//! that turns the known steps and a new view into the next plan's input: the closed loop,
//! `replay` and the tests all call it.

use super::{FrontMark, PlaneSegment};
use nalgebra::{Isometry3, Vector3};
use serde::{Deserialize, Serialize};

/// The median of `values` (0 without any).
fn median(values: impl Iterator<Item = f64>) -> f64 {
    let mut v: Vec<f64> = values.collect();
    v.sort_by(f64::total_cmp);
    match v.len() {
        0 => 0.0,
        n if n % 2 == 1 => v[n / 2],
        n => (v[n / 2 - 1] + v[n / 2]) / 2.0,
    }
}

/// The median of `values` when they agree: more than half of them within `agree_m` of it (0
/// without any, and one value agrees with itself); `None` when they do not, or for a NaN. A
/// drift moves every step of a view alike, so steps that disagree beyond what a view errs by
/// show a misread step, which a median of two would split: regression
/// `a-deep-read-tread-dragged-the-registration`. Two values agree when they lie within
/// twice `agree_m` of each other (their median is their middle).
fn agreed_median(values: impl Iterator<Item = f64>, agree_m: f64) -> Option<f64> {
    let v: Vec<f64> = values.collect();
    let m = median(v.iter().copied());
    let near = v.iter().filter(|x| (*x - m).abs() <= agree_m).count();
    (v.is_empty() || 2 * near > v.len()).then_some(m)
}

/// The median of the matched steps' side-edge shifts `edges` (each step's two: its low and
/// high edge across) when the steps agree on it: more than half of them moved whole, both
/// edges within `agree_m` of it. A drift moves every step of a view alike, both its edges
/// with it; a step whose edges moved apart, or alike but unlike the others', was misread on
/// a side at least. Counted by edges, two steps where one is misread whole (one edge
/// over-read into a stairwell's gap, the other cut short by as much) and one edge of the
/// other happens to move with it agree three to one (regression
/// `swaying-view-of-a-stairwell-moved-the-estimate`, test
/// `a_step_misread_whole_is_not_drift_across`). `None` when the steps do not agree, or for
/// a NaN.
fn agreed_by_whole_steps(edges: &[[f64; 2]], agree_m: f64) -> Option<f64> {
    let m = median(edges.iter().flatten().copied());
    let whole = edges.iter().filter(|e| e.iter().all(|x| (x - m).abs() <= agree_m)).count();
    (2 * whole > edges.len()).then_some(m)
}

/// Parameters of the step map.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct StepMapParams {
    /// Steps lower than the feet plus this are behind the robot, metres.
    pub ahead_margin_m: f64,
    /// A new view's rectangle replaces a known one at its height (within a third of this)
    /// whose centre is within this distance, whose footprint it overlaps, or which it lies
    /// beside across the ascent, over the same depth, less than this apart; known steps the
    /// new view misses (too close under the lidar, say) are kept. Metres.
    pub same_step_m: f64,
    /// A view's rectangle turned from the known step's by more than this (on the nearest of
    /// its axes) is not a view of that tread's outline, and gives it no edges; radians.
    /// 20 degrees: partial views of one tread come back turned by up to about 12 degrees and
    /// their edges still hold (regression `partial-view-turned-a-step`); a view whose flight
    /// axis comes from two near-square pieces under 20 mm of noise can come back turned 40
    /// degrees (regression `near-square-pieces-turned-the-view`).
    pub max_view_turn_rad: f64,
    /// A view's rectangle narrower than this across the flight's ascent (the known steps',
    /// else its own) holds no sole and is no step: a handrail's top, a shoe lying along the
    /// flight. A tread seen in part is cut along the ascent (shallow), not across it, and
    /// stays. HRP-4's sole is 0.13 m wide. Metres.
    pub min_width_m: f64,
    /// A view's rectangle lying over a lower tread (known, or in the same view) by more than
    /// this along the ascent stands on that tread (a parcel, a box left on it) and is no
    /// step: a flight's treads overlap by their nosings only (IRC R311.7.5.3: at most
    /// 32 mm), and perception's edges err by about 2 cm each. Metres.
    pub max_overlap_m: f64,
    /// A registration's correction (see [`StepMap::register`]) under this, along the ascent
    /// or in height, is left alone: a view's fronts on their risers err by about a
    /// centimetre under noise, and a correction from them would move a true estimate; the
    /// matched steps' shifts must agree within it too ([`StepMap::register`]). Metres.
    pub register_min_m: f64,
    /// A registration's correction over this is no drift but a mismatch (another step taken
    /// for a known one), and nothing is corrected. Metres.
    pub register_max_m: f64,
    /// A registration's turn about the vertical under this is left alone: the flight's axis
    /// read from a view's treads errs by a degree or two under 10 mm of range noise, more
    /// than odometry drifts in a flight; a turn beyond is a slip the view can tell. Radians.
    pub register_min_rad: f64,
}

impl Default for StepMapParams {
    fn default() -> Self {
        Self {
            ahead_margin_m: 0.05,
            same_step_m: 0.15,
            max_view_turn_rad: 20f64.to_radians(),
            min_width_m: crate::robot::hrp4::SOLE_SIZE_M[1],
            max_overlap_m: 0.08,
            register_min_m: 0.02,
            register_max_m: 0.12,
            register_min_rad: 3f64.to_radians(),
        }
    }
}

/// The next plan's input.
#[derive(Debug, Clone, PartialEq)]
pub struct NextInput {
    /// The known steps above the feet, the ones to plan on now, lowest first.
    pub ahead: Vec<PlaneSegment>,
    /// The lowest step left out for a closer look (with every step above it): it was seen
    /// shallower than a foot needs while lower steps remain ([`without_partial_top`]).
    pub deferred: Option<PlaneSegment>,
}

/// The steps known so far.
#[derive(Debug, Clone, Default)]
pub struct StepMap {
    /// Every step seen so far (new views first, then the known steps they did not match).
    pub known: Vec<PlaneSegment>,
}

impl StepMap {
    /// Merges a view's rectangles (see [`merge`]).
    pub fn update(&mut self, seen: Vec<PlaneSegment>, p: &StepMapParams) {
        let ascent = self.ascent();
        let treads: Vec<PlaneSegment> = self.known.iter().chain(&seen).cloned().collect();
        let seen = seen
            .into_iter()
            .filter(|s| {
                let along = ascent.unwrap_or(s.along());
                width_across_m(s, &along) >= p.min_width_m
                    && !treads.iter().any(|t| stands_on(s, t, &along, p))
            })
            .collect();
        self.known = merge(&self.known, seen, p);
    }

    /// The flight's ascent as the known steps give it: the axis of the one on most voxels.
    fn ascent(&self) -> Option<Vector3<f64>> {
        self.known.iter().max_by_key(|k| k.voxel_count()).map(|k| k.along())
    }

    /// Where a new view lies against the known steps: the rigid motion that moves the view's
    /// rectangles onto the known ones, when the robot's estimate of its pose (the view's
    /// frame) has drifted. Each of the view's steps is matched to the known step nearest in
    /// height whose riser (under its front) is within `register_max_m` of its own (along the
    /// known ascent).
    /// Then, each the median over the matched steps:
    /// - the turn about the vertical, from the treads' axes, of the steps whose fronts both
    ///   views placed on their risers (a riser is a long straight edge), about the view's
    ///   matched steps' middle;
    /// - along the ascent, from those steps' risers (where the flight is);
    /// - across it, from the treads' side edges, each edge of each matched step one vote (a
    ///   view's side edge is where its sight ended: a shadow, a post, the view's reach),
    ///   agreeing within `register_min_m` of each other, more than half the steps with both
    ///   edges among them;
    /// - in height, from the treads' heights.
    ///
    /// A turn under `register_min_rad` and a shift under `register_min_m` are left at zero,
    /// and so is a turn the side edges do not bear out (turned back, their spread across does
    /// not fall by half `register_min_m`: the treads' axes misread in place, one matched
    /// step, steps too close along the flight to tell);
    /// side edges that disagree (half or fewer of the steps with both edges within half
    /// `register_min_m` of the edges' median) leave the view uncorrected across only; a view
    /// that matches nothing, whose matched steps disagree in height or along the ascent (half
    /// or fewer within `register_min_m` of the median: the whole view is then not trusted),
    /// asks for a turn over 10 times `register_min_rad` or a shift over `register_max_m`, or
    /// would move the robot (at `viewpoint`, where the view was taken) by more than
    /// `register_max_m`, gives `None` (a mismatch, not drift). The turn is a plain median
    /// (the view's steps share one axis), and one matched step's shifts agree with
    /// themselves.
    pub fn register(
        &self,
        seen: &[PlaneSegment],
        viewpoint: &nalgebra::Point3<f64>,
        p: &StepMapParams,
    ) -> Option<Isometry3<f64>> {
        let along = self.ascent()?;
        // Along the ascent, views are matched and moved by their risers, not their fronts: a
        // front on a nose stands a nosing past its riser, and views see a nose differently
        // (from afar its top's returns spread along the tread and the nose reads centimetres
        // out; from near, under the nosing, the riser alone is seen): regression
        // `nose-read-from-afar-moved-the-estimate`, test `a_nose_seen_from_afar_is_not_drift`.
        let riser = |r: &PlaneSegment| r.riser_along(&along);
        // A pair further apart in height than half the flight's least rise is as near another
        // step as its own: no drift, a mismatch (a strip of a step seen past the legs has its
        // "front" mid-tread, by the next step's; test
        // `a_strip_by_the_next_front_is_not_matched_a_rise_away`).
        let max_dz_m = p.register_max_m.min(self.least_rise_m() / 2.0);
        let pairs: Vec<(&PlaneSegment, PlaneSegment)> = seen
            .iter()
            .filter_map(|s| {
                let s = axis_nearest(s, &along);
                let k = self
                    .known
                    .iter()
                    .filter(|k| (riser(k) - riser(&s)).abs() < p.register_max_m)
                    .min_by(|a, b| {
                        (a.height_m() - s.height_m()).abs().total_cmp(&(b.height_m() - s.height_m()).abs())
                    })?;
                ((k.height_m() - s.height_m()).abs() < max_dz_m).then_some((k, s))
            })
            .collect();
        if pairs.is_empty() {
            return None;
        }
        let on_risers = |(k, s): &&(&PlaneSegment, PlaneSegment)| k.front_on_riser() && s.front_on_riser();
        let turn = median(pairs.iter().filter(on_risers).map(|(k, s)| {
            let k = axis_nearest(k, &along).along();
            s.along().cross(&k).z.atan2(s.along().dot(&k))
        }));
        let turn = if turn.abs() < p.register_min_rad { 0.0 } else { turn };
        if turn.abs() > 10.0 * p.register_min_rad {
            return None;
        }
        let middle = pairs.iter().map(|(_, s)| s.center().coords).sum::<Vector3<f64>>() / pairs.len() as f64;
        let pivot = nalgebra::Translation3::from(middle);
        let turned_by = |turn: f64| -> Isometry3<f64> {
            pivot * nalgebra::UnitQuaternion::from_axis_angle(&Vector3::z_axis(), turn) * pivot.inverse()
        };
        let across = Vector3::z().cross(&along);
        // Across, from the treads' side edges, each one vote: an edge cut short by a shadow, a
        // handrail's post or the view's reach is one misread edge among them, where a tread's
        // middle would move with it (regression `one-tread-dragged-the-estimate-across`). An
        // edge is its width about its middle, whatever its rectangle's turn.
        let edges = |r: &PlaneSegment| {
            let (middle, half_width) =
                (r.center().coords.dot(&across), axis_nearest(r, &along).width_m() / 2.0);
            [middle - half_width, middle + half_width]
        };
        let votes = |pairs: &[(&PlaneSegment, PlaneSegment)], moved: &Isometry3<f64>| -> Vec<[f64; 2]> {
            pairs
                .iter()
                .map(|(k, s)| {
                    let (k, s) = (edges(k), edges(&s.clone().transformed(moved)));
                    [k[0] - s[0], k[1] - s[1]]
                })
                .collect()
        };
        // A turn is the estimate's only where the steps' places turned with their treads'
        // axes. A drift turns the whole view: the line of its steps with their treads, and
        // turned back their side edges agree across better than as they came. Treads whose
        // axes alone were misread (strays on a riser moved a front edge) turn about their own
        // middles: turned back, the steps away from the view's middle move across, their
        // edges agree less, and the turn would carry the robot sideways by the turn times
        // its distance from that middle (regression `riser-strays-moved-a-front-edge`). The
        // edges' spread (their median distance from their median) must fall by more than the
        // half of `register_min_m` within which edges agree: a side edge errs by a centimetre
        // or two, and steps close along the flight (one step, pieces of one tread) cannot tell
        // the two apart, and are not turned.
        let spread = |v: Vec<[f64; 2]>| {
            let m = median(v.iter().flatten().copied());
            median(v.iter().flatten().map(|x| (x - m).abs()))
        };
        let turn = match turn != 0.0
            && spread(votes(&pairs, &turned_by(turn))) + p.register_min_m / 2.0
                < spread(votes(&pairs, &Isometry3::identity()))
        {
            true => turn,
            false => 0.0,
        };
        let turned = turned_by(turn);
        let pairs: Vec<(&PlaneSegment, PlaneSegment)> =
            pairs.into_iter().map(|(k, s)| (k, s.transformed(&turned))).collect();
        let keep = |d: f64| if d.abs() < p.register_min_m { 0.0 } else { d };
        let agree_m = p.register_min_m;
        let dz = keep(agreed_median(pairs.iter().map(|(k, s)| k.height_m() - s.height_m()), agree_m)?);
        let d_along =
            keep(agreed_median(pairs.iter().filter(on_risers).map(|(k, s)| riser(k) - riser(s)), agree_m)?);
        // Across, the edges' votes agree within `register_min_m` of each other (half the
        // radius of the other shifts), more than half the steps moved whole
        // ([`agreed_by_whole_steps`]): the two edges of a lone tread agree as its widths do.
        // Edges that disagree say nothing across; the risers and the heights still stand.
        let d_across =
            agreed_by_whole_steps(&votes(&pairs, &Isometry3::identity()), agree_m / 2.0).map_or(0.0, keep);
        let shift = along * d_along + across * d_across + Vector3::z() * dz;
        if [d_along, d_across, dz].iter().any(|d| d.abs() > p.register_max_m) {
            return None;
        }
        let correction = nalgebra::Translation3::from(shift) * turned;
        // The turn is about the steps' middle: far from the robot, a turn within its bound
        // (near-square treads read turned) moves the robot farther than odometry drifts. The
        // robot, where the view was taken, moves by at most `register_max_m` (test
        // `a_turn_that_would_carry_the_robot_off_is_not_drift`).
        if (correction * viewpoint - viewpoint).norm() > p.register_max_m {
            return None;
        }
        (turn != 0.0 || shift != Vector3::zeros()).then_some(correction)
    }

    /// The least rise between two known steps of different heights (more than
    /// [`STANDING_ABOVE_M`] apart), metres; infinite with fewer than two heights.
    fn least_rise_m(&self) -> f64 {
        let mut heights: Vec<f64> = self.known.iter().map(PlaneSegment::height_m).collect();
        heights.sort_by(f64::total_cmp);
        heights
            .windows(2)
            .map(|w| w[1] - w[0])
            .filter(|&d| d > STANDING_ABOVE_M)
            .fold(f64::INFINITY, f64::min)
    }

    /// The steps higher than `feet_z` plus `margin_m` (the ones still to climb).
    pub fn ahead(&self, feet_z: f64, margin_m: f64) -> Vec<PlaneSegment> {
        self.known.iter().filter(|s| s.height_m() > feet_z + margin_m).cloned().collect()
    }

    /// Merges the view `seen` (the rectangles perception found; empty when it found none)
    /// and gives the next plan's input for feet at height `feet_z`: the steps ahead, without
    /// a partly seen top step when lower ones remain (a foot needs `min_tread_m`).
    pub fn next_input(
        &mut self,
        seen: Vec<PlaneSegment>,
        feet_z: f64,
        min_tread_m: f64,
        p: &StepMapParams,
    ) -> NextInput {
        self.update(seen, p);
        without_partial_top(self.ahead(feet_z, p.ahead_margin_m), min_tread_m)
    }
}

/// Whether `s` lies over the lower tread `t` by more than `max_overlap_m` along `along`
/// (and overlaps it across): something standing on that tread. Along the ascent a
/// rectangle lying along it (within `max_view_turn_rad`) reaches its depth about its
/// middle, whatever its small turn: a wide tread read turned reaches past its true edges at
/// its corners by half its width times the turn's sine, and by its corners the next tread
/// up stood over the one below and was left out of the map (regression
/// `a-turned-view-of-the-top-landing-taken-for-an-object`). A rectangle turned farther is
/// no view of a tread of this flight ([`merge_view`] takes no edges from it either): its
/// corners ([`span`]) are all that is known of its reach (regression
/// `lanes-at-the-limit-refused-on-the-flight`).
fn stands_on(s: &PlaneSegment, t: &PlaneSegment, along: &nalgebra::Vector3<f64>, p: &StepMapParams) -> bool {
    if t.height_m() > s.height_m() - STANDING_ABOVE_M {
        return false;
    }
    let across = nalgebra::Vector3::new(-along.y, along.x, 0.0);
    let reach = |r: &PlaneSegment| {
        let r = axis_nearest(r, along);
        if r.along().dot(along) >= p.max_view_turn_rad.cos() {
            let (middle, half) = (r.center().coords.dot(along), r.depth_m() / 2.0);
            [middle - half, middle + half]
        } else {
            span(&r, along)
        }
    };
    let overlap = |[a0, a1]: [f64; 2], [b0, b1]: [f64; 2]| a1.min(b1) - a0.max(b0);
    overlap(reach(s), reach(t)) > p.max_overlap_m && overlap(span(s, &across), span(t, &across)) > 0.0
}

/// Least height above a tread of a rectangle standing on it, metres (two views of one
/// tread differ by about a centimetre).
const STANDING_ABOVE_M: f64 = 0.03;

/// The extent of `s` across the horizontal direction `along`, metres.
fn width_across_m(s: &PlaneSegment, along: &nalgebra::Vector3<f64>) -> f64 {
    let across = nalgebra::Vector3::new(-along.y, along.x, 0.0);
    let t: Vec<f64> = s.corners().iter().map(|c| c.coords.dot(&across)).collect();
    t.iter().copied().fold(f64::NEG_INFINITY, f64::max) - t.iter().copied().fold(f64::INFINITY, f64::min)
}

/// `ahead` up to its lowest step that is shallower than a foot needs, when that is not the
/// next step: at the far edge of what the lidar sees, a tread is often seen only in part
/// (Exp. 2, seed 3: 11 cm of a 26.5 cm tread, from step 2), and planning the next stances
/// must not be refused for a step a later scan, from closer, sees whole. The steps above it
/// wait with it: the plan cannot pass a step it has no foothold on (a step left for later
/// while it was the top, then planned once a higher step came into view, was refused:
/// regression `deferred-step-planned-below-a-higher-one`). A staircase whose next step is
/// too shallow is still refused.
pub fn without_partial_top(mut ahead: Vec<PlaneSegment>, min_tread_m: f64) -> NextInput {
    ahead.sort_by(|a, b| a.height_m().total_cmp(&b.height_m()));
    let first_shallow = ahead.iter().skip(1).position(|s| s.depth_m() < min_tread_m).map(|i| i + 1);
    let deferred = first_shallow.and_then(|i| ahead.drain(i..).next());
    NextInput { ahead, deferred }
}

/// The steps as known after a view: the new rectangles, plus the known ones no new rectangle
/// matches. Where a new rectangle matches a known one, the two views are merged
/// ([`merge_view`]): the one on more voxels, reaching to the other's front and back edges
/// where they are farther out (each view misses part of a tread: its front close to the
/// riser, its back from afar), or where they were placed on their risers. New rectangles
/// that are one step, once merged (a view that split a tread in two), are one: two at one
/// height would leave the first no depth up to the "next" one's front, and its foot on the
/// nose (regression `tread-split-in-two-under-20mm`).
pub fn merge(known: &[PlaneSegment], seen: Vec<PlaneSegment>, p: &StepMapParams) -> Vec<PlaneSegment> {
    let matches = |a: &PlaneSegment, b: &PlaneSegment| same_step(a, b, p);
    let merged = |s: &PlaneSegment, k: &PlaneSegment| merge_view(s, k, p.max_view_turn_rad);
    let kept: Vec<PlaneSegment> =
        known.iter().filter(|k| !seen.iter().any(|s| matches(k, s))).cloned().collect();
    let mut updated: Vec<PlaneSegment> = Vec::with_capacity(seen.len());
    for s in seen {
        let s = match known.iter().find(|k| matches(k, &s)) {
            Some(k) => merged(&s, k),
            None => s,
        };
        match updated.iter_mut().find(|u| matches(u, &s)) {
            Some(u) => *u = merged(&s, u),
            None => updated.push(s),
        }
    }
    updated.into_iter().chain(kept).collect()
}

/// Whether `a` and `b` are views of one tread: at one height (within `same_step_m / 3`),
/// and centred within `same_step_m` of each other, or with overlapping footprints, or side
/// by side. Centres alone missed partial views of a deep tread: from the last step, the near
/// 6 cm of a 1.27 m landing has its centre 0.6 m from the whole landing's, and both stayed
/// in the map, two treads at one height (a rise of 0, a stride backwards: Exp. 2 refused at
/// step 9).
fn same_step(a: &PlaneSegment, b: &PlaneSegment, p: &StepMapParams) -> bool {
    if (a.height_m() - b.height_m()).abs() >= p.same_step_m / 3.0 {
        return false;
    }
    if (a.center() - b.center()).norm() < p.same_step_m {
        return true;
    }
    // Two rectangles overlap when no axis of either separates them (separating axes).
    let overlap = |x: [f64; 2], y: [f64; 2]| x[1].min(y[1]) - x[0].max(y[0]) > 0.0;
    let overlapping = [a.along(), b.along()].iter().all(|u| {
        let w = nalgebra::Vector3::z().cross(u);
        overlap(span(a, u), span(b, u)) && overlap(span(a, &w), span(b, &w))
    });
    overlapping || side_by_side(a, b, p)
}

/// The extent of `r`'s corners along `axis`.
fn span(r: &PlaneSegment, axis: &nalgebra::Vector3<f64>) -> [f64; 2] {
    r.corners().iter().fold([f64::INFINITY, f64::NEG_INFINITY], |[lo, hi], c| {
        let t = c.coords.dot(axis);
        [lo.min(t), hi.max(t)]
    })
}

/// Whether `a` and `b` are two pieces of one tread side by side: lying along each other
/// (within `max_view_turn_rad`), over the same depth (their spans along the ascent overlap
/// by at least half the shallower's), less than `same_step_m` apart across. Under 20 mm of
/// noise one end of a tread may be seen from afar and its middle from nearer, a few
/// millimetres apart; kept as two treads at one height, the first has no depth up to the
/// next one's front (regression `noisy-views-in-pieces-and-turned`). Treads of a flight are
/// a rise apart in height; at one height and over one depth, pieces side by side are one.
fn side_by_side(a: &PlaneSegment, b: &PlaneSegment, p: &StepMapParams) -> bool {
    let u = a.along();
    let b = axis_nearest(b, &u);
    if b.along().dot(&u) < p.max_view_turn_rad.cos() {
        return false;
    }
    let w = nalgebra::Vector3::z().cross(&u);
    let (a_along, b_along) = (span(a, &u), span(&b, &u));
    let shared = a_along[1].min(b_along[1]) - a_along[0].max(b_along[0]);
    let shallower = (a_along[1] - a_along[0]).min(b_along[1] - b_along[0]);
    let (a_across, b_across) = (span(a, &w), span(&b, &w));
    let gap = (b_across[0] - a_across[1]).max(a_across[0] - b_across[1]);
    shared >= shallower / 2.0 && gap < p.same_step_m
}

/// The new view `s` of the known step `k`: the view of the two that rests on more voxels
/// (the fuller), stretched along the ascent to the other's edges where they reach farther,
/// since each view misses part of a tread (the legs hide its front from close, the next
/// nose its back from afar, a sparse view ends short: regression
/// `sparse-view-cut-a-tread-short`). An edge is as far as a view surely saw tread
/// ([`surely_seen`]), not a yawed rectangle's corner nor a turned one's edge midpoint
/// (regression `noisy-views-in-pieces-and-turned`); a view turned beyond `max_turn_rad`
/// gives no edges ([`StepMapParams::max_view_turn_rad`]). The rest is the fuller view's,
/// since a view of part of a tread gets it wrong: its height (regression
/// `tilted-tread-and-sunk-landing`), direction (regression `partial-view-turned-a-step`),
/// sides (regression `side-view-narrowed-a-step`) and plane. An edge placed on its riser
/// (perception's `riser`) outranks one from voxels; of two alike, the farther stays.
fn merge_view(s: &PlaneSegment, k: &PlaneSegment, max_turn_rad: f64) -> PlaneSegment {
    let (fuller, other) = if k.voxel_count() > s.voxel_count() { (k, s) } else { (s, k) };
    // Which of its axes is the ascent, a view of one tread only guesses (see
    // `axis_nearest`): the known step's says, even when the new view is the fuller (the top
    // tread alone in view: regression `top-tread-alone-axes-swapped`).
    let fuller = axis_nearest(fuller, &k.along());
    let along = fuller.along();
    let other = axis_nearest(other, &along);
    if other.along().dot(&along) < max_turn_rad.cos() {
        return fuller;
    }
    let c = fuller.center();
    // A front on its riser (or its face) is the median across the tread, its middle: no
    // inward bound for a turned view (see `surely_seen`).
    let fronts = [&fuller, &other].map(|r| match r.front_measured() {
        true => {
            ((r.center() - r.along() * (r.depth_m() / 2.0) - c).dot(&along), r.front_mark(), r.nosing_m())
        }
        false => (surely_seen(r, &c, &along, -1.0), FrontMark::Voxels, 0.0),
    });
    // A front placed on its riser is the nose, and stands against one from voxels, which
    // errs by centimetres under noise (perception's `riser`); one on its face likewise, but
    // gives way to one on a riser (hundreds of returns over the rise, against a face's few
    // over its thickness); of two alike, the farther out (with its nosing).
    let [a, b] = fronts;
    let (front, mark, nosing_m) = match a.1.cmp(&b.1) {
        std::cmp::Ordering::Greater => a,
        std::cmp::Ordering::Less => b,
        std::cmp::Ordering::Equal if a.0 <= b.0 => a,
        std::cmp::Ordering::Equal => b,
    };
    // Likewise a back placed on the riser above it stands against one from voxels or cells,
    // which runs past that riser under noise (perception's `riser::place_edges`).
    let backs = [&fuller, &other].map(|r| match r.back_on_riser() {
        true => ((r.center() + r.along() * (r.depth_m() / 2.0) - c).dot(&along), true),
        false => (surely_seen(r, &c, &along, 1.0), false),
    });
    let (back, back_on_riser) = match backs {
        [b @ (_, true), (_, false)] | [(_, false), b @ (_, true)] => b,
        [a, b] => {
            if a.0 >= b.0 {
                a
            } else {
                b
            }
        }
    };
    PlaneSegment::new(
        c + along * ((front + back) / 2.0),
        along,
        back - front,
        fuller.width_m(),
        fuller.normal().into_inner(),
        fuller.voxel_count(),
    )
    .map(|m| m.with_front(mark).with_nosing_m(nosing_m).with_back_on_riser(back_on_riser))
    .unwrap_or(fuller)
}

/// How far along `along` (from `c`) the view `r` surely saw tread at its front (`sign`
/// -1) or back (+1) edge: the edge's midpoint, drawn inward by `width/2 * sin(turn)`, the
/// turn being the angle between `r`'s axis and `along`. A view's rectangle is the extent of
/// its voxels along its own axes, so they touch its front edge somewhere along it; when the
/// rectangle is turned against the known ascent, that touching point lies anywhere within
/// `width/2 * sin(turn)` of the midpoint along the ascent, and only the inner bound is
/// sure. A turned rectangle of a tread reaches beyond it at both ends by about
/// `(width * sin(turn) * cos(turn) - depth * sin(turn)^2) / 2`: its midpoints, taken as
/// edges, stretch a merged step centimetres beyond the tread at 20 degrees, and a heel
/// planned on it comes down over the front edge below (regression
/// `noisy-views-in-pieces-and-turned`). For a view along the known ascent, the midpoint.
fn surely_seen(
    r: &PlaneSegment,
    c: &nalgebra::Point3<f64>,
    along: &nalgebra::Vector3<f64>,
    sign: f64,
) -> f64 {
    let sin_turn = r.along().cross(along).norm();
    let midpoint = (r.center() + r.along() * (sign * r.depth_m() / 2.0) - c).dot(along);
    midpoint - sign * r.width_m() / 2.0 * sin_turn
}

/// `r`, the same rectangle, described with the one of its four horizontal axes (ascent,
/// left, their opposites) nearest `along` as its direction of ascent. Which of a
/// rectangle's axes is the ascent is perception's guess, from the view alone; with a single
/// tread in view it guesses from the direction to the sensor, and close to a riser (the
/// sensor almost over the nose) it took the tread's width for its depth (regression
/// `tread-width-taken-for-its-depth`).
fn axis_nearest(r: &PlaneSegment, along: &nalgebra::Vector3<f64>) -> PlaneSegment {
    let u = r.along();
    let left = nalgebra::Vector3::z().cross(&u);
    let (depth, width) = (r.depth_m(), r.width_m());
    let axes = [(u, depth, width), (left, width, depth), (-u, depth, width), (-left, width, depth)];
    let best = axes.iter().max_by(|a, b| a.0.dot(along).total_cmp(&b.0.dot(along)));
    match best {
        Some(&(axis, d, w)) if axis != u => {
            PlaneSegment::new(r.center(), axis, d, w, r.normal().into_inner(), r.voxel_count())
                .unwrap_or_else(|| r.clone())
        }
        _ => r.clone(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Point3, Vector3};

    /// A level rectangle (see `PlaneSegment::new`).
    fn level(
        center: Point3<f64>,
        along: Vector3<f64>,
        depth_m: f64,
        width_m: f64,
        voxels: usize,
    ) -> PlaneSegment {
        PlaneSegment::new(center, along, depth_m, width_m, Vector3::z(), voxels).expect("valid rectangle")
    }

    fn step(x: f64, z: f64, depth_m: f64) -> PlaneSegment {
        level(Point3::new(x, 0.0, z), Vector3::x(), depth_m, 0.5, 10)
    }

    /// A flight along x: treads 0.28 m deep whose fronts stand on their risers, at `(riser
    /// x, height)` each.
    fn on_risers(risers: &[(f64, f64)]) -> Vec<PlaneSegment> {
        risers.iter().map(|&(x, z)| step(x + 0.14, z, 0.28).with_front(FrontMark::Riser)).collect()
    }

    /// A view taken under odometry drift (the robot believes itself 4 cm farther up the
    /// flight and 2.5 cm higher than it is) is registered on the known steps before it is
    /// merged: merged as it came, each step would stretch 4 cm toward the robot (the nearer
    /// of two fronts on their risers is kept), a heel planned there over the nose below.
    #[test]
    fn a_view_under_odometry_drift_is_registered_before_it_is_merged() {
        let p = StepMapParams::default();
        let origin = Point3::new(0.3, 0.0, 1.4);
        let truth = [(0.735, 0.2), (1.005, 0.4), (1.275, 0.6)];
        let known: Vec<PlaneSegment> =
            truth.iter().map(|&(x, z)| step(x, z, 0.27).with_front(FrontMark::Riser)).collect();
        let map = StepMap { known: known.clone() };
        let drift = Vector3::new(0.04, 0.0, 0.025);
        let seen: Vec<PlaneSegment> = known.iter().map(|k| k.clone().moved(&drift)).collect();
        let naive = merge(&known, seen.clone(), &p);
        assert!(naive.iter().all(|r| (r.depth_m() - 0.31).abs() < 1e-9), "merged as it came: 4 cm deeper");
        let correction = map.register(&seen, &origin, &p).expect("a correction");
        assert!((correction.translation.vector + drift).norm() < 1e-9, "{correction:?}");
        let registered: Vec<PlaneSegment> = seen.into_iter().map(|s| s.transformed(&correction)).collect();
        let merged = merge(&known, registered, &p);
        for (r, (x, z)) in merged.iter().zip(truth) {
            assert!((r.center().x - x).abs() < 1e-9 && (r.height_m() - z).abs() < 1e-9, "{r:?}");
            assert!((r.depth_m() - 0.27).abs() < 1e-9);
        }
        // Under a centimetre (a view's own error), or a step away (a mismatch): nothing.
        let small: Vec<PlaneSegment> =
            known.iter().map(|k| k.clone().moved(&Vector3::new(0.01, 0.0, 0.005))).collect();
        assert_eq!(map.register(&small, &origin, &p), None);
        let far: Vec<PlaneSegment> =
            known.iter().map(|k| k.clone().moved(&Vector3::new(0.27, 0.0, 0.0))).collect();
        assert_eq!(map.register(&far, &origin, &p), None, "a step's depth away is not drift");
    }

    /// `regress envelope` case envelope-0005 on the robot's estimate: 10 cm rises, the view
    /// from step 1 sees step 2 only as a 7 cm strip past the legs (its "front" mid-tread,
    /// 6 cm from step 3's) and step 3 whole. The strip matched step 3 by its front, half the
    /// median asked the estimate 5 cm up, step 2 fell below the feet and the plan was
    /// refused. A pair half a rise apart is no drift: nothing is corrected.
    #[test]
    fn a_strip_by_the_next_front_is_not_matched_a_rise_away() {
        let p = StepMapParams::default();
        let origin = Point3::new(0.5, 0.0, 1.5);
        let map = StepMap { known: on_risers(&[(0.60, 0.1), (0.88, 0.2), (1.16, 0.3)]) };
        let seen = vec![step(1.128, 0.199, 0.067), step(1.30, 0.299, 0.28).with_front(FrontMark::Riser)];
        assert_eq!(map.register(&seen, &origin, &p), None);
        // Drift of 2.5 cm in height is still found on such a flight.
        let drifted: Vec<PlaneSegment> =
            seen.iter().map(|s| s.clone().moved(&Vector3::new(0.0, 0.0, -0.025))).collect();
        let dz = map.register(&drifted, &origin, &p).expect("a correction").translation.vector.z;
        assert!((dz - 0.026).abs() < 1e-9, "{dz}");
    }

    /// Regression `nose-read-from-afar-moved-the-estimate`: known steps whose fronts were read
    /// on their noses from afar, centimetres past their risers, and a view from near that saw
    /// the risers alone. The risers agree: nothing is corrected, and a 4 cm drift is still
    /// found.
    #[test]
    fn a_nose_seen_from_afar_is_not_drift() {
        let p = StepMapParams::default();
        let origin = Point3::new(0.3, 0.0, 1.4);
        let risers = [(0.60, 0.18), (0.88, 0.36), (1.16, 0.54)];
        let nose_out_m = 0.035;
        let known: Vec<PlaneSegment> = risers
            .iter()
            .map(|&(x, z)| {
                let depth_m = 0.28 + nose_out_m;
                step(x - nose_out_m + depth_m / 2.0, z, depth_m)
                    .with_front(FrontMark::Riser)
                    .with_nosing_m(nose_out_m)
            })
            .collect();
        let map = StepMap { known };
        let seen = on_risers(&risers);
        assert_eq!(map.register(&seen, &origin, &p), None);
        let drifted: Vec<PlaneSegment> =
            seen.iter().map(|s| s.clone().moved(&Vector3::new(-0.04, 0.0, 0.0))).collect();
        let dx = map.register(&drifted, &origin, &p).expect("a correction").translation.vector.x;
        assert!((dx - 0.04).abs() < 1e-9, "{dx}");
    }

    /// Regression `a-deep-read-tread-dragged-the-registration`: one tread read 61 mm deeper
    /// toward the robot than it is (its riser with it), the next as known. Steps that
    /// disagree on a shift are a mismatch (a median of two would split them); a step off
    /// among agreeing ones is outvoted.
    #[test]
    fn steps_that_disagree_on_the_shift_are_not_drift() {
        let p = StepMapParams::default();
        let origin = Point3::new(0.3, 0.0, 1.4);
        let risers = [(0.60, 0.18), (0.88, 0.36), (1.16, 0.54)];
        let map = StepMap { known: on_risers(&risers) };
        let deep_m = 0.061;
        let mut seen = on_risers(&risers);
        seen[1] =
            step(risers[1].0 + 0.14 - deep_m / 2.0, risers[1].1, 0.28 + deep_m).with_front(FrontMark::Riser);
        assert_eq!(map.register(&seen[1..], &origin, &p), None, "two steps that disagree");
        let drifted: Vec<PlaneSegment> =
            seen.into_iter().map(|s| s.moved(&Vector3::new(-0.03, 0.0, 0.0))).collect();
        let dx = map.register(&drifted, &origin, &p).expect("a correction").translation.vector.x;
        assert!((dx - 0.03).abs() < 1e-9, "{dx}");
    }

    /// Regression `one-tread-dragged-the-estimate-across`: four treads between handrails,
    /// each side edge read differently by two views (posts and shadows cut them short by
    /// centimetres either way), one tread's width alike in both and its middle moved. The
    /// edges do not agree on a shift: nothing is corrected across (a shift taken from the
    /// one tread of like width would move the estimate 41 mm), while a drift in height is
    /// still found. A lone tread's edges must agree as its widths do. A drift across moves
    /// every edge alike and is found with one edge cut short.
    #[test]
    fn edges_that_disagree_across_are_not_drift() {
        let p = StepMapParams::default();
        let origin = Point3::new(0.0, 0.0, 1.4);
        let risers = [(0.94, 0.18), (1.21, 0.36), (1.48, 0.55), (1.75, 0.73)];
        let across = |edges: [(f64, f64); 4]| -> Vec<PlaneSegment> {
            risers
                .iter()
                .zip(edges)
                .map(|(&(x, z), (lo, hi))| {
                    level(Point3::new(x + 0.135, (lo + hi) / 2.0, z), Vector3::x(), 0.27, hi - lo, 10)
                        .with_front(FrontMark::Riser)
                })
                .collect()
        };
        let known = [(-0.434, 0.535), (-0.423, 0.501), (-0.416, 0.497), (-0.358, 0.497)];
        let seen = [(-0.411, 0.521), (-0.424, 0.528), (-0.382, 0.545), (-0.327, 0.488)];
        let map = StepMap { known: across(known) };
        assert_eq!(map.register(&across(seen), &origin, &p), None);
        let lower: Vec<PlaneSegment> =
            across(seen).into_iter().map(|s| s.moved(&Vector3::new(0.0, 0.0, -0.03))).collect();
        let shift = map.register(&lower, &origin, &p).expect("a correction").translation.vector;
        assert!((shift - Vector3::new(0.0, 0.0, 0.03)).norm() < 1e-9, "{shift}");
        // One tread alone, 10 mm off and one edge read 38 mm short besides: its edges do not
        // agree (taken as agreeing at their middle, they would ask for 29 mm).
        let lone = StepMap { known: across(known)[..1].to_vec() };
        let (lo, hi) = known[0];
        let cut = [(lo - 0.01, hi - 0.01 - 0.038), (0.0, 0.1), (0.0, 0.1), (0.0, 0.1)];
        assert_eq!(lone.register(&across(cut)[..1], &origin, &p), None);
        let drift_m = 0.03;
        let mut drifted = known.map(|(lo, hi)| (lo - drift_m, hi - drift_m));
        drifted[2].1 -= 0.05;
        let dy = map.register(&across(drifted), &origin, &p).expect("a correction").translation.vector.y;
        assert!((dy - drift_m).abs() < 1e-9, "{dy}");
    }

    /// Regression `swaying-view-of-a-stairwell-moved-the-estimate` (cycle 14, from step 7):
    /// step 8 and the landing of a flight between stairwell walls 5.8 cm off its sides. The
    /// view read step 8 whole 4.5-4.9 cm across from the map (one edge over-read into the
    /// gap, the other cut short), and the landing's near edge 3.4 cm, its far edge 0.8 cm:
    /// three edges of four within a centimetre of their median, the estimate moved 40 mm by
    /// them. One step of two moved whole is no drift across. Two steps of three moved whole,
    /// one edge of the third cut short, are drift still.
    #[test]
    fn a_step_misread_whole_is_not_drift_across() {
        let p = StepMapParams::default();
        let origin = Point3::new(3.55, -0.75, 2.25);
        // (riser x, height, depth, side edges across) of steps 7 and 8 and the landing.
        let truth = [
            (3.46, 0.995, 0.31, [-0.86, 0.33]),
            (3.77, 1.138, 0.31, [-0.8484, 0.3252]),
            (4.08, 1.281, 1.5, [-0.8757, 0.3154]),
        ];
        // The steps from `truth[from]` on, with side edges `edges`.
        let flight = |from: usize, edges: &[[f64; 2]]| -> Vec<PlaneSegment> {
            truth[from..]
                .iter()
                .zip(&edges[from..])
                .map(|(&(x, z, depth_m, _), &[lo, hi])| {
                    level(
                        Point3::new(x + depth_m / 2.0, (lo + hi) / 2.0, z),
                        Vector3::x(),
                        depth_m,
                        hi - lo,
                        800,
                    )
                    .with_front(FrontMark::Riser)
                })
                .collect()
        };
        let known = truth.map(|t| t.3);
        let map = StepMap { known: flight(1, &known) };
        let map3 = StepMap { known: flight(0, &known) };
        let seen = [known[0], [-0.8035, 0.3744], [-0.8412, 0.3235]];
        assert_eq!(map.register(&flight(1, &seen), &origin, &p), None);
        // A drift of 3 cm across, the landing's far edge cut 5 cm short besides.
        let drift_m = 0.03;
        let mut drifted = known.map(|[lo, hi]| [lo - drift_m, hi - drift_m]);
        drifted[2][1] -= 0.05;
        assert_eq!(map.register(&flight(1, &drifted), &origin, &p), None, "one step of two moved whole");
        let dy = map3.register(&flight(0, &drifted), &origin, &p).expect("a correction").translation.vector.y;
        assert!((dy - drift_m).abs() < 1e-9, "two steps of three moved whole: {dy}");
    }

    /// Regression `riser-strays-moved-a-front-edge`: a view from step 2 whose treads' axes
    /// were all read 4.4 deg turned (strays on a riser moved a front edge; one axis for the
    /// view's steps), each rectangle about its own middle, the steps where they are. Turned
    /// back about the steps' middle, the outer steps would move 20 mm across each way and the
    /// robot 61 mm sideways: no turn is corrected. The same view turned 4.4 deg about the
    /// robot, as a drift of its estimate's yaw turns it, is turned back, and the robot stays
    /// where it was.
    #[test]
    fn treads_misread_turned_in_place_are_not_a_turn_of_the_estimate() {
        let p = StepMapParams::default();
        let robot = Point3::new(0.5, 0.0, 1.8);
        let risers = [(0.9, 0.72), (1.165, 0.9), (1.43, 1.08)];
        let tread = |(x, z): (f64, f64), axis: Vector3<f64>| {
            level(Point3::new(x + 0.1325, 0.0, z), axis, 0.265, 1.23, 800).with_front(FrontMark::Riser)
        };
        let map = StepMap { known: risers.iter().map(|&r| tread(r, Vector3::x())).collect() };
        let turn = nalgebra::UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 4.4f64.to_radians());
        let misread: Vec<PlaneSegment> = risers.iter().map(|&r| tread(r, turn * Vector3::x())).collect();
        let yaw = |c: Option<Isometry3<f64>>| c.map_or(0.0, |c| c.rotation.euler_angles().2);
        assert_eq!(yaw(map.register(&misread, &robot, &p)), 0.0, "a misread is no turn");
        let about_robot = nalgebra::Translation3::from(robot.coords);
        let drift: Isometry3<f64> = about_robot * turn * about_robot.inverse();
        let drifted: Vec<PlaneSegment> = map.known.iter().map(|k| k.clone().transformed(&drift)).collect();
        let back = map.register(&drifted, &robot, &p).expect("a correction");
        assert!((back.rotation.euler_angles().2.to_degrees() + 4.4).abs() < 1e-6, "{back:?}");
        assert!((back * robot - robot).norm() < p.register_min_m, "{back:?}");
    }

    /// `regress ci` case ci-0195, third draw, on the robot's estimate: a 0.45 m wide
    /// flight's near-square treads read 28.8 deg turned, and the turn, within its bound, about
    /// the steps' middle 1.4 m away, moved the robot 0.72 m (the estimate 655 mm off). A
    /// correction that would move the robot farther than `register_max_m` is a mismatch; the
    /// same view seen from beside the steps' middle is still turned back.
    #[test]
    fn a_turn_that_would_carry_the_robot_off_is_not_drift() {
        let p = StepMapParams::default();
        let known: Vec<PlaneSegment> = [(1.2, 0.17), (1.48, 0.34), (1.76, 0.51)]
            .iter()
            .map(|&(x, z)| {
                level(Point3::new(x, 0.0, z), Vector3::x(), 0.28, 0.45, 10).with_front(FrontMark::Riser)
            })
            .collect();
        let map = StepMap { known: known.clone() };
        let middle = nalgebra::Translation3::new(1.48, 0.0, 0.0);
        let turned: Isometry3<f64> = middle
            * nalgebra::UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 25f64.to_radians())
            * middle.inverse();
        let seen: Vec<PlaneSegment> = known.iter().map(|k| k.clone().transformed(&turned)).collect();
        assert_eq!(map.register(&seen, &Point3::new(0.0, 0.0, 1.4), &p), None, "from the floor, 1.5 m off");
        let beside = map.register(&seen, &Point3::new(1.48, 0.05, 1.4), &p).expect("a correction");
        let yaw_deg = beside.rotation.euler_angles().2.to_degrees();
        assert!((yaw_deg + 25.0).abs() < 1e-6, "turned back by {yaw_deg} deg");
    }

    /// The next tread up, read turned (a wide landing seen from the step below), is a step,
    /// not something standing on the tread below: by their corners the two overlap along the
    /// ascent by half their widths times their turns' sines more at each end. The rectangles
    /// of `ci-0145`'s fourth view at x 2 (the tread below as the map had it, 7 cm too deep
    /// and turned -1.3 deg; the landing above turned 2.4 deg): 11.9 cm by the corners, 7.4
    /// by the depths. A parcel standing on the tread is still left out.
    #[test]
    fn a_wide_tread_read_turned_is_not_standing_on_the_one_below() {
        let p = StepMapParams::default();
        let below = level(
            Point3::new(2.0615, 0.1161, 0.776),
            Vector3::new(0.99973, -0.02303, 0.0),
            0.379,
            1.422,
            3000,
        );
        let landing = level(
            Point3::new(2.4879, 0.1475, 0.930),
            Vector3::new(0.99913, 0.04173, 0.0),
            0.622,
            1.387,
            1990,
        );
        let mut map = StepMap { known: vec![below.clone()] };
        map.update(vec![landing], &p);
        assert_eq!(map.known.len(), 2, "the landing is kept: {:?}", map.known);
        let parcel = level(Point3::new(2.02, 0.3, 0.976), Vector3::x(), 0.3, 0.4, 300);
        let mut map = StepMap { known: vec![below] };
        map.update(vec![parcel], &p);
        assert_eq!(map.known.len(), 1, "a parcel on the tread is not a step");
    }

    /// A rectangle turned farther from the ascent than `max_view_turn_rad` is no view of a
    /// tread of the flight, and its corners are its reach: two pieces of treads beside a bag
    /// (`lanes-at-the-limit-refused-on-the-flight`'s second view, their axes misread 24 deg
    /// off a flight yawed 11.7 deg) stand one on the other and the upper is left out, as
    /// before; by their depths about their middles both stayed, and the plan refused the
    /// flight as not straight.
    #[test]
    fn a_piece_turned_beyond_a_view_of_the_flight_is_judged_by_its_corners() {
        let p = StepMapParams::default();
        let ascent = Vector3::new(0.97931, 0.20236, 0.0);
        let flight = level(Point3::new(2.1790, 0.5608, 0.675), ascent, 0.353, 0.946, 591);
        let misread = Vector3::new(-0.59299, 0.80521, 0.0);
        let lower = level(Point3::new(1.6277, 0.0177, 0.328), misread, 0.350, 0.312, 125);
        let upper = level(Point3::new(1.9291, 0.0436, 0.503), misread, 0.307, 0.322, 79);
        let mut map = StepMap { known: vec![flight] };
        map.update(vec![lower, upper], &p);
        assert_eq!(map.known.len(), 2, "{:?}", map.known);
        assert!(
            !map.known.iter().any(|k| (k.height_m() - 0.503).abs() < 1e-9),
            "the upper piece is left out"
        );
    }

    #[test]
    fn a_partial_view_does_not_shrink_a_step_and_a_new_one_is_added() {
        let known = vec![step(0.735, 0.2, 0.27), step(1.005, 0.4, 0.27)];
        // From close to the riser: step 2's far half only, step 1 unseen, step 3 new.
        let seen = vec![step(1.08, 0.4, 0.12), step(1.275, 0.6, 0.27)];
        let merged = merge(&known, seen, &StepMapParams::default());
        assert_eq!(merged.len(), 3);
        let at = |z: f64| merged.iter().find(|r| (r.height_m() - z).abs() < 1e-9).expect("step at z");
        assert_eq!(at(0.2).depth_m(), 0.27, "step 1, unseen, is kept");
        assert!((at(0.4).depth_m() - 0.27).abs() < 1e-9, "step 2 keeps its whole tread");
        assert!((at(0.4).center().x - 1.005).abs() < 1e-9);
        assert!((at(0.6).depth_m() - 0.27).abs() < 1e-9, "step 3 is added");
        // A re-estimate on as many voxels takes its own height and back edge, and the nearer nose.
        let merged = merge(&known, vec![step(1.01, 0.41, 0.26)], &StepMapParams::default());
        let s2 = merged.iter().find(|r| (r.height_m() - 0.41).abs() < 1e-9).expect("re-estimated");
        assert!(!merged.iter().any(|r| (r.height_m() - 0.4).abs() < 1e-9));
        let (front, back) = (s2.center().x - s2.depth_m() / 2.0, s2.center().x + s2.depth_m() / 2.0);
        assert!((front - 0.87).abs() < 1e-9 && (back - 1.14).abs() < 1e-9, "{front} {back}");
    }

    /// A front placed on its riser stands against a view's from voxels farther out (under
    /// noise those err by centimetres, and the farther out of two had put the nose over
    /// air), whichever view is the fuller; two from voxels, or two on risers, the farther.
    #[test]
    fn a_front_on_its_riser_stands_against_one_from_voxels() {
        let p = StepMapParams::default();
        let front = |r: &PlaneSegment| r.center().x - r.depth_m() / 2.0;
        // Known: the nose at 0.87 on its riser; seen nearer, its front 2 cm out, from voxels.
        let on_riser = step(1.005, 0.4, 0.27).with_front(FrontMark::Riser);
        let out = level(Point3::new(0.995, 0.0, 0.4), Vector3::x(), 0.29, 0.5, 20);
        let merged = merge(std::slice::from_ref(&on_riser), vec![out.clone()], &p);
        assert!(
            (front(&merged[0]) - 0.87).abs() < 1e-9 && merged[0].front_on_riser(),
            "{}",
            front(&merged[0])
        );
        assert!((front(&merged[0]) + merged[0].depth_m() - 1.14).abs() < 1e-9, "the back kept");
        // The other way round, the new view on its riser: the same.
        let merged = merge(std::slice::from_ref(&out), vec![on_riser.clone()], &p);
        assert!((front(&merged[0]) - 0.87).abs() < 1e-9 && merged[0].front_on_riser());
        // A view turned 5 degrees, its front on the riser: its middle, not drawn inward by
        // half its width's turn (the riser's median lies across the whole tread).
        let turn = 5f64.to_radians();
        let turned =
            level(Point3::new(1.005, 0.0, 0.4), Vector3::new(turn.cos(), turn.sin(), 0.0), 0.27, 1.0, 20)
                .with_front(FrontMark::Riser);
        let merged = merge(std::slice::from_ref(&out), vec![turned], &p);
        let nose = merged[0].center().x - merged[0].depth_m() / 2.0 * merged[0].along().x;
        assert!((nose - (1.005 - 0.135 * turn.cos())).abs() < 2e-3, "{nose}");
        // Both from voxels: the farther out, as before.
        let merged = merge(std::slice::from_ref(&step(1.005, 0.4, 0.27)), vec![out.clone()], &p);
        assert!((front(&merged[0]) - 0.85).abs() < 1e-9 && !merged[0].front_on_riser());
        // A front on its own face (an open riser) stands against one from voxels as one on a
        // riser does, either way round, and gives way to one on a riser.
        let on_face = step(1.005, 0.4, 0.27).with_front(FrontMark::Face);
        let riser_in = step(1.015, 0.4, 0.25).with_front(FrontMark::Riser);
        // (one view, the other, the front kept, whether it is on a riser)
        for (a, b, at, on_riser) in [(&on_face, &out, 0.87, false), (&on_face, &riser_in, 0.89, true)] {
            for (known, seen) in [(a, b), (b, a)] {
                let merged = merge(std::slice::from_ref(known), vec![seen.clone()], &p);
                let m = &merged[0];
                let marks = (m.front_on_riser(), m.front_on_face());
                assert!(
                    (front(m) - at).abs() < 1e-9 && marks == (on_riser, !on_riser),
                    "{} {marks:?}",
                    front(m)
                );
            }
        }
    }

    /// Likewise a back placed on the riser above it stands against a view's from voxels
    /// farther out (under noise those run past that riser, and the farther of two views'
    /// backs would keep a tread deeper than it is: a foot in its middle against the riser),
    /// whichever view is the fuller; two from voxels, the farther.
    #[test]
    fn a_back_on_its_riser_stands_against_one_from_voxels() {
        let p = StepMapParams::default();
        let back = |r: &PlaneSegment| r.center().x + r.depth_m() / 2.0;
        // Known: the back at 1.14 on its riser; seen again, 6 cm past it, from voxels, fuller.
        let on_riser = step(1.005, 0.4, 0.27).with_front(FrontMark::Riser).with_back_on_riser(true);
        let past = level(Point3::new(1.035, 0.0, 0.4), Vector3::x(), 0.33, 0.5, 40);
        for (known, seen) in [(&on_riser, &past), (&past, &on_riser)] {
            let merged = merge(std::slice::from_ref(known), vec![seen.clone()], &p);
            assert!((back(&merged[0]) - 1.14).abs() < 1e-9, "{}", back(&merged[0]));
            assert!(merged[0].back_on_riser() && merged[0].front_on_riser());
        }
        let merged = merge(std::slice::from_ref(&step(1.005, 0.4, 0.27)), vec![past], &p);
        assert!((back(&merged[0]) - 1.2).abs() < 1e-9 && !merged[0].back_on_riser());
    }

    #[test]
    fn a_partial_view_of_a_deep_landing_is_the_same_landing() {
        // The whole landing seen from the floor, then its far 6 cm from the last step, and
        // the near part of the step before it: one tread each, not two at one height.
        let known = vec![step(1.005, 0.4, 0.27), step(1.775, 0.6, 1.27)];
        let seen = vec![step(2.38, 0.6, 0.06), step(1.1, 0.4, 0.08)];
        let merged = merge(&known, seen, &StepMapParams::default());
        assert_eq!(merged.len(), 2, "{merged:?}");
        let landing = merged.iter().find(|r| (r.height_m() - 0.6).abs() < 1e-9).expect("landing");
        let (front, back) =
            (landing.center().x - landing.depth_m() / 2.0, landing.center().x + landing.depth_m() / 2.0);
        assert!((front - 1.14).abs() < 1e-9 && (back - 2.41).abs() < 1e-9, "landing {front}..{back}");
        // Two treads at one height that do not overlap stay two (a landing between flights).
        let apart = merge(&[step(1.0, 0.4, 0.27)], vec![step(1.6, 0.4, 0.27)], &StepMapParams::default());
        assert_eq!(apart.len(), 2);
    }

    /// Regression `tread-split-in-two-under-20mm`: a view splits the known step 3 (0.9 m
    /// wide) in two pieces side by side; the map keeps one step 3, whole.
    #[test]
    fn a_view_that_splits_a_tread_in_two_leaves_one_step() {
        let known = vec![
            level(Point3::new(0.69, 0.0, 0.51), Vector3::x(), 0.31, 0.83, 400),
            level(Point3::new(0.41, 0.0, 0.34), Vector3::x(), 0.26, 0.60, 300),
        ];
        let seen = vec![
            level(Point3::new(0.70, -0.34, 0.511), Vector3::x(), 0.28, 0.18, 60),
            level(Point3::new(0.74, -0.07, 0.515), Vector3::x(), 0.23, 0.29, 90),
        ];
        let merged = merge(&known, seen, &StepMapParams::default());
        let at_3: Vec<&PlaneSegment> = merged.iter().filter(|r| (r.height_m() - 0.51).abs() < 0.02).collect();
        assert_eq!(at_3.len(), 1, "{at_3:?}");
        let front = at_3[0].center().x - at_3[0].depth_m() / 2.0;
        assert!((at_3[0].width_m() - 0.83).abs() < 1e-9 && (front - 0.535).abs() < 1e-9, "{at_3:?}");
        assert_eq!(merged.len(), 2);
    }

    /// Regression `noisy-views-in-pieces-and-turned` (21 mm of noise): step 1's right end
    /// seen from afar, its middle from nearer, 6 mm apart across: one step, not two at one
    /// height (the first was left "3 mm deep up to the next one's front" and the climb
    /// refused). A piece beside it over another depth, or turned across it, stays apart.
    #[test]
    fn pieces_of_a_tread_side_by_side_are_one_step() {
        let end = level(Point3::new(0.146, -0.40, 0.152), Vector3::x(), 0.244, 0.235, 60);
        let middle = level(Point3::new(0.152, 0.025, 0.152), Vector3::x(), 0.272, 0.601, 150);
        let merged = merge(std::slice::from_ref(&end), vec![middle.clone()], &StepMapParams::default());
        assert_eq!(merged.len(), 1, "{merged:?}");
        let front = merged[0].center().x - merged[0].depth_m() / 2.0;
        assert!((front - 0.016).abs() < 1e-9 && (merged[0].width_m() - 0.601).abs() < 1e-9, "{merged:?}");
        let p = StepMapParams::default();
        let behind = level(Point3::new(0.40, -0.40, 0.152), Vector3::x(), 0.10, 0.235, 60);
        assert!(!same_step(&behind, &middle, &p), "over another depth");
        let turned = level(Point3::new(0.146, -0.55, 0.152), Vector3::new(1.0, 1.0, 0.0), 0.244, 0.235, 60);
        assert!(!same_step(&turned, &middle, &p), "turned 45 degrees");
    }

    #[test]
    fn a_view_of_one_side_of_a_step_does_not_narrow_it() {
        // Regression `side-view-narrowed-a-step`: 0.71 m of a 1.33 m tread, on its left,
        // seen from close.
        let known = level(Point3::new(1.31, 0.0, 0.17), Vector3::x(), 0.26, 1.33, 308);
        let side = level(Point3::new(1.38, 0.24, 0.17), Vector3::x(), 0.12, 0.71, 54);
        let merged = merge(std::slice::from_ref(&known), vec![side], &StepMapParams::default());
        assert_eq!(merged.len(), 1);
        assert!((merged[0].width_m() - 1.33).abs() < 1e-9 && merged[0].center().y.abs() < 1e-9, "{merged:?}");
        assert_eq!(merged[0].voxel_count(), 308, "the fuller view's count stays");
    }

    #[test]
    fn a_partial_view_does_not_tilt_a_step() {
        let full = step(1.005, 0.4, 0.27);
        let tilt = Vector3::new((3f64).to_radians().sin(), 0.0, (3f64).to_radians().cos());
        let partial = PlaneSegment::new(Point3::new(1.075, 0.0, 0.4), Vector3::x(), 0.13, 0.5, tilt, 5)
            .expect("valid rectangle");
        let merged = merge(std::slice::from_ref(&full), vec![partial.clone()], &StepMapParams::default());
        assert_eq!(merged.len(), 1);
        assert_eq!(merged[0].normal(), full.normal(), "the fuller view's plane is kept");
        assert!((merged[0].depth_m() - 0.27).abs() < 1e-9);
        // A view on more voxels than the known one brings its own plane.
        let merged = merge(&[partial], vec![full.clone()], &StepMapParams::default());
        assert_eq!(merged[0].normal(), full.normal());
        let fuller_tilted =
            PlaneSegment::new(Point3::new(1.005, 0.0, 0.4), Vector3::x(), 0.27, 0.5, tilt, 20)
                .expect("valid rectangle");
        let merged = merge(&[full], vec![fuller_tilted.clone()], &StepMapParams::default());
        assert_eq!(merged[0].normal(), fuller_tilted.normal());
    }

    /// A view's rectangle is the extent of its voxels along its own axes; turned against the
    /// tread, it reaches beyond the tread at both ends. What it surely saw lies on the tread,
    /// at any turn, and is the edge itself when it is not turned.
    #[test]
    fn a_turned_view_surely_saw_only_tread() {
        // A tread 0.289 m deep seen over 0.68 m of its width.
        let (depth_m, half_width_m) = (0.289, 0.34);
        let strip =
            [(0.0, -half_width_m), (0.0, half_width_m), (depth_m, -half_width_m), (depth_m, half_width_m)];
        for deg in [0.0, 2.0, 5.0, 12.0, 19.7] {
            let (s, c) = f64::to_radians(deg).sin_cos();
            let (u, w) = (Vector3::new(c, s, 0.0), Vector3::new(-s, c, 0.0));
            let span = |axis: &Vector3<f64>| {
                strip
                    .iter()
                    .map(|&(x, y)| x * axis.x + y * axis.y)
                    .fold([f64::MAX, f64::MIN], |[a, b], t| [a.min(t), b.max(t)])
            };
            let (a, b) = (span(&u), span(&w));
            let centre = u * ((a[0] + a[1]) / 2.0) + w * ((b[0] + b[1]) / 2.0);
            let r = level(Point3::from(centre), u, a[1] - a[0], b[1] - b[0], 100);
            let o = Point3::origin();
            let (front, back) =
                (surely_seen(&r, &o, &Vector3::x(), -1.0), surely_seen(&r, &o, &Vector3::x(), 1.0));
            assert!(front >= -1e-12 && back <= depth_m + 1e-12, "{deg} deg: {front:.4}..{back:.4}");
            if deg == 0.0 {
                assert!(front.abs() < 1e-12 && (back - depth_m).abs() < 1e-12);
            }
        }
    }

    /// Regression `noisy-views-in-pieces-and-turned` (21 mm of noise), in the flight's
    /// frame: step 6 (true 1.444 m to 1.733 m along the flight) was first seen in a view
    /// whose axis came out turned 19.7 degrees, 0.462 m by 0.678 m; the next view saw it
    /// along the flight, 0.322 m deep. The merged step must not reach the turned
    /// rectangle's midpoints (1.367 m and 1.80 m: a heel was planned 25 mm over the step
    /// below's front edge).
    #[test]
    fn a_turned_view_does_not_stretch_a_step() {
        let at = |deg: f64| Vector3::new(deg.to_radians().cos(), deg.to_radians().sin(), 0.0);
        let turned = level(Point3::new(1.585, 0.223, 0.905), at(19.7), 0.462, 0.678, 254);
        let along = level(Point3::new(1.585, 0.005, 0.905), at(0.6), 0.322, 1.090, 405);
        let merged = merge(std::slice::from_ref(&turned), vec![along], &StepMapParams::default());
        assert_eq!(merged.len(), 1);
        let m = &merged[0];
        let (front, back) = (m.center().x - m.depth_m() / 2.0, m.center().x + m.depth_m() / 2.0);
        assert!(front > 1.444 - 0.025 && back < 1.733 + 0.025, "step 6 at {front:.3}..{back:.3} m");
    }

    /// Regression `tread-width-taken-for-its-depth`: with one tread in view, perception
    /// took its width for its depth (ascent turned 90 degrees); the merge must read that
    /// view along the known ascent.
    #[test]
    fn a_view_with_its_axes_swapped_is_read_along_the_known_ascent() {
        let known = level(Point3::new(1.64, 0.01, 0.37), Vector3::x(), 0.29, 1.46, 506);
        // The far 0.225 m of the tread's left part, described as 1.08 m "deep" along +y.
        let swapped = level(Point3::new(1.6725, 0.2, 0.37), Vector3::y(), 1.08, 0.225, 260);
        let merged = merge(std::slice::from_ref(&known), vec![swapped], &StepMapParams::default());
        assert_eq!(merged.len(), 1);
        let m = &merged[0];
        assert!((m.along() - Vector3::x()).norm() < 1e-9, "ascent {:?}", m.along());
        assert!((m.depth_m() - 0.29).abs() < 1e-9, "depth {} (the known 0.29 m)", m.depth_m());
        assert!((m.width_m() - 1.46).abs() < 1e-9, "width {}", m.width_m());
        assert!((m.center() - known.center()).norm() < 1e-9);
        // Regression `top-tread-alone-axes-swapped`: the swapped view is the fuller one; the
        // known ascent still holds.
        let whole = level(Point3::new(1.64, 0.01, 0.37), Vector3::y(), 1.46, 0.27, 520);
        let merged = merge(std::slice::from_ref(&known), vec![whole], &StepMapParams::default());
        let m = &merged[0];
        assert!((m.along() - Vector3::x()).norm() < 1e-9, "ascent {:?}", m.along());
        assert!(
            (m.width_m() - 1.46).abs() < 1e-9 && (m.depth_m() - 0.29).abs() < 1e-9,
            "{} {}",
            m.width_m(),
            m.depth_m()
        );
    }

    /// Regression `sparse-view-cut-a-tread-short`: 8 voxels of a tread must not cut its
    /// back edge (the merged tread came out 0.21 m deep, and the plan was refused).
    #[test]
    fn a_sparse_view_does_not_cut_a_tread() {
        let known = level(Point3::new(1.505, 0.0, 0.51), Vector3::x(), 0.30, 0.94, 417);
        let sparse = level(Point3::new(1.489, 0.06, 0.505), Vector3::x(), 0.186, 0.7, 8);
        let merged = merge(std::slice::from_ref(&known), vec![sparse], &StepMapParams::default());
        assert_eq!(merged.len(), 1);
        assert!((merged[0].depth_m() - 0.30).abs() < 1e-9, "depth {}", merged[0].depth_m());
        assert!((merged[0].center() - known.center()).norm() < 1e-9);
    }

    /// Exp. 2, seed 5, step 6: the farthest view rests on the most voxels but the next nose
    /// hid the back 4 cm of its tread; the closer view's back edge is kept.
    #[test]
    fn a_closer_view_brings_the_back_the_farther_one_missed() {
        let far = level(Point3::new(2.028, 0.0, 1.08), Vector3::x(), 0.249, 1.24, 1067);
        let close = level(Point3::new(2.054, 0.0, 1.08), Vector3::x(), 0.284, 1.24, 966);
        let merged = merge(std::slice::from_ref(&far), vec![close], &StepMapParams::default());
        let m = &merged[0];
        let (front, back) = (m.center().x - m.depth_m() / 2.0, m.center().x + m.depth_m() / 2.0);
        assert!((front - 1.9035).abs() < 1e-9 && (back - 2.196).abs() < 1e-9, "{front} {back}");
    }

    /// Regression `tilted-tread-and-sunk-landing`: a sparse view of a landing must not move
    /// its plane.
    #[test]
    fn a_sparse_view_does_not_move_a_step_height() {
        let landing = level(Point3::new(4.06, 0.36, 1.004), Vector3::x(), 1.35, 1.42, 3671);
        let sparse = level(Point3::new(3.82, 0.28, 0.987), Vector3::x(), 0.7, 1.32, 14);
        let merged = merge(std::slice::from_ref(&landing), vec![sparse], &StepMapParams::default());
        assert_eq!(merged.len(), 1);
        assert!((merged[0].height_m() - 1.004).abs() < 1e-12, "height {}", merged[0].height_m());
        assert!((merged[0].center().z - 1.004).abs() < 1e-12);
    }

    /// Footprints are compared on both rectangles' axes: a turned rectangle beside another
    /// can overlap it on the other's axes and still not touch it.
    #[test]
    fn rectangles_apart_on_the_turned_ones_axis_are_not_one_step() {
        let a = step(1.0, 0.4, 1.0);
        let yaw = 45f64.to_radians();
        // A 0.1 m square turned 45 degrees, its centre 0.62 m diagonally from a's: inside
        // a's spans along x and y, but apart along its own diagonal axes.
        let turned = Vector3::new(yaw.cos(), yaw.sin(), 0.0);
        let b = level(Point3::new(1.55, 0.29, 0.4), turned, 0.1, 0.1, 10);
        let p = StepMapParams::default();
        assert!(!same_step(&a, &b, &p) && !same_step(&b, &a, &p));
        let inside = level(Point3::new(1.4, 0.1, 0.4), turned, 0.1, 0.1, 10);
        assert!(same_step(&a, &inside, &p) && same_step(&inside, &a, &p));
    }

    /// Regression `partial-view-turned-a-step`: a view of half a tread (the legs hide the
    /// rest) came out turned 12 degrees; the merged step must keep the fuller view's
    /// direction of ascent.
    #[test]
    fn a_partial_view_does_not_turn_a_step() {
        let full = level(Point3::new(2.9, -0.36, 1.02), Vector3::x(), 0.36, 0.98, 1123);
        let yaw = 12f64.to_radians();
        let turned = Vector3::new(yaw.cos(), yaw.sin(), 0.0);
        let partial = level(Point3::new(2.97, -0.35, 1.02), turned, 0.32, 0.98, 557);
        let merged = merge(std::slice::from_ref(&full), vec![partial.clone()], &StepMapParams::default());
        assert_eq!(merged.len(), 1);
        let m = &merged[0];
        assert!(
            (m.along() - full.along()).norm() < 1e-9,
            "direction {:?} (the partial view's turned)",
            m.along()
        );
        // The nose and the back stay the known view's: the partial view's back midpoint lies
        // 4.7 cm beyond (3.127 m), but its rectangle, turned 12 degrees on 0.98 m, surely saw
        // tread only to 3.025 m (see `surely_seen`).
        let edges =
            |r: &PlaneSegment| [-1.0, 1.0].map(|k| (r.center() + r.along() * (k * r.depth_m() / 2.0)).x);
        let (e, f) = (edges(m), edges(&full));
        assert!((e[0] - f[0]).abs() < 1e-9 && (e[1] - f[1]).abs() < 1e-9, "{e:?} {f:?}");
        // A fuller new view brings its own direction.
        let merged = merge(&[partial], vec![full.clone()], &StepMapParams::default());
        assert!((merged[0].along() - full.along()).norm() < 1e-9);
    }

    /// Regression `near-square-pieces-turned-the-view` (20 mm of range noise), view 3:
    /// perception found step 1 as a 25-voxel piece at one side and step 2 as 84 voxels; the
    /// flight's axis, taken from those two near-square pieces, came out 40 degrees off and
    /// step 2's rectangle 0.78 m by 0.65 m. Its edges, projected on the known ascent,
    /// brought step 2's front 5 cm toward the robot, and a foot was planned off step 1's
    /// back. A view turned that far from the known step gives it no edges; one turned a
    /// little still does.
    #[test]
    fn a_view_turned_far_from_the_known_step_gives_it_no_edges() {
        let p = StepMapParams::default();
        let known = level(Point3::new(1.0, 0.0, 0.34), Vector3::x(), 0.28, 0.93, 135);
        let at = |deg: f64| Vector3::new(deg.to_radians().cos(), deg.to_radians().sin(), 0.0);
        let broken = level(Point3::new(1.05, 0.0, 0.34), at(40.0), 0.78, 0.65, 84);
        let merged = merge(std::slice::from_ref(&known), vec![broken], &p);
        assert_eq!(merged.len(), 1);
        assert_eq!(merged[0], known, "the known step is kept as it was");
        // Turned 5 degrees, a view reaching 6 cm farther back still brings its back edge, as
        // far as it surely saw tread (its midpoint drawn in by 0.45 m x sin 5 deg).
        let behind = level(Point3::new(1.06, 0.0, 0.34), at(5.0), 0.28, 0.9, 60);
        let merged = merge(&[known], vec![behind], &p);
        let back = merged[0].center().x + merged[0].depth_m() / 2.0;
        let (s, c) = 5f64.to_radians().sin_cos();
        assert!((back - (1.06 + 0.14 * c - 0.45 * s)).abs() < 1e-9, "back edge at {back}");
    }

    #[test]
    fn a_shallow_top_step_waits_for_a_closer_look_but_a_shallow_next_step_is_kept() {
        let ahead = vec![step(1.005, 0.4, 0.27), step(1.3, 0.6, 0.11), step(0.735, 0.2, 0.27)];
        let next = without_partial_top(ahead, 0.22);
        assert_eq!(next.ahead.len(), 2);
        assert!(next.ahead.iter().all(|s| s.height_m() < 0.5), "the 11 cm top is left for later");
        assert_eq!(next.deferred.map(|s| s.height_m()), Some(0.6), "and named");
        let alone = without_partial_top(vec![step(1.3, 0.6, 0.11)], 0.22);
        assert_eq!(alone.ahead.len(), 1, "the only step left is planned (and refused) as it is");
        assert!(alone.deferred.is_none());
        let shallow_below = vec![step(0.735, 0.2, 0.11), step(1.005, 0.4, 0.27)];
        assert_eq!(
            without_partial_top(shallow_below, 0.22).ahead.len(),
            2,
            "the next step is planned as it is"
        );
        // Regression `deferred-step-planned-below-a-higher-one`: the partly seen step is no
        // longer the top once a higher one is seen (also in part); it still waits, with the
        // steps above it.
        let two_partial = vec![step(1.3, 0.6, 0.15), step(0.735, 0.2, 0.27), step(1.005, 0.4, 0.21)];
        let next = without_partial_top(two_partial, 0.22);
        assert_eq!(next.ahead.len(), 1);
        assert!((next.ahead[0].height_m() - 0.2).abs() < 1e-12);
        assert_eq!(next.deferred.map(|s| s.height_m()), Some(0.4), "the lowest partial step is named");
    }

    #[test]
    fn next_input_merges_keeps_what_is_ahead_and_defers_a_partial_top() {
        let p = StepMapParams::default();
        let mut map = StepMap::default();
        let first = map.next_input(vec![step(0.735, 0.2, 0.27), step(1.005, 0.4, 0.27)], 0.0, 0.22, &p);
        assert_eq!(first.ahead.len(), 2);
        // On step 1 (feet at 0.2 m): step 1 is behind; step 3 seen as a 10 cm strip waits.
        let next = map.next_input(vec![step(1.005, 0.4, 0.27), step(1.24, 0.6, 0.1)], 0.2, 0.22, &p);
        assert_eq!(map.known.len(), 3, "every step seen is known");
        assert_eq!(next.ahead.len(), 1);
        assert!((next.ahead[0].height_m() - 0.4).abs() < 1e-12);
        assert!(next.deferred.is_some_and(|s| (s.height_m() - 0.6).abs() < 1e-12));
    }

    /// Perception returns each view of a step yawed a little differently; the front corner
    /// of a view yawed against the known rectangle lies ahead of its front edge, and merging
    /// must not take that corner for the edge, view after view.
    #[test]
    fn merging_views_of_differing_yaw_keeps_the_nose() {
        // Centred `s` along x from (1, 0, 0.4), its ascent yawed by `yaw_deg`.
        let view = |s: f64, depth_m: f64, yaw_deg: f64| {
            let along = Vector3::new(yaw_deg.to_radians().cos(), yaw_deg.to_radians().sin(), 0.0);
            level(Point3::new(1.0 + s, 0.0, 0.4), along, depth_m, 0.5, 10)
        };
        let mut map = StepMap::default();
        for i in 0..6 {
            map.update(vec![view(0.0, 0.27, if i % 2 == 0 { 1.5 } else { -1.5 })], &StepMapParams::default());
        }
        assert_eq!(map.known.len(), 1);
        let s = &map.known[0];
        assert!((s.depth_m() - 0.27).abs() < 1e-9, "depth {} after six views of one step", s.depth_m());
        assert!((s.center() - Point3::new(1.0, 0.0, 0.4)).norm() < 1e-9);
        // A view whose front edge is 1 cm nearer (same back edge) does move the nose by 1 cm.
        map.update(vec![view(-0.005, 0.28, 0.0)], &StepMapParams::default());
        map.update(vec![view(0.0, 0.27, 0.0)], &StepMapParams::default());
        assert!((map.known[0].depth_m() - 0.28).abs() < 1e-9, "{}", map.known[0].depth_m());
    }
}
