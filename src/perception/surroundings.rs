//! What the lidar saw around the robot: every surface, not only the steps. §4's perception
//! keeps near-horizontal surfaces (Filter 1), so the step map knows nothing of a stairwell's
//! walls or of a crate beside the flight, and a wrist met a side wall (issue 19). Each
//! sweep's returns enter a voxel grid in the world frame, those on the robot's own body at
//! the sweep's configuration left out (a real lidar sees its own arms; the simulated one is
//! blind to them, so the filter costs nothing there); the planner keeps the upper body off
//! the occupied voxels' centroids (`planning::clearance::SeenPoints`), the legs off those
//! that are not the steps' or the floor's own, and the soles off what stands on the floor,
//! a tread or a landing (`planning::footholds`). The space the rays crossed is kept beside
//! (`free_space`), and the edge of what the lidar could have seen there and did not is kept
//! off by the upper body as a surface is ([`Surroundings::unseen`]).

use super::free_space::{FreeSpace, FreeSpaceParams};
use crate::cloud::PointCloud;
use crate::geom3d::Capsule;
use nalgebra::{Point3, Vector3};
use rustc_hash::FxHashMap;

/// How the surroundings are kept.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SurroundingsParams {
    /// Edge of a voxel, metres. 3 cm: finer than the clearance kept from it, coarse enough
    /// that a wall's voxels hold several returns each.
    #[serde(deserialize_with = "positive_m")]
    pub voxel_m: f64,
    /// A voxel is a surface once this many returns fell in it over all sweeps (a lone
    /// return is a stray: a noise spike, a mixed pixel at an edge).
    pub min_returns: u32,
    /// Returns within this distance of the robot's own collision shapes are its body,
    /// metres.
    #[serde(deserialize_with = "positive_m")]
    pub self_margin_m: f64,
    /// Whether the upper body is kept off the edge of the space the lidar could have seen
    /// and no ray crossed (a shadow, a moving head's gap), as off a surface. On by default:
    /// what is there is not known (a handrail no ray met, beside the chest).
    pub unseen_kept_off: bool,
    /// Edge of a voxel of the crossed space, metres (1-50 cm). 5 cm: a few beams cross each
    /// at the body's distances, and the edge's voxels are closer together than the body's
    /// capsules are thick.
    #[serde(deserialize_with = "free_voxel_m")]
    pub free_voxel_m: f64,
    /// Every how many beams and rows a ray is traced into the crossed space (the sweep's
    /// 0.25 deg beams and rows are 1 cm apart at 2 m: a 5 cm voxel is crossed by several
    /// of every second). 1 to 64.
    #[serde(deserialize_with = "ray_stride")]
    pub ray_stride: usize,
    /// Rays are traced this far from the sensor into the crossed space, metres (up to 30,
    /// the lidar's range): farther than the body's box and `unseen_around_body_m` reach from
    /// the head (about 2.2 m at the defaults), or the reach's own end reads as unseen.
    #[serde(deserialize_with = "ray_reach_m")]
    pub ray_reach_m: f64,
    /// The unseen edge is drawn this far around the body's box, metres (up to 3): a plan's
    /// moves of the upper body stay nearer (two stairs ahead, 0.6 m).
    #[serde(deserialize_with = "around_body_m")]
    pub unseen_around_body_m: f64,
    /// The unseen edge is drawn from this height above the soles up, metres (0-2): the upper
    /// body's lowest point (a hand, 0.6 m over the soles of HRP-4) is higher; the legs are
    /// kept off the steps' solids instead.
    #[serde(deserialize_with = "above_soles_m")]
    pub unseen_above_soles_m: f64,
}

impl SurroundingsParams {
    /// The crossed space's parameters.
    pub fn free_space(&self) -> FreeSpaceParams {
        FreeSpaceParams {
            voxel_m: self.free_voxel_m,
            ray_stride: self.ray_stride,
            reach_m: self.ray_reach_m,
            around_body_m: self.unseen_around_body_m,
            above_soles_m: self.unseen_above_soles_m,
            self_margin_m: self.self_margin_m,
        }
    }
}

/// A parameters file's number that must lie in `[lo, hi]`, named for the error.
fn within<'de, D: serde::Deserializer<'de>>(d: D, lo: f64, hi: f64, unit: &str) -> Result<f64, D::Error> {
    let v = <f64 as serde::Deserialize>::deserialize(d)?;
    if (lo..=hi).contains(&v) {
        Ok(v)
    } else {
        Err(serde::de::Error::custom(format!("{v} is not within {lo} to {hi} {unit}")))
    }
}

fn free_voxel_m<'de, D: serde::Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    within(d, 0.01, 0.5, "metres")
}

fn ray_reach_m<'de, D: serde::Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    within(d, 0.1, 30.0, "metres")
}

fn around_body_m<'de, D: serde::Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    within(d, 0.0, 3.0, "metres")
}

fn above_soles_m<'de, D: serde::Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    within(d, 0.0, 2.0, "metres")
}

fn ray_stride<'de, D: serde::Deserializer<'de>>(d: D) -> Result<usize, D::Error> {
    let v = <usize as serde::Deserialize>::deserialize(d)?;
    if (1..=64).contains(&v) {
        Ok(v)
    } else {
        Err(serde::de::Error::custom(format!("{v} is not a stride of 1 to 64 rays")))
    }
}

/// A parameters file's length that must be positive and finite.
fn positive_m<'de, D: serde::Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    let v = <f64 as serde::Deserialize>::deserialize(d)?;
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(serde::de::Error::custom(format!("{v} is not a positive length in metres")))
    }
}

impl Default for SurroundingsParams {
    fn default() -> Self {
        Self {
            voxel_m: 0.03,
            min_returns: 2,
            self_margin_m: 0.05,
            unseen_kept_off: true,
            free_voxel_m: 0.05,
            ray_stride: 2,
            ray_reach_m: 2.5,
            unseen_around_body_m: 1.0,
            unseen_above_soles_m: 0.3,
        }
    }
}

#[derive(Debug, Clone, Copy, Default)]
struct Cell {
    sum: Vector3<f64>,
    returns: u32,
}

/// The voxels the lidar's returns fell in, over every sweep so far.
#[derive(Debug, Clone, Default)]
pub struct Surroundings {
    /// Each voxel's place in `cells`, by its integer coordinates.
    index: FxHashMap<[i32; 3], u32>,
    cells: Vec<Cell>,
    /// The space the rays crossed (kept only when `unseen_kept_off`).
    free: FreeSpace,
}

impl Surroundings {
    /// Adds a sweep's returns (world frame), except those within `p.self_margin_m` of the
    /// robot's `body` (its collision shapes at the sweep's configuration) and non-finite
    /// ones.
    pub fn add(&mut self, cloud: &PointCloud, body: &[Capsule], p: &SurroundingsParams) {
        if p.voxel_m.is_nan() || p.voxel_m <= 0.0 {
            return; // no parameters file gives one (`positive_m`); only code could
        }
        if p.unseen_kept_off {
            self.free.add(cloud, body, &p.free_space());
        }
        // The body's box: most returns (the floor, the room) are outside it and need no
        // test against each shape.
        let (lo, hi) = crate::geom3d::capsules_box(body, p.self_margin_m);
        // Neighbouring returns of a scan row often fall in one voxel: the last one is kept at
        // hand, and the map is read only when a return leaves it.
        let mut last: Option<([i32; 3], usize)> = None;
        for q in cloud.points() {
            let q = Point3::new(q.x as f64, q.y as f64, q.z as f64);
            if !(q.x.is_finite() && q.y.is_finite() && q.z.is_finite()) {
                continue;
            }
            let in_box = (0..3).all(|i| q[i] >= lo[i] && q[i] <= hi[i]);
            if in_box && body.iter().any(|c| c.distance_m(&q) < p.self_margin_m) {
                continue;
            }
            let key = [0, 1, 2].map(|i| (q[i] / p.voxel_m).floor() as i32);
            let at = match last {
                Some((k, at)) if k == key => at,
                _ => {
                    let next = self.cells.len() as u32;
                    let at = *self.index.entry(key).or_insert(next) as usize;
                    if at == self.cells.len() {
                        self.cells.push(Cell::default());
                    }
                    last = Some((key, at));
                    at
                }
            };
            let cell = &mut self.cells[at];
            cell.sum += q.coords;
            cell.returns += 1;
        }
    }

    /// The centroids of the voxels with at least `p.min_returns` returns.
    pub fn points(&self, p: &SurroundingsParams) -> Vec<Point3<f64>> {
        let mut out: Vec<Point3<f64>> = self
            .cells
            .iter()
            .filter(|c| c.returns >= p.min_returns.max(1))
            .map(|c| Point3::from(c.sum / c.returns as f64))
            .collect();
        // The voxels are in the order the returns first met them; the planner's input is in
        // one order whatever the sweeps' order.
        // Unstable: points the order cannot tell apart are the same bits.
        out.sort_unstable_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)).then(a.z.total_cmp(&b.z)));
        out
    }

    /// The edge of the space the last sweep could have seen near the body and no ray
    /// crossed ([`FreeSpace::unseen_edge`]); none unless `p.unseen_kept_off`.
    pub fn unseen(&self, p: &SurroundingsParams) -> Vec<Point3<f64>> {
        match p.unseen_kept_off {
            true => self.free.unseen_edge(&p.free_space()),
            false => Vec::new(),
        }
    }

    /// Voxels holding any return.
    pub fn len(&self) -> usize {
        self.cells.len()
    }

    /// Whether no return was kept.
    pub fn is_empty(&self) -> bool {
        self.cells.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Point3;

    fn cloud(points: &[[f32; 3]]) -> PointCloud {
        PointCloud::unorganized(
            points.iter().map(|p| Point3::new(p[0], p[1], p[2])).collect(),
            Point3::origin(),
        )
    }

    #[test]
    fn returns_on_the_body_and_lone_strays_are_not_surroundings() {
        let p = SurroundingsParams::default();
        let arm = Capsule { a: Point3::new(0.0, 0.2, 1.0), b: Point3::new(0.0, 0.2, 0.6), radius_m: 0.04 };
        let mut s = Surroundings::default();
        // A wall at y = 0.45 (two returns in one voxel), the arm's own surface, a stray.
        let wall = [[0.01, 0.451, 0.81], [0.015, 0.452, 0.815]];
        let on_arm = [[0.0, 0.245, 0.8], [0.0, 0.246, 0.801]];
        let stray = [[1.0, 1.0, 1.0]];
        let nan = [[f32::NAN, 0.0, 0.0], [f32::NAN, 0.0, 0.0]];
        s.add(&cloud(&[&wall[..], &on_arm, &stray, &nan].concat()), &[arm], &p);
        let pts = s.points(&p);
        assert_eq!(pts.len(), 1, "{pts:?}");
        assert!((pts[0].y - 0.4515).abs() < 1e-6);
        // Another sweep's return in the stray's voxel makes it a surface.
        s.add(&cloud(&[[1.01, 1.01, 1.01]]), &[arm], &p);
        assert_eq!(s.points(&p).len(), 2);
    }

    #[test]
    fn returns_that_come_back_to_a_voxel_are_counted_in_it() {
        // Returns leaving a voxel and coming back to it, within one sweep and over two: the
        // centroids are each voxel's mean whatever the order, as a plain per-voxel tally has it.
        let p = SurroundingsParams { min_returns: 1, ..Default::default() };
        let pts: Vec<[f32; 3]> = (0..200)
            .map(|i| {
                let t = i as f32 * 0.37;
                [(t.sin() * 0.05), (t * 1.7).cos() * 0.05, 0.01 * (i % 3) as f32]
            })
            .collect();
        let (first, second) = pts.split_at(120);
        let mut s = Surroundings::default();
        s.add(&cloud(first), &[], &p);
        s.add(&cloud(second), &[], &p);
        let mut tally: std::collections::BTreeMap<[i32; 3], (Vector3<f64>, f64)> = Default::default();
        for q in &pts {
            let q = Vector3::new(q[0] as f64, q[1] as f64, q[2] as f64);
            let e = tally.entry([0, 1, 2].map(|i| (q[i] / p.voxel_m).floor() as i32)).or_default();
            e.0 += q;
            e.1 += 1.0;
        }
        let got = s.points(&p);
        assert_eq!(got.len(), tally.len());
        assert_eq!(s.len(), tally.len());
        for (sum, n) in tally.values() {
            let c = sum / *n;
            assert!(got.iter().any(|g| (g.coords - c).norm() < 1e-12), "{c:?} not among {got:?}");
        }
    }

    #[test]
    fn a_length_or_stride_out_of_its_range_is_refused_when_read() {
        for bad in [
            "voxel_m = 0.0",
            "voxel_m = -0.03",
            "voxel_m = nan",
            "self_margin_m = inf",
            "free_voxel_m = 1e-9",
            "ray_stride = 0",
            "ray_reach_m = inf",
            "unseen_around_body_m = 1e9",
            "unseen_above_soles_m = -inf",
            "unseen_above_soles_m = nan",
        ] {
            let e = toml::from_str::<SurroundingsParams>(bad).expect_err(bad).to_string();
            assert!(
                e.contains("not a positive length")
                    || e.contains("is not within")
                    || e.contains("not a stride"),
                "{bad}: {e}"
            );
        }
        let ok: SurroundingsParams = toml::from_str("voxel_m = 0.05").expect("a positive voxel");
        assert_eq!(ok.voxel_m, 0.05);
    }

    /// The planner's input is one list whatever order the sweeps and their returns came in.
    /// The coordinates are multiples of 1/64 m, so every voxel's sum is exact in any order
    /// and only the list's order could differ.
    #[test]
    fn the_seen_points_are_one_list_whatever_the_returns_order() {
        let p = SurroundingsParams::default();
        // Each return twice (a voxel is a surface from two returns on), once in each sweep.
        let pts: Vec<[f32; 3]> = (0..600)
            .map(|i| {
                let i = i % 300;
                let k = (i * 37 % 101) as f32;
                [k / 64.0, ((i * 13) % 29) as f32 / 64.0, ((i * 7) % 11) as f32 / 64.0]
            })
            .collect();
        let (a, b) = pts.split_at(300);
        let mut first = Surroundings::default();
        first.add(&cloud(a), &[], &p);
        first.add(&cloud(b), &[], &p);
        let mut second = Surroundings::default();
        let reversed: Vec<[f32; 3]> = b.iter().rev().copied().collect();
        second.add(&cloud(&reversed), &[], &p);
        second.add(&cloud(&a.iter().rev().copied().collect::<Vec<_>>()), &[], &p);
        let (x, y) = (first.points(&p), second.points(&p));
        assert!(x.len() > 20, "{} voxels: the case is not shown", x.len());
        assert_eq!(x, y);
    }
}
