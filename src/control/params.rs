//! The stabilizer's parameters (`[stabilizer]` of a params file), each with its unit and the
//! source of its default. Defaults follow Caron et al. (ICRA 2019) and hrpsys's foot force
//! difference control, scaled to this bench's stiff position servos.

/// Every parameter of the stabilizer.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct StabilizerParams {
    /// Whether the stabilizer runs (`run --stabilizer on|off`); off executes the planned
    /// q(t) open loop, as the paper did (§6.3).
    pub enabled: bool,
    /// Control rate, Hz: sensors read, wrenches distributed, offsets updated and the QP IK
    /// solved once per tick.
    pub rate_hz: f64,
    /// Gain of the CoM position feedback in the wanted net force, 1/s^2 (Caron 2019's DCM
    /// feedback reduced to the quasi-static case; 0 turns it off).
    pub com_stiffness_per_s2: f64,
    /// Gain of the CoM velocity feedback, 1/s.
    pub com_damping_per_s: f64,
    /// Weight of the net wrench in the distribution QP (it must be met when it can be).
    pub weight_net_wrench: f64,
    /// Weight of the pressure ratio (each foot's share of the normal force, from where the
    /// CoM is between the feet): shifts the weight smoothly before a lift-off and after a
    /// touchdown.
    pub weight_pressure: f64,
    /// Weight of the tangential forces (smaller: more friction margin).
    pub weight_tangential: f64,
    /// Weight of the ankle torques, per N m (smaller: centres of pressure nearer the soles'
    /// centres).
    pub weight_ankle_torque: f64,
    /// Foot damping: ankle roll/pitch rate per N m of torque error, rad/(N m s) (Caron 2019:
    /// 0.01 with HRP-4's own compliance; smaller here, the servos being stiffer).
    pub cop_admittance_rad_per_nm_s: f64,
    /// Largest ankle correction rate, rad/s.
    pub cop_max_rate_rad_s: f64,
    /// Largest ankle correction, rad.
    pub cop_max_rad: f64,
    /// Vertical force difference control: foot height difference rate per newton of
    /// difference error, m/(N s) (mc_rtc's dfz admittance 1e-4; hrpsys's damping 1/3500).
    pub dfz_admittance_m_per_n_s: f64,
    /// Tangential admittance in double support: each sole's horizontal offset rate per
    /// newton of tangential force error, m/(N s). hrpsys uses 1/35000 on HRP-2's compliant
    /// ankles; a leg of this bench's stiff servos resists a sole's sideways shift with about
    /// 8 kN/m, so 1/500 gives the internal force a time constant near 0.06 s, ten control
    /// periods (1/1000 left the touchdown's internal force at 0.41 of the friction cone on
    /// Exp. 1, 1/500 at 0.27).
    pub tangential_admittance_m_per_n_s: f64,
    /// Largest foot offset rate, m/s.
    pub max_offset_rate_m_s: f64,
    /// Largest foot offset (each axis), metres (hrpsys: 0.025).
    pub max_offset_m: f64,
    /// Time constant of the offsets' return to zero, seconds (hrpsys: 1.5).
    pub leak_time_s: f64,
    /// A foot's normal force above which it is in contact, N (touchdown, seek).
    pub contact_force_n: f64,
    /// A swinging foot's normal force from which it has met the ground, N (low, to stop the
    /// descent before the impact builds up; above the force sensor's noise).
    pub touchdown_force_n: f64,
    /// A landed foot's normal force target until it carries `contact_force_n`, at least,
    /// N: between `touchdown_force_n` and `contact_force_n`, so the foot stays on the ground
    /// before the distribution gives it weight (see [`super::admittance::landing`]).
    pub landing_preload_n: f64,
    /// A landed foot's height rate per newton of normal force error until it carries
    /// `contact_force_n`, m/(N s), the rate capped at `approach_speed_m_s`. Default the
    /// default `approach_speed_m_s` over the default `landing_preload_n` (1.67e-3): a foot
    /// that reads nothing goes on down as fast as the approach ends, slowing as the force
    /// comes. A touch can be read in the air (a bounce, or the foot's inertia where the
    /// servos overshoot their set points), and the foot is held there: it must not hang
    /// light while the weight waits for it (test
    /// `a_landed_foot_stays_on_the_ground_until_its_weight_comes`).
    pub landing_admittance_m_per_n_s: f64,
    /// Consecutive ticks the force must stay above `touchdown_force_n`. One tick of force can
    /// be the foot's own inertia where the servos overshoot (what the command shows of it is
    /// taken off by `free_foot_inertia_removed`), but waiting lets the real impacts grow and
    /// the climbs' friction ratios with them (figures in CHANGELOG.md). Default 1.
    pub touchdown_ticks: usize,
    /// Whether a free foot's (swinging or seeking the ground) force reading has the inertia
    /// of its commanded downward acceleration removed
    /// ([`super::measurement::FootSensor::ground_wrench`]).
    /// Left in, a fast descent's start reads as a touch centimetres above the ground: the
    /// foot is held there while the plan moves the CoM onto it (test
    /// `a_free_foots_inertia_is_not_read_as_a_touch`). Default true.
    pub free_foot_inertia_removed: bool,
    /// Fraction of the swing's last piece (the descent) from which a contact stops the foot.
    pub touchdown_window: f64,
    /// Height above its planned landing by which a swinging foot's descent is braked to
    /// `approach_entry_speed_m_s` (`approach_braking_time_s`), and below which it slows
    /// on to `approach_speed_m_s` ([`StabilizerParams::approach_speed_at`]), metres (a
    /// ground a little higher than perceived is met slowly, not at the swing's speed). It
    /// must cover how far below the plan's the sole really hangs, and the servos' lag at
    /// the descent's speed: in a body unlike its model the sole, rolled off the plan's
    /// level, hung about 7.5 mm low at its edge and the servos lagged 3 mm more; begun
    /// 1 cm up, the approach came too late and the edge struck the floor at the swing's
    /// speed (regression `a-sole-hanging-low-struck-at-the-swings-speed`).
    /// The approach's speed falls over it (see `approach_entry_speed_m_s`) to keep its time
    /// short.
    pub approach_height_m: f64,
    /// Descent speed at the planned landing height and below it, m/s: where the approach
    /// ends, and how fast a foot whose swing ends before it meets the ground goes on down
    /// once below it (above it, on down its approach: [`StabilizerParams::approach_speed_at`];
    /// a landed or pressed foot at most this). The servos lag their set points, so when the
    /// sole meets the ground its set point is already below it by this speed times the lag,
    /// and the leg's stiffness pushes that overshoot into the ground along the leg, not
    /// straight down: for a tick or two the landed foot carries 20-35 N normal with up to
    /// 16-30 N tangential: the faster the landing, the larger the climbs' friction ratios
    /// and the likelier a bounce (figures in CHANGELOG.md).
    pub approach_speed_m_s: f64,
    /// Descent speed where the approach begins, `approach_height_m` above the planned
    /// landing, m/s, at least `approach_speed_m_s`; the speed falls linearly with the height
    /// to `approach_speed_m_s` at the planned landing, so a ground where perceived is met at
    /// that speed and the approach takes `h / (v1 - v0) ln(v1 / v0)` (h the approach's
    /// height, v1 this speed, v0 `approach_speed_m_s`; `h / v0` when they are equal). The
    /// approach, the same after the swing's end (the plan waiting for the foot), is time in
    /// single support, in which a soft ankle lets the body roll out
    /// over its sole: approaches of about 0.4 s kept the soft-ankle test's body up, of
    /// 0.5 s and more did not (test
    /// `the_lean_compensation_keeps_a_soft_ankled_body_over_its_sole`). 0.05 m/s: 1.5 cm in
    /// 0.42 s.
    pub approach_entry_speed_m_s: f64,
    /// Time constant with which a swinging foot's descent (and its going on down after its
    /// swing's segment has ended) is brought down to
    /// `approach_entry_speed_m_s` by `approach_height_m` above its planned landing, seconds:
    /// above it the target's speed is capped at `v1 + (h - approach_height_m) / tau` (v1 the
    /// entry speed, h the height above the planned landing, tau this; see
    /// [`StabilizerParams::approach_speed_at`]), so a descent at speed v is braked over
    /// about v tau above the approach, at most v / tau: the braking's distance grows with the
    /// swing's speed, and its time does not. The swing's own time law ends its descent fast;
    /// a cap stepped down to the entry speed within one tick leaves the servos to brake the
    /// foot over the millimetres of their lag, and a sole hanging lower than its model says
    /// meets the floor at the swing's speed (test
    /// `a_fast_swing_is_braked_before_its_approach`, regression
    /// `a-sole-hanging-low-struck-at-the-swings-speed`). Default 0.02 s, about two and a
    /// half times the servos' lag at a swing's speed (figures: CHANGELOG, sixty-third
    /// session).
    /// 0 steps the speed down at `approach_height_m`; between 0 and one control tick
    /// (`1 / rate_hz`) it is refused: a tick's step would carry the target past the
    /// approach's top. The braking reads on the ankle's sensor as a pull of the foot's
    /// mass times it, left in the reading (see the stabilizer's `free_foot_accel_m_s2`): a
    /// ground met while braking reads as a touch that much later.
    pub approach_braking_time_s: f64,
    /// Longest the plan may wait, over a whole plan, for feet that should be down and have
    /// not met the ground yet, seconds (the CoM is held meanwhile).
    pub max_hold_s: f64,
    /// How long a foot held where it touched may read no contact (no touch by the
    /// `touchdown_force_n` rule) before it has carried `contact_force_n` that long, before
    /// the touch is taken for none, seconds. A support of a double support then seeks the
    /// ground from its target's height at the approach's speed there (no faster than
    /// `approach_entry_speed_m_s`) and the plan waits for it as
    /// for a foot whose swing ended in the air (within `max_hold_s`); a swinging foot goes
    /// on down its approach from where it was held. A touch read in the air (the sole's own
    /// inertia as a fast descent begins, when `free_foot_inertia_removed` is off), kept,
    /// holds the foot centimetres up and lowers it at the landing's pace while the plan
    /// moves the CoM onto it, and the robot can fall; let go, it recovers (test
    /// `a_free_foots_inertia_is_not_read_as_a_touch`, at 0.1 s: longer than a landing's
    /// bounces). Opt-in: `inf` (the default) keeps every touch. At 0.1 s it lets go touches
    /// at the default timing too, and the climbs' friction ratios rise (the figures:
    /// CHANGELOG, sixty-first session).
    pub touch_lost_after_s: f64,
    /// Longest the stabilizer holds the plan's last instant after the plan's clock has ended,
    /// for the body to come still (its base no faster than `RunParams::still_speed_m_s` for
    /// `RunParams::still_s`), seconds. The plan ends at rest, the body does not: it lags the
    /// last weight shift, and cut there, its sway goes on under the servos alone and can
    /// slide a sole (regression `a-plan-ending-mid-sway-slid-a-sole`). A real robot's
    /// stabilizer runs on; so does this one, until the body is still. Still is judged as the
    /// stand judges it, on the base's linear speed as the robot's own estimate has it
    /// ([`crate::estimate::still`]; the simulator's where the loop reads the truth).
    pub max_end_hold_s: f64,
    /// How far below its planned height a late foot may seek the ground, metres.
    pub max_seek_m: f64,
    /// Time constant of the IMU's tilt filter, seconds ([`super::attitude::TiltFilter`]):
    /// the gyro carries the tilt over shorter times, the accelerometer sets it over longer.
    /// The climb's own accelerations pull the accelerometer off gravity, the more the
    /// shorter this is: at 2 s the filtered tilt stays within 0.15 deg of MuJoCo's at the
    /// median and 0.75 deg at the 99th percentile over Exp. 1, rigid or on soft ankle bushes
    /// (test `the_stabilizer_reads_the_true_tilt_and_sees_the_lean`, which prints its
    /// figures with `--nocapture`); at 0.5 s it does not.
    /// A gyro bias `b` offsets it by `b` times this: 0.02 deg at a MEMS gyro's 0.01 deg/s.
    pub tilt_filter_time_s: f64,
    /// The tilt filter takes the accelerometer's direction for up only from readings whose
    /// magnitude is within this fraction of gravity's ([`super::attitude::TiltFilter`]). A
    /// quasi-static climb accelerates the base by a few per cent of g; a foot's impact, or
    /// the robot set down at the start, by far more, and its direction then says little of
    /// where up is (test `the_tilt_filter_carries_on_from_plan_to_plan`).
    pub tilt_accel_tolerance: f64,
    /// Lean compensation in single support: the support sole's commanded roll and pitch
    /// change at this rate per radian of the body's lean beyond what the encoders say (the
    /// IMU's, [`super::attitude::TiltFilter::lean`], in the sole's axes), 1/s, within
    /// `cop_max_rate_rad_s` and `cop_max_rad`, leaking back at `leak_time_s` (on top of the
    /// leak every offset has in single support); 0 turns it off. Without it a body on
    /// compliant ankles rolls out over its support sole until the CoM leaves it: the `robust`
    /// suite's softest ankle bush (500 N m/rad) at x 1.33 the quasi-static timing leaned 50 mm
    /// out at lift-off and fell in single support. Default -0.3, by trial on that case at
    /// x 1.33 when it was chosen: -0.15 to -0.5
    /// climbed it; +0.3, +1, +3, -1 and -3 fell at once (test
    /// `the_lean_compensation_keeps_a_soft_ankled_body_over_its_sole`, which holds the sign
    /// and that the body falls without it). Not a setting for every timing: that body falls
    /// with it alone at x 1 to x 1.26 the quasi-static (no rate holds it at every timing);
    /// `lean_washout_gain` holds it there.
    pub lean_follow_rate_per_s: f64,
    /// Sway damping in single support: the support sole's commanded roll and pitch move by
    /// this gain times each change of the lean the encoders do not read
    /// ([`super::attitude::TiltFilter::unseen_lean`], in the sole's axes, low-passed by
    /// `lean_washout_filter_s`), washing out to the plan with time constant
    /// `lean_washout_time_s`: the sole follows the sway, not a lean that stands.
    /// Dimensionless; 0 turns it off. A body on soft ankle bushes sways on them and, with
    /// `lean_follow_rate_per_s` alone, falls at slow timings (test
    /// `the_lean_compensation_keeps_a_soft_ankled_body_over_its_sole`, at 0.15). Default
    /// 0, off: at 0.15 `ci`'s friction tail rises, `robust`'s servo-latency rows lose two
    /// cases (CHANGELOG), and the friction ratio a landing shows is the physics step's chance
    /// (CHANGELOG, sixtieth session).
    pub lean_washout_gain: f64,
    /// Time constant of `lean_washout_gain`'s washout, seconds: the tilt for a lean that
    /// stands decays by 1/e in this time, leaving that lean to `lean_follow_rate_per_s`.
    /// Default 0.75, about a quarter of the soft ankle's sway period (0.35 Hz).
    pub lean_washout_time_s: f64,
    /// Time constant of the low-pass the unseen lean goes through before its changes move
    /// the sole (`lean_washout_gain`), seconds; 0 takes it raw. The sway it damps is slow (a
    /// soft ankle's 0.35 Hz, which 0.03 s delays by 4 deg); under a stiff body the unseen
    /// lean is the simulated contact's own give, which changes within a few physics steps,
    /// and fed back raw it made Exp. 1's figures depend on the step (test
    /// `the_sway_washout_gives_the_figures_of_half_the_physics_step`). Default
    /// [`LEAN_WASHOUT_FILTER_S`].
    pub lean_washout_filter_s: f64,
    /// The wanted net wrench taken about the CoM where the stabilizer estimates it (the
    /// encoders' CoM leaning as the IMU says), not about the plan's reference CoM: the
    /// distribution then asks the soles for the centre of pressure the body's weight puts
    /// where the body is, and the feet's admittance shares that between them instead of
    /// pushing it toward the reference (as lipm_walking_controller's stabilizer takes its
    /// moment about the measured CoM, which there ended a slow sway on robots with more
    /// ankle flexibility). Opt-in (default false): at `--speedup 1.25` regression
    /// `walking-trunk-twisted-off-unseen-space`, whose bowed trunk rocks the stance sole
    /// toward its edges, climbs clean with it and lands a foot off its target without (test
    /// `the_wrench_about_the_estimated_com_lands_the_bowed_trunks_feet`), and another case
    /// fails instead; not every suite is measured with it yet (CHANGELOG, sixty-fourth
    /// session).
    pub wrench_about_estimated_com: bool,
    /// DCM feedback in single support, 1/s (0 turns it off): the support foot's damping
    /// (`cop_admittance_rad_per_nm_s`, in double support only otherwise) moves its sole to
    /// put the centre of pressure at `com_ref + (1 + k / omega) (xi - xi_ref)`
    /// horizontally, `xi = c + v / omega` the divergent component of motion of the
    /// estimated CoM (encoders leaning as the IMU says, its velocity over one tick) and
    /// `xi_ref` the plan's, `omega = sqrt(g / h)` with `h` the reference CoM's height above
    /// the sole (Caron et al. 2019's DCM feedback and foot damping, kept in single support
    /// as lipm_walking_controller keeps them). It damps a sway the single support has no
    /// other hold on: a body on soft ankle bushes sways out over the sole's inner edge and
    /// falls without it (regression `soft-ankles-swayed-off-the-inner-edge`; test
    /// `the_dcm_feedback_holds_the_sway_of_a_soft_ankled_single_support`). Opt-in (default
    /// 0): it trades some of `robust`'s slowest servo-latency rows, and its landings come
    /// later; the figures are in CHANGELOG, sixty-fifth and sixty-sixth sessions.
    pub single_support_dcm_gain_per_s: f64,
}

/// Default `StabilizerParams::lean_washout_filter_s`, seconds: with a gain of 0.15 it holds
/// the soft-ankle fixture at every timing tried and Exp. 1's figures do not depend on the
/// physics step (the tests named at the parameter; the trials in CHANGELOG, fifty-fifth
/// session).
const LEAN_WASHOUT_FILTER_S: f64 = 0.03;
/// Default `StabilizerParams::approach_speed_m_s`, m/s.
const APPROACH_SPEED_M_S: f64 = 0.025;
/// Default `StabilizerParams::landing_preload_n`, N.
const LANDING_PRELOAD_N: f64 = 15.0;

impl Default for StabilizerParams {
    fn default() -> Self {
        Self {
            enabled: true,
            rate_hz: 200.0,
            com_stiffness_per_s2: 0.0,
            com_damping_per_s: 0.0,
            weight_net_wrench: 1.0,
            weight_pressure: 0.1,
            weight_tangential: 1e-3,
            weight_ankle_torque: 1e-2,
            cop_admittance_rad_per_nm_s: 0.005,
            cop_max_rate_rad_s: 0.2,
            cop_max_rad: 0.1,
            dfz_admittance_m_per_n_s: 1.0 / 10000.0,
            tangential_admittance_m_per_n_s: 1.0 / 500.0,
            max_offset_rate_m_s: 0.05,
            max_offset_m: 0.025,
            leak_time_s: 1.5,
            contact_force_n: 30.0,
            touchdown_force_n: 10.0,
            landing_preload_n: LANDING_PRELOAD_N,
            landing_admittance_m_per_n_s: APPROACH_SPEED_M_S / LANDING_PRELOAD_N,
            touchdown_ticks: 1,
            free_foot_inertia_removed: true,
            touchdown_window: 0.0,
            approach_height_m: 0.015,
            approach_speed_m_s: APPROACH_SPEED_M_S,
            approach_entry_speed_m_s: 0.05,
            approach_braking_time_s: 0.02,
            max_hold_s: 2.0,
            touch_lost_after_s: f64::INFINITY,
            max_end_hold_s: 2.0,
            max_seek_m: 0.03,
            tilt_filter_time_s: 2.0,
            tilt_accel_tolerance: 0.1,
            lean_follow_rate_per_s: -0.3,
            lean_washout_gain: 0.0,
            lean_washout_time_s: 0.75,
            lean_washout_filter_s: LEAN_WASHOUT_FILTER_S,
            wrench_about_estimated_com: false,
            single_support_dcm_gain_per_s: 0.0,
        }
    }
}

impl StabilizerParams {
    /// Refuses settings that cannot run, naming the field: approach settings that cannot
    /// land a foot (the speeds finite, the landing speed above zero: a foot that never comes
    /// down waits out `max_hold_s` in the air; the entry speed at least the landing speed;
    /// the height finite and not negative; the braking time 0 or at least one control
    /// tick), and a sway washout whose gain is not finite or
    /// whose time is not a finite time above zero, and a lost touch's time that is not above
    /// zero.
    pub fn validate(&self) -> Result<(), String> {
        // `inf` keeps every touch.
        if self.touch_lost_after_s.is_nan() || self.touch_lost_after_s <= 0.0 {
            return Err(format!(
                "stabilizer.touch_lost_after_s must be a time > 0 (inf: keep every touch), got {}",
                self.touch_lost_after_s
            ));
        }
        if !(self.approach_speed_m_s > 0.0 && self.approach_speed_m_s.is_finite()) {
            return Err(format!(
                "stabilizer.approach_speed_m_s must be a finite speed > 0, got {}",
                self.approach_speed_m_s
            ));
        }
        if !(self.approach_entry_speed_m_s >= self.approach_speed_m_s
            && self.approach_entry_speed_m_s.is_finite())
        {
            return Err(format!(
                "stabilizer.approach_entry_speed_m_s must be finite and at least approach_speed_m_s ({}), got {}",
                self.approach_speed_m_s, self.approach_entry_speed_m_s
            ));
        }
        let tick_s = 1.0 / self.rate_hz;
        let braking_s = self.approach_braking_time_s;
        if !(braking_s == 0.0 || (braking_s >= tick_s && braking_s.is_finite())) {
            return Err(format!(
                "stabilizer.approach_braking_time_s must be 0 (no braking) or a finite time of at least one control tick ({tick_s} s), got {braking_s}"
            ));
        }
        if !(self.approach_height_m >= 0.0 && self.approach_height_m.is_finite()) {
            return Err(format!(
                "stabilizer.approach_height_m must be a finite height >= 0, got {}",
                self.approach_height_m
            ));
        }
        if !self.lean_washout_gain.is_finite() {
            return Err(format!(
                "stabilizer.lean_washout_gain must be finite, got {}",
                self.lean_washout_gain
            ));
        }
        if !(self.lean_washout_time_s > 0.0 && self.lean_washout_time_s.is_finite()) {
            return Err(format!(
                "stabilizer.lean_washout_time_s must be a finite time > 0, got {}",
                self.lean_washout_time_s
            ));
        }
        let dcm_gain = self.single_support_dcm_gain_per_s;
        if !(dcm_gain >= 0.0 && dcm_gain.is_finite()) {
            return Err(format!(
                "stabilizer.single_support_dcm_gain_per_s must be a finite gain >= 0 (0: off), got {dcm_gain}"
            ));
        }
        if !(self.lean_washout_filter_s >= 0.0 && self.lean_washout_filter_s.is_finite()) {
            return Err(format!(
                "stabilizer.lean_washout_filter_s must be a finite time >= 0, got {}",
                self.lean_washout_filter_s
            ));
        }
        Ok(())
    }

    /// The fastest a swinging foot may descend at `height_m` above its planned landing, m/s:
    /// above `approach_height_m`, braking with time constant `approach_braking_time_s` to
    /// `approach_entry_speed_m_s` there (`+inf` when that time is 0); below it, falling
    /// linearly to `approach_speed_m_s` at the landing (and that below it).
    pub fn approach_speed_at(&self, height_m: f64) -> f64 {
        let above_m = height_m - self.approach_height_m;
        if above_m > 0.0 {
            return self.approach_entry_speed_m_s + above_m / self.approach_braking_time_s;
        }
        let share = if self.approach_height_m > 0.0 {
            (height_m / self.approach_height_m).clamp(0.0, 1.0)
        } else {
            0.0
        };
        self.approach_speed_m_s + share * (self.approach_entry_speed_m_s - self.approach_speed_m_s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The approach slows from its entry speed to its landing speed, lands no faster than
    /// `approach_speed_m_s`, and its 1.5 cm (from a swing that would end there) take about
    /// 0.42 s, the single support a soft ankle stands (see `approach_entry_speed_m_s`).
    #[test]
    fn the_approach_slows_to_its_landing_speed_in_about_0_42_s() {
        let p = StabilizerParams::default();
        assert_eq!(p.approach_speed_at(p.approach_height_m), p.approach_entry_speed_m_s);
        let braked = StabilizerParams { approach_braking_time_s: 0.0, ..p.clone() };
        assert_eq!(braked.approach_speed_at(p.approach_height_m + 1e-6), f64::INFINITY);
        assert_eq!(p.approach_speed_at(0.0), p.approach_speed_m_s);
        assert_eq!(p.approach_speed_at(-0.01), p.approach_speed_m_s);
        let (mut z, mut t, dt) = (p.approach_height_m, 0.0, 1e-4);
        let mut last = f64::INFINITY;
        while z > 0.0 {
            let v = p.approach_speed_at(z);
            assert!(v <= last && v >= p.approach_speed_m_s);
            last = v;
            z -= v * dt;
            t += dt;
        }
        let (v0, v1) = (p.approach_speed_m_s, p.approach_entry_speed_m_s);
        let closed = p.approach_height_m / (v1 - v0) * (v1 / v0).ln();
        assert!((t - closed).abs() < 1e-3, "{t} against {closed}");
        assert!((0.40..=0.43).contains(&t), "{t}");
    }

    /// Above the approach, the speed cap brakes with time constant
    /// `approach_braking_time_s` to the entry speed: a swing at speed v is braked from
    /// about v tau above the approach, at most v / tau, whatever v.
    #[test]
    fn a_fast_descent_is_braked_to_the_approachs_entry_speed() {
        let p = StabilizerParams::default();
        let tau = p.approach_braking_time_s;
        for v0 in [0.25, 0.31, 0.5, 1.0] {
            let (mut z, mut v, dt) = (0.2, v0, 1e-5);
            let mut braked_at = None;
            while z > p.approach_height_m {
                let cap = p.approach_speed_at(z);
                if cap < v {
                    braked_at.get_or_insert(z);
                    let a = (v - cap) / dt;
                    assert!(a <= v / tau * 1.001, "{a}");
                    v = cap;
                }
                z -= v * dt;
            }
            let from_m = braked_at.expect("the cap brakes the swing") - p.approach_height_m;
            assert!((v - p.approach_entry_speed_m_s).abs() < 1e-3, "{v}");
            let expected_m = (v0 - p.approach_entry_speed_m_s) * tau;
            assert!((from_m - expected_m).abs() < 1e-4, "from {from_m} against {expected_m}");
        }
    }

    #[test]
    fn approach_settings_that_cannot_land_a_foot_are_refused() {
        assert!(StabilizerParams::default().validate().is_ok());
        let with = |f: fn(&mut StabilizerParams)| {
            let mut p = StabilizerParams::default();
            f(&mut p);
            p.validate()
        };
        assert!(with(|p| p.approach_speed_m_s = 0.0).is_err_and(|e| e.contains("approach_speed_m_s")));
        assert!(with(|p| p.approach_speed_m_s = f64::NAN).is_err());
        assert!(with(|p| p.approach_entry_speed_m_s = 0.01)
            .is_err_and(|e| e.contains("approach_entry_speed_m_s")));
        assert!(with(|p| p.approach_entry_speed_m_s = f64::INFINITY).is_err());
        assert!(with(|p| p.approach_height_m = -0.01).is_err_and(|e| e.contains("approach_height_m")));
        assert!(
            with(|p| p.approach_braking_time_s = -0.01).is_err_and(|e| e.contains("approach_braking_time_s"))
        );
        assert!(with(|p| p.approach_braking_time_s = f64::NAN).is_err());
        assert!(with(|p| p.approach_braking_time_s = f64::INFINITY).is_err());
        assert!(with(|p| p.approach_braking_time_s = 0.0).is_ok());
        assert!(
            with(|p| p.approach_braking_time_s = 0.5 / p.rate_hz).is_err_and(|e| e.contains("control tick"))
        );
        assert!(with(|p| p.approach_braking_time_s = 1.0 / p.rate_hz).is_ok());
        assert!(with(|p| p.approach_entry_speed_m_s = p.approach_speed_m_s).is_ok());
        assert!(with(|p| p.touch_lost_after_s = 0.0).is_err_and(|e| e.contains("touch_lost_after_s")));
        assert!(with(|p| p.touch_lost_after_s = f64::NAN).is_err());
        assert!(with(|p| p.touch_lost_after_s = f64::INFINITY).is_ok());
    }

    #[test]
    fn a_sway_washout_that_cannot_run_is_refused() {
        let with = |gain: f64, time_s: f64| {
            StabilizerParams { lean_washout_gain: gain, lean_washout_time_s: time_s, ..Default::default() }
                .validate()
        };
        assert!(with(0.2, 0.75).is_ok());
        assert!(with(f64::NAN, 0.75).is_err_and(|e| e.contains("lean_washout_gain")));
        assert!(with(0.2, 0.0).is_err_and(|e| e.contains("lean_washout_time_s")));
        assert!(with(0.2, f64::INFINITY).is_err_and(|e| e.contains("lean_washout_time_s")));
        let filtered = |filter_s: f64| {
            StabilizerParams { lean_washout_filter_s: filter_s, ..Default::default() }.validate()
        };
        assert!(filtered(0.0).is_ok());
        assert!(filtered(-0.01).is_err_and(|e| e.contains("lean_washout_filter_s")));
        assert!(filtered(f64::NAN).is_err_and(|e| e.contains("lean_washout_filter_s")));
    }
}
