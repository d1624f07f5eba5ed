//! The lidar's rays against a world made of static boxes, as MuJoCo's `mj_ray` casts them and
//! with its answers (distance and geom), faster: the boxes are read once (a static box never
//! moves), and a box the ray does not enter (its world-aligned bounding box, grown by
//! [`CULL_SLACK_M`]) before the nearest hit found so far is not tested: a room's walls and
//! ceiling, which every ray's bounding sphere test passes, are passed over by a ray that met
//! a tread first. Each box is tested in geom order with `mj_ray`'s own arithmetic (its
//! bounding-sphere test, then each face), so the distances are the same numbers; ties go to
//! the lower geom id, as `mj_ray`'s do. A world with any other geom a ray may meet is left
//! to `mj_ray`. Same numbers as long as the MuJoCo library computes without fused
//! multiply-adds, as Rust does (an x86-64 build without `-mfma`, as the one this bench
//! fetches; tests/lidar.rs checks it).

use mujoco_rs::mujoco_c::mjNGROUP;
use mujoco_rs::prelude::{MjData, MjModel, MjtGeomBase};
use std::sync::Arc;

/// MuJoCo's `mjMINVAL`: the smallest value it divides by.
const MIN_VAL: f64 = 1e-15;
/// Slack of the cull, metres: each box's bounds are grown by it, far above the rounding of a
/// distance, so a box the cull passes over is one `mj_ray`'s arithmetic finds no nearer.
const CULL_SLACK_M: f64 = 1e-6;

/// One static box: its centre, rotation (row-major, MuJoCo's `geom_xmat`), half sizes, squared
/// bounding radius, its world-aligned bounds grown by [`CULL_SLACK_M`] (lowest, highest), and
/// geom id.
#[derive(Debug, Clone)]
struct RayBox {
    pos_m: [f64; 3],
    mat: [f64; 9],
    half_m: [f64; 3],
    radius_m2: f64,
    bounds_m: [[f64; 3]; 2],
    geom: usize,
}

/// The boxes a ray may meet, in geom order.
#[derive(Debug, Clone)]
pub struct BoxRays {
    boxes: Vec<RayBox>,
}

impl BoxRays {
    /// The boxes of `model` (posed as in `data`) that `mj_ray` with `groups` and static geoms
    /// included would test, or `None` when any such geom is not a static box.
    pub fn of(model: &MjModel, data: &MjData<Arc<MjModel>>, groups: &[u8]) -> Option<Self> {
        let (bodies, weld) = (model.geom_bodyid(), model.body_weldid());
        let (matid, rgba, mat_rgba) = (model.geom_matid(), model.geom_rgba(), model.mat_rgba());
        let (xpos, xmat, size) = (data.geom_xpos(), data.geom_xmat(), model.geom_size());
        let mut boxes = Vec::new();
        for g in 0..model.ffi().ngeom as usize {
            // `mj_ray`'s exclusions: invisible geoms (by their colour or their material's),
            // and the groups not asked for.
            let m = matid[g];
            let invisible = match usize::try_from(m) {
                Ok(m) => mat_rgba.get(m).is_none_or(|c| c[3] == 0.0),
                Err(_) => rgba[g][3] == 0.0,
            };
            let group = model.geom_group()[g].clamp(0, mjNGROUP as i32 - 1) as usize;
            if invisible || groups.get(group).is_none_or(|&on| on == 0) {
                continue;
            }
            let is_static = weld.get(bodies[g] as usize).is_some_and(|&w| w == 0);
            if model.geom_type()[g] != MjtGeomBase::mjGEOM_BOX || !is_static {
                return None;
            }
            let (s, pos, mat) = (size[g], xpos[g], xmat[g]);
            let radius_m2 = s[0] * s[0] + s[1] * s[1] + s[2] * s[2];
            // The rotated box's reach along each world axis (row i of the rotation).
            let reach = |i: usize| (0..3).map(|j| mat[3 * i + j].abs() * s[j]).sum::<f64>() + CULL_SLACK_M;
            let bounds_m = [[0, 1, 2].map(|i| pos[i] - reach(i)), [0, 1, 2].map(|i| pos[i] + reach(i))];
            boxes.push(RayBox { pos_m: pos, mat, half_m: s, radius_m2, bounds_m, geom: g });
        }
        Some(Self { boxes })
    }

    /// The nearest box the ray from `pnt` along `vec` meets: its distance in units of `vec`'s
    /// length and its geom id.
    pub fn ray(&self, pnt: &[f64; 3], vec: &[f64; 3]) -> Option<(f64, usize)> {
        let inv = vec.map(|v| 1.0 / v);
        let mut best: Option<(f64, usize)> = None;
        for b in &self.boxes {
            let beyond = best.map_or(f64::INFINITY, |(d, _)| d);
            if !b.entered_before(pnt, &inv, beyond) {
                continue;
            }
            let x = b.ray(pnt, vec, beyond);
            if x >= 0.0 && best.is_none_or(|(d, _)| x < d) {
                best = Some((x, b.geom));
            }
        }
        best
    }
}

impl RayBox {
    /// Whether the ray from `pnt` with `inv` the inverse of each component of its direction
    /// enters the grown bounds ahead and before `beyond` (in units of the direction's
    /// length): the slab test. Grown by [`CULL_SLACK_M`], the bounds are entered at least
    /// that much before the box itself, so a box `mj_ray` finds nearer than `beyond` always
    /// passes. A component of 0 gives infinite slabs: none where `pnt` lies between the
    /// bounds, an empty one where it does not (and where it lies on a bound, a NaN that may
    /// empty it: rightly, the box itself lies [`CULL_SLACK_M`] inside, unmet).
    #[inline(always)]
    fn entered_before(&self, pnt: &[f64; 3], inv: &[f64; 3], beyond: f64) -> bool {
        let [lo, hi] = &self.bounds_m;
        let (mut enter, mut leave) = (0.0f64, beyond);
        for i in 0..3 {
            let (a, b) = ((lo[i] - pnt[i]) * inv[i], (hi[i] - pnt[i]) * inv[i]);
            enter = enter.max(a.min(b));
            leave = leave.min(a.max(b));
        }
        enter <= leave
    }

    /// `mj_ray`'s distance to this box, negative for none and for one no nearer than
    /// `beyond`: the bounding sphere first, then the nearest face ahead whose rectangle holds
    /// the crossing.
    fn ray(&self, pnt: &[f64; 3], vec: &[f64; 3], beyond: f64) -> f64 {
        // The bounding sphere: a x^2 + 2 b x + c = 0 with a root ahead.
        let dif = [pnt[0] - self.pos_m[0], pnt[1] - self.pos_m[1], pnt[2] - self.pos_m[2]];
        let a = vec[0] * vec[0] + vec[1] * vec[1] + vec[2] * vec[2];
        let b = vec[0] * dif[0] + vec[1] * dif[1] + vec[2] * dif[2];
        let c = dif[0] * dif[0] + dif[1] * dif[1] + dif[2] * dif[2] - self.radius_m2;
        let det = b * b - a * c;
        // No root, or both behind: the larger, (-b + sqrt(det)) / a, below zero. That needs the
        // origin outside the sphere and the ray leaving it (b, c > 0; else the root is not
        // negative), and only then is the root taken.
        if det < MIN_VAL || (b > 0.0 && c > 0.0 && (-b + det.sqrt()) / a < 0.0) {
            return -1.0;
        }
        // The ray in the box's frame (the transposed rotation).
        let m = &self.mat;
        let lpnt = [
            m[0] * dif[0] + m[3] * dif[1] + m[6] * dif[2],
            m[1] * dif[0] + m[4] * dif[1] + m[7] * dif[2],
            m[2] * dif[0] + m[5] * dif[1] + m[8] * dif[2],
        ];
        let lvec = [
            m[0] * vec[0] + m[3] * vec[1] + m[6] * vec[2],
            m[1] * vec[0] + m[4] * vec[1] + m[7] * vec[2],
            m[2] * vec[0] + m[5] * vec[1] + m[8] * vec[2],
        ];
        const FACES: [[usize; 2]; 3] = [[1, 2], [0, 2], [0, 1]];
        let s = &self.half_m;
        let mut x = -1.0;
        for (i, [f0, f1]) in FACES.into_iter().enumerate() {
            if lvec[i].abs() <= MIN_VAL {
                continue;
            }
            for side in [-1.0, 1.0] {
                let sol = (side * s[i] - lpnt[i]) / lvec[i];
                // A face no nearer than the nearest found (here or before) cannot be the
                // answer: its rectangle is not looked at.
                if sol >= 0.0 && sol < beyond && (x < 0.0 || sol < x) {
                    let p0 = lpnt[f0] + sol * lvec[f0];
                    let p1 = lpnt[f1] + sol * lvec[f1];
                    if p0.abs() <= s[f0] && p1.abs() <= s[f1] {
                        x = sol;
                    }
                }
            }
        }
        x
    }
}
