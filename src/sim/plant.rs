//! The simulated body ([`Plant`]): one draw of a scenario's `[plant]` errors, seeded, as the
//! MJCF's [`BodyVariation`] (masses, centres of mass, inertias, friction, gains, ankle bushes)
//! and the servos' [`Actuation`] (latency and backlash, applied at every physics step by the
//! world). The planner and the stabilizer keep the nominal model; only this body changes.

use crate::robot::mjcf::{AnkleBush, BodyVariation};
use crate::robot::model::RobotModel;
use crate::scenario::PlantErrors;
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::collections::VecDeque;

/// Mixed into the scenario's seed for the plant's draw, so the body's errors do not follow
/// the range noise's draws.
const PLANT_STREAM: u64 = 0x706c_616e_7431;

/// One simulated body.
#[derive(Debug, Clone, PartialEq)]
pub struct Plant {
    /// The errors it was drawn from.
    pub errors: PlantErrors,
    /// The MJCF's differences from the model.
    pub body: BodyVariation,
    /// The servos' delay and play.
    pub actuation: Actuation,
}

/// What stands between the controller's set points and the servos' torques.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Actuation {
    /// Delay of a set point, seconds.
    pub latency_s: f64,
    /// Width of each servo's dead zone, rad.
    pub backlash_rad: f64,
}

impl Plant {
    /// The model's own body.
    pub fn nominal(model: &RobotModel) -> Self {
        Self {
            errors: PlantErrors::NOMINAL,
            body: BodyVariation::nominal(model),
            actuation: Actuation { latency_s: 0.0, backlash_rad: 0.0 },
        }
    }

    /// A body of `model` with `errors`, each link's and servo's error drawn uniformly within
    /// its bound from `seed`.
    pub fn draw(model: &RobotModel, errors: &PlantErrors, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ PLANT_STREAM);
        let mut within = |bound: f64| if bound > 0.0 { rng.random_range(-bound..=bound) } else { 0.0 };
        let links = model.links().len();
        let mass_scale = (0..links).map(|_| 1.0 + within(errors.mass_error)).collect();
        let com_offset_m = (0..links)
            .map(|_| {
                let e = errors.com_error_m;
                Vector3::new(within(e), within(e), within(e))
            })
            .collect();
        let inertia_scale = (0..links).map(|_| 1.0 + within(errors.inertia_error)).collect();
        let gain_scale = (0..model.joints().len()).map(|_| 1.0 + within(errors.servo_gain_error)).collect();
        let ankle_bush = (errors.ankle_stiffness_nm_per_rad > 0.0).then_some(AnkleBush {
            stiffness_nm_per_rad: errors.ankle_stiffness_nm_per_rad,
            damping_nms_per_rad: errors.ankle_damping_nms_per_rad,
        });
        Self {
            errors: *errors,
            body: BodyVariation {
                mass_scale,
                com_offset_m,
                inertia_scale,
                gain_scale,
                joint_friction_nm: errors.joint_friction_nm,
                ankle_bush,
            },
            actuation: Actuation { latency_s: errors.latency_s, backlash_rad: errors.backlash_rad },
        }
    }

    /// The body of `scenario`'s `[plant]`, drawn from its seed.
    pub fn of_scenario(model: &RobotModel, scenario: &crate::scenario::Scenario) -> Self {
        Self::draw(model, &scenario.plant.errors(), scenario.seed)
    }

    /// The body's total mass over the model's.
    pub fn mass_ratio(&self, model: &RobotModel) -> f64 {
        let links = model.links();
        let total: f64 = links.iter().map(|l| l.mass_kg).sum();
        links.iter().zip(&self.body.mass_scale).map(|(l, s)| l.mass_kg * s).sum::<f64>() / total
    }
}

/// The servos' delay line and dead zones, stepped with the physics.
#[derive(Debug, Clone)]
pub struct ServoLine {
    /// Set points sent, oldest first; the front reaches the servos.
    queue: VecDeque<Vec<f64>>,
    /// Physics steps of delay.
    delay_steps: usize,
    half_play_rad: f64,
    /// The joints' angles before the step (read into it, not allocated each step).
    q_rad: Vec<f64>,
}

impl ServoLine {
    /// The line of `a` at physics step `dt_s`, holding `held` (the set points in force).
    pub fn new(a: &Actuation, dt_s: f64, held: &[f64]) -> Self {
        let delay_steps = (a.latency_s / dt_s).round() as usize;
        Self {
            queue: std::iter::repeat_n(held.to_vec(), delay_steps + 1).collect(),
            delay_steps,
            half_play_rad: a.backlash_rad / 2.0,
            q_rad: vec![0.0; held.len()],
        }
    }

    /// The set points the controller sent last.
    pub fn sent(&self) -> &[f64] {
        self.queue.back().map(Vec::as_slice).unwrap_or(&[])
    }

    /// The controller sends `set_points` (they replace the last ones sent this step).
    pub fn send(&mut self, set_points: &[f64]) {
        if let Some(last) = self.queue.back_mut() {
            last.copy_from_slice(set_points);
        }
    }

    /// Reads the joints' angles before a step: joint `a` at `qpos[adr[a]]`.
    pub fn read_joints(&mut self, qpos: &[f64], adr: &[usize]) {
        for (q, &i) in self.q_rad.iter_mut().zip(adr) {
            *q = qpos[i];
        }
    }

    /// Before a physics step (after [`ServoLine::read_joints`]): the set points due reach
    /// the servos as `ctrl`, each moved toward its joint's angle by half the play (within the
    /// play, no torque but damping); then the line advances one step, the last set points
    /// held.
    pub fn apply(&mut self, ctrl: &mut [f64]) {
        let due = &self.queue[0];
        for (a, c) in ctrl.iter_mut().enumerate() {
            let (qa, e) = (self.q_rad[a], due[a] - self.q_rad[a]);
            *c = qa + e.signum() * (e.abs() - self.half_play_rad).max(0.0);
        }
        if self.delay_steps > 0 {
            let last = self.queue.pop_front().unwrap_or_default();
            self.queue.push_back(last);
            let n = self.queue.len();
            let (older, newest) = self.queue.make_contiguous().split_at_mut(n - 1);
            newest[0].copy_from_slice(&older[n - 2]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_set_point_reaches_the_servos_after_the_latency_through_the_play() {
        let a = Actuation { latency_s: 0.003, backlash_rad: 0.01 };
        let mut line = ServoLine::new(&a, 0.001, &[0.0]);
        let mut ctrl = [0.0];
        let mut seen = Vec::new();
        for k in 0..6 {
            line.send(&[if k == 0 { 0.1 } else { line.sent()[0] }]);
            line.read_joints(&[0.0], &[0]);
            line.apply(&mut ctrl);
            seen.push(ctrl[0]);
        }
        // Sent at step 0, due at step 3, less half the play.
        assert_eq!(seen[..3], [0.0, 0.0, 0.0]);
        assert!((seen[3] - 0.095).abs() < 1e-12, "{seen:?}");
        // Within the play of the joint's angle: no error reaches the servo.
        line.read_joints(&[0.097], &[0]);
        line.apply(&mut ctrl);
        assert_eq!(ctrl[0], 0.097);
    }

    #[test]
    fn the_draw_is_seeded_and_within_its_bounds() {
        let model = crate::robot::hrp4::model().unwrap();
        let e = PlantErrors::HRP4_LIKE;
        let (a, b) = (Plant::draw(&model, &e, 3), Plant::draw(&model, &e, 3));
        assert_eq!(a, b);
        assert_ne!(a, Plant::draw(&model, &e, 4));
        assert!(a.body.mass_scale.iter().all(|s| (s - 1.0).abs() <= e.mass_error));
        assert!(a.body.mass_scale.iter().any(|s| (s - 1.0).abs() > e.mass_error / 10.0));
        assert!(a.body.com_offset_m.iter().all(|c| c.amax() <= e.com_error_m));
        assert_eq!(Plant::draw(&model, &PlantErrors::NOMINAL, 3), Plant::nominal(&model));
    }
}
