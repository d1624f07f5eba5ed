//! The body's angular momentum about its centre of mass (the centroidal angular momentum),
//! from two configurations a short time apart, and the moment its change asks of the
//! contacts. A quasi-static plan (§6.2) keeps the CoM's projection inside the support
//! polygon, but a body that swings its trunk or arms fast also turns the ground reaction
//! about the CoM: about a horizontal axis that moves the ZMP off the CoM's projection by
//! `|dL_xy/dt| / (m g)`, and about the vertical the support soles must hold the turn by
//! friction. Neither is in the CoM's path; this measures them on a planned motion.

#[cfg(doc)]
use super::kinematics::Kinematics;
use super::model::RobotModel;
use nalgebra::{Isometry3, Point3, Vector3};

/// The angular momentum about the centre of mass, world frame, kg m^2/s, of `model` moving
/// from the link poses `a` to `b` (world, [`Kinematics::link_poses`]) over `dt_s` seconds.
/// Each link's velocity is its pose's change over the interval, taken at the interval's
/// middle: `sum_i m_i (c_i - c) x v_i + R_i I_i R_i^T w_i`, the inertia term averaged over
/// the interval's ends. Exact as `dt_s` goes to zero (test: against MuJoCo's
/// `subtree_angmom`, in `tests/robot.rs`).
pub fn centroidal_angular_momentum(
    model: &RobotModel,
    a: &[Isometry3<f64>],
    b: &[Isometry3<f64>],
    dt_s: f64,
) -> Vector3<f64> {
    let mut mass_kg = 0.0;
    let (mut moment, mut momentum) = (Vector3::zeros(), Vector3::zeros());
    let mut total = Vector3::zeros();
    for ((link, pa), pb) in model.links().iter().zip(a).zip(b).filter(|((l, _), _)| l.mass_kg > 0.0) {
        let (ca, cb) = (pa * Point3::from(link.com_m), pb * Point3::from(link.com_m));
        let (at, v) = ((ca.coords + cb.coords) / 2.0, (cb - ca) / dt_s);
        // About the origin first; moved to the CoM below.
        total += link.mass_kg * at.cross(&v);
        mass_kg += link.mass_kg;
        moment += link.mass_kg * at;
        momentum += link.mass_kg * v;
        // The turn from a to b in the world frame, R_b R_a^T, against the inertia in the world
        // frame averaged over the two ends (R I R^T w at each).
        // The turn's axis times its angle is twice the vector part of its (short way)
        // quaternion, to within the angle squared over 6 (3e-4 for 2 rad/s over 10 ms).
        let turn = (pb.rotation * pa.rotation.inverse()).into_inner();
        let w = turn.imag() * (2.0_f64.copysign(turn.w) / dt_s);
        let spun = |r: &nalgebra::UnitQuaternion<f64>| r * (link.inertia * r.inverse_transform_vector(&w));
        total += (spun(&pa.rotation) + spun(&pb.rotation)) / 2.0;
    }
    if mass_kg <= 0.0 {
        return Vector3::zeros();
    }
    // sum m (c_i - c) x v_i = sum m c_i x v_i - c x (sum m v_i).
    total - (moment / mass_kg).cross(&momentum)
}

/// The window over which [`MomentRates`] takes the momentum's change, seconds. A plan's
/// IK steps its joint velocities tick by tick (every 10 ms at its 100 Hz), and a change
/// within one tick is such a step, which the servos' interpolation and the body's
/// compliance smooth: the Exp. 1 plan's largest change over one tick is 29 N m about a
/// horizontal axis, over 0.1 s 19 N m. What a sole must hold is the change the body keeps
/// up: over 0.1 s, the plans of the two runs of `wide` whose stance soles slid asked
/// 16.6 and 21.1 N m about the vertical, those of every other run at most 7.7 N m
/// (CHANGELOG, thirty-sixth session).
pub const RATE_WINDOW_S: f64 = 0.1;

/// The moments a motion's angular momentum asks of the contacts, largest over a motion, each
/// the momentum's change over [`RATE_WINDOW_S`]: fed its momentum at successive instants
/// ([`MomentRates::add`]), each with a label of the caller's (the part of the motion it is
/// in), so a window's rate can be charged to every part it spans.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MomentRates {
    /// The momenta given within the window (and the last before it), oldest first, with
    /// their times and labels.
    recent: std::collections::VecDeque<(f64, Vector3<f64>, usize)>,
    /// Largest rate of change of the angular momentum about a horizontal axis, N m.
    pub max_tipping_nm: f64,
    /// Largest rate of change about the vertical (the turn the soles hold by friction), N m.
    pub max_yaw_nm: f64,
}

impl MomentRates {
    /// The angular momentum `l` (kg m^2/s, world, z up) at time `t_s`, labelled `label`,
    /// after those given before (in order of time); its rate of change over the window that
    /// ends now, N m, and the label of the momentum the window starts from, once a window
    /// has passed.
    pub fn add(&mut self, t_s: f64, l: Vector3<f64>, label: usize) -> Option<(Vector3<f64>, usize)> {
        // Keep the newest momentum at least a window old, and those after it.
        let since = t_s - RATE_WINDOW_S * (1.0 - 1e-9);
        while self.recent.len() > 1 && self.recent[1].0 <= since {
            self.recent.pop_front();
        }
        let rate = self
            .recent
            .front()
            .filter(|(t0, _, _)| *t0 <= since)
            .map(|&(t0, l0, first)| ((l - l0) / (t_s - t0), first));
        if let Some((rate, _)) = rate {
            self.max_tipping_nm = self.max_tipping_nm.max(rate.xy().norm());
            self.max_yaw_nm = self.max_yaw_nm.max(rate.z.abs());
        }
        self.recent.push_back((t_s, l, label));
        rate
    }
}

/// The mean distance of a rectangle's points (half sides `a_m`, `b_m`) from its centre,
/// metres: the lever of the friction that holds a sole at uniform pressure from turning.
pub fn mean_radius_m(a_m: f64, b_m: f64) -> f64 {
    let d = a_m.hypot(b_m);
    if a_m <= 0.0 || b_m <= 0.0 {
        return d / 2.0;
    }
    // (1 / ab) of the integral of r over [0, a] x [0, b].
    (2.0 * a_m * b_m * d + a_m.powi(3) * ((b_m + d) / a_m).ln() + b_m.powi(3) * ((a_m + d) / b_m).ln())
        / (6.0 * a_m * b_m)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::robot::hrp4;

    #[test]
    fn a_soles_mean_radius_is_its_points_mean_distance_from_its_centre() {
        for (a, b) in [(0.11, 0.065), (0.1, 0.1), (0.2, 0.01)] {
            let n = 400;
            let mut sum = 0.0;
            for i in 0..n {
                for j in 0..n {
                    let x = a * (2.0 * (i as f64 + 0.5) / n as f64 - 1.0);
                    let y = b * (2.0 * (j as f64 + 0.5) / n as f64 - 1.0);
                    sum += x.hypot(y);
                }
            }
            let grid = sum / (n * n) as f64;
            assert!(
                (mean_radius_m(a, b) - grid).abs() < 1e-5,
                "{a} x {b}: {} against {grid}",
                mean_radius_m(a, b)
            );
        }
    }

    #[test]
    fn a_body_standing_still_has_no_angular_momentum() {
        let m = hrp4::model().unwrap();
        let joints = hrp4::half_sitting_joints(&m).unwrap();
        let q = hrp4::standing_config(&m, &joints, &nalgebra::Isometry3::identity()).unwrap();
        let mut k = crate::robot::Kinematics::new(&m);
        k.update(&q).unwrap();
        assert!(centroidal_angular_momentum(&m, k.link_poses(), k.link_poses(), 0.01).norm() < 1e-12);
    }

    #[test]
    fn the_rates_are_the_momentums_change_over_the_window_horizontal_and_vertical_apart() {
        // A momentum rising steadily at (3, 4, -2) N m for 0.3 s, with a 10 ms step of
        // (50, 0, 50) kg m^2/s in its middle that is taken back 10 ms later.
        let mut r = MomentRates::default();
        let dt = 0.01;
        for k in 0..=30 {
            let t = k as f64 * dt;
            let blip = if k == 15 { Vector3::new(0.5, 0.0, 0.5) } else { Vector3::zeros() };
            r.add(t, Vector3::new(3.0, 4.0, -2.0) * t + blip, 0);
        }
        // Over a window the step adds (5, 0, 5) N m to the steady rate as it comes, (8, 4, 3),
        // and takes it away as it leaves, (-2, 4, -7); over a tick it would be 50 N m.
        assert!((r.max_tipping_nm - 8.0_f64.hypot(4.0)).abs() < 1e-9, "{}", r.max_tipping_nm);
        assert!((r.max_yaw_nm - 7.0).abs() < 1e-9, "{}", r.max_yaw_nm);
        // Nothing before a whole window has passed.
        let mut short = MomentRates::default();
        assert!(short.add(0.0, Vector3::zeros(), 0).is_none());
        assert!(short.add(0.05, Vector3::new(1.0, 1.0, 1.0), 0).is_none());
        assert_eq!((short.max_tipping_nm, short.max_yaw_nm), (0.0, 0.0));
    }

    #[test]
    fn a_windows_rate_names_the_label_its_first_momentum_was_given() {
        let mut r = MomentRates::default();
        let dt = 0.01;
        for k in 0..=30 {
            let got = r.add(k as f64 * dt, Vector3::zeros(), k);
            // The window starts from the newest momentum at least a window old: 10 ticks back.
            assert_eq!(got.map(|(_, first)| first), (k >= 10).then(|| k - 10), "tick {k}");
        }
    }
}
