//! The space the lidar's rays crossed, and the space it could have seen but did not. A
//! return says a surface is at its end and nothing is between it and the sensor; the
//! surroundings' voxels (`surroundings`) keep the first, this keeps the second. Where the
//! last sweep looked (its rays' directions from where its last row was cast) and no ray of
//! any sweep passed, nothing is known: a standing sweep's shadows, and the gaps a moving
//! head leaves (it looks in a direction only once a sweep, from wherever it then is). The
//! planner keeps the upper body off the edge of the space known free
//! ([`FreeSpace::unseen_edge`]) as off a surface: such a gap may hold what no ray met (a
//! handrail beside the chest). Space the sensor cannot look at (above its highest beam,
//! behind its field of view) is not judged: the body goes there unseen, as it must (the
//! head rises above where its scan plane was).

use super::ray_walk::{self, chunk_of, voxel, Chunks, Walker, CHUNK_WORDS};
use crate::cloud::PointCloud;
use crate::geom3d::{capsules_box, Capsule};
use nalgebra::{Point3, Unit, Vector3};

/// Coordinates farther than this from the origin are not traced, metres: a pose or a
/// return there is garbage, and its voxel indices would near the integers' ends.
const FAR_M: f64 = 1e4;
/// Most voxels the unseen edge is looked for in (the defaults' box: about 10^5).
const MAX_EDGE_VOXELS: f64 = 1e7;
/// Bins of the directions a sweep looked in, per degree of azimuth and of elevation.
const BINS_PER_DEG: f64 = 1.0;
const AZIMUTH_BINS: usize = (360.0 * BINS_PER_DEG) as usize;
const ELEVATION_BINS: usize = (180.0 * BINS_PER_DEG) as usize + 1;

/// How the crossed space is kept and its unseen edge drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FreeSpaceParams {
    /// Edge of a voxel of the crossed space, metres.
    pub voxel_m: f64,
    /// Every how many beams and rows a ray is traced (1: all).
    pub ray_stride: usize,
    /// Rays are traced this far from their origin, metres: the body's next moves are
    /// nearer.
    pub reach_m: f64,
    /// The unseen edge is drawn this far around the body, metres.
    pub around_body_m: f64,
    /// The unseen edge is drawn from this height above the body's lowest point up, metres:
    /// the upper body's lowest point (the hands) is higher.
    pub above_soles_m: f64,
    /// Returns within this distance of the body are its own, metres: what lies behind
    /// them (the body's own shadow, on a real robot) is not judged.
    pub self_margin_m: f64,
}

/// The directions a sweep's rays went in, binned by azimuth and elevation about `up`.
#[derive(Debug, Clone)]
struct Regard {
    from: Point3<f64>,
    up: Unit<Vector3<f64>>,
    east: Vector3<f64>,
    north: Vector3<f64>,
    /// The bins rays went in, and those in which a ray met the body itself.
    looked: Vec<u64>,
    shadowed: Vec<u64>,
}

impl Regard {
    fn new(from: Point3<f64>, up: Unit<Vector3<f64>>) -> Self {
        let east = up
            .cross(&Vector3::x())
            .try_normalize(1e-6)
            .unwrap_or_else(|| up.cross(&Vector3::y()).normalize());
        let north = up.cross(&east);
        let words = (AZIMUTH_BINS * ELEVATION_BINS).div_ceil(64);
        Self { from, up, east, north, looked: vec![0; words], shadowed: vec![0; words] }
    }

    fn bin(&self, d: &Vector3<f64>) -> Option<usize> {
        let n = d.norm();
        if n.is_nan() || n <= 1e-9 {
            return None;
        }
        let elevation = (d.dot(&self.up) / n).clamp(-1.0, 1.0).asin().to_degrees() + 90.0;
        let azimuth = d.dot(&self.north).atan2(d.dot(&self.east)).to_degrees() + 180.0;
        let e = ((elevation * BINS_PER_DEG) as usize).min(ELEVATION_BINS - 1);
        let a = ((azimuth * BINS_PER_DEG) as usize).min(AZIMUTH_BINS - 1);
        Some(e * AZIMUTH_BINS + a)
    }

    fn mark(&mut self, d: &Vector3<f64>, on_body: bool) {
        if let Some(i) = self.bin(d) {
            let bins = if on_body { &mut self.shadowed } else { &mut self.looked };
            bins[i / 64] |= 1 << (i % 64);
        }
    }

    /// Whether a ray went in the direction of `p`'s bin, and none there met the body.
    fn looks_at(&self, p: &Point3<f64>) -> bool {
        let bit = |bins: &[u64], i: usize| bins[i / 64] & (1 << (i % 64)) != 0;
        self.bin(&(p - self.from)).is_some_and(|i| bit(&self.looked, i) && !bit(&self.shadowed, i))
    }

    /// Whether rays went in the directions of all of voxel `v`'s corners: the voxel lies
    /// within where the sweep looked, not across its border (the space just past its
    /// steepest row, or past its field of view's ends, is not judged).
    fn looks_at_voxel(&self, v: [i32; 3], voxel_m: f64) -> bool {
        (0..8).all(|c: i32| {
            let corner = [0, 1, 2].map(|k| (v[k] + ((c >> k) & 1)) as f64 * voxel_m);
            self.looks_at(&Point3::from(corner))
        })
    }
}

/// The voxels rays crossed (or the body filled) over every sweep, and where the last sweep
/// looked.
#[derive(Debug, Clone, Default)]
pub struct FreeSpace {
    chunks: Chunks,
    last: Option<Regard>,
    body: Vec<Capsule>,
}

impl FreeSpace {
    fn set(&mut self, v: [i32; 3]) {
        let (key, bit) = chunk_of(v);
        self.chunks.entry(key).or_insert_with(|| Box::new([0; CHUNK_WORDS]))[bit / 64] |= 1 << (bit % 64);
    }

    /// How many voxels rays crossed or the body filled.
    pub fn crossed_voxels(&self) -> usize {
        self.chunks.values().map(|c| c.iter().map(|w| w.count_ones() as usize).sum::<usize>()).sum()
    }

    /// Whether a ray crossed voxel `v` (or the body filled it).
    fn crossed(&self, v: [i32; 3]) -> bool {
        let (key, bit) = chunk_of(v);
        self.chunks.get(&key).is_some_and(|c| c[bit / 64] & (1 << (bit % 64)) != 0)
    }

    /// Adds a sweep: the voxels its rays crossed short of their returns (traced from each
    /// row's own origin where the sweep moved, else from its viewpoint), the voxels the
    /// robot's `body` fills (it stands there), and the directions it looked in (those
    /// where a ray met the body apart).
    pub fn add(&mut self, cloud: &PointCloud, body: &[Capsule], p: &FreeSpaceParams) {
        self.add_walked(cloud, body, p, Walker::Block);
    }

    /// [`FreeSpace::add`] with the rays walked by `walker` (the same voxels either way).
    pub fn add_walked(&mut self, cloud: &PointCloud, body: &[Capsule], p: &FreeSpaceParams, walker: Walker) {
        if !(p.voxel_m >= 1e-3 && p.voxel_m.is_finite() && p.reach_m.is_finite()) {
            return; // a parameters file gives neither (`SurroundingsParams`); only code could
        }
        let stride = p.ray_stride.max(1);
        let grid = cloud.grid();
        let origins = grid.map(|g| g.row_origins()).unwrap_or(&[]);
        let mut regard = Regard::new(cloud.sensor_at_end(), -cloud.gravity());
        let mut rays: Vec<(Point3<f64>, Point3<f64>)> = Vec::new();
        match grid {
            Some(g) => {
                for row in (0..g.rows()).step_by(stride) {
                    let from = origins.get(row).copied().unwrap_or_else(|| cloud.viewpoint());
                    for beam in (0..g.beams()).step_by(stride) {
                        if let Some(i) = g.point_at(row, beam) {
                            let q = cloud.points()[i];
                            rays.push((from, Point3::new(q.x as f64, q.y as f64, q.z as f64)));
                        }
                    }
                }
            }
            None => {
                let from = cloud.viewpoint();
                for q in cloud.points().iter().step_by(stride.saturating_mul(stride)) {
                    rays.push((from, Point3::new(q.x as f64, q.y as f64, q.z as f64)));
                }
            }
        }
        // Non-finite coordinates, and garbage far off, are neither marked nor walked.
        rays.retain(|(from, to)| from.coords.iter().chain(to.coords.iter()).all(|v| v.abs() < FAR_M));
        let (lo, hi) = capsules_box(body, p.self_margin_m);
        for (from, to) in &rays {
            let in_box = (0..3).all(|i| to[i] >= lo[i] && to[i] <= hi[i]);
            let on_body = in_box && body.iter().any(|c| c.distance_m(to) < p.self_margin_m);
            regard.mark(&(to - from), on_body);
        }
        ray_walk::merge(&mut self.chunks, ray_walk::walk(&rays, p.voxel_m, p.reach_m, walker));
        for c in body {
            self.fill(c, p.voxel_m);
        }
        self.last = Some(regard);
        self.body = body.to_vec();
    }

    /// Marks the voxels whose centres lie in capsule `c`.
    fn fill(&mut self, c: &Capsule, voxel_m: f64) {
        let r = Vector3::repeat(c.radius_m);
        let lo = voxel(&Point3::from(c.a.coords.inf(&c.b.coords) - r), voxel_m);
        let hi = voxel(&Point3::from(c.a.coords.sup(&c.b.coords) + r), voxel_m);
        for x in lo[0]..=hi[0] {
            for y in lo[1]..=hi[1] {
                for z in lo[2]..=hi[2] {
                    let centre = Point3::new(x as f64 + 0.5, y as f64 + 0.5, z as f64 + 0.5) * voxel_m;
                    if c.distance_m(&centre) <= 0.0 {
                        self.set([x, y, z]);
                    }
                }
            }
        }
    }

    /// The centres of the voxels at the edge of the space known free near the body of the
    /// last sweep: those no ray crossed, beside one a ray crossed, in a direction the last
    /// sweep looked in, within `p.around_body_m` of the body's box and higher than
    /// `p.above_soles_m` over its lowest point. Those within `p.self_margin_m` of the body
    /// are not judged: a return there would have been taken for the body's own, so a
    /// missing one says nothing either (the same blind margin the surfaces have).
    pub fn unseen_edge(&self, p: &FreeSpaceParams) -> Vec<Point3<f64>> {
        let Some(regard) = self.last.as_ref() else { return Vec::new() };
        let (lo, hi) = capsules_box(&self.body, 0.0);
        let lo = Point3::new(lo.x - p.around_body_m, lo.y - p.around_body_m, lo.z + p.above_soles_m);
        let hi = Point3::from(hi + Vector3::repeat(p.around_body_m));
        // A garbage pose, or parameters only code could give (a file's are bounded): nothing.
        let voxels: f64 = (0..3).map(|i| ((hi[i] - lo[i]) / p.voxel_m).max(0.0) + 1.0).product();
        let sane = lo.coords.iter().chain(hi.coords.iter()).all(|v| v.abs() < FAR_M);
        if self.body.is_empty() || !sane || !(p.voxel_m >= 1e-3 && voxels <= MAX_EDGE_VOXELS) {
            return Vec::new();
        }
        let (lo, hi) = (voxel(&lo, p.voxel_m), voxel(&hi, p.voxel_m));
        let mut out = Vec::new();
        for x in lo[0]..=hi[0] {
            for y in lo[1]..=hi[1] {
                for z in lo[2]..=hi[2] {
                    let v = [x, y, z];
                    if self.crossed(v) {
                        continue;
                    }
                    let beside = (0..3).any(|i| {
                        [-1, 1].iter().any(|&s| {
                            let mut n = v;
                            n[i] += s;
                            self.crossed(n)
                        })
                    });
                    if !beside {
                        continue;
                    }
                    let centre = Point3::new(x as f64 + 0.5, y as f64 + 0.5, z as f64 + 0.5) * p.voxel_m;
                    let by_body = self.body.iter().any(|c| c.distance_m(&centre) < p.self_margin_m);
                    if !by_body && regard.looks_at_voxel(v, p.voxel_m) {
                        out.push(centre);
                    }
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const VIEW: Point3<f64> = Point3::new(0.0, 0.0, 1.5);

    fn params() -> FreeSpaceParams {
        FreeSpaceParams {
            voxel_m: 0.05,
            ray_stride: 1,
            reach_m: 2.5,
            around_body_m: 1.0,
            above_soles_m: 0.3,
            self_margin_m: 0.05,
        }
    }

    /// A sweep's returns on a floor 0.3-2.5 m ahead, 1 cm apart, seen from 1.5 m up, one
    /// ray a row, but for the rays that would cross `gap` (lower and upper corners): those
    /// were cast in the same directions from 0.3 m behind and 0.2 m below, as a head that
    /// walked while it swept casts them, and passed beside the gap.
    fn floor_seen_but(gap: Option<(Point3<f64>, Point3<f64>)>) -> PointCloud {
        let crosses = |q: &Point3<f64>| {
            gap.is_some_and(|(lo, hi)| {
                (0..=200).any(|i| {
                    let at = VIEW + (q - VIEW) * (i as f64 / 200.0);
                    (0..3).all(|k| at[k] >= lo[k] && at[k] <= hi[k])
                })
            })
        };
        let (mut points, mut origins) = (Vec::new(), Vec::new());
        for i in 0..=220 {
            for j in 0..=200 {
                let q = Point3::new(0.3 + 0.01 * i as f64, -1.0 + 0.01 * j as f64, 0.0);
                let from = if crosses(&q) { VIEW + Vector3::new(-0.3, 0.0, -0.2) } else { VIEW };
                let d = (q - VIEW).normalize();
                points.push((from + d * (from.z / -d.z)).cast::<f32>());
                origins.push(from);
            }
        }
        let n = points.len();
        let grid = crate::cloud::ScanGrid::new(n, 1, (0..n as u32).collect())
            .and_then(|g| g.with_row_origins(origins))
            .expect("a grid");
        PointCloud::new(points, VIEW, -Vector3::z_axis(), Some(grid))
    }

    fn body() -> Vec<Capsule> {
        vec![Capsule { a: Point3::new(0.0, 0.0, 0.05), b: Point3::new(0.0, 0.0, 1.4), radius_m: 0.15 }]
    }

    #[test]
    fn space_no_ray_crossed_where_the_sweep_looked_is_the_edge_of_the_known_free_space() {
        let p = params();
        // Every ray there: nothing near the body is unseen (the floor is below the drawn
        // band; behind the body, beside it at its height and above the head no ray looked).
        let mut all = FreeSpace::default();
        all.add(&floor_seen_but(None), &body(), &p);
        assert_eq!(all.unseen_edge(&p), Vec::<Point3<f64>>::new());
        // A gap where a handrail could stand, 0.8-1.0 m ahead, 0.3-0.5 m to the right, at
        // 0.9-1.1 m: its edge is drawn round it, and only along the rays that missed it.
        let (lo, hi) = (Point3::new(0.8, -0.5, 0.9), Point3::new(1.0, -0.3, 1.1));
        let mut gap = FreeSpace::default();
        gap.add(&floor_seen_but(Some((lo, hi))), &body(), &p);
        let edge = gap.unseen_edge(&p);
        let centre = Point3::from((lo.coords + hi.coords) / 2.0);
        let axis = (centre - VIEW).normalize();
        let within_cone = |q: &Point3<f64>| {
            let d = q - VIEW;
            // The gap's half-width seen from the view, and a voxel's diagonal more.
            let half_angle = (0.18_f64 / (centre - VIEW).norm()).atan();
            let off = d.norm() * d.normalize().angle(&axis).sin();
            off <= d.norm() * half_angle.tan() + p.voxel_m * 3f64.sqrt()
        };
        assert!(!edge.is_empty());
        assert!(edge.iter().all(within_cone), "{:?}", edge.iter().find(|q| !within_cone(q)));
        let in_gap = |q: &Point3<f64>| (0..3).all(|k| q[k] >= lo[k] - p.voxel_m && q[k] <= hi[k] + p.voxel_m);
        assert!(edge.iter().any(in_gap), "no unseen point at the gap: {edge:?}");
        // The body's own place is known free, the gap or not.
        assert!(edge.iter().all(|q| body()[0].distance_m(q) > 0.0));
    }

    #[test]
    fn the_crossed_space_is_the_same_on_any_number_of_threads() {
        let cloud = floor_seen_but(Some((Point3::new(0.8, -0.5, 0.9), Point3::new(1.0, -0.3, 1.1))));
        let on = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("a pool");
            let mut s = FreeSpace::default();
            pool.install(|| s.add(&cloud, &body(), &params()));
            let mut bits: Vec<([i32; 3], Vec<u64>)> = s
                .chunks
                .iter()
                .filter(|(_, w)| w.iter().any(|&x| x != 0))
                .map(|(k, w)| (*k, w.to_vec()))
                .collect();
            bits.sort();
            (bits, s.unseen_edge(&params()))
        };
        let one = on(1);
        assert!(!one.0.is_empty() && !one.1.is_empty());
        assert_eq!(one, on(3));
    }

    #[test]
    fn the_rows_of_a_moving_sweep_are_traced_from_their_own_origins() {
        // Two rows of one beam each, down onto the floor from two origins 1 m apart: each
        // crosses the voxels below its own origin.
        let points = vec![Point3::new(0.0f32, 0.0, 0.0), Point3::new(1.0, 0.0, 0.0)];
        let grid = crate::cloud::ScanGrid::new(2, 1, vec![0, 1])
            .and_then(|g| g.with_row_origins(vec![Point3::new(0.0, 0.0, 1.0), Point3::new(1.0, 0.0, 1.0)]))
            .expect("a grid");
        let cloud = PointCloud::new(points, Point3::new(0.5, 0.0, 1.0), -Vector3::z_axis(), Some(grid));
        let p = params();
        let mut s = FreeSpace::default();
        s.add(&cloud, &[], &p);
        for x in [0.01, 1.01] {
            for z in [0.12, 0.5, 0.9] {
                assert!(s.crossed(voxel(&Point3::new(x, 0.01, z), p.voxel_m)), "({x}, {z})");
            }
        }
        assert!(!s.crossed(voxel(&Point3::new(0.51, 0.01, 0.5), p.voxel_m)));
        // The returns' own voxels are not crossed.
        assert!(!s.crossed(voxel(&Point3::new(0.01, 0.01, 0.01), p.voxel_m)));
    }

    /// Space no ray crossed a few centimetres from the body is where a return would have been
    /// taken for the body's own: not judged; the same 20 cm off is.
    #[test]
    fn space_within_the_self_margin_of_the_body_is_not_judged() {
        let p = params();
        let mut s = FreeSpace::default();
        let near = [3, 0, 20]; // centre 2.7 cm from the capsule's surface
        let far = [6, 0, 20]; // 17.6 cm
        for x in -40..40 {
            for y in -40..40 {
                for z in 0..60 {
                    if [x, y, z] != near && [x, y, z] != far {
                        s.set([x, y, z]);
                    }
                }
            }
        }
        let mut regard = Regard::new(VIEW, Vector3::z_axis());
        regard.looked.iter_mut().for_each(|w| *w = !0);
        s.last = Some(regard);
        s.body = body();
        let at =
            |v: [i32; 3]| Point3::new(v[0] as f64 + 0.5, v[1] as f64 + 0.5, v[2] as f64 + 0.5) * p.voxel_m;
        assert!(body()[0].distance_m(&at(near)) < p.self_margin_m);
        let edge = s.unseen_edge(&p);
        assert!(edge == vec![at(far)], "{} points, first {:?}", edge.len(), edge.first());
    }

    /// A ground a sweep's rays fall on, nothing else.
    struct Ground;

    impl crate::sensor::RayCaster for Ground {
        fn ray(&self, o: &Point3<f64>, d: &Vector3<f64>) -> Option<crate::sensor::RayHit> {
            (d.z < -1e-9).then(|| crate::sensor::RayHit { distance_m: o.z / -d.z, geom: 0 })
        }
    }

    /// A head that walks 0.3 m forward and 0.15 m up a step while the lidar sweeps: the
    /// space the chest moves into next, just ahead of the head and below it, is looked at
    /// by the shallow rows, which a sweep run level last casts from where the head ends;
    /// one run from level down casts them from 0.3 m back and lower, under that space,
    /// which is then left unseen.
    #[test]
    fn a_sweep_taken_walking_crosses_the_space_just_ahead_of_where_the_head_ends() {
        let spec = crate::scenario::LidarSpec {
            noise_sigma_m: 0.0,
            dropout_probability: 0.0,
            ..crate::scenario::LidarSpec::default()
        };
        let rows = crate::sensor::TiltSweep::from_spec(&spec).rows();
        let heads: Vec<_> = (0..rows)
            .map(|k| {
                let s = k as f64 / (rows - 1) as f64;
                let at = nalgebra::Isometry3::translation(0.3 * s, 0.0, 1.3 + 0.15 * s);
                (at, at)
            })
            .collect();
        let head = heads[rows - 1].0.translation.vector;
        let ahead = |q: &&Point3<f64>| {
            let d = q.coords - head;
            (0.1..=0.5).contains(&d.x) && d.y.abs() <= 0.3 && (-0.3..=0.05).contains(&d.z)
        };
        // The unseen voxels ahead, the pass run level last or level first.
        let unseen_ahead = |level_last: bool| {
            let lidar = crate::sensor::SimLidar::moving(&Ground, &spec, &heads, 1).expect("a head per row");
            let lidar = match level_last {
                true => lidar,
                false => lidar.along(crate::sensor::TiltSweep::from_spec(&spec)),
            };
            let sweep = lidar.sweep_rows(&crate::cancel::Cancel::never(), &mut |_, _| {}).expect("a sweep");
            let cloud = sweep.assemble(&Default::default()).expect("a cloud");
            let chest =
                Capsule { a: Point3::new(0.3, 0.0, 0.1), b: Point3::new(0.3, 0.0, 1.3), radius_m: 0.15 };
            let p = FreeSpaceParams { ray_stride: 2, ..params() };
            let mut space = FreeSpace::default();
            space.add(&cloud, &[chest], &p);
            space.unseen_edge(&p).iter().filter(ahead).count()
        };
        assert_eq!(unseen_ahead(true), 0, "run level last");
        assert!(unseen_ahead(false) > 0, "run level first, the space ahead is left unseen");
    }
}
