//! Plane extraction on the scan grid, after CAPE (Proença and Gao, 2018) and PEAC (Feng et
//! al., ICRA 2014): a tilting lidar's sweep is an organized grid (rows x beams) in which
//! neighbours on a surface are neighbours in the grid, so planes grow over cells of the grid
//! with no k-d tree, no normal per point and no supervoxels. Selected by
//! `PerceptionParams::method` = `cells`; its steps come out of the same staircase extraction
//! as the paper's (§4.3, [`super::staircase::from_surfaces`]).
//!
//! 1. **Cells.** The grid is cut into cells of [`CellParams::rows`] x [`CellParams::beams`];
//!    a cell holding enough points gets their least-squares plane from its moments. It is a
//!    plane when its points' RMS distance from that plane is at most
//!    [`CellParams::planarity_noise_factor`] times the sweep's range noise (measured on the
//!    sweep, at least [`CellParams::planarity_floor_m`]): a cell across a nose holds tread
//!    and riser and is not. It is level when its normal passes Filter 1's slope test.
//! 2. **Regions.** From the flattest level cell not yet taken, a region grows over the
//!    grid's 4-neighbours: a level plane cell joins when its centre lies within
//!    [`CellParams::merge_distance_m`] of the region's plane, refitted from the summed
//!    moments as it grows. Two treads meet in the grid where a riser is hidden, a rise apart.
//! 3. **Points.** Each point of a region's cell or of a cell beside one (8-neighbours) goes
//!    to the nearest such region's plane within [`CellParams::point_noise_factor`] times the
//!    noise (at least `merge_distance_m`), and within reach of the region's cell it borders
//!    (grid neighbours across a depth jump are far apart in space). This gives back the
//!    edges that cells across them lost, point by point, as CAPE's refinement does.
//! 4. **Columns.** A region's points are binned into vertical columns of the voxel edge v;
//!    each column's mean is one "voxel" of the region, as the paper's segments are voxels.

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
    /// points under 10 mm of range noise fit a normal within about 2 deg.
    pub rows: usize,
    /// Beams per cell (see `rows`).
    pub beams: usize,
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
    /// A cell joins a region when its centre is within this distance of the region's plane,
    /// metres: under the least rise a step has, above what noise and a tread's tilt of a
    /// degree over its width leave.
    pub merge_distance_m: f64,
    /// A point joins a region when within this many times its range noise, as seen across
    /// the plane (the noise moves a point along its ray: `sigma |ray . n|` off the plane), of
    /// the region's plane ...
    pub point_noise_factor: f64,
    /// ... or within this distance, metres (surfaces' roughness, the plane's own error).
    pub point_floor_m: f64,
}

impl Default for CellParams {
    fn default() -> Self {
        Self {
            rows: 8,
            beams: 8,
            min_fill: 0.5,
            planarity_noise_factor: 2.0,
            planarity_floor_m: 0.004,
            level_sigmas: 2.0,
            merge_distance_m: 0.02,
            point_noise_factor: 1.5,
            point_floor_m: 0.005,
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
        for (f, v) in [
            ("cells.planarity_noise_factor", self.planarity_noise_factor),
            ("cells.planarity_floor_m", self.planarity_floor_m),
            ("cells.level_sigmas", self.level_sigmas),
            ("cells.merge_distance_m", self.merge_distance_m),
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
#[derive(Debug, Clone, Copy)]
struct Moments {
    n: f64,
    sum: Vector3<f64>,
    outer: Matrix3<f64>,
    /// Sum of d d^T over the points' unit rays d: range noise scatters a point along its
    /// ray, adding `sigma^2 d d^T` to the points' covariance.
    rays: Matrix3<f64>,
}

impl Moments {
    const ZERO: Self = Self {
        n: 0.0,
        sum: Vector3::new(0.0, 0.0, 0.0),
        outer: Matrix3::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
        rays: Matrix3::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
    };

    fn add(&mut self, q: &Vector3<f64>) {
        self.n += 1.0;
        self.sum += q;
        self.outer += q * q.transpose();
        let norm2 = q.norm_squared();
        if norm2 > 0.0 {
            self.rays += q * q.transpose() / norm2;
        }
    }

    fn merge(&mut self, o: &Self) {
        self.n += o.n;
        self.sum += o.sum;
        self.outer += o.outer;
        self.rays += o.rays;
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
        let centre = self.sum / self.n;
        let cov = self.outer / self.n - centre * centre.transpose();
        // Less the noise along the rays, plus as much again in every direction (which
        // leaves the eigenvectors as they are and the matrix positive semi-definite).
        let fit = cov - self.rays * (noise_var_m2 / self.n) + Matrix3::identity() * noise_var_m2;
        let v = smallest_eigenvector(&fit.cast::<f32>())?.cast::<f64>().normalize();
        let normal = if v.dot(&centre) > 0.0 { -v } else { v };
        let l0 = normal.dot(&(cov * normal)).max(0.0);
        // The two larger eigenvalues from the trace and the sum of the principal 2 x 2
        // minors (c1 = l0 l1 + l0 l2 + l1 l2); the smaller of them, l1, is the spread
        // across which the normal tilts most easily.
        let sum12 = (cov.trace() - l0).max(0.0);
        let c1 = cov[(0, 0)] * cov[(1, 1)] + cov[(0, 0)] * cov[(2, 2)] + cov[(1, 1)] * cov[(2, 2)]
            - cov[(0, 1)].powi(2)
            - cov[(0, 2)].powi(2)
            - cov[(1, 2)].powi(2);
        let prod12 = (c1 - l0 * sum12).max(0.0);
        let l1 = (sum12 - (sum12 * sum12 - 4.0 * prod12).max(0.0).sqrt()) / 2.0;
        let tilt_sd_rad = if l1 > 0.0 { (l0 / (self.n * l1)).sqrt() } else { f64::INFINITY };
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
    /// in-plane spread), radians.
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
    /// Its plane, when it is a level plane.
    level: Option<Plane>,
    /// Its plane, when it is a plane too steep to be level (a riser, a wall): its points
    /// nearer that plane than a region's stay out of the region.
    steep: Option<Plane>,
    /// Farthest of its points from its centre, metres.
    radius_m: f64,
}

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

/// The centre of a cell's points.
fn plane_centre(c: &Cell) -> Vector3<f64> {
    c.moments.sum / c.moments.n.max(1.0)
}

/// The grid's cell rows and columns for `p`.
fn cell_dims(grid: &ScanGrid, p: &CellParams) -> (usize, usize) {
    (grid.rows().div_ceil(p.rows), grid.beams().div_ceil(p.beams))
}

/// The point indices of cell (`cr`, `cb`).
fn cell_points<'a>(
    grid: &'a ScanGrid,
    p: &CellParams,
    cr: usize,
    cb: usize,
) -> impl Iterator<Item = usize> + 'a {
    let beams = grid.beams();
    let (r0, b0) = (cr * p.rows, cb * p.beams);
    let (r1, b1) = ((r0 + p.rows).min(grid.rows()), (b0 + p.beams).min(beams));
    (r0..r1)
        .flat_map(move |r| grid.cells()[r * beams + b0..r * beams + b1].iter())
        .filter_map(|&c| (c != ScanGrid::EMPTY).then_some(c as usize))
}

/// Level planes grown on `cloud`'s scan grid (see the module's doc) with voxel edge
/// `voxel_m`, `cos_slope` the least cosine of a level normal from up (Filter 1's), and
/// `noise_m` the sweep's range noise. `None` for a cloud without a scan grid.
pub fn extract(
    cloud: &PointCloud,
    voxel_m: f64,
    cos_slope: f64,
    noise_m: f64,
    p: &CellParams,
) -> Option<Regions> {
    let grid = cloud.grid()?;
    let origin = cloud.viewpoint().coords;
    let up = -cloud.gravity().into_inner();
    let points = cloud.points();
    let rel = |i: usize| -> Option<Vector3<f64>> {
        let q = points[i];
        q.coords.iter().all(|v| v.is_finite()).then(|| q.coords.cast::<f64>() - origin)
    };
    let (crs, cbs) = cell_dims(grid, p);
    let min_points = (p.min_fill * (p.rows * p.beams) as f64).ceil().max(3.0);
    let max_rms_m = (p.planarity_noise_factor * noise_m).max(p.planarity_floor_m);
    let max_tilt_rad = cos_slope.clamp(-1.0, 1.0).acos();
    let noise_var_m2 = noise_m * noise_m;

    // 1. Cells.
    let start = Instant::now();
    let cells: Vec<Cell> = (0..crs)
        .into_par_iter()
        .flat_map_iter(|cr| {
            (0..cbs).map(move |cb| {
                let mut m = Moments::ZERO;
                cell_points(grid, p, cr, cb).filter_map(rel).for_each(|q| m.add(&q));
                let plane = (m.n >= min_points)
                    .then(|| m.plane(noise_var_m2))
                    .flatten()
                    .filter(|f| f.rms_m <= max_rms_m);
                let steep = plane.filter(|f| {
                    let tilt_rad = f.normal.dot(&up).clamp(-1.0, 1.0).acos();
                    tilt_rad > max_tilt_rad + p.level_sigmas * f.tilt_sd_rad
                });
                let level = plane.filter(|_| steep.is_none());
                let radius_m = level.or(steep).map_or(0.0, |f| {
                    cell_points(grid, p, cr, cb)
                        .filter_map(rel)
                        .map(|q| (q - f.centre).norm())
                        .fold(0.0, f64::max)
                });
                Cell { moments: m, level, steep, radius_m }
            })
        })
        .collect();
    let fitted = cells.iter().filter(|c| c.moments.n >= min_points).count();

    let cells_ms = start.elapsed().as_secs_f64() * 1e3;
    let start = Instant::now();

    // 2. Regions, grown from the flattest cells first.
    let mut seeds: Vec<usize> = (0..cells.len()).filter(|&i| cells[i].level.is_some()).collect();
    let level_cells = seeds.len();
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
        let mut m = cells[seed].moments;
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
                    m.merge(&cells[nb].moments);
                    plane = m.plane(noise_var_m2).filter(|f| f.normal.dot(&up) > 0.0).unwrap_or(plane);
                    queue.push(nb);
                }
            }
        }
        planes.push(plane);
    }

    // 3. Points, cell by cell: each to the likeliest of the planes of the cell and its
    // 8-neighbours (regions' and steep cells'), judged in its own noise, which moves it along
    // its ray: its distance from a plane over `sigma |ray . n|`. A point likeliest on a
    // steep plane (the foot of a riser, seen through noise within a tread's tolerance of
    // it) joins no region.
    let assigned: Vec<Vec<(u32, u32)>> = (0..crs)
        .into_par_iter()
        .map(|cr| {
            let mut out = Vec::new();
            // (plane, region or NONE for a steep cell's, the cell it lies in)
            let mut near: Vec<(Plane, u32, usize)> = Vec::with_capacity(18);
            for cb in 0..cbs {
                near.clear();
                let mut any_region = false;
                for dr in -1i64..=1 {
                    for db in -1i64..=1 {
                        let (r, b) = (cr as i64 + dr, cb as i64 + db);
                        if r < 0 || b < 0 || r >= crs as i64 || b >= cbs as i64 {
                            continue;
                        }
                        let q = r as usize * cbs + b as usize;
                        if label[q] != NONE {
                            near.push((planes[label[q] as usize], label[q], q));
                            any_region = true;
                        } else if let Some(f) = cells[q].steep {
                            near.push((f, NONE, q));
                        }
                    }
                }
                if !any_region {
                    continue;
                }
                let own = cr * cbs + cb;
                for i in cell_points(grid, p, cr, cb) {
                    let Some(q) = rel(i) else { continue };
                    let ray = q.normalize();
                    let mut best: Option<(f64, u32)> = None;
                    for &(plane, id, via) in &near {
                        let d = plane.distance_m(&q);
                        let seen_sd_m = noise_m * ray.dot(&plane.normal).abs();
                        let z = d / seen_sd_m.max(p.point_floor_m / p.point_noise_factor);
                        if best.is_some_and(|(bz, _)| bz <= z) {
                            continue;
                        }
                        if id == NONE {
                            best = Some((z, NONE));
                        } else if d <= (p.point_noise_factor * seen_sd_m).max(p.point_floor_m)
                            && (via == own
                                || (q - plane_centre(&cells[via])).norm() <= 3.0 * cells[via].radius_m)
                        {
                            best = Some((z, id));
                        }
                    }
                    // Behind a steep plane that its ray meets near that plane's cell, when
                    // the region lies before it (on the sensor's side): the steep surface's
                    // own point, pushed behind it by the noise (a riser's foot landing on
                    // the plane of the tread below, past the tread's end). A tread lies
                    // behind the riser under its own nose, and keeps its points there.
                    let range_m = q.norm();
                    let behind = |region: &Plane, &(f, id, via): &(Plane, u32, usize)| {
                        let along = f.normal.dot(&ray);
                        let t = f.normal.dot(&f.centre) / along;
                        id == NONE
                            && along.abs() > 1e-6
                            && t > 0.0
                            && t < range_m
                            && f.normal.dot(&(region.centre - f.centre)) > 0.0
                            && (ray * t - f.centre).norm() <= 3.0 * cells[via].radius_m
                    };
                    if let Some((_, id)) = best.filter(|b| b.1 != NONE) {
                        if !near.iter().any(|n| behind(&planes[id as usize], n)) {
                            out.push((id, i as u32));
                        }
                    }
                }
            }
            out
        })
        .collect();

    // 4. Columns per region.
    let mut by_region: Vec<Vec<u32>> = vec![Vec::new(); planes.len()];
    let mut points_in_regions = 0;
    for (id, i) in assigned.into_iter().flatten() {
        by_region[id as usize].push(i);
        points_in_regions += 1;
    }
    let columns: Vec<Vec<(Point3<f32>, u32)>> =
        by_region.par_iter().map(|members| columns_of(points, members, voxel_m)).collect();
    let mut voxels = VoxelCloud { resolution_m: voxel_m as f32, ..Default::default() };
    let mut surfaces = Vec::with_capacity(planes.len());
    for (cols, plane) in columns.into_iter().zip(&planes) {
        if cols.is_empty() {
            continue;
        }
        let first = voxels.len() as u32;
        let normal = plane.normal.cast::<f32>();
        for (pos, count) in cols {
            let key = [pos.x, pos.y, pos.z].map(|v| (f64::from(v) / voxel_m).floor() as i32);
            voxels.keys.push(key);
            voxels.positions.push(pos);
            voxels.normals.push(normal);
            voxels.counts.push(count);
            voxels.adjacency.push(0);
        }
        surfaces.push(((first..voxels.len() as u32).collect(), plane.normal));
    }
    let regions_ms = start.elapsed().as_secs_f64() * 1e3;
    Some(Regions { voxels, surfaces, cells: fitted, level_cells, points_in_regions, cells_ms, regions_ms })
}

/// The columns (vertical, `v` on a side, world-aligned) of the points `members`: each
/// occupied one's mean point and point count.
fn columns_of(points: &[Point3<f32>], members: &[u32], v: f64) -> Vec<(Point3<f32>, u32)> {
    let col = |q: &Point3<f32>| ((f64::from(q.x) / v).floor() as i64, (f64::from(q.y) / v).floor() as i64);
    let Some(&first) = members.first() else { return Vec::new() };
    let (mut lo, mut hi) = (col(&points[first as usize]), col(&points[first as usize]));
    for &i in members {
        let (x, y) = col(&points[i as usize]);
        lo = (lo.0.min(x), lo.1.min(y));
        hi = (hi.0.max(x), hi.1.max(y));
    }
    let (nx, ny) = ((hi.0 - lo.0 + 1) as usize, (hi.1 - lo.1 + 1) as usize);
    if nx.saturating_mul(ny) > 4 * members.len() + 1024 {
        // Sparse over its box (a region spread far): sorted by column instead of a table.
        let mut keyed: Vec<((i64, i64), u32)> =
            members.iter().map(|&i| (col(&points[i as usize]), i)).collect();
        keyed.sort_unstable();
        return keyed
            .chunk_by(|a, b| a.0 == b.0)
            .map(|run| {
                let s =
                    run.iter().map(|&(_, i)| points[i as usize].coords.cast::<f64>()).sum::<Vector3<f64>>();
                (Point3::from((s / run.len() as f64).cast::<f32>()), run.len() as u32)
            })
            .collect();
    }
    let mut sums = vec![(Vector3::<f64>::zeros(), 0u32); nx * ny];
    for &i in members {
        let q = &points[i as usize];
        let (x, y) = col(q);
        let s = &mut sums[(x - lo.0) as usize * ny + (y - lo.1) as usize];
        s.0 += q.coords.cast::<f64>();
        s.1 += 1;
    }
    sums.into_iter()
        .filter(|s| s.1 > 0)
        .map(|(s, n)| (Point3::from((s / f64::from(n)).cast::<f32>()), n))
        .collect()
}
