//! Beyond the paper: a tread's front edge placed on the riser below it, and its back edge
//! on the riser above it.
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
//! edge as it was. The window reaches farther inside the edge than out past it: the cell
//! method's rectangles run out past their risers toward the sensor. A tread whose nose
//! stands out before its riser has a nosing, seen as its face's returns just under the top
//! standing before the riser: its front is then the nose, not the riser (a foot on the
//! tread below keeps its toes behind the nose, not under it). Where no riser is seen whole
//! (an open riser's slab, a riser shadowed), the front goes onto the tread's own face, the
//! returns a little under its top standing as a peak across the flight ([`face_along`]; the
//! rectangles' own fronts run out past an open riser's nose by centimetres under noise). A
//! tread's back edge errs
//! the other way: the foot of the riser above, seen through noise, lands on the tread's
//! plane past it, and the rectangle runs on past the riser by centimetres; that riser, seen
//! whole across the tread, is its back ([`place_backs`]).

use super::{FrontMark, PlaneSegment};
use crate::stats::median;
use nalgebra::{Point3, Vector3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Where a tread's riser is looked for and when it is believed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RiserParams {
    /// Whether the fronts (and, with `backs`, the backs) are placed on the risers (`false`:
    /// the rectangles as §4 gives them).
    pub enabled: bool,
    /// How far out past a segment's front edge (against its ascent) its riser is looked
    /// for, metres: the paper's edges err by up to about 4 cm under 25 mm of noise (inside
    /// the edge: `front_inward_m`). For a back edge, how far past it the riser above is
    /// looked for; and how far before a riser a nosing's face may stand.
    pub half_window_m: f64,
    /// How far inside a tread's front edge its riser is looked for, metres (out past the
    /// edge: `half_window_m`). The cell method's rectangles run out past the riser toward
    /// the sensor, by up to 84 mm under 20-25 mm of noise (the `wide` suite with
    /// `riser.enabled = false`, `perceive --json`'s `front_error_m`): the nose's returns,
    /// scattered along the rays, lie in the tread's plane before it.
    pub front_inward_m: f64,
    /// The band below the tread's top in which a return may be the riser's, metres below
    /// the top: [nearest, farthest]. Its near end keeps the tread's own returns out (they
    /// scatter about 1-2 cm in height under 10-25 mm of noise), its far end the tread or
    /// floor below (a rise is 10 cm or more: building codes, the generated suites); for a
    /// step with a tread below it the band also ends `band_m[0]` above that tread. The
    /// riser above a tread is looked for as far above its top, the band ending `band_m[0]`
    /// short of the tread above.
    pub band_m: [f64; 2],
    /// Returns this far inside the segment's sides only, metres (a wall or a rail beside
    /// the flight is no riser).
    pub side_margin_m: f64,
    /// Least returns on the riser (about the median) for it to place the front; for a back,
    /// on the riser's foot (the band's lower half).
    pub min_returns: usize,
    /// Least share of those returns in each half of the band (upper, lower): a riser seen
    /// whole. A riser seen in part, a strip of returns at one height, is not believed.
    pub min_half_share: f64,
    /// Whether each tread's back edge is placed on the riser above it too (`false`: as its
    /// voxels, or the cells, give it).
    pub backs: bool,
    /// How far inside a tread's back edge the riser above it is looked for, metres (out past
    /// the edge: `half_window_m`). Under 20-25 mm of noise the foot of the riser above lands
    /// on the tread's plane past the riser, and the tread's rectangle runs up to about 7 cm
    /// past it (`perceive --json`'s `back_error_m`; the top treads seen from the floor).
    pub back_inward_m: f64,
    /// Least share, of the strips across the tread (`WIDTH_STRIP_M` wide, inside
    /// `side_margin_m`) in which the back's window shows returns in the band, of those in
    /// which they are the riser's, for it to place the back: a riser spans the flight, a
    /// thing left on the tread before it spans part (the `real` suite's shoe, parcel, bag
    /// or person: at most 0.5 m across, on treads 0.8 m wide or more), and the riser is
    /// seen beside it. A strip the sweep did not reach says nothing either way (the riser
    /// above the top tread seen is often reached across part of the tread only); so where
    /// nothing but such a thing stands in the window (an open riser behind it), its face
    /// is taken for the riser, and the tread ends before it.
    pub min_width_share: f64,
    /// Least share, of the strips across the tread in which the front's window shows
    /// returns in the band, in which returns in the band's lower half are the riser's (about
    /// the middle's peak, or about the riser's own line through it where the rectangle is
    /// turned against the riser), for it to place the front: a riser spans the flight (a
    /// nosing's face, in the upper half, spans it over whatever stands under it). A thing
    /// on the tread below, as tall as the band's lower half, shows there as a dense peak
    /// across its own width alone (regression `shoe-top-taken-for-the-riser-above`). Lower than
    /// `min_width_share`: a front not placed stays where the rectangle puts it, out past
    /// the riser by centimetres with the cell method under noise (see `front_inward_m`).
    pub min_front_width_share: f64,
}

impl Default for RiserParams {
    fn default() -> Self {
        Self {
            enabled: true,
            half_window_m: 0.05,
            front_inward_m: 0.10,
            band_m: [0.02, 0.08],
            side_margin_m: 0.05,
            min_returns: 30,
            min_half_share: 0.3,
            backs: true,
            back_inward_m: 0.10,
            min_width_share: 0.8,
            min_front_width_share: 0.5,
        }
    }
}

impl RiserParams {
    /// Why the parameters are unusable, naming the field; `None` when they are fine.
    pub fn invalid(&self) -> Option<(&'static str, &'static str)> {
        let pos = |v: f64| v.is_finite() && v > 0.0;
        // The nose's face is looked for as far before the riser: a window short of the least
        // nosing would never find one.
        if !(self.half_window_m.is_finite() && self.half_window_m > NOSING_MIN_M) {
            return Some(("riser.half_window_m", "must be > 0.015 (the least nosing)"));
        }
        if !pos(self.front_inward_m) {
            return Some(("riser.front_inward_m", "must be > 0"));
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
        if !pos(self.back_inward_m) {
            return Some(("riser.back_inward_m", "must be > 0"));
        }
        if !(self.min_width_share.is_finite() && (0.0..=1.0).contains(&self.min_width_share)) {
            return Some(("riser.min_width_share", "must be in [0, 1]"));
        }
        if !(self.min_front_width_share.is_finite() && (0.0..=1.0).contains(&self.min_front_width_share)) {
            return Some(("riser.min_front_width_share", "must be in [0, 1]"));
        }
        None
    }
}

/// The points about some heights ordered by height, in bins of `BIN_M` (taller where more
/// than `MAX_BINS` would be needed), so that the searches about a tread's edges, each in a
/// band a few centimetres high about its top, read the points of their band's bins only,
/// not the whole cloud (a sweep holds about 260 000 points, and each step's front, nosing
/// and back look at it).
#[derive(Debug, Clone)]
struct ByHeight {
    /// The lowest bin's floor, metres.
    z0_m: f64,
    /// Bin height, metres.
    bin_m: f64,
    /// Where each bin's points start in `points` (one more entry than bins).
    starts: Vec<usize>,
    /// The points kept, bin by bin.
    points: Vec<Point3<f32>>,
}

/// Height of a bin of [`ByHeight`], metres: the bands are 4-6 cm high.
const BIN_M: f64 = 0.01;
/// The most bins (points spanning more than this many `BIN_M`s get taller bins).
const MAX_BINS: usize = 4096;
/// Points read by one thread at a time when [`ByHeight`] picks its points.
const CHUNK: usize = 1 << 14;

impl ByHeight {
    /// Those of `points` within `reach_m` of one of the heights `about_m` (and of a finite
    /// height), binned by height.
    fn new(points: &[Point3<f32>], about_m: &[f64], reach_m: f64) -> Self {
        let near = |z: f32| z.is_finite() && about_m.iter().any(|h| (f64::from(z) - h).abs() <= reach_m);
        let picked: Vec<Vec<Point3<f32>>> =
            points.par_chunks(CHUNK).map(|c| c.iter().filter(|q| near(q.z)).copied().collect()).collect();
        let (lo, hi) = picked
            .iter()
            .flatten()
            .map(|q| f64::from(q.z))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), z| (lo.min(z), hi.max(z)));
        if lo > hi {
            return Self { z0_m: 0.0, bin_m: BIN_M, starts: vec![0, 0], points: Vec::new() };
        }
        // Capped before the cast: a spread of 1e17 m would overflow the count.
        let bins = ((hi - lo) / BIN_M).min((MAX_BINS - 1) as f64) as usize + 1;
        let bin_m = ((hi - lo) / bins as f64).max(BIN_M);
        let index = Self { z0_m: lo, bin_m, starts: Vec::new(), points: Vec::new() };
        let mut starts = vec![0usize; bins + 1];
        for q in picked.iter().flatten() {
            starts[index.bin(f64::from(q.z), bins) + 1] += 1;
        }
        for k in 1..=bins {
            starts[k] += starts[k - 1];
        }
        let mut next = starts.clone();
        let mut sorted = vec![Point3::origin(); starts[bins]];
        for q in picked.iter().flatten() {
            let k = index.bin(f64::from(q.z), bins);
            sorted[next[k]] = *q;
            next[k] += 1;
        }
        Self { starts, points: sorted, ..index }
    }

    /// The bin of height `z_m` among `bins`: monotone in the height, so every point of a
    /// band lies in the bins of its ends and between.
    fn bin(&self, z_m: f64, bins: usize) -> usize {
        (((z_m - self.z0_m) / self.bin_m).max(0.0) as usize).min(bins - 1)
    }

    /// Every point kept with a height in (`lo_m`, `hi_m`), among the others of the bins that
    /// band meets (the lowest or highest bin where it reaches past the points kept).
    fn within(&self, lo_m: f64, hi_m: f64) -> &[Point3<f32>] {
        let bins = self.starts.len() - 1;
        if self.points.is_empty() || lo_m.partial_cmp(&hi_m) != Some(std::cmp::Ordering::Less) {
            return &[];
        }
        let (a, b) = (self.bin(lo_m, bins), self.bin(hi_m, bins));
        &self.points[self.starts[a]..self.starts[b + 1]]
    }

    /// The points in a box about `s`, each as (its offset from `s`'s centre along `out`,
    /// its height, its offset across), metres: heights within `heights_m`, offsets across
    /// within `half_width_m` of the centre, along within `window_m` (all open).
    fn about(
        &self,
        s: &PlaneSegment,
        out: &Vector3<f64>,
        heights_m: [f64; 2],
        half_width_m: f64,
        window_m: [f64; 2],
    ) -> Vec<(f64, f64, f64)> {
        let side = Vector3::new(-out.y, out.x, 0.0);
        let c = s.center();
        let [lo, hi] = heights_m;
        self.within(lo, hi)
            .iter()
            .map(|q| q.cast::<f64>())
            .filter(|q| q.z > lo && q.z < hi)
            .map(|q| (q - c, q.z))
            .filter(|(d, _)| d.dot(&side).abs() < half_width_m)
            .map(|(d, z)| (d.dot(out), z, d.dot(&side)))
            .filter(|(t, _, _)| *t > window_m[0] && *t < window_m[1] && t.is_finite())
            .collect()
    }
}

/// Places each segment's front edge on the riser below it (`place_fronts`), then its back
/// edge on the riser above it (`place_backs`), both searches reading one index of `points`
/// by height about the treads' tops (`ByHeight`). Returns how many edges moved, and onto
/// what.
pub fn place_edges(
    segments: &mut [PlaneSegment],
    points: &[Point3<f32>],
    viewpoint: &Point3<f64>,
    ground_m: Option<f64>,
    noise_m: Option<f64>,
    p: &RiserParams,
) -> Placed {
    if !p.enabled || segments.is_empty() {
        return Placed::default();
    }
    // Every band looked in lies within `band_m[1]` of its tread's top, the nose's face within
    // `FACE_BAND_M[1]`.
    let tops: Vec<f64> = segments.iter().map(|s| s.height_m()).collect();
    let index = ByHeight::new(points, &tops, p.band_m[1].max(FACE_BAND_M[1]));
    let view = ViewPoints { index: &index, cloud: points, viewpoint: *viewpoint, ground_m, noise_m };
    let (riser_fronts, face_fronts) = place_fronts(segments, &view, p);
    Placed { riser_fronts, face_fronts, riser_backs: place_backs(segments, &view, p) }
}

/// A view as the edge searches read it: its points, indexed by height about the treads'
/// tops and all of them, where it was seen from, the height of the surface the sensor
/// stands over (the floor, or the tread under the robot) and the sweep's measured range
/// noise.
#[derive(Clone, Copy)]
struct ViewPoints<'a> {
    index: &'a ByHeight,
    cloud: &'a [Point3<f32>],
    viewpoint: Point3<f64>,
    ground_m: Option<f64>,
    noise_m: Option<f64>,
}

/// How many of a view's edges [`place_edges`] moved.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Placed {
    /// Fronts placed on the riser below (or on the nose before it).
    pub riser_fronts: usize,
    /// Fronts placed on the tread's own face, no riser seen under it ([`face_along`]).
    pub face_fronts: usize,
    /// Backs placed on the riser above.
    pub riser_backs: usize,
}

/// Where a tread's front edge was found.
#[derive(Debug, Clone, Copy)]
enum Front {
    /// On its riser, `at_m` from the tread's centre toward its front, and its nose that far
    /// before it where a nosing was seen.
    Riser { at_m: f64, nosing_m: Option<f64> },
    /// On its own face, `at_m` from the centre (no riser seen whole under it).
    Face { at_m: f64 },
}

/// Places each segment's front edge (its end against its ascent, facing `viewpoint`) on the
/// riser below it where `points` show one whole (see the module's doc); the segment keeps
/// its back edge, width, height and normal, and is marked [`PlaneSegment::front_on_riser`].
/// Where no riser is seen whole (an open riser, a riser shadowed), the front goes onto the
/// tread's own face where that is seen ([`face_along`]), marked
/// [`PlaneSegment::front_on_face`].
/// The view's `ground_m` bounds the band of the lowest segment as a tread below does; its
/// `noise_m` sets the least nosing believed.
/// Left as they are: a segment whose front does not face the sensor (the sensor past its
/// middle: a tread under or behind the robot), and a lone segment deeper than wide (with
/// no flight to give its ascent, its "front" may be a side: the step's side face or a
/// wall would be taken for its riser). Returns how many fronts moved onto risers and how
/// many onto faces. The view's index must hold every point of its cloud within `band_m[1]`
/// and `FACE_BAND_M[1]` of each segment's top ([`place_edges`] builds it so).
fn place_fronts(segments: &mut [PlaneSegment], view: &ViewPoints, p: &RiserParams) -> (usize, usize) {
    let ViewPoints { index: points, cloud, viewpoint, ground_m, noise_m } = *view;
    if !p.enabled {
        return (0, 0);
    }
    let heights: Vec<f64> = segments.iter().map(|s| s.height_m()).chain(ground_m).collect();
    let lone = segments.len() == 1;
    let least_m = NOSING_MIN_M.max(NOSING_NOISE_FACTOR * noise_m.unwrap_or(0.0));
    // Each segment's riser, and how far its nose projects past it where a nosing is seen;
    // else its face.
    let found: Vec<Option<Front>> = segments
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
            match riser_along(s, points, band, p) {
                Some(at_m) => Some(Front::Riser {
                    at_m,
                    nosing_m: nose_face(s, points, at_m, p).filter(|&nose| nose >= least_m),
                }),
                None => face_along(s, points, cloud, below, p).map(|at_m| Front::Face { at_m }),
            }
        })
        .collect();
    // A flight's treads have one nosing (building codes: within a few millimetres): where
    // at least half the risers found show one, every front goes that far past its riser (the
    // median); else none does. Mixed, a tread whose nosing went unseen would keep its front
    // on the riser while the next one's moved to its nose, and the span between them lose a
    // nosing's depth. A front on its face is on its nose already.
    let risers = found.iter().filter(|f| matches!(f, Some(Front::Riser { .. }))).count();
    let seen: Vec<f64> = found
        .iter()
        .filter_map(|f| match f {
            Some(Front::Riser { nosing_m, .. }) => *nosing_m,
            _ => None,
        })
        .collect();
    let nosing_m =
        if !seen.is_empty() && 2 * seen.len() >= risers { median(seen).unwrap_or(0.0) } else { 0.0 };
    let (mut on_risers, mut on_faces) = (0, 0);
    for (s, f) in segments.iter_mut().zip(found) {
        match f {
            Some(Front::Riser { at_m, .. }) => {
                if let Some(placed) = with_front(s, at_m + nosing_m) {
                    *s = placed.with_front(FrontMark::Riser).with_nosing_m(nosing_m);
                    on_risers += 1;
                }
            }
            Some(Front::Face { at_m }) => {
                if let Some(placed) = with_front(s, at_m) {
                    *s = placed.with_front(FrontMark::Face);
                    on_faces += 1;
                }
            }
            None => {}
        }
    }
    (on_risers, on_faces)
}

/// The riser's distance from `s`'s centre toward its front (against its ascent), metres,
/// when the returns in `band` (heights) and the window about the front show one whole,
/// across `min_front_width_share` of the width they show.
fn riser_along(s: &PlaneSegment, points: &ByHeight, band: [f64; 2], p: &RiserParams) -> Option<f64> {
    riser_seen(s, points, &front_look(s, band, p), p)
        .filter(|r| r.width_share >= p.min_front_width_share)
        .map(|r| r.at_m)
}

/// Where the riser under `s`'s front is looked for: heights in `band`, from `front_inward_m`
/// inside the front to `half_window_m` out past it, a nosing's face before it.
fn front_look(s: &PlaneSegment, band: [f64; 2], p: &RiserParams) -> Look {
    let front = s.depth_m() / 2.0;
    Look {
        out: -s.along(),
        window_m: [front - p.front_inward_m, front + p.half_window_m],
        band_m: band,
        nose_outward: true,
        foot_suffices: false,
    }
}

/// Where a riser is looked for about one edge of a tread.
struct Look {
    /// Unit horizontal direction from the tread's centre toward the edge.
    out: Vector3<f64>,
    /// The window along `out`, metres from the centre: [inner, outer].
    window_m: [f64; 2],
    /// The band of heights its returns are taken in, metres: [low, high]. Its lower half
    /// is the riser's alone; in its upper half a nosing's face may stand before it.
    band_m: [f64; 2],
    /// Whether that nosing stands outward of the riser along `out` (the tread's own, under
    /// its front) or inward (the next tread's, over its back); weighed only where the foot
    /// alone does not suffice.
    nose_outward: bool,
    /// Whether the riser's returns in the band's lower half alone show it: above a tread,
    /// the riser's foot is where the riser rises from it, however little of the riser the
    /// sweep reaches above (the top tread seen from afar: its riser runs out of the sweep).
    foot_suffices: bool,
}

/// A riser seen whole about an edge.
struct Seen {
    /// Its distance from the tread's centre along the look's `out`, metres.
    at_m: f64,
    /// Of the strips across the tread (`WIDTH_STRIP_M` wide, inside the side margin) in
    /// which the window shows returns in the band, the share with returns on the riser in
    /// the band's lower half.
    width_share: f64,
}

/// Width of the strips across a tread in which a riser's returns are counted, metres
/// (about a foot's width; under its least share a thing left on the tread, not a riser).
const WIDTH_STRIP_M: f64 = 0.05;

/// The riser about an edge of `s` as `look` says where, when the returns show one whole.
fn riser_seen(s: &PlaneSegment, points: &ByHeight, look: &Look, p: &RiserParams) -> Option<Seen> {
    let band = look.band_m;
    if band[1] - band[0] < p.band_m[0] {
        return None;
    }
    let half_width = s.width_m() / 2.0 - p.side_margin_m;
    let near = points.about(s, &look.out, band, half_width, look.window_m);
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
    let at = peak(&lower, p.half_window_m)?;
    // Seen whole: returns about it in the band's lower half, and in its upper half either
    // its own or a nosing's face before it (which shadows the riser's top from near:
    // regression `riser-under-a-nosing-not-believed`).
    let at_riser = |t: f64| (t - at).abs() < p.half_window_m / 4.0;
    let by_nose = |t: f64| if look.nose_outward { t > at } else { t < at };
    let lower_all = near.iter().filter(|r| r.1 < mid).count();
    let lower = near.iter().filter(|r| r.1 < mid && at_riser(r.0)).count();
    let whole = match look.foot_suffices {
        // The riser's foot is a peak: at least twice the share of the lower half's returns
        // that a spread even along the window would put about it (under noise a tread's
        // strays reach the band too, spread thin along it: an open riser's tread seen from
        // near, the `real` suite's `open-risers-noisy`, about a sixth; a riser's foot under
        // 24 mm of noise, 40-95 %).
        // And it stands: the upper half of the lower half holds its share of them (a
        // tread's strays thin out with height above it).
        true => {
            let even_share = (p.half_window_m / 2.0) / (look.window_m[1] - look.window_m[0]);
            let quarter = (band[0] + mid) / 2.0;
            let risen = near.iter().filter(|r| r.1 >= quarter && r.1 < mid && at_riser(r.0)).count();
            lower >= p.min_returns
                && lower as f64 >= 2.0 * even_share * lower_all as f64
                && risen as f64 >= p.min_half_share * lower as f64
        }
        false => {
            let upper = near.iter().filter(|r| r.1 >= mid && (at_riser(r.0) || by_nose(r.0))).count();
            let least = (p.min_half_share * (lower + upper) as f64).ceil() as usize;
            lower + upper >= p.min_returns && upper >= least && lower >= least
        }
    };
    if !whole {
        return None;
    }
    // Where the rectangle is turned against its riser (its axis errs by degrees), the far
    // strips' returns lie off the middle's peak (by 12.5 mm at 1.5 deg on a 1 m tread): the
    // share is also taken about the riser's own line, as its strips place it, where that
    // line passes through the peak (a line through the strips beside a thing that made the
    // peak is not the peak's). The strips on it are those with its returns in the band's
    // lower half, where its peak was taken; a strip showing the upper half alone counts as
    // seen, not on it. In the upper half a nosing's face stands across the flight, and a
    // sparse line of strays in the lower half within `half_window_m / 4` before it would
    // take the face's width for its own (regression
    // `stray-line-under-a-nosing-taken-for-its-riser`).
    let aligned = width_share(&near, half_width, |&(t, z, _)| z < mid && at_riser(t));
    let lower: Vec<(f64, f64)> = near.iter().filter(|r| r.1 < mid).map(|r| (r.0, r.2)).collect();
    let width_share = match riser_line(&lower, half_width, p.half_window_m) {
        Some((a, b)) if at_riser(a) => aligned.max(width_share(&near, half_width, |&(t, z, y)| {
            z < mid && (t - a - b * y).abs() < p.half_window_m / 4.0
        })),
        _ => aligned,
    };
    Some(Seen { at_m: at, width_share })
}

/// Least returns in a strip across a tread for its own peak to place the riser there
/// ([`riser_line`]): a tread's strays in the band are one or two a strip.
const STRIP_MIN_RETURNS: usize = 3;

/// Largest turn of a riser against its tread's rectangle that [`riser_line`] fits, radians
/// (a rectangle's axis errs by a few degrees; regression `wall-column-turned-the-flight`).
const MAX_TURN_RAD: f64 = 0.2;

/// The riser's line across a tread as its strips place it: each strip's own peak
/// ([`peak`]) of its `returns` (offset along, offset across; metres) where it holds
/// [`STRIP_MIN_RETURNS`] or more, and through those Theil and Sen's line (the median of the
/// pairwise slopes, then the median intercept): (offset along at the middle, metres; along
/// per metre across). `None` with fewer than two such strips, or turned more than
/// [`MAX_TURN_RAD`].
fn riser_line(returns: &[(f64, f64)], half_width_m: f64, half_window_m: f64) -> Option<(f64, f64)> {
    let strips = strip_count(half_width_m);
    let mut by_strip: Vec<Vec<f64>> = vec![Vec::new(); strips];
    for &(t, y) in returns {
        by_strip[strip_of(y, half_width_m, strips)].push(t);
    }
    let peaks: Vec<(f64, f64)> = by_strip
        .iter()
        .enumerate()
        .filter(|(_, ts)| ts.len() >= STRIP_MIN_RETURNS)
        .filter_map(|(k, ts)| {
            Some(((k as f64 + 0.5) * WIDTH_STRIP_M - half_width_m, peak(ts, half_window_m)?))
        })
        .collect();
    let slopes = peaks
        .iter()
        .enumerate()
        .flat_map(|(i, a)| peaks[i + 1..].iter().map(move |b| (b.1 - a.1) / (b.0 - a.0)));
    let slope = median(slopes)?;
    if slope.abs() > MAX_TURN_RAD.tan() {
        return None;
    }
    Some((median(peaks.iter().map(|(y, t)| t - slope * y))?, slope))
}

/// The peak of `ts` (offsets along a look, metres): their median, then twice again the
/// median of those within a halved window about it (`half_window_m / 2`, then `/ 4`). A
/// surface's returns are a dense peak, strays a thin spread on either side. `None` when
/// nothing is left.
fn peak(ts: &[f64], half_window_m: f64) -> Option<f64> {
    let mut at = median(ts.iter().copied())?;
    for w in [half_window_m / 2.0, half_window_m / 4.0] {
        at = median(ts.iter().copied().filter(|t| (t - at).abs() < w))?;
    }
    Some(at)
}

/// How many strips (`WIDTH_STRIP_M` wide) cut a tread within `half_width_m` of its middle.
fn strip_count(half_width_m: f64) -> usize {
    ((2.0 * half_width_m / WIDTH_STRIP_M).ceil() as usize).max(1)
}

/// The strip of `strips` (see [`strip_count`]) that a return `across_m` from the middle
/// falls in.
fn strip_of(across_m: f64, half_width_m: f64, strips: usize) -> usize {
    (((across_m + half_width_m) / WIDTH_STRIP_M) as usize).min(strips - 1)
}

/// Of the strips across a tread (`WIDTH_STRIP_M` wide, within `half_width_m` of its middle)
/// in which `near` (returns as (along, height, across), metres) shows anything, the share in
/// which some return is `on` the surface sought (the return as (along, height, across)): a
/// strip the sweep did not reach says nothing either way.
fn width_share(near: &[(f64, f64, f64)], half_width_m: f64, on: impl Fn(&(f64, f64, f64)) -> bool) -> f64 {
    let strips = strip_count(half_width_m);
    let (mut seen, mut on_it) = (vec![false; strips], vec![false; strips]);
    for r in near {
        let k = strip_of(r.2, half_width_m, strips);
        seen[k] = true;
        on_it[k] |= on(r);
    }
    let count = |v: &[bool]| v.iter().filter(|b| **b).count() as f64;
    count(&on_it) / count(&seen).max(1.0)
}

/// A tread's front on its own face, where no riser is seen whole under it: its distance
/// from `s`'s centre toward its front, metres. An open riser's tread is a slab whose face,
/// as deep as the tread is thick (25-45 mm, the `real` suite), is all that stands under its
/// nose; a riser shadowed or seen in part still shows its top there. The face is looked for
/// in the returns `FACE_DEEP_M` under the top (the deeper half of the nosing's band: the
/// tread's own returns, scattered in height by the noise, crowd the shallower half, spread
/// along the tread behind the nose; seen steeply from near, they outnumber the face's
/// there), inside the side margins and in the front's window (as for the riser:
/// `front_inward_m` inside the edge, `half_window_m` out past it). It is the densest span
/// of them `half_window_m / 2` long ([`densest`]), when that is:
/// - a peak: at least `min_returns`, and at least twice as dense as the window beside it,
///   as far on either side (the tread's strays behind it, the nose's before it; where the
///   sweep's sight begins on a tread, its strays begin there too, an edge, no peak);
/// - across the flight: in `min_width_share` of the strips where the window shows returns
///   (a thing on the tread below, as tall as this tread's face, stands across part of it);
/// - seen past: at least `min_returns` returns lie before it, as far out as the peak is
///   long, below the band and above the surface below (`below_m`, the highest tread or
///   ground under this tread, less `band_m[0]`). Where the sweep's sight begins on a tread
///   (a robot near the first riser, the floor and the riser under its lidar), its returns
///   begin as a dense line (the servo dwells at the end of its sweep), their strays under
///   the top with them, and nothing before them: no face is seen there (regression
///   `sight-edge-taken-for-a-face`).
///
/// Not marked as on a riser: the planner keeps the toes `toe_clearance_m` behind a next
/// step's front only where a riser stands under it.
fn face_along(
    s: &PlaneSegment,
    points: &ByHeight,
    cloud: &[Point3<f32>],
    below_m: f64,
    p: &RiserParams,
) -> Option<f64> {
    let out = -s.along();
    let side = Vector3::new(-out.y, out.x, 0.0);
    let c = s.center();
    let half_width = s.width_m() / 2.0 - p.side_margin_m;
    let front = s.depth_m() / 2.0;
    let window = [front - p.front_inward_m, front + p.half_window_m];
    let lo = s.height_m() - FACE_DEEP_M[1];
    let near = points.about(s, &out, [lo, s.height_m() - FACE_DEEP_M[0]], half_width, window);
    if near.len() < p.min_returns {
        return None;
    }
    let ts: Vec<f64> = near.iter().map(|r| r.0).collect();
    let w = p.half_window_m / 4.0;
    let at = densest(&ts, w)?;
    let on_face = |t: f64| (t - at).abs() < w;
    let about = ts.iter().filter(|&&t| on_face(t)).count();
    // Returns per metre along the window beside the peak on each side, as far as the peak is
    // long (a side the window cuts shorter than the peak's half-width says nothing).
    let flank = |from: f64, to: f64| {
        let (from, to) = (from.max(window[0]), to.min(window[1]));
        let n = ts.iter().filter(|&&t| t > from && t < to).count();
        if to - from >= w {
            n as f64 / (to - from)
        } else {
            0.0
        }
    };
    let flanks = flank(at - 3.0 * w, at - w).max(flank(at + w, at + 3.0 * w));
    // Last, and over the whole cloud (the surface below may be the ground, which the height
    // index leaves out): only a face otherwise believed comes to it.
    let seen_past = || {
        let (lo_past, hi_past) = (below_m - p.band_m[0], lo);
        let past = cloud
            .par_iter()
            .filter(|q| f64::from(q.z) > lo_past && f64::from(q.z) < hi_past)
            .map(|q| q.cast::<f64>() - c)
            .filter(|d| d.dot(&side).abs() < half_width && (d.dot(&out) - at - 2.0 * w).abs() < w)
            .count();
        past >= p.min_returns
    };
    let seen = about >= p.min_returns
        && about as f64 / (2.0 * w) >= 2.0 * flanks
        && width_share(&near, half_width, |r| on_face(r.0)) >= p.min_width_share
        && seen_past();
    seen.then_some(at)
}

/// The middle of the densest span of `ts` `2 half_m` long: the median of the values in it
/// (the first such span where several hold as many). `None` for no values.
fn densest(ts: &[f64], half_m: f64) -> Option<f64> {
    let mut v: Vec<f64> = ts.iter().copied().filter(|t| t.is_finite()).collect();
    v.sort_by(f64::total_cmp);
    let (mut best, mut end, mut j) = (0, 0, 0);
    for i in 0..v.len() {
        while v[i] - v[j] > 2.0 * half_m {
            j += 1;
        }
        if i + 1 - j > best {
            (best, end) = (i + 1 - j, i);
        }
    }
    median(v.get(end + 1 - best..=end)?.iter().copied())
}

/// Places each tread's back edge (its end up its ascent) on the riser rising from it, where
/// the view's points show that riser's foot, within `back_inward_m` inside the edge or
/// `half_window_m` past it: the returns in a band above the tread's top (from `band_m[0]`
/// to `band_m[1]` up, and `band_m[0]` short of the next tread up), its lower half, in which
/// the riser's are a peak (twice the share an even spread would give), stand (the upper
/// half of that half holds `min_half_share` of them) and span `min_width_share` of the
/// width seen (see [`RiserParams::min_width_share`]). A tread's back from its voxels or
/// cells runs past the riser above where that riser's foot, seen through range noise, lands
/// on the tread's plane; the top
/// tread seen is then as deep as its foot's place allows, and more (a foot put in its
/// middle stands against the riser). The segment keeps its front edge (and whether it was
/// placed), width, height and normal, and is marked [`PlaneSegment::back_on_riser`]. Left
/// as they are: a segment whose back the sensor stands at or past, and a lone segment
/// deeper than wide (see [`place_fronts`]). Returns how many backs moved. The view's index
/// must hold every point within `band_m[1]` of each segment's top, as for [`place_fronts`].
fn place_backs(segments: &mut [PlaneSegment], view: &ViewPoints, p: &RiserParams) -> usize {
    let (points, viewpoint) = (view.index, view.viewpoint);
    if !(p.enabled && p.backs) {
        return 0;
    }
    let heights: Vec<f64> = segments.iter().map(|s| s.height_m()).collect();
    let lone = segments.len() == 1;
    let found: Vec<Option<f64>> = segments
        .par_iter()
        .map(|s| {
            let back = s.depth_m() / 2.0;
            let edge = s.center() + s.along() * back;
            if (viewpoint - edge).dot(&s.along()) >= 0.0 || (lone && s.depth_m() > s.width_m()) {
                return None;
            }
            let top = s.height_m();
            // The lowest tread above this one (a rise of more than twice the band's near end).
            let above = heights
                .iter()
                .copied()
                .filter(|&h| h > top + 2.0 * p.band_m[0])
                .fold(f64::INFINITY, f64::min);
            let look = Look {
                out: s.along(),
                window_m: [back - p.back_inward_m, back + p.half_window_m],
                band_m: [top + p.band_m[0], (top + p.band_m[1]).min(above - p.band_m[0])],
                nose_outward: false,
                foot_suffices: true,
            };
            let seen = riser_seen(s, points, &look, p)?;
            (seen.width_share >= p.min_width_share).then_some(seen.at_m)
        })
        .collect();
    let mut moved = 0;
    for (s, f) in segments.iter_mut().zip(found) {
        if let Some(placed) = f.and_then(|riser| with_back(s, riser)) {
            *s = placed;
            moved += 1;
        }
    }
    moved
}

/// How far a tread's nose stands out before its riser (at `riser_m` from `s`'s centre
/// toward its front), metres: the peak (a median, narrowed twice) of the offsets from the
/// riser of the returns `FACE_BAND_M` under the tread's top, from `FACE_BEHIND_M` behind
/// the riser to `half_window_m` before it; `None` with fewer than `min_returns` of them.
/// Under a nosing (IRC R311.7.5.3: 19 to 32 mm deep on short treads; 25-40 mm thick, the
/// `real` suite) they are its face's, a nosing's depth out; under a plain nose, the riser's
/// top, about the riser, and the nose's strays past it (a return scattered along its ray
/// past the nose lies before the riser and below the top), a thin spread the peak sees
/// through. A tread's own returns, scattered in height, reach the band too, behind the
/// riser: those past `FACE_BEHIND_M` are left out.
fn nose_face(s: &PlaneSegment, points: &ByHeight, riser_m: f64, p: &RiserParams) -> Option<f64> {
    let half_width = s.width_m() / 2.0 - p.side_margin_m;
    let heights = [s.height_m() - FACE_BAND_M[1], s.height_m() - FACE_BAND_M[0]];
    let window = [riser_m - FACE_BEHIND_M, riser_m + p.half_window_m];
    let offsets: Vec<f64> =
        points.about(s, &-s.along(), heights, half_width, window).iter().map(|r| r.0 - riser_m).collect();
    if offsets.len() < p.min_returns {
        return None;
    }
    // The face's returns are a dense peak, the strays a thin spread before it.
    peak(&offsets, p.half_window_m)
}

/// The heights under a tread's top in which its nosing's face is looked for, metres: below
/// the tread's own returns' scatter about its top (about 1 cm in height under 20 mm of
/// noise seen from 1-2 m), within the thinnest nosing's face (25 mm, the `real` suite).
const FACE_BAND_M: [f64; 2] = [0.008, 0.025];

/// The heights under a tread's top in which its own face is looked for where no riser
/// stands under it, metres: the deeper half of `FACE_BAND_M` (see [`face_along`]).
const FACE_DEEP_M: [f64; 2] = [(FACE_BAND_M[0] + FACE_BAND_M[1]) / 2.0, FACE_BAND_M[1]];

/// How far behind the riser a return may lie and count toward the nose's face, metres:
/// the riser's peak's own half-width with the default window (`half_window_m / 4`, see
/// [`riser_seen`]), so a plain nose's face reads about the riser. The window reaching
/// `half_window_m` before the riser takes in more of the nose's strays than of the
/// tread's behind it, and pulls a plain nose's face a few millimetres out (see
/// [`NOSING_MIN_M`]).
const FACE_BEHIND_M: f64 = 0.0125;

/// Least projection of a nose before its riser for a nosing, metres: IRC's least nosing is
/// 19 mm, and under 20 mm of range noise a plain nose's face reads up to about 12 mm
/// before its riser (`wide` and `real`, one view each).
const NOSING_MIN_M: f64 = 0.015;

/// ... and at least this many times the sweep's measured range noise: at grazing incidence
/// a range error moves a return almost wholly along the tread, and the nose's strays past
/// it under more noise reach farther. A nosing shorter than that under such noise is left
/// on its riser.
const NOSING_NOISE_FACTOR: f64 = 1.0;

/// `s` with its front `front_m` from its old centre against its ascent, its back kept (and
/// its marks: the caller marks where the front now is); `None` when that leaves no depth.
fn with_front(s: &PlaneSegment, front_m: f64) -> Option<PlaneSegment> {
    with_edges(s, -front_m, s.depth_m() / 2.0)
}

/// `s` with its back `back_m` from its old centre up its ascent, its front kept (and
/// whether it is on its riser, with its nosing); `None` when that leaves no depth.
fn with_back(s: &PlaneSegment, back_m: f64) -> Option<PlaneSegment> {
    with_edges(s, -s.depth_m() / 2.0, back_m).map(|placed| placed.with_back_on_riser(true))
}

/// `s` running from `front_m` to `back_m` along its ascent from its old centre, every mark
/// of its edges kept (whether each is on its riser, its nosing); `None` when that leaves no
/// depth.
fn with_edges(s: &PlaneSegment, front_m: f64, back_m: f64) -> Option<PlaneSegment> {
    let depth_m = back_m - front_m;
    if depth_m <= 0.0 {
        return None;
    }
    let centre = s.center() + s.along() * (front_m + back_m) / 2.0;
    PlaneSegment::new(centre, s.along(), depth_m, s.width_m(), s.normal().into_inner(), s.voxel_count()).map(
        |placed| {
            placed
                .with_front(s.front_mark())
                .with_back_on_riser(s.back_on_riser())
                .with_nosing_m(s.nosing_m())
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every point of `points`, by height.
    fn all(points: &[Point3<f32>]) -> ByHeight {
        ByHeight::new(points, &[0.0], f64::INFINITY)
    }

    /// [`place_fronts`] over all of `cloud`, seen from `eye`.
    fn fronts(
        segments: &mut [PlaneSegment],
        cloud: &[Point3<f32>],
        eye: &Point3<f64>,
        ground_m: Option<f64>,
        noise_m: Option<f64>,
        p: &RiserParams,
    ) -> (usize, usize) {
        let view = ViewPoints { index: &all(cloud), cloud, viewpoint: *eye, ground_m, noise_m };
        place_fronts(segments, &view, p)
    }

    /// [`place_backs`] over all of `cloud`, seen from `eye`.
    fn backs(
        segments: &mut [PlaneSegment],
        cloud: &[Point3<f32>],
        eye: &Point3<f64>,
        p: &RiserParams,
    ) -> usize {
        place_backs(
            segments,
            &ViewPoints { index: &all(cloud), cloud, viewpoint: *eye, ground_m: None, noise_m: None },
            p,
        )
    }

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
    fn a_band_of_the_height_index_holds_every_point_of_that_band() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        // Spreads from under a bin to past what the bins' count can be (bins then taller).
        for spread_m in [0.005, 2.0, 1e5, 1e30] {
            // More points than one thread reads at a time, some of no finite height.
            let z = |u: f64| (u * spread_m - 0.3) as f32;
            let mut pts: Vec<Point3<f32>> =
                (0..3 * CHUNK).map(|_| Point3::new(rng.random(), rng.random(), z(rng.random()))).collect();
            pts.extend([f32::NAN, f32::INFINITY, f32::NEG_INFINITY].map(|z| Point3::new(0.0, 0.0, z)));
            let about: Vec<f64> = (0..3).map(|_| f64::from(z(rng.random()))).collect();
            // Bands and reaches a few centimetres high, or a hundredth of a wider spread.
            let scale_m = (spread_m / 100.0).max(0.1);
            for reach_m in [0.8 * scale_m, f64::INFINITY] {
                let index = ByHeight::new(&pts, &about, reach_m);
                let kept = |q: &Point3<f32>| about.iter().any(|h| (f64::from(q.z) - h).abs() <= reach_m);
                let mut nonempty = 0;
                for k in 0..200 {
                    // Bands about a kept height (a tread's), and anywhere.
                    let lo = match k % 2 {
                        0 => about[k % 3] + (rng.random::<f64>() - 0.5) * 2.0 * scale_m,
                        _ => f64::from(z(rng.random::<f64>() * 1.2 - 0.1)),
                    };
                    let hi = lo + rng.random::<f64>() * scale_m;
                    let inside = |q: &&Point3<f32>| f64::from(q.z) > lo && f64::from(q.z) < hi;
                    let mut want: Vec<[f32; 3]> =
                        pts.iter().filter(inside).filter(|q| kept(q)).map(|q| q.coords.into()).collect();
                    let mut got: Vec<[f32; 3]> =
                        index.within(lo, hi).iter().filter(inside).map(|q| q.coords.into()).collect();
                    want.sort_by(|a, b| a.partial_cmp(b).unwrap());
                    got.sort_by(|a, b| a.partial_cmp(b).unwrap());
                    assert_eq!(got, want, "band ({lo}, {hi}) over a spread of {spread_m} m, reach {reach_m}");
                    nonempty += usize::from(!want.is_empty());
                }
                // The comparisons are not all of empty bands.
                assert!(nonempty >= 20, "{nonempty} bands held points, spread {spread_m} m, reach {reach_m}");
            }
        }
        assert!(all(&[]).within(-1.0, 1.0).is_empty());
        assert!(all(&[Point3::new(0.0, 0.0, f32::NAN)]).within(-1.0, 1.0).is_empty());
        let one = [Point3::new(0.0, 0.0, 0.3)];
        assert_eq!(all(&one).within(0.29, 0.31), &one);
        let level: Vec<Point3<f32>> = (0..100).map(|i| Point3::new(i as f32, 0.0, 0.3)).collect();
        assert_eq!(all(&level).within(0.2, 0.4).len(), 100);
        assert_eq!(ByHeight::new(&level, &[0.5], 0.1).within(0.2, 0.4).len(), 0);
    }

    #[test]
    fn both_edges_placed_through_one_index_are_as_placed_over_every_point() {
        // Step 1 (top 0.3 m, nose at 1.0) and step 2 (top 0.45 m, nose at 1.3), their risers
        // and treads, a wall 2 m up and a floor far below the bands.
        let eye = Point3::new(0.0, 0.0, 1.4);
        let p = RiserParams::default();
        let mut cloud = wall(1.0, 0.15, 0.3);
        cloud.extend(patch(1.0, 1.3, 0.3));
        cloud.extend(wall(1.3, 0.3, 0.45));
        cloud.extend(patch(1.3, 1.6, 0.45));
        cloud.extend(wall(1.9, 0.45, 2.0));
        cloud.extend(patch(0.0, 1.0, 0.0));
        let steps = [tread(1.02, 0.3, 0.33), tread(1.31, 0.45, 0.25)];
        let mut one = steps.clone();
        let moved = place_edges(&mut one, &cloud, &eye, Some(0.0), None, &p);
        let mut every = steps.clone();
        let (riser_fronts, face_fronts) = fronts(&mut every, &cloud, &eye, Some(0.0), None, &p);
        let riser_backs = backs(&mut every, &cloud, &eye, &p);
        assert_eq!(moved, Placed { riser_fronts, face_fronts, riser_backs });
        assert!(
            riser_fronts >= 1 && riser_backs >= 1,
            "fronts {riser_fronts}, backs {riser_backs}: the test places something"
        );
        assert_eq!(one, every);
    }

    /// `seg` with its front placed over `cloud`, seen from 1.4 m over the origin under
    /// `noise_m`: how many fronts moved, and where its front edge lies along x.
    fn front_over(seg: &PlaneSegment, cloud: &[Point3<f32>], noise_m: Option<f64>) -> (usize, PlaneSegment) {
        let mut one = [seg.clone()];
        let (risers, faces) =
            fronts(&mut one, cloud, &Point3::new(0.0, 0.0, 1.4), None, noise_m, &RiserParams::default());
        let [placed] = one;
        (risers + faces, placed)
    }

    #[test]
    fn a_nosing_past_its_riser_is_the_front_not_the_riser() {
        // A tread 0.3 m up, 30 mm thick, whose nose stands 25 mm before its riser (at 1.025
        // m); the segment's front from voxels at 1.003.
        let seg = tread(1.003, 0.3, 0.297);
        let mut cloud = wall(1.025, 0.15, 0.27);
        cloud.extend(wall(1.0, 0.27, 0.3));
        cloud.extend(patch(1.0, 1.3, 0.3));
        let (moved, placed) = front_over(&seg, &cloud, None);
        let front = edges(&placed).0;
        // On the nose's face at 1.0, not the riser at 1.025.
        assert!(
            moved == 1 && (front - 1.0).abs() < 1e-3,
            "the front on the nose at 1.0, not the riser: {front:.4}"
        );
        assert!(placed.front_on_riser());
        assert!((placed.nosing_m() - 0.025).abs() < 1e-3, "nosing {}", placed.nosing_m());
        // The same riser under a plain nose, with the nose's strays scattered along the rays
        // 40-45 mm before it, below its top: fewer than its face's returns, but far enough
        // that the mean of both would read 18 mm out. The front on the riser.
        let mut plain = wall(1.025, 0.15, 0.3);
        plain.extend(patch(1.025, 1.3, 0.3));
        for x in [0.98, 0.9825, 0.985] {
            plain.extend(wall(x, 0.28, 0.2805));
        }
        let (moved, placed) = front_over(&seg, &plain, None);
        let front = edges(&placed).0;
        assert!(moved == 1 && (front - 1.025).abs() < 1e-3, "{front:.4}");
        assert_eq!(placed.nosing_m(), 0.0);
        // A nosing is believed from 15 mm out, and from the sweep's noise: a 13 mm one never,
        // a 19 mm one under 10 or 17 mm of noise, not under 25 mm.
        for (nose, noise_m, at) in [
            (1.012, None, 1.025),
            (1.012, Some(0.01), 1.025),
            (1.006, Some(0.01), 1.006),
            (1.006, Some(0.017), 1.006),
            (1.006, Some(0.025), 1.025),
        ] {
            let mut nosed = wall(1.025, 0.15, 0.27);
            nosed.extend(wall(nose, 0.27, 0.3));
            let front = edges(&front_over(&seg, &nosed, noise_m).1).0;
            assert!((front - at).abs() < 1e-3, "nose at {nose}, {noise_m:?}: front at {front:.4}");
        }
    }

    /// Every `every`-th return of a level patch at height z from x0 to x1 (see `patch`).
    fn thinned(x0: f64, x1: f64, z: f64, every: usize) -> Vec<Point3<f32>> {
        patch(x0, x1, z).into_iter().step_by(every).collect()
    }

    #[test]
    fn an_open_risers_front_is_its_slab_face() {
        // A slab tread 0.3 m up, 40 mm thick, its face at 1.0 m and nothing under it (an open
        // riser); the rectangle's front 30 mm out past it (the cell method's: the nose's
        // strays in the tread's plane). The tread's own returns, scattered in height by the
        // noise, reach under its top behind the face, thinning with depth: 10 mm under, ten
        // times as dense as the face's (the tread seen steeply from near), 20 mm under, a
        // fifth as dense. The tread below, 15 cm down, seen before the face.
        let seg = tread(0.97, 0.3, 0.33);
        let mut strays = patch(1.0, 1.3, 0.29);
        strays.extend(thinned(1.0, 1.3, 0.28, 20));
        let mut cloud = wall(1.0, 0.26, 0.3);
        cloud.extend(strays.iter().copied());
        cloud.extend(patch(0.85, 1.0, 0.15));
        let (moved, placed) = front_over(&seg, &cloud, None);
        let front = edges(&placed).0;
        assert!(moved == 1 && (front - 1.0).abs() < 1e-3, "front at {front:.4}");
        assert!(placed.front_on_face() && !placed.front_on_riser() && placed.front_measured());
        assert_eq!(placed.nosing_m(), 0.0);
        assert!((edges(&placed).1 - edges(&seg).1).abs() < 1e-9, "the back kept");
        // The same strays with no face (where the sweep's sight begins on the tread, or a
        // tread seen through noise alone), twice as many 20 mm under as the face had: an even
        // spread, no face; left as it was.
        let mut no_face = patch(1.0, 1.3, 0.29);
        no_face.extend(thinned(1.0, 1.3, 0.28, 5));
        no_face.extend(patch(0.85, 1.0, 0.15));
        assert_eq!(front_over(&seg, &no_face, None).0, 0);
        // Where the sweep's sight begins on the tread, at 1.0 m, nothing seen before it: the
        // tread's returns begin as a dense line (the servo dwells at the end of its sweep),
        // their strays under the top with them, a peak across the flight. Not a face.
        let mut sight_edge = strays.clone();
        for z in [0.3, 0.29, 0.28] {
            sight_edge.extend(patch(1.0, 1.0075, z));
        }
        assert_eq!(front_over(&seg, &sight_edge, None).0, 0);
        // A thing on the tread below, 0.3 m across, its top in the face's band 2.5 cm before
        // the face, its returns there outnumbering the face's: not the face. (The riser
        // search, before the face's, takes a thing as tall as that for the riser.)
        let mut thing = cloud.clone();
        for k in 0..8 {
            thing.extend(face(0.975 + 0.0005 * k as f64, [-0.15, 0.15], 0.27, 0.29));
        }
        let at =
            face_along(&seg, &all(&thing), &thing, 0.15, &RiserParams::default()).map(|t| seg.center().x - t);
        // The densest span is the thing's, and across part of the flight it is no face.
        assert_eq!(at, None, "the face at {at:?}");
    }

    #[test]
    fn a_rectangle_run_out_past_its_riser_comes_back_onto_it() {
        // The cell method's tread rectangle 8 cm out past the riser at 1.0 m, toward the
        // sensor (the nose's returns scattered along the rays, in the tread's plane).
        let mut cloud = wall(1.0, 0.15, 0.3);
        cloud.extend(patch(1.0, 1.3, 0.3));
        let (moved, placed) = front_over(&tread(0.92, 0.3, 0.38), &cloud, None);
        let front = edges(&placed).0;
        assert!(moved == 1 && (front - 1.0).abs() < 1e-3, "front at {front:.4}");
        assert_eq!(placed.nosing_m(), 0.0);
        // Past the window inside the edge: left as it was.
        assert_eq!(front_over(&tread(0.88, 0.3, 0.42), &cloud, None).0, 0);
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
            let riser = riser_along(&seg, &all(&pts), band, &p).expect("a riser seen whole");
            let at_x = seg.center().x - riser;
            assert!((at_x - 1.025).abs() < 2e-3, "the riser at {at_x:.4}, not 1.025");
        }
    }

    #[test]
    fn a_nosings_face_across_the_flight_does_not_make_a_stray_line_a_riser() {
        // A tread 0.3 m up, 35 mm thick, its nose 25 mm before its riser at 1.025 m; the
        // riser shadowed whole in the band, its nosing's face across the flight in the band's
        // upper half (one row of returns, seen at grazing). In the lower half, 77 mm under
        // the top, a sparse line of strays across a fifth of the flight, 7-16 mm before the
        // face (regression `stray-line-under-a-nosing-taken-for-its-riser`). The face stands
        // within `half_window_m / 4` of the line's peak, so both halves show it whole: only
        // the width tells the line from a riser, and the face's returns say nothing of it.
        let p = RiserParams::default();
        let seg = tread(1.003, 0.3, 0.297);
        let mut cloud = wall(1.0, 0.27, 0.275);
        for k in 0..45 {
            let x = 0.984 + 0.0002 * k as f64;
            cloud.push(Point3::new(x as f32, (-0.08 + 0.0035 * k as f64) as f32, 0.223));
        }
        let band = [0.3 - p.band_m[1], 0.3 - p.band_m[0]];
        let seen = riser_seen(&seg, &all(&cloud), &front_look(&seg, band, &p), &p).expect("seen whole");
        let line_x = seg.center().x - seen.at_m;
        assert!((1.0 - line_x) < p.half_window_m / 4.0, "the line's peak {line_x:.4} near the face");
        assert!(seen.width_share < p.min_front_width_share, "width share {}", seen.width_share);
        assert_eq!(riser_along(&seg, &all(&cloud), band, &p), None);
        // Seen from farther, the face whole and the riser under it across the flight in the
        // lower half: the riser placed.
        let mut seen = cloud.clone();
        seen.extend(wall(1.0, 0.265, 0.3));
        seen.extend(wall(1.025, 0.2, 0.25));
        let at = riser_along(&seg, &all(&seen), band, &p).map(|t| seg.center().x - t);
        assert!(at.is_some_and(|x| (x - 1.025).abs() < 2e-3), "the riser at {at:?}, not 1.025");
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
        assert_eq!(fronts(&mut one, &riser, &eye, None, None, &p), (1, 0));
        let front = one[0].center().x - one[0].depth_m() / 2.0;
        assert!((front - 1.0).abs() < 1e-3, "front at {front:.4}");
        assert!((one[0].center().x + one[0].depth_m() / 2.0 - 1.3).abs() < 1e-9, "the back kept");
        assert_eq!(one[0].height_m(), 0.3);
        assert!(one[0].front_on_riser());
        // A riser seen only in its upper part (a view over the nose), nothing seen before it:
        // not believed, nor is its top for the nose's face.
        let mut part = [seg.clone()];
        assert_eq!(fronts(&mut part, &wall(1.0, 0.25, 0.3), &eye, None, None, &p), (0, 0));
        assert_eq!(part[0], seg);
        // Nothing within the window (the true nose 10 cm off): not believed.
        let mut far = [seg.clone()];
        assert_eq!(fronts(&mut far, &wall(0.9, 0.15, 0.3), &eye, None, None, &p), (0, 0));
        // Disabled: the rectangles as §4 gives them.
        let mut off = [seg.clone()];
        assert_eq!(
            fronts(&mut off, &riser, &eye, None, None, &RiserParams { enabled: false, ..p.clone() }),
            (0, 0)
        );
        // Seen from past its middle (a tread under or behind the robot), its front does not
        // face the sensor: left as it is, whatever stands under its back edge.
        let mut back = [seg.clone()];
        let behind = Point3::new(1.2, 0.0, 1.4);
        assert_eq!(fronts(&mut back, &riser, &behind, None, None, &p), (0, 0));
        assert_eq!(back[0], seg);
        // A lone segment deeper than wide may have its axes swapped: left as it is.
        let deep = PlaneSegment::new(Point3::new(1.5, 0.0, 0.3), Vector3::x(), 1.0, 0.4, Vector3::z(), 100)
            .expect("valid rectangle");
        let mut lone = [deep.clone()];
        assert_eq!(fronts(&mut lone, &wall(1.0, 0.15, 0.3), &eye, None, None, &p), (0, 0));
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
        fronts(&mut segs, &pts, &eye, None, None, &p);
        let front = segs[1].center().x - segs[1].depth_m() / 2.0;
        assert!((front - 0.8).abs() < 1e-3, "front at {front:.4}");
        // The same with the lower tread known only as the ground under the sensor (the
        // floor, or the tread the robot stands on).
        let mut upper = [tread(0.825, 0.30, 0.3)];
        fronts(&mut upper, &pts, &eye, Some(0.22), None, &p);
        let front = upper[0].center().x - upper[0].depth_m() / 2.0;
        assert!((front - 0.8).abs() < 1e-3, "front at {front:.4}");
        // Unbounded, the strays outnumber the riser, and it is not believed; the front goes
        // onto the riser's top, its nose's face, under the tread.
        let mut unbounded = [tread(0.825, 0.30, 0.3)];
        assert_eq!(
            fronts(&mut unbounded, &pts, &eye, None, None, &p),
            (0, 1),
            "the strays outnumber the riser"
        );
        assert!((edges(&unbounded[0]).0 - 0.8).abs() < 1e-3 && unbounded[0].front_on_face());
    }

    /// Where `s`'s front and back edges are along x.
    fn edges(s: &PlaneSegment) -> (f64, f64) {
        (s.center().x - s.depth_m() / 2.0, s.center().x + s.depth_m() / 2.0)
    }

    /// `pts` without those whose y lies in `y`.
    fn beside(pts: Vec<Point3<f32>>, y: [f64; 2]) -> Vec<Point3<f32>> {
        pts.into_iter().filter(|q| !(y[0]..y[1]).contains(&(q.y as f64))).collect()
    }

    /// A face standing on the tread at `x`, across `y`, from `z0` to `z1` (every 5 mm up,
    /// 1 cm across).
    fn face(x: f64, y: [f64; 2], z0: f64, z1: f64) -> Vec<Point3<f32>> {
        let (mut v, mut z) = (Vec::new(), z0);
        while z < z1 {
            let mut w = y[0];
            while w < y[1] {
                v.push(Point3::new(x as f32, w as f32, z as f32));
                w += 0.01;
            }
            z += 0.005;
        }
        v
    }

    #[test]
    fn a_back_moves_onto_the_riser_above_seen_across_the_tread() {
        let eye = Point3::new(0.0, 0.0, 1.4);
        let p = RiserParams::default();
        // A tread 0.3 m up from its nose at 1.0 m, its rectangle running 6 cm past the
        // riser above it at 1.28 m (that riser's foot, seen through noise, on its plane).
        let seg = tread(1.0, 0.3, 0.34).with_front(FrontMark::Riser);
        let mut cloud = wall(1.28, 0.3, 0.45);
        cloud.extend(patch(1.0, 1.28, 0.3));
        let mut one = [seg.clone()];
        assert_eq!(backs(&mut one, &cloud, &eye, &p), 1);
        let (front, back) = edges(&one[0]);
        assert!((back - 1.28).abs() < 1e-3, "back at {back:.4}");
        assert!((front - 1.0).abs() < 1e-9, "the front kept: {front:.4}");
        assert!(one[0].back_on_riser() && one[0].front_on_riser());
        assert_eq!((one[0].height_m(), one[0].width_m()), (0.3, 1.0));
        // Its foot alone, the sweep ending 4.5 cm above the tread: the riser all the same.
        let mut foot = [seg.clone()];
        assert_eq!(backs(&mut foot, &wall(1.28, 0.3, 0.345), &eye, &p), 1);
        assert!((edges(&foot[0]).1 - 1.28).abs() < 1e-3);
        // A tread's own strays in the band, spread along it (an open riser: no riser
        // above), are no riser.
        let mut strays = [seg.clone()];
        assert_eq!(backs(&mut strays, &patch(1.18, 1.34, 0.325), &eye, &p), 0);
        assert_eq!(strays[0], seg);
        // The sensor past the back edge; backs not asked for: left as they are.
        let mut past = [seg.clone()];
        assert_eq!(backs(&mut past, &cloud, &Point3::new(1.4, 0.0, 1.4), &p), 0);
        let mut off = [seg.clone()];
        assert_eq!(backs(&mut off, &cloud, &eye, &RiserParams { backs: false, ..p.clone() }), 0);
        assert_eq!((past[0].clone(), off[0].clone()), (seg.clone(), seg));
    }

    #[test]
    fn a_thing_left_by_the_riser_is_not_the_riser() {
        let eye = Point3::new(0.0, 0.0, 1.4);
        let p = RiserParams::default();
        let seg = tread(1.0, 0.3, 0.34);
        // A shoe (12 cm across, 11 cm tall) or a person (0.5 m across) 3 cm before the riser
        // above at 1.28 m, their face seen more densely than the riser it hides: the back
        // goes on the riser or stays, never onto the face (a person's spans most of the
        // width seen, but not the tread's).
        for (across, tall) in [([-0.06, 0.06], 0.11), ([-0.25, 0.25], 0.5)] {
            let mut cloud = beside(wall(1.28, 0.3, 0.45), across);
            for _ in 0..4 {
                cloud.extend(face(1.25, across, 0.3, 0.3 + tall));
            }
            let mut one = [seg.clone()];
            backs(&mut one, &cloud, &eye, &p);
            let back = edges(&one[0]).1;
            assert!(
                (back - 1.28).abs() < 1e-3 || (back - 1.34).abs() < 1e-9,
                "{across:?}: back at {back:.4}"
            );
        }
    }
    #[test]
    fn a_thing_on_the_tread_below_is_not_the_riser_above_it() {
        let eye = Point3::new(0.0, 0.0, 1.4);
        let p = RiserParams::default();
        let seg = tread(1.0, 0.3, 0.3);
        // A shoe (12 cm across) on the tread below, against this tread's riser, its top 5 cm
        // under this tread's (the middle of the riser's band, its returns scattered about
        // it), seen from a step below over this tread's nose: the riser is shadowed, the tread's
        // strays spread thin behind its nose in the band's upper half, across the flight.
        let shoe: Vec<Point3<f32>> = [0.24, 0.245, 0.25, 0.255, 0.26]
            .iter()
            .flat_map(|&z| beside(patch(0.95, 0.99, z), [-0.28, 0.4]))
            .collect();
        let strays = thinned(1.0, 1.1, 0.27, 4);
        let mut cloud = shoe.clone();
        cloud.extend(&strays);
        let mut alone = [seg.clone()];
        assert_eq!(fronts(&mut alone, &cloud, &eye, None, None, &p), (0, 0));
        assert_eq!(alone[0], seg, "the front moved onto the shoe");
        // The riser seen beside it, denser than the shoe's top: the front on the riser.
        let riser = beside(wall(1.0, 0.22, 0.3), [-0.4, -0.28]);
        let mut cloud = [riser.clone(), riser].concat();
        cloud.extend(shoe);
        cloud.extend(strays);
        let mut beside_it = [seg.clone()];
        assert_eq!(fronts(&mut beside_it, &cloud, &eye, None, None, &p), (1, 0));
        assert!((edges(&beside_it[0]).0 - 1.0).abs() < 1e-3, "front at {:.4}", edges(&beside_it[0]).0);
    }
    #[test]
    fn a_riser_turned_against_its_tread_or_seen_in_part_places_the_front() {
        let eye = Point3::new(0.0, 0.0, 1.4);
        let p = RiserParams::default();
        let seg = tread(1.0, 0.3, 0.3);
        // The riser turned 5 deg against the rectangle (its axis erring so), its returns every
        // 2 cm across the tread and 5 mm up its band: a third of the strips lie within the
        // peak's half-width of the middle's peak, all of them on the riser's own line.
        let turn = 5f64.to_radians().tan();
        let turned: Vec<Point3<f32>> = wall(1.0, 0.22, 0.3)
            .into_iter()
            .map(|q| Point3::new((1.0 + f64::from(q.y) * turn) as f32, q.y, q.z))
            .collect();
        let mut one = [seg.clone()];
        assert_eq!(fronts(&mut one, &turned, &eye, None, None, &p), (1, 0));
        assert!((edges(&one[0]).0 - 1.0).abs() < 0.005, "front at {:.4}", edges(&one[0]).0);
        // The riser reached across 0.3 m of the tread only, nothing else in the window: the
        // strips the sweep did not reach say nothing.
        let part: Vec<Point3<f32>> = wall(1.0, 0.22, 0.3).into_iter().filter(|q| q.y.abs() < 0.15).collect();
        let mut one = [seg.clone()];
        assert_eq!(fronts(&mut one, &part, &eye, None, None, &p), (1, 0));
    }
}
