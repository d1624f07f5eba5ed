//! The `[plant]` section: how the simulated body differs from the model the planner and the
//! stabilizer use (link masses, centres of mass and inertias, joint friction, backlash,
//! latency from sensing to actuation, servo gains, and a compliant bush between each ankle and
//! its sole). Every error is zero by default (the body is the model, exactly); a preset gives
//! a documented realistic set, and any field set beside it overrides it.

use serde::{Deserialize, Serialize};

/// A named set of plant errors.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum PlantPreset {
    /// The body is the model: every error zero, rigid ankles.
    #[default]
    Nominal,
    /// Errors of the size a real HRP-4 shows against its model; see [`PlantErrors::HRP4_LIKE`].
    Hrp4Like,
}

/// The `[plant]` section as written: a preset and the fields that override it.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PlantSpec {
    /// The set the fields below start from.
    pub preset: PlantPreset,
    /// Each link's mass off by up to this fraction (uniform draw per link), in [0, 0.5].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mass_error: Option<f64>,
    /// Each link's centre of mass off by up to this distance along each axis, metres.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub com_error_m: Option<f64>,
    /// Each link's inertia tensor scaled by up to this fraction, in [0, 0.5].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub inertia_error: Option<f64>,
    /// Dry (Coulomb) friction of every joint, N m.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub joint_friction_nm: Option<f64>,
    /// Play of every joint's drive, rad: the servo's torque acts on its error beyond half of
    /// it on either side (a dead zone of this width).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub backlash_rad: Option<f64>,
    /// Delay from sensing to actuation, seconds: a set point reaches the servos this long
    /// after the controller computed it, in [0, 0.05].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub latency_s: Option<f64>,
    /// Stiffness of the bush between each ankle and its sole, about the sole's pitch and roll
    /// axes, N m/rad; 0 = rigid (no bush).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ankle_stiffness_nm_per_rad: Option<f64>,
    /// Damping of that bush, N m s/rad.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ankle_damping_nms_per_rad: Option<f64>,
    /// Each servo's gains (position and damping) off by up to this fraction, in [0, 0.5].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub servo_gain_error: Option<f64>,
}

/// The plant's errors, resolved (the preset with the file's overrides).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PlantErrors {
    /// See [`PlantSpec::mass_error`].
    pub mass_error: f64,
    /// See [`PlantSpec::com_error_m`].
    pub com_error_m: f64,
    /// See [`PlantSpec::inertia_error`].
    pub inertia_error: f64,
    /// See [`PlantSpec::joint_friction_nm`].
    pub joint_friction_nm: f64,
    /// See [`PlantSpec::backlash_rad`].
    pub backlash_rad: f64,
    /// See [`PlantSpec::latency_s`].
    pub latency_s: f64,
    /// See [`PlantSpec::ankle_stiffness_nm_per_rad`].
    pub ankle_stiffness_nm_per_rad: f64,
    /// See [`PlantSpec::ankle_damping_nms_per_rad`].
    pub ankle_damping_nms_per_rad: f64,
    /// See [`PlantSpec::servo_gain_error`].
    pub servo_gain_error: f64,
}

impl PlantErrors {
    /// The body is the model.
    pub const NOMINAL: Self = Self {
        mass_error: 0.0,
        com_error_m: 0.0,
        inertia_error: 0.0,
        joint_friction_nm: 0.0,
        backlash_rad: 0.0,
        latency_s: 0.0,
        ankle_stiffness_nm_per_rad: 0.0,
        ankle_damping_nms_per_rad: 0.0,
        servo_gain_error: 0.0,
    };

    /// Errors of the size a real HRP-4 shows against its model (estimates, sources in
    /// models/hrp4/README.md, "The plant"): link masses +/-5 % and CoMs +/-1 cm (CAD models
    /// against identified inertial parameters of humanoids), inertias +/-10 %, 1 N m of dry
    /// friction and 1 mrad of play per joint (harmonic drives with belt stages), one 5 ms
    /// control period between sensing and actuation (HRP-4's controller runs at 200 Hz),
    /// servo gains +/-10 %, and rubber bushes of 2,000 N m/rad and 20 N m s/rad between the
    /// ankles and the soles (about 1 degree of deflection for the whole weight 9 cm off the
    /// ankle).
    pub const HRP4_LIKE: Self = Self {
        mass_error: 0.05,
        com_error_m: 0.01,
        inertia_error: 0.10,
        joint_friction_nm: 1.0,
        backlash_rad: 0.001,
        latency_s: 0.005,
        ankle_stiffness_nm_per_rad: 2000.0,
        ankle_damping_nms_per_rad: 20.0,
        servo_gain_error: 0.10,
    };

    /// Whether the body is the model (every error zero, rigid ankles).
    pub fn is_nominal(&self) -> bool {
        *self == Self::NOMINAL
    }

    /// The errors as `name = value` pairs, in the file's field names (for reports).
    pub fn fields(&self) -> [(&'static str, f64); 9] {
        [
            ("mass_error", self.mass_error),
            ("com_error_m", self.com_error_m),
            ("inertia_error", self.inertia_error),
            ("joint_friction_nm", self.joint_friction_nm),
            ("backlash_rad", self.backlash_rad),
            ("latency_s", self.latency_s),
            ("ankle_stiffness_nm_per_rad", self.ankle_stiffness_nm_per_rad),
            ("ankle_damping_nms_per_rad", self.ankle_damping_nms_per_rad),
            ("servo_gain_error", self.servo_gain_error),
        ]
    }
}

impl PlantPreset {
    /// The preset's errors.
    pub fn errors(self) -> PlantErrors {
        match self {
            Self::Nominal => PlantErrors::NOMINAL,
            Self::Hrp4Like => PlantErrors::HRP4_LIKE,
        }
    }
}

impl PlantSpec {
    /// Whether the section is absent or empty (it is then left out of a written scenario).
    pub fn is_nominal_default(&self) -> bool {
        *self == Self::default()
    }

    /// The preset with the fields the file sets in its place.
    pub fn errors(&self) -> PlantErrors {
        let p = self.preset.errors();
        PlantErrors {
            mass_error: self.mass_error.unwrap_or(p.mass_error),
            com_error_m: self.com_error_m.unwrap_or(p.com_error_m),
            inertia_error: self.inertia_error.unwrap_or(p.inertia_error),
            joint_friction_nm: self.joint_friction_nm.unwrap_or(p.joint_friction_nm),
            backlash_rad: self.backlash_rad.unwrap_or(p.backlash_rad),
            latency_s: self.latency_s.unwrap_or(p.latency_s),
            ankle_stiffness_nm_per_rad: self
                .ankle_stiffness_nm_per_rad
                .unwrap_or(p.ankle_stiffness_nm_per_rad),
            ankle_damping_nms_per_rad: self.ankle_damping_nms_per_rad.unwrap_or(p.ankle_damping_nms_per_rad),
            servo_gain_error: self.servo_gain_error.unwrap_or(p.servo_gain_error),
        }
    }

    /// Sets the error named `name` (a field of the file) to `value`; false for no such field.
    pub fn set(&mut self, name: &str, value: f64) -> bool {
        let slot = match name {
            "mass_error" => &mut self.mass_error,
            "com_error_m" => &mut self.com_error_m,
            "inertia_error" => &mut self.inertia_error,
            "joint_friction_nm" => &mut self.joint_friction_nm,
            "backlash_rad" => &mut self.backlash_rad,
            "latency_s" => &mut self.latency_s,
            "ankle_stiffness_nm_per_rad" => &mut self.ankle_stiffness_nm_per_rad,
            "ankle_damping_nms_per_rad" => &mut self.ankle_damping_nms_per_rad,
            "servo_gain_error" => &mut self.servo_gain_error,
            _ => return false,
        };
        *slot = Some(value);
        true
    }

    /// The section with every field written out (for `scene --resolved`).
    pub fn resolved(&self) -> Self {
        let e = self.errors();
        Self {
            preset: self.preset,
            mass_error: Some(e.mass_error),
            com_error_m: Some(e.com_error_m),
            inertia_error: Some(e.inertia_error),
            joint_friction_nm: Some(e.joint_friction_nm),
            backlash_rad: Some(e.backlash_rad),
            latency_s: Some(e.latency_s),
            ankle_stiffness_nm_per_rad: Some(e.ankle_stiffness_nm_per_rad),
            ankle_damping_nms_per_rad: Some(e.ankle_damping_nms_per_rad),
            servo_gain_error: Some(e.servo_gain_error),
        }
    }

    /// Each field out of its range, as (field, reason).
    pub fn issues(&self) -> Vec<(String, String)> {
        let e = self.errors();
        let mut v = Vec::new();
        let fraction = ["mass_error", "inertia_error", "servo_gain_error"];
        for (name, x) in e.fields() {
            let field = format!("plant.{name}");
            if !x.is_finite() || x < 0.0 {
                v.push((field, format!("{x} must be a finite number, 0 or more")));
            } else if fraction.contains(&name) && x > 0.5 {
                v.push((field, format!("{x} is more than 0.5 (a fraction of the model's value)")));
            }
        }
        if e.com_error_m > 0.05 {
            v.push(("plant.com_error_m".into(), format!("{} m is more than 0.05 m", e.com_error_m)));
        }
        if e.latency_s > 0.05 {
            v.push(("plant.latency_s".into(), format!("{} s is more than 0.05 s", e.latency_s)));
        }
        if e.backlash_rad > 0.05 {
            v.push(("plant.backlash_rad".into(), format!("{} rad is more than 0.05 rad", e.backlash_rad)));
        }
        if e.ankle_stiffness_nm_per_rad > 0.0 && e.ankle_stiffness_nm_per_rad < 200.0 {
            v.push((
                "plant.ankle_stiffness_nm_per_rad".into(),
                format!("{} N m/rad is below 200 (0 for rigid ankles)", e.ankle_stiffness_nm_per_rad),
            ));
        }
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_field_set_beside_the_preset_overrides_it() {
        let s: PlantSpec = toml::from_str("preset = \"hrp4-like\"\nlatency_s = 0.0\n").unwrap();
        let e = s.errors();
        assert_eq!(e.latency_s, 0.0);
        assert_eq!(e.mass_error, PlantErrors::HRP4_LIKE.mass_error);
        assert!(PlantSpec::default().errors().is_nominal());
        assert_eq!(s.resolved().errors(), e);
    }

    #[test]
    fn errors_out_of_range_are_named() {
        let s = PlantSpec { mass_error: Some(0.7), latency_s: Some(-0.1), ..Default::default() };
        let fields: Vec<String> = s.issues().into_iter().map(|(f, _)| f).collect();
        assert_eq!(fields, ["plant.mass_error", "plant.latency_s"]);
    }
}
