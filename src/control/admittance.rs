//! Foot admittance: each foot's reference pose yields to the difference between the wrench
//! its sensor measures and the one the distribution wants (Caron et al. 2019, §IV; hrpsys's
//! foot force difference control). A rate per unit of error, clamped, with a leak back to
//! the plan so that offsets never accumulate. In single support the support sole's roll and
//! pitch also follow the body's lean the IMU sees, at a signed rate (`follow_lean`; a
//! compliant ankle lets the body roll out over the sole), and its sway, washed out
//! (`follow_sway`).

use super::measurement::SoleWrench;
use super::params::StabilizerParams;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

/// A foot's correction to its planned pose: a translation (world) and a roll and pitch about
/// the sole's own axes, at the sole's centre.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct FootOffset {
    /// Translation, metres, world frame.
    pub translation_m: Vector3<f64>,
    /// Rotation about the sole's x, rad.
    pub roll_rad: f64,
    /// Rotation about the sole's y, rad.
    pub pitch_rad: f64,
}

impl FootOffset {
    /// `planned` moved by the offset.
    pub fn apply(&self, planned: &Isometry3<f64>) -> Isometry3<f64> {
        let tilt = UnitQuaternion::from_euler_angles(self.roll_rad, self.pitch_rad, 0.0);
        Isometry3::from_parts(
            Translation3::from(planned.translation.vector + self.translation_m),
            planned.rotation * tilt,
        )
    }

    /// The offset scaled by `s` (0 = none).
    pub fn scaled(&self, s: f64) -> Self {
        Self {
            translation_m: self.translation_m * s,
            roll_rad: self.roll_rad * s,
            pitch_rad: self.pitch_rad * s,
        }
    }
}

/// One step of `x` at rate `rate` (clamped at `max_rate`) with a leak toward 0 of time
/// constant `leak_s`, clamped at `max`.
fn integrate(x: f64, rate: f64, max_rate: f64, max: f64, leak_s: f64, dt_s: f64) -> f64 {
    let rate = rate.clamp(-max_rate, max_rate) - x / leak_s;
    (x + rate * dt_s).clamp(-max, max)
}

/// Foot damping: the ankle rolls and pitches with the torque error about the sole's centre,
/// moving the centre of pressure to where the distribution wants it (a torque above the
/// wanted one means the ground presses that edge too hard: the foot yields to it).
pub fn cop_damping(
    offset: &mut FootOffset,
    measured: &SoleWrench,
    wanted: &SoleWrench,
    p: &StabilizerParams,
    dt_s: f64,
) {
    let a = p.cop_admittance_rad_per_nm_s;
    let e = measured.torque_nm - wanted.torque_nm;
    let step = |x, e: f64| integrate(x, a * e, p.cop_max_rate_rad_s, p.cop_max_rad, p.leak_time_s, dt_s);
    offset.roll_rad = step(offset.roll_rad, e.x);
    offset.pitch_rad = step(offset.pitch_rad, e.y);
}

/// Lean compensation of the support sole in single support: its roll and pitch change at
/// `lean_follow_rate_per_s` times the body's lean `lean_sole_rad` (a rotation vector in the
/// sole's axes: what the IMU sees beyond the encoders), leaking back to the plan.
pub fn follow_lean(offset: &mut FootOffset, lean_sole_rad: &Vector3<f64>, p: &StabilizerParams, dt_s: f64) {
    let g = p.lean_follow_rate_per_s;
    let step =
        |x, lean: f64| integrate(x, g * lean, p.cop_max_rate_rad_s, p.cop_max_rad, p.leak_time_s, dt_s);
    offset.roll_rad = step(offset.roll_rad, lean_sole_rad.x);
    offset.pitch_rad = step(offset.pitch_rad, lean_sole_rad.y);
}

/// A sole's tilt that follows the body's sway, `[roll, pitch]` about the sole's axes, rad:
/// moved by `lean_washout_gain` times the change since the last tick of the lean the
/// encoders do not read (`lean_change_rad`, [`super::attitude::TiltFilter::unseen_lean`], a
/// rotation vector in the sole's axes; zero for a sole not in single
/// support, or whose distribution failed) and decaying by 1/e per `lean_washout_time_s`,
/// within `cop_max_rad` (and with the admittance's offsets, within it too: the stabilizer
/// clamps their sum).
pub fn follow_sway(tilt_rad: &mut [f64; 2], lean_change_rad: &Vector3<f64>, p: &StabilizerParams, dt_s: f64) {
    let washed = (1.0 - dt_s / p.lean_washout_time_s).max(0.0);
    for (t, change) in tilt_rad.iter_mut().zip([lean_change_rad.x, lean_change_rad.y]) {
        *t = (*t * washed + p.lean_washout_gain * change).clamp(-p.cop_max_rad, p.cop_max_rad);
    }
}

/// The unseen lean `unseen_rad` (a rotation vector) low-passed with time constant `filter_s`
/// (0: taken raw): `filtered_rad` moves toward it by one tick of `dt_s`, and that move is
/// returned, the change [`follow_sway`] takes. A lean that changes for a tick and comes back
/// (the contact's give under a stiff body) moves it by `dt_s / (filter_s + dt_s)` of that
/// and back; one that stands is followed whole within a few `filter_s`.
pub fn low_passed_change(
    filtered_rad: &mut Vector3<f64>,
    unseen_rad: &Vector3<f64>,
    filter_s: f64,
    dt_s: f64,
) -> Vector3<f64> {
    let change = (unseen_rad - *filtered_rad) * (dt_s / (filter_s + dt_s));
    *filtered_rad += change;
    change
}

/// Vertical force difference control in double support: the feet's height difference
/// follows the error of their normal force difference (a foot carrying less than wanted
/// goes down, the other up, by the same amount).
pub fn force_difference(
    offsets: &mut [FootOffset; 2],
    measured: [f64; 2],
    wanted: [f64; 2],
    p: &StabilizerParams,
    dt_s: f64,
) {
    let error = (wanted[1] - wanted[0]) - (measured[1] - measured[0]);
    let d = offsets[1].translation_m.z - offsets[0].translation_m.z;
    let next = integrate(
        d,
        -p.dfz_admittance_m_per_n_s * error,
        p.max_offset_rate_m_s,
        p.max_offset_m,
        p.leak_time_s,
        dt_s,
    );
    let mid = (offsets[1].translation_m.z + offsets[0].translation_m.z) / 2.0;
    offsets[0].translation_m.z = mid - next / 2.0;
    offsets[1].translation_m.z = mid + next / 2.0;
}

/// Tangential admittance in double support: each sole's horizontal offset follows its
/// tangential force error (world x, y), relaxing the internal force the closed chain of the
/// two legs builds from any kinematic mismatch.
pub fn tangential(
    offset: &mut FootOffset,
    measured: &Vector3<f64>,
    wanted: &Vector3<f64>,
    p: &StabilizerParams,
    dt_s: f64,
) {
    for k in 0..2 {
        offset.translation_m[k] = integrate(
            offset.translation_m[k],
            p.tangential_admittance_m_per_n_s * (measured[k] - wanted[k]),
            p.max_offset_rate_m_s,
            p.max_offset_m,
            p.leak_time_s,
            dt_s,
        );
    }
}

/// A foot down but lightly loaded in double support (just landed, or about to lift): its
/// normal force and centre of pressure are too small to steer by, but the internal force the
/// two legs' closed chain builds does not wait for the load (24 cm step, seed 9: a landed
/// foot at 40 N normal held 19 N tangential). Its horizontal offset yields to its tangential
/// force error as in [`tangential`]; its height and tilt return to the plan.
pub fn light_contact(
    offset: &mut FootOffset,
    measured: &Vector3<f64>,
    wanted: &Vector3<f64>,
    p: &StabilizerParams,
    dt_s: f64,
) {
    let mut rest = *offset;
    leak(&mut rest, p, dt_s);
    tangential(offset, measured, wanted, p, dt_s);
    offset.translation_m.z = rest.translation_m.z;
    offset.roll_rad = rest.roll_rad;
    offset.pitch_rad = rest.pitch_rad;
}

/// A foot of a double support from its touchdown until it carries `contact_force_n`: its
/// height follows its normal force error (`normal_n`: measured, target), so it is set down
/// and loaded without a second impact. Held where it touched and left to the other laws, a
/// landed foot hovered: the touch was often the foot's own inertia or a brief bounce, it
/// then read 0-7 N for a second while the weight was still on the other foot, and once the
/// distribution wanted its share, [`press`] drove it down at the approach's speed into a
/// second impact (regression `landed-foot-pressed-into-a-second-impact`). The target is at
/// least `landing_preload_n`, so the foot stays down before the weight comes. (The preload
/// makes a straight leg's touchdown strike harder; the plan keeps the leading leg from
/// landing straight, see [`crate::planning::reach`] and regression
/// `leading-leg-landed-straight`.) Its horizontal offset yields to its tangential force
/// error once it touches (as in [`light_contact`]); its tilt returns to the plan.
pub fn landing(
    offset: &mut FootOffset,
    measured: &Vector3<f64>,
    wanted: &Vector3<f64>,
    normal_n: [f64; 2],
    p: &StabilizerParams,
    dt_s: f64,
) {
    let mut rest = *offset;
    leak(&mut rest, p, dt_s);
    if normal_n[0] > p.touchdown_force_n {
        tangential(offset, measured, wanted, p, dt_s);
    } else {
        offset.translation_m.x = rest.translation_m.x;
        offset.translation_m.y = rest.translation_m.y;
    }
    offset.translation_m.z = integrate(
        offset.translation_m.z,
        -p.landing_admittance_m_per_n_s * (normal_n[1] - normal_n[0]),
        p.approach_speed_m_s,
        p.max_seek_m,
        p.leak_time_s,
        dt_s,
    );
    offset.roll_rad = rest.roll_rad;
    offset.pitch_rad = rest.pitch_rad;
}

/// A foot of a double support that should carry some of the weight and reads no contact:
/// its landing was read from a tick of force with the sole still in the air (at x 2 speed,
/// Exp. 1's left foot read 20.5 N for one tick 3 mm above the floor, was held there, and
/// the CoM moved onto it until the robot tipped onto it, 0.2 mm outside its polygon), or it
/// stands on the ground with the other leg holding all the weight (regression
/// `far-step-in-part-and-an-unloaded-foot`). It goes down at the approach's speed
/// (`approach_speed_m_s`, no farther than `max_seek_m` below the plan) to meet the ground;
/// its horizontal offset and tilt return to the plan. A foot that has just landed follows
/// [`landing`] instead until it is loaded.
pub fn press(offset: &mut FootOffset, p: &StabilizerParams, dt_s: f64) {
    let z = offset.translation_m.z;
    leak(offset, p, dt_s);
    offset.translation_m.z = (z - p.approach_speed_m_s * dt_s).max(-p.max_seek_m);
}

/// The offsets' return to zero alone (a foot whose wrench is not controlled this tick).
pub fn leak(offset: &mut FootOffset, p: &StabilizerParams, dt_s: f64) {
    let k = (1.0 - dt_s / p.leak_time_s).max(0.0);
    *offset = offset.scaled(k);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_foot_pressed_on_its_left_edge_rolls_to_unload_it() {
        let p = StabilizerParams::default();
        let mut off = FootOffset::default();
        // CoP at +y: torque about x = y f_z > 0, wanted 0.
        let measured =
            SoleWrench { force_n: Vector3::new(0.0, 0.0, 200.0), torque_nm: Vector3::new(4.0, 0.0, 0.0) };
        cop_damping(&mut off, &measured, &SoleWrench::default(), &p, 0.005);
        let pose = off.apply(&Isometry3::identity());
        // The foot's +y edge goes up.
        assert!((pose * nalgebra::Point3::new(0.0, 0.06, 0.0)).z > 0.0);
    }

    #[test]
    fn the_lighter_foot_goes_down() {
        let p = StabilizerParams::default();
        let mut offs = [FootOffset::default(); 2];
        force_difference(&mut offs, [300.0, 100.0], [200.0, 200.0], &p, 0.005);
        assert!(offs[1].translation_m.z < 0.0 && offs[0].translation_m.z > 0.0);
        assert!((offs[0].translation_m.z + offs[1].translation_m.z).abs() < 1e-15);
    }

    #[test]
    fn an_unloaded_foot_goes_down_at_the_approach_speed_as_far_as_it_may_seek() {
        let p = StabilizerParams::default();
        let mut off = FootOffset { translation_m: Vector3::new(0.01, 0.0, 0.0), ..Default::default() };
        press(&mut off, &p, 0.005);
        assert!((off.translation_m.z + p.approach_speed_m_s * 0.005).abs() < 1e-12);
        assert!(off.translation_m.x < 0.01, "the horizontal offset returns to the plan");
        for _ in 0..10_000 {
            press(&mut off, &p, 0.005);
        }
        assert!((off.translation_m.z + p.max_seek_m).abs() < 1e-12);
    }

    #[test]
    fn a_landed_foot_goes_down_to_its_target_force_and_yields_sideways_once_it_touches() {
        let p = StabilizerParams::default();
        let dt = 0.005;
        let (side, none) = (Vector3::new(20.0, 0.0, 0.0), Vector3::zeros());
        // In the air: down as fast as the approach ends, no sideways yield to noise.
        let mut off = FootOffset::default();
        landing(&mut off, &side, &none, [0.0, p.landing_preload_n], &p, dt);
        let z = off.translation_m.z;
        assert!((-z - p.approach_speed_m_s * dt).abs() < 1e-15, "at the approach's landing speed: {z}");
        assert_eq!(off.translation_m.x, 0.0);
        // Touching but lighter than its target: on down more slowly, yielding to the push.
        let mut touching = FootOffset::default();
        landing(&mut touching, &side, &none, [p.landing_preload_n - 2.0, p.landing_preload_n], &p, dt);
        assert!(touching.translation_m.z < 0.0 && touching.translation_m.z > z);
        assert!(touching.translation_m.x > 0.0, "yields along the measured tangential force");
        // Heavier than its target: up.
        let mut heavy = FootOffset::default();
        landing(&mut heavy, &none, &none, [40.0, p.landing_preload_n], &p, dt);
        assert!(heavy.translation_m.z > 0.0);
        // Never farther down than a late foot may seek.
        for _ in 0..100_000 {
            landing(&mut off, &none, &none, [0.0, p.landing_preload_n], &p, dt);
        }
        assert!(off.translation_m.z >= -p.max_seek_m - 1e-12);
    }

    /// A lean that changes for one tick and comes back moves the low-passed lean by a share
    /// of it and back, where taken raw it moves the sole by all of it and back; a lean that
    /// stands is followed whole within a few time constants.
    #[test]
    fn the_sway_follows_a_lean_that_stands_not_a_ticks_transient() {
        let (dt, filter_s) = (0.005, 0.03);
        let step = Vector3::new(0.01, -0.02, 0.0);
        let (mut raw, mut filtered) = (Vector3::zeros(), Vector3::zeros());
        let (mut raw_most, mut filtered_most) = (0.0f64, 0.0f64);
        for lean in [step, Vector3::zeros(), Vector3::zeros()] {
            low_passed_change(&mut raw, &lean, 0.0, dt);
            low_passed_change(&mut filtered, &lean, filter_s, dt);
            raw_most = raw_most.max(raw.norm());
            filtered_most = filtered_most.max(filtered.norm());
        }
        assert!(raw.norm() < 1e-15 && filtered.norm() < filtered_most, "both come back");
        assert!((raw_most - step.norm()).abs() < 1e-15, "raw: the whole transient, {raw_most}");
        let share = dt / (filter_s + dt);
        assert!((filtered_most - share * step.norm()).abs() < 1e-15, "filtered: {filtered_most}");
        // A lean that stands: its changes sum to it, within 1 % after five time constants.
        let (mut filtered, mut followed) = (Vector3::zeros(), Vector3::zeros());
        for _ in 0..(5.0 * filter_s / dt).ceil() as usize {
            followed += low_passed_change(&mut filtered, &step, filter_s, dt);
        }
        assert!((followed - step).norm() < 0.01 * step.norm(), "{followed} against {step}");
        assert_eq!(followed, filtered);
    }

    #[test]
    fn offsets_stay_within_their_travel() {
        let p = StabilizerParams::default();
        let mut off = FootOffset::default();
        for _ in 0..100_000 {
            tangential(&mut off, &Vector3::new(1e6, -1e6, 0.0), &Vector3::zeros(), &p, 0.005);
        }
        assert!(off.translation_m.x <= p.max_offset_m && off.translation_m.y >= -p.max_offset_m);
    }
}
