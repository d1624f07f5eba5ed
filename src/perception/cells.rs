//! Plane extraction on the scan grid, after CAPE (Proença and Gao, 2018) and PEAC (Feng et
//! al., ICRA 2014): a tilting lidar's sweep is an organized grid (rows x beams) in which
//! neighbours on a surface are neighbours in the grid, so planes grow over cells of the grid
//! with no k-d tree, no normal per point and no supervoxels. Selected by
//! `PerceptionParams::method` = `cells`; its steps come out of the same staircase extraction
//! as the paper's (§4.3, [`super::staircase::from_surfaces`]).
//!
//! 1. **Cells.** The grid is cut into cells of [`CellParams::rows`] x [`CellParams::beams`];
//!    a cell holding enough points gets their least-squares plane from its moments, less the
//!    scatter the range noise adds along the rays. It is a plane when its points' RMS
//!    distance from that plane is at most [`CellParams::planarity_noise_factor`] times the
//!    sweep's range noise (measured on the sweep, at least [`CellParams::planarity_floor_m`]):
//!    a cell across a nose holds tread and riser and is not. A plane whose tilt is known
//!    (`is_known`) is level within Filter 1's slope plus the uncertainty of its tilt
//!    ([`CellParams::level_sigmas`]), else steep. A cell that is neither is cut into its
//!    upper and lower rows, and is level by a half that is ([`CellParams::split_rows`]): a
//!    tread seen over few rows (far, or from low) holds no whole cell.
//! 2. **Regions.** From the flattest level cell not yet taken, a region grows over the
//!    grid's 4-neighbours: a level plane cell joins when its centre lies within
//!    [`CellParams::merge_distance_m`] of the region's plane, refitted from the summed
//!    moments as it grows. Two treads meet in the grid where a riser is hidden, a rise apart.
//!    A region is judged level again on all the points its cells were fitted to.
//! 3. **Points.** Each point of a region's cell or of a cell beside one (8-neighbours) goes
//!    to the likeliest plane among those cells' regions and steep planes, in its own noise
//!    (`region_of`): to a region only within its tolerance and within reach of the
//!    region's cell it borders (grid neighbours across a depth jump are far apart in space),
//!    and not when it lies behind a steep plane before the region. This gives back the edges
//!    that cells across them lost, point by point, as CAPE's refinement does.
//! 4. **Columns.** A region's points are binned into vertical columns of the voxel edge v
//!    as step 3 gives them (a table over the region's box of columns, one per band of cell
//!    rows, summed at the end); each column's mean is one "voxel" of the region, as the
//!    paper's segments are voxels. A region is one surface: its columns' parts a gap away
//!    from its body, and small beside it, are not its ([`CellParams::min_part_share`]). A
//!    gap is two or more places no return came from, or one seen through: step 3 also
//!    marks where the rays of points well below a region's plane came down through it.
//!
//! Step 1's sums need only a cell's own rows: [`Stream`] takes them as a sweep's rows
//! arrive, and leaves the rest, which needs the sweep's noise and every cell, for its end.

use super::normals::smallest_eigenvector;
use super::voxel::VoxelCloud;
use crate::cloud::{PointCloud, ScanGrid};
use nalgebra::{Matrix3, Point3, Vector3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// Parameters of the cell-based plane extraction (`[perception.cells]` in a parameters file).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CellParams {
    /// Scan rows per cell. With the default lidar (0.25 deg between rows and between beams)
    /// an 8 x 8 cell spans about 3.5 cm at 1 m across the rays, more along a tread seen
    /// obliquely: small enough that a 25 cm tread holds several, large enough that 64
    /// points under 10 mm of range noise fit a normal within about 2 deg. A tread seen over
    /// fewer than `2 rows - 1` rows may hold no whole cell; see `split_rows`.
    pub rows: usize,
    /// Beams per cell (see `rows`).
    pub beams: usize,
    /// A cell that is neither a level nor a steep plane (across a nose, or a tread and the
    /// wall behind it) is cut into its upper and lower rows, and a half that is a level
    /// plane makes the cell level with that half's points (all its points still go where
    /// step 3 gives them). A row of the tilting lidar crosses a tread along its width and
    /// the rows step along its depth: a tread seen over `R` rows always holds a whole cell
    /// when `R >= 2 rows - 1` (from `R >= rows` only where the cells' edges happen to fall
    /// right), and a whole half when `R >= rows - 1`. A 27 cm tread 0.8 m below the head
    /// and 2.3 m ahead spans about 8 rows (test `a_tread_seen_over_few_rows_is_found_by_the_cells`).
    /// Cells of 4 rows everywhere see it too, but lose near treads seen steeply through
    /// high noise (regression `pelvis-held-turned-from-the-flight`).
    pub split_rows: bool,
    /// A cell is fitted when at least this share of its grid places returned a point.
    pub min_fill: f64,
    /// A cell is a plane when its points' RMS distance from their plane is at most this
    /// many times the sweep's range noise. Range noise moves a point along its ray, at most
    /// its whole size off the plane; 2 keeps a level cell under noise and rejects one across
    /// a nose, whose riser part lies centimetres off.
    pub planarity_noise_factor: f64,
    /// ... and at least this RMS is allowed, metres (a noise-free sweep still has its
    /// surfaces' own roughness and the float rounding).
    pub planarity_floor_m: f64,
    /// A plane cell is level unless its normal is farther from up than Filter 1's slope by
    /// more than this many standard deviations of its tilt (what its points' scatter leaves
    /// of it). A near tread seen steeply under 20 mm of range noise spans 2-3 cm a cell,
    /// and its cells' normals scatter by more than the 15 deg slope itself; the region
    /// grown from them has its plane judged again, on all its points, by the staircase.
    pub level_sigmas: f64,
    /// ... and a cell or region whose tilt is that uncertain (radians) is not judged at
    /// all: its points lie about a line, and any normal fits them. The cells of a near
    /// tread seen through 25 mm of noise are within about 0.3 rad.
    pub max_tilt_sd_rad: f64,
    /// ... nor one whose plane the rays meet at less than this angle (radians): seen
    /// edge-on, it is the plane of the rays themselves (see `is_known`). A tread 4 m away
    /// is seen at about 19 deg from HRP-4's head.
    pub min_incidence_rad: f64,
    /// A cell joins a region when its centre is within this distance of the region's plane,
    /// metres: under the least rise a step has, above what noise and a tread's tilt of a
    /// degree over its width leave.
    pub merge_distance_m: f64,
    /// A region's plane is fitted to those of its cells whose points lie about it within
    /// this many times the range noise as seen across it (RMS of `sigma |ray . n|`, at
    /// least [`CellParams::planarity_floor_m`]). A cell at a tread's back edge holds the
    /// foot of the riser above, one at its front the top of the riser below: under noise
    /// such a cell still passes as a level plane, and its riser returns, 1-3 cm off the
    /// tread, tilt the region's plane toward the sensor by degrees, a tilt that step 3's
    /// tolerance about that plane then keeps (test `a_tread_under_range_noise_comes_out_level`).
    /// The cells stay the region's; only its plane leaves them out.
    pub fit_noise_factor: f64,
    /// A point joins a region when within this many times its range noise, as seen across
    /// the plane (the noise moves a point along its ray: `sigma |ray . n|` off the plane), of
    /// the region's plane ...
    pub point_noise_factor: f64,
    /// ... or within this distance, metres (surfaces' roughness, the plane's own error).
    pub point_floor_m: f64,
    /// A region is one surface, as the paper's segment is one cluster's part of a plane: its
    /// columns fall into parts that touch (within two columns, as `join_touching` joins
    /// parts, but not across an empty column that rays were seen through below the plane),
    /// and a part with fewer columns than this share of the region's biggest is not the
    /// region's. Step 3 gives a tread the returns of a wall beside the flight at the tread's
    /// height (they lie in its plane, within reach of its edge cell): a few columns a gap
    /// away, which widen the tread by the gap, and under 20 mm of noise turn the line
    /// through the treads' middles, the flight's axis, by degrees. A wall two columns off
    /// (a stairwell's 4-6 cm gap) is kept apart from the tread by the rays that came down
    /// through that gap to the wall below (test
    /// `a_stairwells_gap_beside_the_flight_is_not_read_as_tread`). A tread cut in two by a
    /// leg's shadow, or seen one scan line in three, keeps its parts: each is a like share
    /// of the whole.
    pub min_part_share: f64,
}

impl Default for CellParams {
    fn default() -> Self {
        Self {
            rows: 8,
            beams: 8,
            split_rows: true,
            min_fill: 0.5,
            planarity_noise_factor: 2.0,
            planarity_floor_m: 0.004,
            level_sigmas: 2.0,
            max_tilt_sd_rad: 0.5,
            min_incidence_rad: 5f64.to_radians(),
            merge_distance_m: 0.02,
            fit_noise_factor: 1.5,
            point_noise_factor: 1.5,
            point_floor_m: 0.005,
            min_part_share: 0.1,
        }
    }
}

impl CellParams {
    /// The first field out of range and why, if any.
    pub fn invalid(&self) -> Option<(&'static str, &'static str)> {
        let pos = |v: f64| v.is_finite() && v > 0.0;
        if !(2..=64).contains(&self.rows) || !(2..=64).contains(&self.beams) || self.rows * self.beams < 6 {
            return Some((
                "cells.rows",
                "cells.rows and cells.beams must be in [2, 64], at least 6 places a cell",
            ));
        }
        if !(self.min_fill > 0.0 && self.min_fill <= 1.0) {
            return Some(("cells.min_fill", "must be in (0, 1]"));
        }
        if !(self.min_part_share >= 0.0 && self.min_part_share <= 1.0) {
            return Some(("cells.min_part_share", "must be in [0, 1]"));
        }
        for (f, v) in [
            ("cells.planarity_noise_factor", self.planarity_noise_factor),
            ("cells.planarity_floor_m", self.planarity_floor_m),
            ("cells.level_sigmas", self.level_sigmas),
            ("cells.max_tilt_sd_rad", self.max_tilt_sd_rad),
            ("cells.min_incidence_rad", self.min_incidence_rad),
            ("cells.merge_distance_m", self.merge_distance_m),
            ("cells.fit_noise_factor", self.fit_noise_factor),
            ("cells.point_noise_factor", self.point_noise_factor),
            ("cells.point_floor_m", self.point_floor_m),
        ] {
            if !pos(v) {
                return Some((f, "must be > 0"));
            }
        }
        None
    }
}

/// Sums of a set of points (relative to the viewpoint) from which their plane is fitted.
#[derive(Debug, Clone, Copy, Default)]
struct Moments {
    n: f64,
    sum: [f64; 3],
    /// Sum of q q^T, its upper triangle (xx, xy, xz, yy, yz, zz).
    outer: [f64; 6],
    /// Sum of d d^T over the points' unit rays d, upper triangle: range noise scatters a
    /// point along its ray, adding `sigma^2 d d^T` to the points' covariance.
    rays: [f64; 6],
}

/// The symmetric matrix of an upper triangle (xx, xy, xz, yy, yz, zz).
fn symmetric(u: &[f64; 6]) -> Matrix3<f64> {
    Matrix3::new(u[0], u[1], u[2], u[1], u[3], u[4], u[2], u[4], u[5])
}

impl Moments {
    /// A point `q` seen from the viewpoint.
    #[cfg(test)]
    fn add(&mut self, q: &Vector3<f64>) {
        self.add_seen(q, q);
    }

    /// A point `q` seen along the ray `d` (from its row's own origin, when the sensor moved
    /// during the sweep; `q` itself when it did not). Inlined, the sums stay in registers
    /// over a cell's points.
    #[inline(always)]
    fn add_seen(&mut self, q: &Vector3<f64>, d: &Vector3<f64>) {
        let (x, y, z) = (q.x, q.y, q.z);
        let o = [x * x, x * y, x * z, y * y, y * z, z * z];
        let r = if q == d { o } else { [d.x * d.x, d.x * d.y, d.x * d.z, d.y * d.y, d.y * d.z, d.z * d.z] };
        let norm2 = r[0] + r[3] + r[5];
        let inv = if norm2 > 0.0 { 1.0 / norm2 } else { 0.0 };
        self.n += 1.0;
        self.sum[0] += x;
        self.sum[1] += y;
        self.sum[2] += z;
        for (((outer, rays), o), r) in self.outer.iter_mut().zip(&mut self.rays).zip(o).zip(r) {
            *outer += o;
            *rays += r * inv;
        }
    }

    fn merge(&mut self, o: &Self) {
        self.n += o.n;
        for k in 0..3 {
            self.sum[k] += o.sum[k];
        }
        for k in 0..6 {
            self.outer[k] += o.outer[k];
            self.rays[k] += o.rays[k];
        }
    }

    /// The points' mean square distance from `plane`, and what the range noise of variance
    /// `noise_var_m2` alone would give (it moves a point along its ray `d`, `|d . n|` of it
    /// across the plane).
    fn mean_square_m2(&self, plane: &Plane, noise_var_m2: f64) -> (f64, f64) {
        let n = &plane.normal;
        let inv = 1.0 / self.n.max(1.0);
        let along = n.dot(&self.centre());
        let offset = n.dot(&plane.centre);
        let spread = n.dot(&(symmetric(&self.outer) * n)) * inv - along * along;
        let seen = n.dot(&(symmetric(&self.rays) * n)) * inv * noise_var_m2;
        (spread.max(0.0) + (along - offset).powi(2), seen)
    }

    /// The centre of the points (the origin for none).
    fn centre(&self) -> Vector3<f64> {
        Vector3::from(self.sum) / self.n.max(1.0)
    }

    /// The least-squares plane, its normal toward the origin (the viewpoint: the side the
    /// sensor sees, so a ceiling's faces down); `None` for fewer than three points or points
    /// that span no plane.
    ///
    /// The plane is fitted to the scatter less what a range noise of variance
    /// `noise_var_m2` adds along the rays (the errors-in-variables correction): seen
    /// obliquely through 20 mm of noise, a tread's least-squares plane through the raw
    /// points turns by 20 deg toward the rays, where the corrected one stays level.
    fn plane(&self, noise_var_m2: f64) -> Option<Plane> {
        if self.n < 3.0 {
            return None;
        }
        let centre = self.centre();
        let cov = symmetric(&self.outer) / self.n - centre * centre.transpose();
        // Less the noise along the rays, plus as much again in every direction (which
        // leaves the eigenvectors as they are and the matrix positive semi-definite).
        let fit = cov - symmetric(&self.rays) * (noise_var_m2 / self.n) + Matrix3::identity() * noise_var_m2;
        let v = smallest_eigenvector(&fit.cast::<f32>())?.cast::<f64>().normalize();
        let normal = if v.dot(&centre) > 0.0 { -v } else { v };
        let l0 = normal.dot(&(cov * normal)).max(0.0);
        // The fit's two larger eigenvalues from its trace and the sum of its principal
        // 2 x 2 minors (c1 = m0 m1 + m0 m2 + m1 m2); the smaller, less the shift, is the
        // in-plane spread the noise did not make, across which the normal tilts most easily.
        let m0 = normal.dot(&(fit * normal));
        let sum12 = fit.trace() - m0;
        let c1 = fit[(0, 0)] * fit[(1, 1)] + fit[(0, 0)] * fit[(2, 2)] + fit[(1, 1)] * fit[(2, 2)]
            - fit[(0, 1)].powi(2)
            - fit[(0, 2)].powi(2)
            - fit[(1, 2)].powi(2);
        let prod12 = (c1 - m0 * sum12).max(0.0);
        let spread_m2 = (sum12 - (sum12 * sum12 - 4.0 * prod12).max(0.0).sqrt()) / 2.0 - noise_var_m2;
        // Points about a line (no spread across it but the noise's) leave the normal free
        // to turn about it.
        let tilt_sd_rad = if spread_m2 > 0.0 { (l0 / (self.n * spread_m2)).sqrt() } else { f64::INFINITY };
        Some(Plane { centre, normal, rms_m: l0.sqrt(), tilt_sd_rad })
    }
}

/// A fitted plane, in coordinates relative to the extraction's origin.
#[derive(Debug, Clone, Copy)]
struct Plane {
    centre: Vector3<f64>,
    /// Unit, up.
    normal: Vector3<f64>,
    /// RMS distance of the points from the plane, metres.
    rms_m: f64,
    /// Standard deviation of the normal's tilt that the points' scatter about the plane
    /// leaves (least squares: the RMS over the root of the count times the smaller
    /// in-plane spread, less the scatter), radians.
    tilt_sd_rad: f64,
}

impl Plane {
    fn distance_m(&self, q: &Vector3<f64>) -> f64 {
        self.normal.dot(&(q - self.centre)).abs()
    }
}

/// One cell of the grid.
#[derive(Debug, Clone, Copy)]
struct Cell {
    moments: Moments,
    /// The sums of the points its level plane was fitted to, which a region takes in: all
    /// of `moments`, or a half's ([`CellParams::split_rows`]).
    fit: Moments,
    /// Its plane, when it is a level plane.
    level: Option<Plane>,
    /// Its plane, when it is a plane too steep to be level (a riser, a wall): its points
    /// nearer that plane than a region's stay out of the region.
    steep: Option<Plane>,
    /// Points within this of its centre (`fit`'s) are near it, metres
    /// ([`REACH_DIAGONALS`]; a level half's own, [`CellParams::split_rows`]).
    reach_m: f64,
    /// Its points' horizontal bounding box (world x, y), metres: lowest, highest.
    box_m: [[f32; 2]; 2],
}

/// A cell's reach, in diagonals of its points' bounding box: its neighbours' points lie
/// within about one and a half diagonals of its centre.
const REACH_DIAGONALS: f64 = 1.5;

/// What the extraction found: the regions' columns as voxels, and each region as the
/// indices of its voxels with its plane's normal (up).
#[derive(Debug, Clone, Default)]
pub struct Regions {
    /// Columns of every region.
    pub voxels: VoxelCloud,
    /// Each region's columns (indices into `voxels`) and normal.
    pub surfaces: Vec<(Vec<u32>, Vector3<f64>)>,
    /// Cells fitted (enough points).
    pub cells: usize,
    /// Cells that are level planes.
    pub level_cells: usize,
    /// Points given to a region.
    pub points_in_regions: usize,
    /// Wall time of step 1 (cells), milliseconds.
    pub cells_ms: f64,
    /// Wall time of steps 2 to 4 (regions, points, columns), milliseconds.
    pub regions_ms: f64,
}

const NONE: u32 = u32::MAX;

/// A plane beside a cell's points in step 3: a region's, or a steep cell's ([`NONE`]).
struct Near {
    normal: Vector3<f64>,
    /// `normal . x` on the plane.
    offset_m: f64,
    region: u32,
    /// The centre of the cell it was found in, and the square of that cell's reach (infinite
    /// for the points' own cell).
    cell_centre: Vector3<f64>,
    reach2_m2: f64,
}

/// The region the point `q` (from the viewpoint, seen along the ray `d`: from its row's own
/// origin where the sensor moved, else `q` again) joins among `near`, if any: the likeliest
/// plane in the point's own noise, which moves it along its ray (distance over
/// `sigma |ray . n|`); a region's only within its tolerance and within reach of the cell it
/// was found in, and not when the point lies behind a steep plane its ray meets near that
/// plane's cell while the region lies before it (on the sensor's side): the steep surface's
/// own point, pushed behind it by the noise (a riser's foot landing on the plane of the tread
/// below, past the tread's end). A tread lies behind the riser under its own nose, and keeps
/// its points there.
///
/// `crossed` is told, for each region among `near` whose plane the point lies below by more
/// than [`SEEN_THROUGH_SIGMAS`] of its noise, where the point's ray crossed that plane on
/// its way down (from its row's origin): a place where there is no surface of that plane,
/// for step 4. A region beside the point in several cells is told once.
fn region_of(
    q: &Vector3<f64>,
    d: &Vector3<f64>,
    near: &[Near],
    planes: &[Plane],
    noise_m: f64,
    p: &CellParams,
    crossed: &mut impl FnMut(u32, Vector3<f64>),
) -> Option<u32> {
    // The ray's origin, from the viewpoint (zero but where the sensor moved).
    let seen_from = q - d;
    let range_m = d.norm();
    let inv_range = 1.0 / range_m;
    let floor_sd_m = p.point_floor_m / p.point_noise_factor;
    // The likeliest so far: its distance and its noise as seen (`d / sd` compared by
    // cross-multiplying, with no division per plane).
    let mut best: Option<(f64, f64, &Near)> = None;
    for (k, n) in near.iter().enumerate() {
        let along = n.normal.dot(q);
        let d_m = (along - n.offset_m).abs();
        let seen_sd_m = noise_m * (n.normal.dot(d) * inv_range).abs();
        let sd_m = seen_sd_m.max(floor_sd_m);
        let tolerance_m = (p.point_noise_factor * seen_sd_m).max(p.point_floor_m);
        if n.region != NONE && along < n.offset_m - (SEEN_THROUGH_SIGMAS * seen_sd_m).max(p.point_floor_m) {
            // Below the plane, its ray came down through it (from above: the plane's normal
            // is up) at this fraction of the way from the viewpoint.
            let above_m = n.normal.dot(&seen_from) - n.offset_m;
            if above_m > 0.0 && !near[..k].iter().any(|m| m.region == n.region) {
                crossed(n.region, seen_from + d * (above_m / (above_m + n.offset_m - along)));
            }
        }
        if best.is_some_and(|(bd, bsd, _)| bd * sd_m <= d_m * bsd) {
            continue;
        }
        let joins =
            n.region == NONE || (d_m <= tolerance_m && (q - n.cell_centre).norm_squared() <= n.reach2_m2);
        if joins {
            best = Some((d_m, sd_m, n));
        }
    }
    let (_, _, chosen) = best?;
    if chosen.region == NONE {
        return None;
    }
    let region = &planes[chosen.region as usize];
    let behind = |s: &Near| {
        if s.region != NONE {
            return false;
        }
        let along = s.normal.dot(d) * inv_range;
        let t = (s.offset_m - s.normal.dot(&seen_from)) / along;
        along.abs() > 1e-6
            && t > 0.0
            && t < range_m
            && s.normal.dot(&region.centre) > s.offset_m
            && (seen_from + d * (t * inv_range) - s.cell_centre).norm_squared() <= s.reach2_m2
    };
    (!near.iter().any(behind)).then_some(chosen.region)
}

/// [`region_of`] where `near` is the one region's plane `n` alone: whether the point joins
/// it (the same arithmetic, so the same answer to the last bit), `crossed` told as there.
#[inline(always)]
fn joins_alone(
    q: &Vector3<f64>,
    d: &Vector3<f64>,
    n: &Near,
    noise_m: f64,
    p: &CellParams,
    crossed: &mut impl FnMut(u32, Vector3<f64>),
) -> bool {
    let along = n.normal.dot(q);
    let d_m = (along - n.offset_m).abs();
    // Within the floor it joins whatever its noise (the tolerance is at least the floor),
    // and lies too little below the plane for its ray to have come through it: no need of
    // its range.
    if d_m <= p.point_floor_m && along >= n.offset_m - p.point_floor_m {
        return (q - n.cell_centre).norm_squared() <= n.reach2_m2;
    }
    let inv_range = 1.0 / d.norm();
    let seen_sd_m = noise_m * (n.normal.dot(d) * inv_range).abs();
    if along < n.offset_m - (SEEN_THROUGH_SIGMAS * seen_sd_m).max(p.point_floor_m) {
        let seen_from = q - d;
        let above_m = n.normal.dot(&seen_from) - n.offset_m;
        if above_m > 0.0 {
            crossed(n.region, seen_from + d * (above_m / (above_m + n.offset_m - along)));
        }
    }
    d_m <= (p.point_noise_factor * seen_sd_m).max(p.point_floor_m)
        && (q - n.cell_centre).norm_squared() <= n.reach2_m2
}

/// Whether `f`'s tilt can be judged: within [`CellParams::max_tilt_sd_rad`], and seen at
/// [`CellParams::min_incidence_rad`] or more. Points about a line have a plane of any tilt;
/// and a single scan line's points, scattered along their rays by the range noise, lie on
/// the plane through the sensor that holds those rays, seen edge-on: across a ceiling
/// 0.6 m above the sensor such a plane is within 14 deg of level and would pass for a tread
/// (regression `noisy-views-in-pieces-and-turned` from its top landing, with this method).
fn is_known(f: &Plane, p: &CellParams) -> bool {
    let incidence = f.normal.dot(&f.centre).abs() / f.centre.norm().max(1e-9);
    f.tilt_sd_rad <= p.max_tilt_sd_rad && incidence >= p.min_incidence_rad.sin()
}

/// Whether `f` may be level: judged (`is_known`), its normal within `max_tilt_rad` of
/// `up` but for [`CellParams::level_sigmas`] standard deviations of its tilt.
fn is_level(f: &Plane, up: &Vector3<f64>, max_tilt_rad: f64, p: &CellParams) -> bool {
    let tilt_rad = f.normal.dot(up).clamp(-1.0, 1.0).acos();
    is_known(f, p) && tilt_rad <= max_tilt_rad + p.level_sigmas * f.tilt_sd_rad
}

/// What a cell's plane is judged by in step 1.
struct Limits {
    /// The fewest points a cell is fitted on.
    min_points: f64,
    up: Vector3<f64>,
    /// Filter 1's slope, radians.
    max_tilt_rad: f64,
    /// The sweep's range noise, squared.
    noise_var_m2: f64,
    /// The most RMS distance of a plane's points from it.
    max_rms_m: f64,
}

/// The level plane of cell `(cr, cb)`'s upper or lower rows, with the sums of its points
/// and its reach ([`REACH_DIAGONALS`] of its points' box), when one half is one
/// ([`CellParams::split_rows`]): the half with more points, or of two as full the flatter.
/// `None` when neither is a known level plane, or for cells of under 4 rows (a half of one
/// row is a line, of any tilt).
fn level_half(g: &Grid, (cr, cb): (usize, usize), l: &Limits) -> Option<(Moments, Plane, f64)> {
    let p = g.p;
    let (r0, r2) = g.rows_of(cr);
    let r1 = r0 + p.rows / 2;
    if p.rows < 4 || r1 >= r2 {
        return None;
    }
    // Each half's least count from its full size (a last, partial row of cells counts short).
    [(r0, r1, p.rows / 2), (r1, r2, p.rows - p.rows / 2)]
        .into_iter()
        .filter_map(|(a, b, full)| {
            let min_points = (p.min_fill * (full * p.beams) as f64).ceil().max(3.0);
            let mut m = Moments::default();
            let (mut lo, mut hi) = (Vector3::repeat(f64::INFINITY), Vector3::repeat(f64::NEG_INFINITY));
            g.for_points((a, b), cb, |_, q, d| {
                m.add_seen(&q, &d);
                lo = lo.inf(&q);
                hi = hi.sup(&q);
            });
            let f = (m.n >= min_points).then(|| m.plane(l.noise_var_m2)).flatten()?;
            let level = f.rms_m <= l.max_rms_m && is_level(&f, &l.up, l.max_tilt_rad, p);
            level.then(|| (m, f, REACH_DIAGONALS * (hi - lo).norm()))
        })
        .max_by(|(a, f, _), (b, g, _)| a.n.total_cmp(&b.n).then(g.rms_m.total_cmp(&f.rms_m)))
}

/// A sweep's scan grid as the cells read it: the grid, its points, the sensor's origin (the
/// points are read from it) and the cells' parameters.
#[derive(Clone, Copy)]
struct Grid<'a> {
    grid: &'a ScanGrid,
    points: &'a [Point3<f32>],
    origin: Vector3<f64>,
    /// Where each row was seen from, from the origin, when the sensor moved during the
    /// sweep ([`ScanGrid::row_origins`]); empty when it did not.
    row_offsets: &'a [Vector3<f64>],
    p: &'a CellParams,
}

impl<'a> Grid<'a> {
    /// `cloud`'s grid for `p`, its rows seen from `row_offsets` (their own origins from the
    /// viewpoint, [`row_offsets`]; empty for a sensor that stood); `None` without a grid.
    fn of(cloud: &'a PointCloud, row_offsets: &'a [Vector3<f64>], p: &'a CellParams) -> Option<Self> {
        Some(Self {
            grid: cloud.grid()?,
            points: cloud.points(),
            origin: cloud.viewpoint().coords,
            row_offsets,
            p,
        })
    }

    /// Its cell rows and columns.
    fn dims(&self) -> (usize, usize) {
        (self.grid.rows().div_ceil(self.p.rows), self.grid.beams().div_ceil(self.p.beams))
    }

    /// The scan rows of cell row `cr`.
    fn rows_of(&self, cr: usize) -> (usize, usize) {
        let r0 = cr * self.p.rows;
        (r0, (r0 + self.p.rows).min(self.grid.rows()))
    }

    /// Calls `f` with each finite point of rows `r0..r1` of cell column `cb` (a cell's:
    /// [`Grid::rows_of`]): its index, its position from the origin and its ray (from its
    /// row's own origin where the sensor moved, else the position again), row by row.
    #[inline(always)]
    fn for_points(
        &self,
        (r0, r1): (usize, usize),
        cb: usize,
        mut f: impl FnMut(u32, Vector3<f64>, Vector3<f64>),
    ) {
        let beams = self.grid.beams();
        let b0 = cb * self.p.beams;
        let b1 = (b0 + self.p.beams).min(beams);
        for r in r0..r1 {
            let offset = self.row_offsets.get(r);
            for &c in &self.grid.cells()[r * beams + b0..r * beams + b1] {
                let Some(q) = self.points.get(c as usize) else { continue };
                if q.x.is_finite() && q.y.is_finite() && q.z.is_finite() {
                    let q = q.coords.cast::<f64>() - self.origin;
                    f(c, q, offset.map_or(q, |o| q - o));
                }
            }
        }
    }
}

/// The offsets of `cloud`'s rows' own origins from its viewpoint, when its sensor moved
/// during the sweep ([`ScanGrid::row_origins`]); empty when it did not.
fn row_offsets(cloud: &PointCloud) -> Vec<Vector3<f64>> {
    let origin = cloud.viewpoint();
    cloud.grid().map_or(Vec::new(), |g| g.row_origins().iter().map(|o| o - origin).collect())
}

/// Step 1's sums of one cell, from its points alone (no noise needed, so a stream takes
/// them as its rows arrive): its moments, reach and box.
#[derive(Debug, Clone, Copy)]
struct CellSums {
    moments: Moments,
    /// [`REACH_DIAGONALS`] of its points' bounding box, metres.
    reach_m: f64,
    /// Its points' horizontal bounding box (world x, y), metres: lowest, highest.
    box_m: [[f32; 2]; 2],
}

/// The sums of the cells of cell row `cr`, in order: taken scan row by scan row across the
/// whole cell row (the points in the order they lie in memory), each cell's points in the
/// same order as cell by cell, so its sums are the same to the last bit.
fn sums_of_row(g: &Grid, cr: usize) -> impl Iterator<Item = CellSums> {
    #[derive(Clone, Copy)]
    struct Acc {
        m: Moments,
        lo: Vector3<f64>,
        hi: Vector3<f64>,
        box_m: [[f32; 2]; 2],
    }
    let empty = Acc {
        m: Moments::default(),
        lo: Vector3::repeat(f64::INFINITY),
        hi: Vector3::repeat(f64::NEG_INFINITY),
        // The box in the points' own coordinates, as step 4 bins them.
        box_m: [[f32::INFINITY; 2], [f32::NEG_INFINITY; 2]],
    };
    let mut acc = vec![empty; g.dims().1];
    let (r0, r1) = g.rows_of(cr);
    for r in r0..r1 {
        for (cb, a) in acc.iter_mut().enumerate() {
            let Acc { m, lo, hi, box_m } = a;
            g.for_points((r, r + 1), cb, |i, q, d| {
                m.add_seen(&q, &d);
                *lo = lo.inf(&q);
                *hi = hi.sup(&q);
                let w = &g.points[i as usize];
                *box_m = [
                    [box_m[0][0].min(w.x), box_m[0][1].min(w.y)],
                    [box_m[1][0].max(w.x), box_m[1][1].max(w.y)],
                ];
            });
        }
    }
    acc.into_iter().map(|Acc { m, lo, hi, box_m }| {
        let reach_m = if m.n > 0.0 { REACH_DIAGONALS * (hi - lo).norm() } else { 0.0 };
        CellSums { moments: m, reach_m, box_m }
    })
}

/// Cell `cell` (its row and column) of sums `s` judged (step 1): a level plane, a steep one,
/// or neither, and then perhaps level by a half ([`CellParams::split_rows`]).
fn judge(s: &CellSums, g: &Grid, cell: (usize, usize), l: &Limits) -> Cell {
    let p = g.p;
    let m = s.moments;
    let plane =
        (m.n >= l.min_points).then(|| m.plane(l.noise_var_m2)).flatten().filter(|f| f.rms_m <= l.max_rms_m);
    // A plane of uncertain tilt is neither (see `is_known`).
    let known = plane.filter(|f| is_known(f, p));
    let steep = known.filter(|f| !is_level(f, &l.up, l.max_tilt_rad, p));
    let mut level = known.filter(|_| steep.is_none());
    let (mut fit, mut reach_m) = (m, s.reach_m);
    // Neither a level nor a steep plane: perhaps two surfaces, one in each half. A level
    // half reaches its neighbours' points from its own centre and box: the whole cell's may
    // span a depth jump.
    if p.split_rows && level.is_none() && steep.is_none() && m.n >= l.min_points {
        if let Some((half, f, r)) = level_half(g, cell, l) {
            (fit, level, reach_m) = (half, Some(f), r);
        }
    }
    Cell { moments: m, fit, level, steep, reach_m, box_m: s.box_m }
}

/// The sums of every cell of `cloud`'s grid, row-major; `None` without a grid.
fn all_sums(cloud: &PointCloud, p: &CellParams) -> Option<Vec<CellSums>> {
    let offsets = row_offsets(cloud);
    let g = Grid::of(cloud, &offsets, p)?;
    let crs = g.dims().0;
    Some((0..crs).into_par_iter().flat_map_iter(|cr| sums_of_row(&g, cr)).collect())
}

/// Step 1's sums gathered as a sweep's rows arrive, each row of cells as soon as its last
/// scan row is in; the rest of the extraction, which needs the sweep's noise and every
/// cell, is left for [`Stream::finish`]. It gives exactly what [`extract`] gives on the
/// whole sweep.
#[derive(Debug, Clone)]
pub struct Stream {
    sums: Vec<CellSums>,
    /// Cell rows summed.
    cell_rows: usize,
}

impl Stream {
    /// An empty stream for `cloud`'s grid (its rows not yet arrived are not read); `None`
    /// without a grid.
    pub fn new(cloud: &PointCloud) -> Option<Self> {
        cloud.grid().map(|_| Self { sums: Vec::new(), cell_rows: 0 })
    }

    /// The sweep's first `rows` scan rows have arrived (of `cloud`, the one given to `new`):
    /// sums the rows of cells they complete.
    pub fn arrived(&mut self, cloud: &PointCloud, rows: usize, p: &CellParams) {
        let offsets = row_offsets(cloud);
        let Some(g) = Grid::of(cloud, &offsets, p) else { return };
        let crs = g.dims().0;
        let complete = if rows >= g.grid.rows() { crs } else { rows / p.rows };
        for cr in self.cell_rows..complete {
            self.sums.extend(sums_of_row(&g, cr));
        }
        self.cell_rows = self.cell_rows.max(complete);
    }

    /// [`extract`]'s regions once every row has arrived (the rest are summed now); `None`
    /// without a grid. Its `cells_ms` counts the sums taken now and the cells' judging.
    pub fn finish(mut self, cloud: &PointCloud, s: &Setting) -> Option<Regions> {
        let start = Instant::now();
        self.arrived(cloud, usize::MAX, s.params);
        regions(cloud, &self.sums, start, s)
    }
}

/// What the extraction works to, besides the cloud.
#[derive(Debug, Clone, Copy)]
pub struct Setting<'a> {
    /// The columns' edge (the voxel edge), metres.
    pub voxel_m: f64,
    /// The least cosine of a level normal from up (Filter 1's).
    pub cos_slope: f64,
    /// The sweep's range noise, metres.
    pub noise_m: f64,
    /// The cells' own parameters.
    pub params: &'a CellParams,
}

/// Level planes grown on `cloud`'s scan grid (see the module's doc) as `s` says. `None` for
/// a cloud without a scan grid.
pub fn extract(cloud: &PointCloud, s: &Setting) -> Option<Regions> {
    let start = Instant::now();
    let sums = all_sums(cloud, s.params)?;
    regions(cloud, &sums, start, s)
}

/// Steps 1 (the cells judged) to 4 from every cell's `sums`; step 1's time counted from
/// `start`.
fn regions(cloud: &PointCloud, sums: &[CellSums], start: Instant, s: &Setting) -> Option<Regions> {
    let Setting { voxel_m, cos_slope, noise_m, params: p } = *s;
    let offsets = row_offsets(cloud);
    let g = Grid::of(cloud, &offsets, p)?;
    let (origin, points) = (g.origin, g.points);
    let up = -cloud.gravity().into_inner();
    let (crs, cbs) = g.dims();
    let min_points = (p.min_fill * (p.rows * p.beams) as f64).ceil().max(3.0);
    let max_rms_m = (p.planarity_noise_factor * noise_m).max(p.planarity_floor_m);
    let max_tilt_rad = cos_slope.clamp(-1.0, 1.0).acos();
    let noise_var_m2 = noise_m * noise_m;
    let limits = Limits { min_points, up, max_tilt_rad, noise_var_m2, max_rms_m };

    // 1. Cells.
    let cells: Vec<Cell> =
        sums.par_iter().enumerate().map(|(i, s)| judge(s, &g, (i / cbs, i % cbs), &limits)).collect();
    let fitted = cells.iter().filter(|c| c.moments.n >= min_points).count();

    let cells_ms = start.elapsed().as_secs_f64() * 1e3;
    let start = Instant::now();

    // 2. Regions.
    let level_cells = cells.iter().filter(|c| c.level.is_some()).count();
    let (mut label, planes) = grow(&cells, (crs, cbs), &up, noise_var_m2, p);
    // A region is judged level again on all the points its cells were fitted to: a
    // wall's cells seen at grazing incidence, thin across their rays, each pass within
    // their wide uncertainty, and grown together make a vertical strip whose columns, at
    // the wall's mean height, a sole's size and dense, would pass for a tread.
    let steep: Vec<bool> = planes.iter().map(|f| !is_level(f, &up, max_tilt_rad, p)).collect();
    for l in label.iter_mut().filter(|l| **l != NONE && steep[**l as usize]) {
        *l = NONE;
    }
    let planes = fit_to_members(&cells, &label, planes, &up, noise_var_m2, p);

    // 3. Points, cell by cell: each to the likeliest of the planes of the cell and its
    // 8-neighbours (regions' and steep cells'), see [`region_of`]; 4. binned on the way
    // into its region's columns, each band of cell rows into tables of its own.
    let tables = ColumnTables::new(&cells, &label, &planes, (crs, cbs), voxel_m, &origin);
    let bands = BANDS.clamp(1, crs.max(1));
    let binned: Vec<Binned> = (0..bands)
        .into_par_iter()
        .map(|band| {
            let mut out = tables.empty();
            let mut near: Vec<Near> = Vec::with_capacity(18);
            for cr in band * crs / bands..(band + 1) * crs / bands {
                for cb in 0..cbs {
                    if !near_planes(&cells, &label, &planes, (crs, cbs), (cr, cb), &mut near) {
                        continue;
                    }
                    // A cell beside no plane but its own region's (most of a tread's):
                    // `region_of` for that one plane alone.
                    if let [own] = near.as_slice() {
                        if own.region != NONE {
                            g.for_points(g.rows_of(cr), cb, |i, q, d| {
                                let mut crossed =
                                    |id: u32, at: Vector3<f64>| tables.cross(&mut out, id, &(at + origin));
                                if joins_alone(&q, &d, own, noise_m, p, &mut crossed) {
                                    tables.add(&mut out, own.region, i, &points[i as usize]);
                                }
                            });
                            continue;
                        }
                    }
                    g.for_points(g.rows_of(cr), cb, |i, q, d| {
                        let mut crossed =
                            |id: u32, at: Vector3<f64>| tables.cross(&mut out, id, &(at + origin));
                        if let Some(id) = region_of(&q, &d, &near, &planes, noise_m, p, &mut crossed) {
                            tables.add(&mut out, id, i, &points[i as usize]);
                        }
                    });
                }
            }
            out
        })
        .collect();
    let (columns, crossed, points_in_regions) = tables.finish(binned, points);
    // floor(), as i32, without the library call that x86-64's baseline makes of it.
    let key = |v: f32| {
        let t = f64::from(v) / voxel_m;
        let i = t as i32;
        i - i32::from(f64::from(i) > t)
    };
    // Each region's body, and its columns' voxel keys, in parallel.
    let columns: Vec<(Vec<Column>, Vec<[i32; 3]>)> = columns
        .into_par_iter()
        .zip(crossed)
        .map(|(cols, crossed)| {
            let cols = body(cols, voxel_m, p.min_part_share, &crossed);
            let keys = cols.iter().map(|(pos, _)| [key(pos.x), key(pos.y), key(pos.z)]).collect();
            (cols, keys)
        })
        .collect();
    let mut voxels = VoxelCloud { resolution_m: voxel_m as f32, ..Default::default() };
    let mut surfaces = Vec::with_capacity(planes.len());
    let total: usize = columns.iter().map(|c| c.0.len()).sum();
    voxels.keys.reserve(total);
    voxels.positions.reserve(total);
    voxels.normals.reserve(total);
    voxels.counts.reserve(total);
    voxels.adjacency.resize(total, 0);
    for ((cols, keys), plane) in columns.into_iter().zip(&planes) {
        if cols.is_empty() {
            continue;
        }
        let first = voxels.positions.len() as u32;
        voxels.keys.extend(keys);
        voxels.positions.extend(cols.iter().map(|c| c.0));
        voxels.normals.extend(std::iter::repeat_n(plane.normal.cast::<f32>(), cols.len()));
        voxels.counts.extend(cols.iter().map(|c| c.1));
        surfaces.push(((first..voxels.positions.len() as u32).collect(), plane.normal));
    }
    let regions_ms = start.elapsed().as_secs_f64() * 1e3;
    Some(Regions { voxels, surfaces, cells: fitted, level_cells, points_in_regions, cells_ms, regions_ms })
}

/// Fills `near` with the planes beside cell `(cr, cb)` for step 3: its own and its
/// 8-neighbours' regions' and steep cells'. False when none is a region's (its points
/// join none).
fn near_planes(
    cells: &[Cell],
    label: &[u32],
    planes: &[Plane],
    (crs, cbs): (usize, usize),
    (cr, cb): (usize, usize),
    near: &mut Vec<Near>,
) -> bool {
    near.clear();
    let mut any_region = false;
    for dr in -1i64..=1 {
        for db in -1i64..=1 {
            let (r, b) = (cr as i64 + dr, cb as i64 + db);
            if r < 0 || b < 0 || r >= crs as i64 || b >= cbs as i64 {
                continue;
            }
            let q = r as usize * cbs + b as usize;
            let c = &cells[q];
            let (plane, region) = match (label[q], c.steep) {
                (NONE, Some(f)) => (f, NONE),
                (NONE, None) => continue,
                (id, _) => (planes[id as usize], id),
            };
            any_region |= region != NONE;
            let own = dr == 0 && db == 0;
            near.push(Near {
                normal: plane.normal,
                offset_m: plane.normal.dot(&plane.centre),
                region,
                cell_centre: c.fit.centre(),
                reach2_m2: if own { f64::INFINITY } else { c.reach_m * c.reach_m },
            });
        }
    }
    if !any_region {
        return false;
    }
    // The points' own cell's region reaches them all: its other cells add nothing.
    let own_region = label[cr * cbs + cb];
    if own_region != NONE {
        near.retain(|n| n.region != own_region || n.reach2_m2.is_infinite());
    }
    true
}

/// Step 3's bands of cell rows, each binned on its own and the bands' sums added in
/// order: a fixed count, so that the columns' sums (in f32) are added in the same order,
/// and the steps found are the same, on a machine of any number of cores (with a band per
/// thread a 16-core machine found other steps than a 2-core one). Two, the cores of the
/// machine the suites' figures were taken on.
const BANDS: usize = 2;

/// floor(), without the library call that x86-64's baseline makes of it.
#[inline(always)]
fn floor_i32(t: f32) -> i32 {
    let i = t as i32;
    i - i32::from((i as f32) > t)
}

/// Where step 3's points are binned into their regions' columns (vertical, the voxel edge
/// on a side, world-aligned): a table over each region's box of columns, from the boxes of
/// the cells whose points may join it; a region whose box is mostly empty (spread far for
/// its points) keeps its points' indices instead, binned by [`columns_of`].
struct ColumnTables {
    inv_m: f32,
    voxel_m: f64,
    /// Per region: its box's lowest column and size, and the corner its sums are taken
    /// from (in f32: centimetres over a few metres keep 0.1 mm); `None` when sparse.
    boxes: Vec<Option<ColumnBox>>,
}

/// A column's mean point and its count of points.
type Column = (Point3<f32>, u32);

/// A column's place: its index along x and y (multiples of the voxel edge, world-aligned).
type Place = (i32, i32);

/// Each region's columns, its empty places rays crossed below its plane, and the points
/// binned in all ([`ColumnTables::finish`]).
type Binning = (Vec<Vec<Column>>, Vec<Vec<Place>>, usize);

/// A region's columns so far: the lowest and highest column (x, y) and the points of the
/// cells that reach it.
type Extent = ((i32, i32), (i32, i32), f64);

#[derive(Clone, Copy)]
struct ColumnBox {
    lo: (i32, i32),
    ny: usize,
    len: usize,
    corner: Vector3<f32>,
}

/// One band's binning: per region, its table of column sums and counts, or the points'
/// indices for a sparse region (allocated when a point first comes); and per dense region,
/// its places a ray crossed below its plane (allocated when one first does).
struct Binned {
    tables: Vec<Vec<([f32; 3], u32)>>,
    members: Vec<Vec<u32>>,
    crossed: Vec<Vec<bool>>,
}

impl ColumnTables {
    /// The tables for regions `planes` (their centres from `origin`, the viewpoint) grown
    /// over `cells` (`label`: each cell's region) of a `dims.0` x `dims.1` grid.
    fn new(
        cells: &[Cell],
        label: &[u32],
        planes: &[Plane],
        (crs, cbs): (usize, usize),
        voxel_m: f64,
        origin: &Vector3<f64>,
    ) -> Self {
        let inv_m = (1.0 / voxel_m) as f32;
        // Per region: its columns' box over the cells whose points may join it (each cell
        // beside one of its cells), and those cells' points.
        let mut extent: Vec<Option<Extent>> = vec![None; planes.len()];
        for cr in 0..crs {
            for cb in 0..cbs {
                let c = &cells[cr * cbs + cb];
                if c.moments.n == 0.0 {
                    continue;
                }
                let [lo, hi] = c.box_m.map(|[x, y]| (floor_i32(x * inv_m), floor_i32(y * inv_m)));
                let mut seen = [NONE; 9];
                for (k, (r, b)) in (cr.saturating_sub(1)..(cr + 2).min(crs))
                    .flat_map(|r| (cb.saturating_sub(1)..(cb + 2).min(cbs)).map(move |b| (r, b)))
                    .enumerate()
                {
                    let id = label[r * cbs + b];
                    if id == NONE || seen[..k].contains(&id) {
                        continue;
                    }
                    seen[k] = id;
                    let e = extent[id as usize].get_or_insert((lo, hi, 0.0));
                    e.0 = (e.0 .0.min(lo.0), e.0 .1.min(lo.1));
                    e.1 = (e.1 .0.max(hi.0), e.1 .1.max(hi.1));
                    e.2 += c.moments.n;
                }
            }
        }
        let boxes = extent
            .iter()
            .zip(planes)
            .map(|(e, plane)| {
                let (lo, hi, n) = (*e)?;
                let (nx, ny) = ((hi.0 - lo.0) as usize + 1, (hi.1 - lo.1) as usize + 1);
                // Mostly empty: sorted by column instead of a table (as `columns_of` does).
                if nx.saturating_mul(ny) > 4 * n as usize + 1024 {
                    return None;
                }
                let corner = Vector3::new(
                    lo.0 as f32 / inv_m,
                    lo.1 as f32 / inv_m,
                    (plane.centre.z + origin.z) as f32,
                );
                Some(ColumnBox { lo, ny, len: nx * ny, corner })
            })
            .collect();
        Self { inv_m, voxel_m, boxes }
    }

    /// A band's binning, nothing in it yet.
    fn empty(&self) -> Binned {
        let n = self.boxes.len();
        Binned { tables: vec![Vec::new(); n], members: vec![Vec::new(); n], crossed: vec![Vec::new(); n] }
    }

    /// Region `id`'s place under `at` (world) crossed by a ray below its plane; a place
    /// outside its box, or a sparse region's, is not kept.
    #[inline]
    fn cross(&self, out: &mut Binned, id: u32, at: &Vector3<f64>) {
        let id = id as usize;
        let Some(b) = &self.boxes[id] else { return };
        let (x, y) =
            (floor_i32(at.x as f32 * self.inv_m) - b.lo.0, floor_i32(at.y as f32 * self.inv_m) - b.lo.1);
        if x >= 0 && y >= 0 && (y as usize) < b.ny && (x as usize) < b.len / b.ny {
            let crossed = &mut out.crossed[id];
            if crossed.is_empty() {
                crossed.resize(b.len, false);
            }
            crossed[x as usize * b.ny + y as usize] = true;
        }
    }

    /// Point `i` (at `q`, world) into region `id`'s columns.
    #[inline(always)]
    fn add(&self, out: &mut Binned, id: u32, i: u32, q: &Point3<f32>) {
        let id = id as usize;
        let Some(b) = &self.boxes[id] else {
            out.members[id].push(i);
            return;
        };
        let table = &mut out.tables[id];
        if table.is_empty() {
            table.resize(b.len, ([0.0; 3], 0));
        }
        let (x, y) = (floor_i32(q.x * self.inv_m) - b.lo.0, floor_i32(q.y * self.inv_m) - b.lo.1);
        // A point's column lies in its cell's box (taken on the same f32 coordinates), and
        // the region's box holds the box of every cell whose points may join it.
        let inside = x >= 0 && y >= 0 && (y as usize) < b.ny && (x as usize) < b.len / b.ny;
        debug_assert!(inside, "a point's column outside its region's box");
        if inside {
            let s = &mut table[x as usize * b.ny + y as usize];
            let d = q.coords - b.corner;
            s.0[0] += d.x;
            s.0[1] += d.y;
            s.0[2] += d.z;
            s.1 += 1;
        }
    }

    /// Each region's columns (mean point and count) from the bands' binnings, its empty
    /// places a ray crossed below its plane (column keys, as [`body`] takes them), and the
    /// points binned in all.
    fn finish(&self, binned: Vec<Binned>, points: &[Point3<f32>]) -> Binning {
        let mut bands = binned.into_iter();
        let n = self.boxes.len();
        let Some(mut all) = bands.next() else { return (vec![Vec::new(); n], vec![Vec::new(); n], 0) };
        for band in bands {
            for (into, from) in all.crossed.iter_mut().zip(band.crossed) {
                if into.is_empty() {
                    *into = from;
                } else if !from.is_empty() {
                    for (a, b) in into.iter_mut().zip(from) {
                        *a |= b;
                    }
                }
            }
            for (into, from) in all.tables.iter_mut().zip(band.tables) {
                if into.is_empty() {
                    *into = from;
                } else if !from.is_empty() {
                    for (a, b) in into.iter_mut().zip(from) {
                        a.0[0] += b.0[0];
                        a.0[1] += b.0[1];
                        a.0[2] += b.0[2];
                        a.1 += b.1;
                    }
                }
            }
            for (into, from) in all.members.iter_mut().zip(band.members) {
                into.extend(from);
            }
        }
        let crossed = (all.crossed.iter().zip(&all.tables).zip(&self.boxes))
            .map(|((crossed, table), b)| match b {
                Some(b) if !crossed.is_empty() && !table.is_empty() => {
                    let (nx, ny) = ((b.len / b.ny) as i64, b.ny as i64);
                    let filled = |x: i64, y: i64| {
                        x >= 0 && y >= 0 && x < nx && y < ny && table[(x * ny + y) as usize].1 > 0
                    };
                    // Empty places beside a column: the only ones that part columns.
                    (0..b.len)
                        .filter(|&k| crossed[k] && table[k].1 == 0)
                        .filter(|&k| {
                            let (x, y) = ((k / b.ny) as i64, (k % b.ny) as i64);
                            (-1..=1).any(|dx| (-1..=1).any(|dy| filled(x + dx, y + dy)))
                        })
                        .map(|k| (b.lo.0 + (k / b.ny) as i32, b.lo.1 + (k % b.ny) as i32))
                        .collect()
                }
                _ => Vec::new(),
            })
            .collect();
        let mut count = 0;
        let columns = (all.tables.into_par_iter().zip(all.members).zip(&self.boxes))
            .map(|((table, members), b)| match b {
                Some(b) => table
                    .into_iter()
                    .filter(|s| s.1 > 0)
                    .map(|(s, n)| (Point3::from(Vector3::from(s) / n as f32 + b.corner), n))
                    .collect(),
                None => columns_of(points, &members, self.voxel_m),
            })
            .collect::<Vec<Vec<_>>>();
        for cols in &columns {
            count += cols.iter().map(|c| c.1 as usize).sum::<usize>();
        }
        (columns, crossed, count)
    }
}

/// Step 2: regions grown over the level cells of a `dims.0` x `dims.1` grid of `cells`,
/// from the flattest first; each cell's region (or [`NONE`]) and each region's plane.
fn grow(
    cells: &[Cell],
    (crs, cbs): (usize, usize),
    up: &Vector3<f64>,
    noise_var_m2: f64,
    p: &CellParams,
) -> (Vec<u32>, Vec<Plane>) {
    let mut seeds: Vec<usize> = (0..cells.len()).filter(|&i| cells[i].level.is_some()).collect();
    seeds.sort_by(|&a, &b| {
        let rms = |i: usize| cells[i].level.map_or(f64::INFINITY, |f| f.rms_m);
        rms(a).total_cmp(&rms(b)).then(a.cmp(&b))
    });
    let mut label = vec![NONE; cells.len()];
    let mut planes: Vec<Plane> = Vec::new();
    let mut queue: Vec<usize> = Vec::new();
    for &seed in &seeds {
        if label[seed] != NONE {
            continue;
        }
        let id = planes.len() as u32;
        let Some(mut plane) = cells[seed].level else { continue };
        let mut m = cells[seed].fit;
        label[seed] = id;
        queue.clear();
        queue.push(seed);
        while let Some(c) = queue.pop() {
            let (cr, cb) = (c / cbs, c % cbs);
            let nbs = [
                (cr > 0).then(|| c - cbs),
                (cr + 1 < crs).then(|| c + cbs),
                (cb > 0).then(|| c - 1),
                (cb + 1 < cbs).then(|| c + 1),
            ];
            for nb in nbs.into_iter().flatten() {
                let joins = label[nb] == NONE
                    && cells[nb].level.is_some_and(|f| plane.distance_m(&f.centre) <= p.merge_distance_m);
                if joins {
                    label[nb] = id;
                    m.merge(&cells[nb].fit);
                    plane = m.plane(noise_var_m2).filter(|f| f.normal.dot(up) > 0.0).unwrap_or(plane);
                    queue.push(nb);
                }
            }
        }
        planes.push(plane);
    }
    (label, planes)
}

/// Each region's plane refitted to those of its cells that lie about it as the noise lets
/// them ([`CellParams::fit_noise_factor`]): twice, each time from the cells the plane
/// before kept. A region none of whose cells would be kept keeps its plane.
fn fit_to_members(
    cells: &[Cell],
    label: &[u32],
    mut planes: Vec<Plane>,
    up: &Vector3<f64>,
    noise_var_m2: f64,
    p: &CellParams,
) -> Vec<Plane> {
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); planes.len()];
    for (i, &l) in label.iter().enumerate() {
        if l != NONE {
            members[l as usize].push(i);
        }
    }
    let floor_m2 = p.planarity_floor_m * p.planarity_floor_m;
    let factor2 = p.fit_noise_factor * p.fit_noise_factor;
    for (plane, cells_of) in planes.iter_mut().zip(&members).filter(|(_, m)| m.len() > 1) {
        for _ in 0..2 {
            let mut m = Moments::default();
            for &i in cells_of {
                let (ms, seen) = cells[i].fit.mean_square_m2(plane, noise_var_m2);
                if ms <= (factor2 * seen).max(floor_m2) {
                    m.merge(&cells[i].fit);
                }
            }
            match m.plane(noise_var_m2).filter(|f| f.normal.dot(up) > 0.0) {
                Some(f) => *plane = f,
                None => break,
            }
        }
    }
    planes
}

/// The parts of a region's columns `cols` (edge `v`) that touch (within two columns) with at
/// least `min_share` of the biggest part's columns: its body, without the strays a gap
/// away (see [`CellParams::min_part_share`]). Two columns a place apart touch through an
/// empty place beside both, unless a ray crossed the region's plane there on its way down
/// (`crossed`, column keys): space seen through is a gap, where a place no return came
/// from (a shadow, between scan lines) is not. The columns keep their order.
///
/// With nothing crossed the parts are joined in one pass over the region's columns in
/// order of place, each column with the columns before it within reach (union-find): over
/// a table of the region's box, or, for a region spread too far for one (a stray a long
/// way off), a map of its places; else by [`join_bridged`], over a table.
fn body(cols: Vec<Column>, v: f64, min_share: f64, crossed: &[Place]) -> Vec<Column> {
    if cols.len() < 2 || min_share <= 0.0 {
        return cols;
    }
    let inv = (1.0 / v) as f32;
    let keys: Vec<(i32, i32)> =
        cols.iter().map(|(q, _)| (floor_i32(q.x * inv), floor_i32(q.y * inv))).collect();
    let (mut lo, mut hi) = (keys[0], keys[0]);
    for &(x, y) in &keys {
        lo = (lo.0.min(x), lo.1.min(y));
        hi = (hi.0.max(x), hi.1.max(y));
    }
    let (nx, ny) = ((hi.0 - lo.0) as usize + 1, (hi.1 - lo.1) as usize + 1);
    let mut parts = UnionFind::new(cols.len());
    if !crossed.is_empty() {
        join_bridged(&keys, crossed, lo, [nx, ny], &mut parts);
    } else if nx.saturating_mul(ny) > 64 * cols.len() + 4096 {
        join_by_map(&keys, &mut parts);
    } else {
        join_by_table(&keys, lo, [nx, ny], &[], &mut parts);
    }
    let roots: Vec<u32> = (0..cols.len() as u32).map(|i| parts.find(i)).collect();
    let mut sizes = vec![0usize; cols.len()];
    for &r in &roots {
        sizes[r as usize] += 1;
    }
    let biggest = sizes.iter().copied().max().unwrap_or(0);
    if biggest == cols.len() {
        return cols;
    }
    let least = min_share * biggest as f64;
    cols.into_iter().zip(roots).filter(|(_, r)| sizes[*r as usize] as f64 >= least).map(|(c, _)| c).collect()
}

/// Columns touch within this many columns (as `join_touching` joins segments).
const TOUCH: i32 = 2;

/// Parts of a set, joined pairwise: each item's part is its root's index.
struct UnionFind {
    parent: Vec<u32>,
}

impl UnionFind {
    fn new(n: usize) -> Self {
        Self { parent: (0..n as u32).collect() }
    }

    /// The root of `i`'s part (halving the path on the way).
    fn find(&mut self, mut i: u32) -> u32 {
        while self.parent[i as usize] != i {
            self.parent[i as usize] = self.parent[self.parent[i as usize] as usize];
            i = self.parent[i as usize];
        }
        i
    }

    /// Joins the parts of `a` and `b`; returns the joined part's root (the lower).
    fn join(&mut self, a: u32, b: u32) -> u32 {
        let (a, b) = (self.find(a), self.find(b));
        self.parent[a.max(b) as usize] = a.min(b);
        a.min(b)
    }
}

/// Joins the columns at `keys` that touch, over a table of their box (corner `lo`, `size`
/// places each way), by runs: along each row of places (x fixed), the places each within
/// [`TOUCH`] of the one before form a run, all of whose columns touch. A place touches a run
/// of a row within `TOUCH` when it lies within `TOUCH` of the run's ends (no gap in a run
/// is wider than that), so two runs of such rows touch when their spans, widened by `TOUCH`,
/// overlap: the rows' runs are joined in one merge of their sorted spans. The parts are
/// those of every pair of columns within `TOUCH` both ways, as a pass over each place's
/// reach would join them, with work in the runs rather than the places. The keys `skip`
/// marks (by index; none when it is empty) are left out: their pairs are joined elsewhere.
fn join_by_table(
    keys: &[(i32, i32)],
    lo: (i32, i32),
    [nx, ny]: [usize; 2],
    skip: &[bool],
    parts: &mut UnionFind,
) {
    let mut at = vec![NONE; nx * ny];
    for (i, &(x, y)) in keys.iter().enumerate() {
        if skip.get(i) == Some(&true) {
            continue;
        }
        let place = &mut at[(x - lo.0) as usize * ny + (y - lo.1) as usize];
        // A column whose mean rounded onto another's place (at a column's edge, in f32) is
        // in that one's part.
        if *place == NONE {
            *place = i as u32;
        } else {
            parts.join(i as u32, *place);
        }
    }
    let touch = TOUCH as usize;
    // Each row's runs: their first and last places (y) and a column of each.
    let mut runs: Vec<(usize, usize, u32)> = Vec::new();
    let mut row_start = Vec::with_capacity(nx + 1);
    for x in 0..nx {
        let first_of_row = runs.len();
        row_start.push(first_of_row);
        for (y, &i) in at[x * ny..(x + 1) * ny].iter().enumerate() {
            if i == NONE {
                continue;
            }
            let in_row = runs.len() > first_of_row;
            match runs.last_mut() {
                Some((_, hi, j)) if in_row && y - *hi <= touch => {
                    *hi = y;
                    parts.join(i, *j);
                }
                _ => runs.push((y, y, i)),
            }
        }
        // The rows before this one within reach.
        for dx in 1..=touch.min(x) {
            let (before, this) = (&runs[row_start[x - dx]..row_start[x - dx + 1]], &runs[first_of_row..]);
            let (mut a, mut b) = (0, 0);
            while a < before.len() && b < this.len() {
                let ((a_lo, a_hi, i), (b_lo, b_hi, j)) = (before[a], this[b]);
                if a_hi + touch < b_lo {
                    a += 1;
                } else if b_hi + touch < a_lo {
                    b += 1;
                } else {
                    parts.join(i, j);
                    // The run that ends first touches no later run of the other row.
                    if a_hi <= b_hi {
                        a += 1;
                    } else {
                        b += 1;
                    }
                }
            }
        }
    }
}

/// How far below a region's plane, in the point's noise as seen across it (`sigma |ray .
/// n|`), a point must lie for its ray to have passed through where the plane has no
/// surface: 4. Within a region's tolerance ([`CellParams::point_noise_factor`], 1.5) lie
/// 87 % of its own points; below it, 7 %: the noise's tail under the region. Such a ray
/// crosses the plane where the surface truly is (the noise moves a point along its ray),
/// in the point's own column, which is empty where that point was its only return (far
/// off, or at an edge): thousands of places beside a floor's columns at 1.5 sigma, about
/// one at 4 (CHANGELOG, forty-eighth session). Beyond 4 sigma lie 3 in 100 000
/// (Gaussian), a few of a sweep. A gap the sensor sees through is crossed by the rays that
/// reach past it, about one to a place of a few-centimetre gap: one crossing is enough
/// (regression `riser-strays-under-the-floor-toes`, whose stairwell is 5.8 cm off).
const SEEN_THROUGH_SIGMAS: f64 = 4.0;

/// A place of [`join_bridged`]'s table a ray crossed below the region's plane, with no
/// column.
const CROSSED: u32 = u32::MAX - 1;

/// Joins the columns at `keys` that touch: neighbours (8-connected), and any two beside one
/// place that holds a column or is empty with no ray crossed below the plane there
/// (`crossed`): the [`TOUCH`] of two places but for space seen through. Two columns of
/// which one has no crossed place about it touch as they do without any (their places
/// between are about it): those pairs are joined by [`join_by_table`], and only the pairs
/// of columns beside a crossed place are judged here, over a table of the keys' box
/// (lowest place `lo`, `nx` x `ny` places) and two places around it. The box is within
/// the region's [`ColumnTables`] box (the only regions with crossed places), whose size
/// its points bound.
fn join_bridged(
    keys: &[Place],
    crossed: &[Place],
    lo: (i32, i32),
    [nx, ny]: [usize; 2],
    parts: &mut UnionFind,
) {
    const MARGIN: usize = 2;
    let (wide, tall) = (nx + 2 * MARGIN, ny + 2 * MARGIN);
    let slot = |(x, y): (i32, i32)| -> Option<usize> {
        let (x, y) = (x - lo.0 + MARGIN as i32, y - lo.1 + MARGIN as i32);
        (x >= 0 && y >= 0 && (x as usize) < wide && (y as usize) < tall)
            .then(|| x as usize * tall + y as usize)
    };
    let mut at = vec![NONE; wide * tall];
    let slots: Vec<usize> = keys.iter().filter_map(|&k| slot(k)).collect();
    debug_assert_eq!(slots.len(), keys.len(), "the keys lie in their box");
    for (i, &s) in slots.iter().enumerate() {
        // A column whose mean rounded onto another's place is in that one's part.
        match at[s] {
            NONE => at[s] = i as u32,
            owner => {
                parts.join(i as u32, owner);
            }
        }
    }
    // The 8 places about a place, as steps in the table: a column lies MARGIN places or
    // more from the table's edge, and so do the places within two of it.
    let t = tall as isize;
    let around: [isize; 8] = [-t - 1, -t, -t + 1, -1, 1, t - 1, t, t + 1];
    let mut by_gap_place = vec![false; wide * tall];
    // A crossed place two or more from the keys' box is beside no column.
    let near_box = |&&(x, y): &&(i32, i32)| {
        (lo.0 - 1..=lo.0 + nx as i32).contains(&x) && (lo.1 - 1..=lo.1 + ny as i32).contains(&y)
    };
    for s in crossed.iter().filter(near_box).filter_map(|&k| slot(k)) {
        if at[s] == NONE {
            at[s] = CROSSED;
            for d in around {
                by_gap_place[s.wrapping_add_signed(d)] = true;
            }
        }
    }
    let by_gap: Vec<bool> = slots.iter().map(|&s| by_gap_place[s]).collect();
    join_by_table(keys, lo, [nx, ny], &by_gap, parts);
    let column = |v: u32| v < CROSSED;
    for (i, &s) in slots.iter().enumerate().filter(|(i, _)| by_gap[*i]) {
        for dx in -2isize..=2 {
            for dy in -2isize..=2 {
                let q = s.wrapping_add_signed(dx * t + dy);
                let j = at[q];
                if !column(j) || j == i as u32 {
                    continue;
                }
                let touch = !by_gap[j as usize]
                    || (dx.abs() <= 1 && dy.abs() <= 1)
                    || around.iter().any(|&d| {
                        let p = s.wrapping_add_signed(d);
                        let (px, py) = (
                            (p / tall) as isize - (q / tall) as isize,
                            (p % tall) as isize - (q % tall) as isize,
                        );
                        px.abs() <= 1 && py.abs() <= 1 && at[p] != CROSSED
                    });
                if touch {
                    parts.join(i as u32, j);
                }
            }
        }
    }
}

/// Joins the columns at `keys` that touch, by a map of their places (a region spread too far
/// for a table of its box).
fn join_by_map(keys: &[(i32, i32)], parts: &mut UnionFind) {
    let mut at: std::collections::HashMap<(i32, i32), u32> =
        std::collections::HashMap::with_capacity(keys.len());
    for (i, &k) in keys.iter().enumerate() {
        // A column whose mean rounded onto another's place is in that one's part.
        if let Some(&owner) = at.get(&k) {
            parts.join(i as u32, owner);
        } else {
            at.insert(k, i as u32);
        }
    }
    for (i, &(x, y)) in keys.iter().enumerate() {
        for (dx, dy) in reach_back() {
            if let Some(&j) = at.get(&(x - dx, y - dy)) {
                parts.join(i as u32, j);
            }
        }
    }
}

/// The places before a place (x first, then y) within its reach, as steps back.
fn reach_back() -> impl Iterator<Item = (i32, i32)> {
    (0..=TOUCH).flat_map(|dx| (-TOUCH..=TOUCH).map(move |dy| (dx, dy))).filter(|&(dx, dy)| dx > 0 || dy > 0)
}

/// The columns (vertical, `v` on a side, world-aligned) of the points `members`: each
/// occupied one's mean point and point count.
fn columns_of(points: &[Point3<f32>], members: &[u32], v: f64) -> Vec<Column> {
    let inv = (1.0 / v) as f32;
    let col = |q: &Point3<f32>| (floor_i32(q.x * inv), floor_i32(q.y * inv));
    let Some(&first) = members.first() else { return Vec::new() };
    let (mut lo, mut hi) = (col(&points[first as usize]), col(&points[first as usize]));
    for &i in members {
        let (x, y) = col(&points[i as usize]);
        lo = (lo.0.min(x), lo.1.min(y));
        hi = (hi.0.max(x), hi.1.max(y));
    }
    let (nx, ny) = ((hi.0 - lo.0) as usize + 1, (hi.1 - lo.1) as usize + 1);
    let mean = |s: Vector3<f64>, n: usize| Point3::from((s / n as f64).cast::<f32>());
    if nx.saturating_mul(ny) > 4 * members.len() + 1024 {
        // Sparse over its box (a region spread far): sorted by column instead of a table.
        let mut keyed: Vec<((i32, i32), u32)> =
            members.iter().map(|&i| (col(&points[i as usize]), i)).collect();
        keyed.sort_unstable();
        return keyed
            .chunk_by(|a, b| a.0 == b.0)
            .map(|run| {
                let s =
                    run.iter().map(|&(_, i)| points[i as usize].coords.cast::<f64>()).sum::<Vector3<f64>>();
                (mean(s, run.len()), run.len() as u32)
            })
            .collect();
    }
    // Sums from the box's corner, in f32: centimetres over a few metres keep 0.1 mm.
    let corner = Vector3::new(lo.0 as f32 / inv, lo.1 as f32 / inv, points[first as usize].z);
    let mut sums = vec![([0f32; 3], 0u32); nx * ny];
    for &i in members {
        let q = &points[i as usize];
        let (x, y) = col(q);
        let s = &mut sums[(x - lo.0) as usize * ny + (y - lo.1) as usize];
        let d = q.coords - corner;
        s.0[0] += d.x;
        s.0[1] += d.y;
        s.0[2] += d.z;
        s.1 += 1;
    }
    sums.into_iter()
        .filter(|s| s.1 > 0)
        .map(|(s, n)| (Point3::from(Vector3::from(s) / n as f32 + corner), n))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::seq::SliceRandom;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    /// A level patch the size of a cell (10 cm deep, 6 cm wide), 2 m ahead of and 1.4 m
    /// under the sensor, its points 2 mm apart, each moved along its ray by noise of
    /// `sigma_m`: its moments.
    fn oblique_patch(sigma_m: f64) -> Moments {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let noise = Normal::new(0.0, sigma_m.max(1e-12)).unwrap();
        let mut m = Moments::default();
        for i in 0..50 {
            for j in 0..30 {
                let q = Vector3::new(2.0 + 0.002 * f64::from(i), -0.03 + 0.002 * f64::from(j), -1.4);
                m.add(&(q + q.normalize() * noise.sample(&mut rng)));
            }
        }
        m
    }

    /// A patch of a side wall 0.6 m to the right, as a cell of 8 rows and 8 beams sees it
    /// while the head rises and walks on at the start of a sweep (each row seen 4 mm farther
    /// on and 3 mm higher, the sweep's viewpoint 0.18 m from where the rows were seen), under
    /// 10 mm of range noise along each point's own ray. The noise taken out along each
    /// point's ray from its row's origin fits the wall's normal better than along rays from
    /// the viewpoint, as if the head had stood there (over 40 noise draws, the mean error).
    #[test]
    fn a_patch_seen_as_the_head_moved_is_fitted_on_each_rows_own_rays() {
        let noise = Normal::new(0.0, 0.01).unwrap();
        let wall = Vector3::y();
        let error_deg = |f: &Plane| f.normal.dot(&wall).abs().clamp(0.0, 1.0).acos().to_degrees();
        let (mut rows_deg, mut viewpoint_deg) = (0.0, 0.0);
        for seed in 0..40 {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let (mut seen, mut one_origin) = (Moments::default(), Moments::default());
            for i in 0..8 {
                let origin = Vector3::new(-0.15 + 0.004 * f64::from(i), 0.0, -0.1 + 0.003 * f64::from(i));
                for j in 0..8 {
                    let (i, j) = (f64::from(i), f64::from(j));
                    let q = Vector3::new(0.1 + 0.004 * (i + j), -0.6, -0.2 + 0.004 * i - 0.001 * j);
                    let q = q + (q - origin).normalize() * noise.sample(&mut rng);
                    seen.add_seen(&q, &(q - origin));
                    one_origin.add(&q);
                }
            }
            rows_deg += error_deg(&seen.plane(1e-4).unwrap()) / 40.0;
            viewpoint_deg += error_deg(&one_origin.plane(1e-4).unwrap()) / 40.0;
        }
        println!("the wall's normal off by {rows_deg:.2} deg on the rows' rays, {viewpoint_deg:.2} on the viewpoint's");
        assert!(rows_deg < viewpoint_deg, "{rows_deg} / {viewpoint_deg} deg");
    }

    /// A cell row's sums are taken scan row by scan row across the cells (the order the
    /// points lie in memory); each cell's must be what its own points give taken cell by
    /// cell, to the bit: a sweep with missing and non-finite returns, partial cells at its
    /// edges, and its rows seen from a moving head.
    #[test]
    fn a_cell_rows_sums_are_each_cells_own_to_the_bit() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let unit = Normal::new(0.0, 1.0).unwrap();
        let (rows, beams) = (21, 29);
        let mut points = Vec::new();
        let mut cells = Vec::new();
        for r in 0..rows {
            for b in 0..beams {
                if (r * beams + b) % 13 == 0 {
                    cells.push(ScanGrid::EMPTY);
                    continue;
                }
                cells.push(points.len() as u32);
                let q = Point3::new(
                    (1.0 + 0.01 * b as f64 + 0.01 * unit.sample(&mut rng)) as f32,
                    (0.02 * r as f64 - 0.3) as f32,
                    (-0.8 + 0.004 * unit.sample(&mut rng)) as f32,
                );
                points.push(if (r * beams + b) % 17 == 0 { Point3::new(f32::NAN, 0.0, 0.0) } else { q });
            }
        }
        let origins = (0..rows).map(|r| Point3::new(0.003 * r as f64, 0.0, 0.6 + 0.001 * r as f64)).collect();
        let grid = ScanGrid::new(rows, beams, cells).unwrap().with_row_origins(origins).unwrap();
        let cloud = PointCloud::new(points, Point3::new(0.03, 0.0, 0.61), -Vector3::z_axis(), Some(grid));
        let p = CellParams::default();
        let offsets = row_offsets(&cloud);
        let g = Grid::of(&cloud, &offsets, &p).unwrap();
        let (crs, cbs) = g.dims();
        assert!(crs * p.rows > rows && cbs * p.beams > beams, "partial cells at the edges");
        for cr in 0..crs {
            let by_rows: Vec<CellSums> = sums_of_row(&g, cr).collect();
            assert_eq!(by_rows.len(), cbs);
            for (cb, got) in by_rows.iter().enumerate() {
                let mut m = Moments::default();
                let (mut lo, mut hi) = (Vector3::repeat(f64::INFINITY), Vector3::repeat(f64::NEG_INFINITY));
                let mut box_m = [[f32::INFINITY; 2], [f32::NEG_INFINITY; 2]];
                g.for_points(g.rows_of(cr), cb, |i, q, d| {
                    m.add_seen(&q, &d);
                    lo = lo.inf(&q);
                    hi = hi.sup(&q);
                    let w = &g.points[i as usize];
                    box_m = [
                        [box_m[0][0].min(w.x), box_m[0][1].min(w.y)],
                        [box_m[1][0].max(w.x), box_m[1][1].max(w.y)],
                    ];
                });
                let reach_m = if m.n > 0.0 { REACH_DIAGONALS * (hi - lo).norm() } else { 0.0 };
                let own = CellSums { moments: m, reach_m, box_m };
                // Debug prints each float's shortest exact form: equal text, equal bits.
                assert_eq!(format!("{got:?}"), format!("{own:?}"), "cell ({cr}, {cb})");
            }
        }
    }

    /// Step 3's shortcut for a cell beside its own region's plane alone must answer as
    /// `region_of` does, and tell the same places crossed: points about tilted planes, in
    /// and past the floor and the noise's tolerance, above and below, seen from a moving
    /// head, the cell's reach infinite (its own) or not.
    #[test]
    fn a_point_beside_its_regions_plane_alone_joins_as_region_of_says() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let unit = Normal::new(0.0, 1.0).unwrap();
        let p = CellParams::default();
        let (mut joined, mut crossed_any) = (0, 0);
        for k in 0..20000 {
            let mut draw = || unit.sample(&mut rng);
            let normal = Vector3::new(0.1 * draw(), 0.1 * draw(), 1.0).normalize();
            let centre = Vector3::new(1.0 + 0.3 * draw(), 0.3 * draw(), -0.8 + 0.1 * draw());
            let plane = Plane { centre, normal, rms_m: 0.003, tilt_sd_rad: 0.01 };
            let reach2_m2 = if k % 3 == 0 { 0.04 + 0.02 * draw() } else { f64::INFINITY };
            let near =
                Near { normal, offset_m: normal.dot(&centre), region: 0, cell_centre: centre, reach2_m2 };
            let q = centre + Vector3::new(0.1 * draw(), 0.1 * draw(), 0.0) + normal * (0.015 * draw());
            let seen_from = Vector3::new(0.02 * draw(), 0.0, 0.0);
            let d = if k % 2 == 0 { q } else { q - seen_from };
            let noise_m = 0.003 + 0.02 * draw().abs();
            let (mut a, mut b) = (Vec::new(), Vec::new());
            let by_region_of = region_of(&q, &d, &[near], &[plane], noise_m, &p, &mut |id, at| {
                a.push((id, format!("{at:?}")))
            });
            let near =
                Near { normal, offset_m: normal.dot(&centre), region: 0, cell_centre: centre, reach2_m2 };
            let alone =
                joins_alone(&q, &d, &near, noise_m, &p, &mut |id, at| b.push((id, format!("{at:?}"))));
            assert_eq!(by_region_of == Some(0), alone, "draw {k}");
            assert_eq!(a, b, "draw {k}");
            joined += usize::from(alone);
            crossed_any += usize::from(!a.is_empty());
        }
        // Both answers and the crossing were drawn.
        assert!(
            joined > 2000 && joined < 18000 && crossed_any > 100,
            "{joined} joined, {crossed_any} crossed"
        );
    }

    fn tilt_deg(f: &Plane) -> f64 {
        f.normal.z.clamp(-1.0, 1.0).acos().to_degrees()
    }

    #[test]
    fn a_noisy_plane_seen_obliquely_fits_level_only_with_the_rays_noise_taken_out() {
        let sigma_m = 0.02;
        let m = oblique_patch(sigma_m);
        let raw = m.plane(0.0).unwrap();
        let corrected = m.plane(sigma_m * sigma_m).unwrap();
        assert!(tilt_deg(&raw) > 5.0, "the raw fit tilts {:.2} deg: the case is not shown", tilt_deg(&raw));
        assert!(tilt_deg(&corrected) < 1.5, "the corrected fit tilts {:.2} deg", tilt_deg(&corrected));
        // The RMS is the points' own (noise included), and the normal faces the sensor.
        assert!(corrected.rms_m > 0.5 * sigma_m * 0.57 && corrected.normal.z > 0.0);
        // Noise-free, exact.
        let exact = oblique_patch(0.0).plane(0.0).unwrap();
        assert!(tilt_deg(&exact) < 1e-4 && exact.rms_m < 1e-9);
    }

    #[test]
    fn a_plane_facing_away_from_the_sensor_faces_down() {
        let mut m = Moments::default();
        for i in 0..5 {
            for j in 0..5 {
                m.add(&Vector3::new(f64::from(i) * 0.01, f64::from(j) * 0.01, 1.0));
            }
        }
        assert!(m.plane(0.0).unwrap().normal.z < -0.999, "a ceiling's normal");
    }

    #[test]
    fn a_scan_line_seen_edge_on_is_not_judged_level() {
        // One scan line across a ceiling 0.6 m above the sensor and 2.5 m ahead, 20 mm of
        // range noise along the rays: the line's plane is anyone's, its tilt unknown.
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let noise = Normal::new(0.0, 0.02).unwrap();
        let mut m = Moments::default();
        for j in 0..64 {
            let q = Vector3::new(2.5, -0.1 + 0.003 * f64::from(j), 0.6);
            m.add(&(q + q.normalize() * noise.sample(&mut rng)));
        }
        let f = m.plane(0.0).unwrap();
        let p = CellParams::default();
        let tilt_deg = f.normal.z.abs().acos().to_degrees();
        assert!(tilt_deg < 15.0, "the line's plane tilts {tilt_deg:.1} deg: the case is not shown");
        assert!(!is_known(&f, &p) && !is_level(&f, &Vector3::z(), 15f64.to_radians(), &p));
        // A patch of the ceiling is judged, and is not level: it faces down.
        let mut m = Moments::default();
        for i in 0..8 {
            for j in 0..8 {
                m.add(&Vector3::new(2.5 + 0.03 * f64::from(i), -0.1 + 0.01 * f64::from(j), 0.6));
            }
        }
        let f = m.plane(0.0).unwrap();
        assert!(f.tilt_sd_rad < 0.01 && !is_level(&f, &Vector3::z(), 15f64.to_radians(), &p));
    }

    #[test]
    fn the_tables_bin_as_columns_of_does_over_bands_dense_or_sparse() {
        // Two cells of one region side by side, and a third cell far off joining a second
        // region alone with two points 3 m apart (its box mostly empty: sparse).
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let mut pts: Vec<Point3<f32>> = (0..400)
            .map(|i| {
                let x = f64::from(i % 20) * 0.013 + if i < 200 { 0.0 } else { 0.26 };
                Point3::new(x as f32, (f64::from(i / 20) * 0.017) as f32, 0.2 + 0.001 * (i % 7) as f32)
            })
            .collect();
        pts.push(Point3::new(5.0, 5.0, 0.6));
        pts.push(Point3::new(8.0, 2.0, 0.6));
        let cell = |members: std::ops::Range<usize>| {
            let (mut lo, mut hi) = ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]);
            for q in &pts[members] {
                lo = [lo[0].min(q.x), lo[1].min(q.y)];
                hi = [hi[0].max(q.x), hi[1].max(q.y)];
            }
            Cell {
                moments: Moments { n: 2.0, ..Default::default() },
                fit: Moments::default(),
                level: None,
                steep: None,
                reach_m: 0.0,
                box_m: [lo, hi],
            }
        };
        // A 1 x 5 grid of cells: region 0, region 0, empty, empty, region 1.
        let empty = Cell {
            moments: Moments::default(),
            fit: Moments::default(),
            level: None,
            steep: None,
            reach_m: 0.0,
            box_m: [[0.0; 2]; 2],
        };
        let cells = [cell(0..200), cell(200..400), empty, empty, cell(400..402)];
        let label = [0, 0, NONE, NONE, 1];
        let plane = |z: f64| Plane {
            centre: Vector3::new(0.0, 0.0, z),
            normal: Vector3::z(),
            rms_m: 0.0,
            tilt_sd_rad: 0.0,
        };
        let tables =
            ColumnTables::new(&cells, &label, &[plane(0.2), plane(0.6)], (1, 5), 0.02, &Vector3::zeros());
        assert!(tables.boxes[0].is_some() && tables.boxes[1].is_none(), "dense, then sparse");
        // Points in random order over three bands.
        let mut order: Vec<u32> = (0..pts.len() as u32).collect();
        order.shuffle(&mut rng);
        let binned: Vec<Binned> = order
            .chunks(150)
            .enumerate()
            .map(|(band, chunk)| {
                let mut out = tables.empty();
                for &i in chunk {
                    tables.add(&mut out, u32::from(i >= 400), i, &pts[i as usize]);
                }
                // Rays crossed region 0's plane at an empty place of its box beside a
                // column (twice, in two bands), at one beside none, at a place with points,
                // and outside its box; region 1's (sparse).
                if band < 2 {
                    tables.cross(&mut out, 0, &Vector3::new(0.01, 0.17, 0.2));
                }
                tables.cross(&mut out, 0, &Vector3::new(0.01, 0.30, 0.2));
                tables.cross(&mut out, 0, &Vector3::new(0.001, 0.001, 0.2));
                tables.cross(&mut out, 0, &Vector3::new(3.0, 3.0, 0.2));
                tables.cross(&mut out, 1, &Vector3::new(5.0, 5.0, 0.6));
                out
            })
            .collect();
        let (columns, crossed, count) = tables.finish(binned, &pts);
        assert_eq!(count, pts.len());
        assert_eq!(crossed, [vec![(0, 8)], vec![]], "the empty place beside a column, once");
        let members: [Vec<u32>; 2] = [(0..400).collect(), vec![400, 401]];
        for (got, members) in columns.into_iter().zip(members) {
            let key = |c: &Column| (floor_i32(c.0.x * 50.0), floor_i32(c.0.y * 50.0));
            let mut want = columns_of(&pts, &members, 0.02);
            let mut got = got;
            want.sort_by_key(key);
            got.sort_by_key(key);
            assert_eq!(got.len(), want.len());
            for (g, w) in got.iter().zip(&want) {
                assert_eq!(g.1, w.1);
                assert!((g.0 - w.0).norm() < 1e-5, "{:?} against {:?}", g.0, w.0);
            }
        }
    }

    /// A region's columns over `x` x `y` places (column indices, 2 cm columns).
    fn columns(xs: impl Iterator<Item = i32> + Clone, ys: impl Iterator<Item = i32>) -> Vec<Column> {
        ys.flat_map(|y| {
            xs.clone().map(move |x| (Point3::new(x as f32 * 0.02 + 0.01, y as f32 * 0.02 + 0.01, 0.5), 3))
        })
        .collect()
    }

    #[test]
    fn a_regions_strays_a_gap_away_are_not_its_and_its_like_parts_are() {
        // A tread 1.76 m wide and 30 cm deep, and a wall's returns at its height 12 cm past
        // its side: three columns, five empty ones between.
        let tread = columns(0..88, 0..15);
        let mut region = tread.clone();
        region.extend(columns(94..95, [2, 7, 12].into_iter()));
        let kept = body(region, 0.02, CellParams::default().min_part_share, &[]);
        assert_eq!(kept, tread, "the strays dropped, the tread whole and in order");
        // A tread cut in two by a leg's shadow, and one seen one scan line in three: kept.
        let halves: Vec<Column> = columns(0..40, 0..15).into_iter().chain(columns(55..88, 0..15)).collect();
        assert_eq!(body(halves.clone(), 0.02, 0.1, &[]), halves);
        let lines = columns(0..88, (0..15).step_by(3));
        assert_eq!(body(lines.clone(), 0.02, 0.1, &[]), lines);
        // Parts that touch (one empty column between) are one part, however small.
        let touching: Vec<Column> = columns(0..88, 0..15).into_iter().chain(columns(89..90, 0..1)).collect();
        assert_eq!(body(touching.clone(), 0.02, 0.1, &[]), touching);
        // Two columns on one place (a mean rounded onto a column's edge) stay with it.
        let mut twice = tread.clone();
        twice.push(tread[20]);
        assert_eq!(body(twice.clone(), 0.02, 0.1, &[]), twice);
        // A wall's returns two places past the side, one empty column between: one part
        // with the tread where nothing was seen between them (a shadow), not where rays
        // came down through that gap to the wall below (a stairwell's gap beside the flight).
        let mut walled = tread.clone();
        walled.extend(columns(89..90, 0..15));
        assert_eq!(body(walled.clone(), 0.02, 0.1, &[]), walled);
        // The gap runs on past the tread's front and back edges, as a stairwell's does.
        let gap: Vec<(i32, i32)> = (-1..16).map(|y| (88, y)).collect();
        assert_eq!(body(walled.clone(), 0.02, 0.1, &gap), tread, "the gap seen through");
        let shadow: Vec<(i32, i32)> = gap.iter().copied().filter(|&(_, y)| y != 7).collect();
        assert_eq!(body(walled.clone(), 0.02, 0.1, &shadow), walled, "one place not seen through");
    }

    /// `body` against a plain search: random columns over a 30 x 30 grid (and strays far
    /// off), the parts found by a depth-first search over every pair within two columns; and
    /// a region one place wide.
    #[test]
    fn the_body_is_the_parts_a_plain_search_finds() {
        let column = |y: i32| (Point3::new(0.01, y as f32 * 0.02 + 0.01, 0.5), 1);
        let line: Vec<Column> = [0, 2, 5].map(column).to_vec();
        assert_eq!(body(line.clone(), 0.02, 0.6, &[]), line[..2].to_vec(), "5 is three places from 2");
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for trial in 0..200 {
            let fill = 0.05 + 0.6 * (trial as f64 / 200.0);
            let mut places: Vec<(i32, i32)> = (0..30)
                .flat_map(|x| (0..30).map(move |y| (x, y)))
                .filter(|_| rand::Rng::random_bool(&mut rng, fill))
                .collect();
            // One trial in four has strays a long way off (two touching, one alone): the
            // region is then too spread for a table of its box.
            if trial % 4 == 3 {
                places.extend([(4000, -3000), (4002, -2998), (-5000, 6000)]);
            }
            if places.is_empty() {
                continue;
            }
            // One trial in three has columns whose means fell on another's place (at an
            // edge, in f32), out of order; one in five is shuffled whole.
            if trial % 3 == 1 {
                let twins: Vec<(i32, i32)> = places.iter().step_by(7).copied().collect();
                places.extend(twins);
            }
            if trial % 5 == 2 {
                use rand::seq::SliceRandom;
                places.shuffle(&mut rng);
            }
            let cols: Vec<Column> = places
                .iter()
                .map(|&(x, y)| (Point3::new(x as f32 * 0.02 + 0.01, y as f32 * 0.02 + 0.01, 0.5), 1))
                .collect();
            // Places rays crossed: some empty, some a column's (which changes nothing), some
            // outside the box. Only a region whose tables were dense has them, never one
            // with strays a long way off.
            let mut crossed: Vec<(i32, i32)> = (-3..33)
                .flat_map(|x| (-3..33).map(move |y| (x, y)))
                .filter(|_| rand::Rng::random_bool(&mut rng, 0.3))
                .collect();
            crossed.push((90, -90));
            let tries = if trial % 4 == 3 { vec![Vec::new()] } else { vec![Vec::new(), crossed] };
            for crossed in tries {
                let chebyshev = |a: (i32, i32), b: (i32, i32)| (a.0 - b.0).abs().max((a.1 - b.1).abs());
                let open = |q: (i32, i32)| places.contains(&q) || !crossed.contains(&q);
                let touch = |a: (i32, i32), b: (i32, i32)| match chebyshev(a, b) {
                    0 | 1 => true,
                    2 => (a.0 - 1..=a.0 + 1)
                        .flat_map(|x| (a.1 - 1..=a.1 + 1).map(move |y| (x, y)))
                        .any(|q| chebyshev(q, a) == 1 && chebyshev(q, b) == 1 && open(q)),
                    _ => false,
                };
                let mut part = vec![usize::MAX; places.len()];
                let mut sizes = Vec::new();
                for s in 0..places.len() {
                    if part[s] != usize::MAX {
                        continue;
                    }
                    let (id, mut queue, mut size) = (sizes.len(), vec![s], 0);
                    part[s] = id;
                    while let Some(i) = queue.pop() {
                        size += 1;
                        for j in 0..places.len() {
                            if part[j] == usize::MAX && touch(places[i], places[j]) {
                                part[j] = id;
                                queue.push(j);
                            }
                        }
                    }
                    sizes.push(size);
                }
                let biggest = sizes.iter().copied().max().unwrap_or(0) as f64;
                // At a share of 1 only the biggest parts are kept: a wrong join among
                // parts the share keeps (or drops) shows there.
                for share in [0.3, 1.0] {
                    let want: Vec<Column> = cols
                        .iter()
                        .zip(&part)
                        .filter(|(_, k)| sizes[**k] as f64 >= share * biggest)
                        .map(|(c, _)| *c)
                        .collect();
                    let n = crossed.len();
                    assert_eq!(
                        body(cols.clone(), 0.02, share, &crossed),
                        want,
                        "trial {trial}, fill {fill:.2}, share {share}, {n} crossed"
                    );
                }
            }
        }
    }

    #[test]
    fn columns_average_their_points_and_count_them() {
        let pts = [
            Point3::new(0.001f32, 0.001, 0.2),
            Point3::new(0.011, 0.019, 0.4),
            Point3::new(0.031, 0.001, 0.0),
            Point3::new(-0.001, -0.001, 0.0),
        ];
        let mut cols = columns_of(&pts, &[0, 1, 2, 3], 0.02);
        cols.sort_by(|a, b| a.0.x.total_cmp(&b.0.x));
        assert_eq!(cols.len(), 3);
        assert_eq!(cols.iter().map(|c| c.1).collect::<Vec<_>>(), [1, 2, 1]);
        assert!((cols[1].0 - Point3::new(0.006, 0.01, 0.3)).norm() < 1e-6, "{:?}", cols[1].0);
    }
}
