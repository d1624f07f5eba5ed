//! Scenario files: the TOML that describes one bench case (staircase, clutter, room, lidar,
//! robot start, the simulated body's errors, seed), its defaults (the paper's Exp. 1) and its validation.
//!
//! Units: metres and seconds; angles are in degrees in the file (the user's edge) and are
//! converted with the `*_rad()` accessors. Unknown keys are rejected; every error names the
//! field and, when the file has it, the line.

mod plant;
mod validate;

use serde::{Deserialize, Serialize};
use std::path::Path;

pub use plant::{PlantErrors, PlantPreset, PlantSpec};
pub use validate::{ScenarioError, ROBOT_HEADROOM_M, ROBOT_RADIUS_M};

/// One bench case. Every field has a default; an empty file is the paper's Exp. 1 (§5).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Scenario {
    /// Short name used in reports and output file names.
    pub name: String,
    /// Free text for people.
    pub description: String,
    /// Seed of every random draw of the case (range noise, dropouts).
    pub seed: u64,
    /// The staircase.
    pub staircase: StaircaseSpec,
    /// The room around it (floor, four walls, ceiling).
    pub room: RoomSpec,
    /// Extra boxes: clutter, walls, obstacles.
    pub boxes: Vec<BoxSpec>,
    /// Things left on a tread or on the floor, placed relative to the flight.
    pub objects: Vec<ObjectSpec>,
    /// The robot's start on the floor.
    pub robot: RobotStart,
    /// The tilting lidar.
    pub lidar: LidarSpec,
    /// How the simulated body differs from the robot's model (nothing, by default).
    #[serde(skip_serializing_if = "PlantSpec::is_nominal_default")]
    pub plant: PlantSpec,
    /// What the bench should do with this case, when known (`regress` writes it from the
    /// ground truth and the planner's declared limits; `run` reports its verdict against it).
    pub expect: Option<ExpectSpec>,
}

/// What the bench should do with a case.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ExpectedOutcome {
    /// Climb to the top with no check violated.
    Climb,
    /// Refuse before a foot is set on the staircase (walking closer on the floor is allowed).
    Refuse,
    /// Within perception's tolerance of a declared limit: either of the above passes.
    Either,
}

/// The expected outcome of a case and why.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExpectSpec {
    /// The outcome.
    pub outcome: ExpectedOutcome,
    /// Why (the limit and the value that decide it).
    #[serde(default)]
    pub reason: String,
    /// For `refuse`, and `either`'s refusal: the step (1 = the lowest) no foot may be set on
    /// before refusing; the steps below it may be climbed first (something in or near a lane
    /// on a high tread is seen only from nearer). Absent: a refusal comes before any foot is
    /// on the staircase.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub before_step: Option<u32>,
    /// The most the robot's own estimate of its base may stray from the truth at a sweep,
    /// metres: a run that passed otherwise, its estimate farther off, is `estimate_strayed`
    /// (a misread view taken for drift moves the estimate while the climb still succeeds:
    /// regression `one-tread-dragged-the-estimate-across`). Absent, or without the truth to
    /// judge it by (a real robot): not judged.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_estimate_error_m: Option<f64>,
}

impl ExpectSpec {
    /// `outcome` for `reason`, a refusal before any foot is on the staircase, the estimate not
    /// judged.
    pub fn new(outcome: ExpectedOutcome, reason: String) -> Self {
        Self { outcome, reason, before_step: None, max_estimate_error_m: None }
    }
}

impl Default for Scenario {
    fn default() -> Self {
        Self {
            name: "exp1".into(),
            description: "Paper Exp. 1: 3 steps, 50 cm wide, 20 cm rise, 27 cm tread, 11 x 7 x 3 m room"
                .into(),
            seed: 0,
            staircase: StaircaseSpec::default(),
            room: RoomSpec::default(),
            boxes: Vec::new(),
            objects: Vec::new(),
            robot: RobotStart::default(),
            lidar: LidarSpec::default(),
            plant: PlantSpec::default(),
            expect: None,
        }
    }
}

/// A straight staircase. Its steps are alike unless per-step lists say otherwise; each is a
/// solid block from the floor to its tread (closed risers) or a slab between two stringers
/// (open risers), with an optional nosing. Step `i`'s riser stands at the sum of the treads
/// before it along the ascent, its tread at the sum of the rises up to it; the nosing
/// projects past the riser toward the robot. [`StaircaseSpec::layout`] gives each step's
/// numbers, which the world, the ground truth and the expectations all read.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct StaircaseSpec {
    /// Number of steps (at least 1).
    pub steps: u32,
    /// Height of each step above the previous one, metres (`rises_m` overrides it).
    pub rise_m: f64,
    /// Depth of each tread along the staircase direction, riser to riser (the going),
    /// metres (`treads_m` overrides it).
    pub tread_m: f64,
    /// Each step's own rise, lowest first, metres; empty: every step rises `rise_m`. Real
    /// flights vary: IRC R311.7.5.1 allows 9.5 mm between the largest and smallest rise, and
    /// a floor finish laid later makes the bottom or top rise differ by more.
    pub rises_m: Vec<f64>,
    /// Each step's own tread (riser to riser), lowest first, metres; empty: `tread_m`.
    pub treads_m: Vec<f64>,
    /// Width of the steps across the staircase direction, metres.
    pub width_m: f64,
    /// Direction of ascent in the world, degrees about +z from +x.
    pub yaw_deg: f64,
    /// World (x, y) of the middle of the first step's riser, on the floor, metres (the first
    /// nosing, if any, projects `nosing_m` before it).
    pub start_m: [f64; 2],
    /// Extra depth of the top step (a landing), metres; 0 for none.
    pub landing_m: f64,
    /// Coulomb friction coefficient of the step surfaces (`frictions` overrides it).
    pub friction: f64,
    /// Each step's own friction coefficient, lowest first; empty: `friction`.
    pub frictions: Vec<f64>,
    /// Steps left out of the flight (1 = the lowest; not the top one): the tread before
    /// the gap is followed by one two rises up, as on a stair with a missing step.
    pub missing_steps: Vec<u32>,
    /// How far each tread projects past the riser below it toward the robot, metres (IRC
    /// R311.7.5.3: 19 to 32 mm on solid-riser stairs with treads under 279 mm); 0: none.
    pub nosing_m: f64,
    /// Thickness of the projecting nosing (the tread board's edge), metres.
    pub nosing_thickness_m: f64,
    /// Closed risers (solid steps) or open ones (treads as slabs with a gap between them,
    /// carried by a stringer at each side).
    pub risers: Risers,
    /// Thickness of a tread slab on an open-riser flight, metres.
    pub tread_thickness_m: f64,
    /// Handrails along the flight's sides.
    pub handrails: Handrails,
    /// Height of a handrail's top above the nosing line, metres (IRC R311.7.8.1: 34 to 38 in,
    /// 0.86 to 0.97 m).
    pub handrail_height_m: f64,
    /// Posts (balusters) under a handrail: one on every tread when 1, every other when 2 ...;
    /// 0: one at each end only.
    pub handrail_post_every: u32,
}

/// How the space under each tread is closed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Risers {
    /// Solid steps: each a block from the floor to its tread.
    #[default]
    Closed,
    /// Treads as slabs `tread_thickness_m` thick, open between them, on two side stringers.
    Open,
}

/// Which sides of the flight have a handrail.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Handrails {
    /// No handrail.
    #[default]
    None,
    /// On the left of the ascent.
    Left,
    /// On the right of the ascent.
    Right,
    /// On both sides.
    Both,
}

impl Handrails {
    /// The sides with a rail: +1 left, -1 right.
    pub fn sides(self) -> &'static [f64] {
        match self {
            Handrails::None => &[],
            Handrails::Left => &[1.0],
            Handrails::Right => &[-1.0],
            Handrails::Both => &[1.0, -1.0],
        }
    }
}

impl Default for StaircaseSpec {
    fn default() -> Self {
        Self {
            steps: 3,
            rise_m: 0.20,
            tread_m: 0.27,
            rises_m: Vec::new(),
            treads_m: Vec::new(),
            width_m: 0.50,
            yaw_deg: 0.0,
            start_m: [0.60, 0.0],
            landing_m: 0.0,
            friction: 0.7,
            frictions: Vec::new(),
            missing_steps: Vec::new(),
            nosing_m: 0.0,
            nosing_thickness_m: 0.03,
            risers: Risers::Closed,
            tread_thickness_m: 0.04,
            handrails: Handrails::None,
            handrail_height_m: 0.90,
            handrail_post_every: 1,
        }
    }
}

/// One step of a flight as built (indices from 0 = the lowest).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepLayout {
    /// Its index, 0 for the lowest.
    pub index: usize,
    /// Its rise above the tread below (the floor for the first), metres.
    pub rise_m: f64,
    /// Its tread's height above the floor, metres.
    pub height_m: f64,
    /// Distance along the ascent from the first riser to its riser, metres.
    pub riser_m: f64,
    /// Its tread's depth from its riser to the next riser (with the landing for the top
    /// step), metres; the nosing adds to it in front.
    pub going_m: f64,
    /// Friction coefficient of its surfaces.
    pub friction: f64,
    /// Whether the flight leaves it out (a missing step).
    pub missing: bool,
}

impl StepLayout {
    /// Distance along the ascent from the first riser to its tread's front edge (the nose),
    /// metres.
    pub fn nose_m(&self, nosing_m: f64) -> f64 {
        self.riser_m - nosing_m
    }
}

impl StaircaseSpec {
    /// Direction of ascent, radians.
    pub fn yaw_rad(&self) -> f64 {
        self.yaw_deg.to_radians()
    }

    /// Step `i`'s rise, metres.
    pub fn rise_of(&self, i: usize) -> f64 {
        self.rises_m.get(i).copied().unwrap_or(self.rise_m)
    }

    /// Step `i`'s tread, riser to riser, landing not included, metres.
    pub fn tread_of(&self, i: usize) -> f64 {
        self.treads_m.get(i).copied().unwrap_or(self.tread_m)
    }

    /// Every step of the flight, lowest first, missing ones included (flagged).
    pub fn layout(&self) -> Vec<StepLayout> {
        let n = self.steps as usize;
        let (mut riser_m, mut height_m) = (0.0, 0.0);
        (0..n)
            .map(|i| {
                let rise_m = self.rise_of(i);
                height_m += rise_m;
                let going_m = self.tread_of(i) + if i + 1 == n { self.landing_m } else { 0.0 };
                let step = StepLayout {
                    index: i,
                    rise_m,
                    height_m,
                    riser_m,
                    going_m,
                    friction: self.frictions.get(i).copied().unwrap_or(self.friction),
                    missing: self.missing_steps.contains(&(i as u32 + 1)),
                };
                riser_m += self.tread_of(i);
                step
            })
            .collect()
    }

    /// Length of the flight along its ascent from the first riser, landing included, metres.
    pub fn length_m(&self) -> f64 {
        (0..self.steps as usize).map(|i| self.tread_of(i)).sum::<f64>() + self.landing_m
    }

    /// Height of the top tread, metres.
    pub fn top_m(&self) -> f64 {
        (0..self.steps as usize).map(|i| self.rise_of(i)).sum()
    }

    /// The flight's footprint on the floor, its first nosing included, counter-clockwise
    /// from the first step's front right corner (x, y), metres.
    pub fn footprint_m(&self) -> [[f64; 2]; 4] {
        let (c, s) = (self.yaw_rad().cos(), self.yaw_rad().sin());
        let at = |a: f64, w: f64| [self.start_m[0] + a * c - w * s, self.start_m[1] + a * s + w * c];
        let (l, h) = (self.length_m(), self.width_m / 2.0);
        let front = -self.nosing_m;
        [at(front, -h), at(l, -h), at(l, h), at(front, h)]
    }
}

/// The room: a closed box with the floor at z = 0.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RoomSpec {
    /// Inner size (x, y, z), metres.
    pub size_m: [f64; 3],
    /// World (x, y) of the room's centre, metres.
    pub center_m: [f64; 2],
    /// Whether the four walls exist.
    pub walls: bool,
    /// Whether the ceiling exists.
    pub ceiling: bool,
    /// Friction coefficient of the floor.
    pub floor_friction: f64,
}

impl Default for RoomSpec {
    fn default() -> Self {
        // Exp. 1's room, 11 x 7 x 3 m, with x in [-3, 8] and y in [-3.5, 3.5].
        Self {
            size_m: [11.0, 7.0, 3.0],
            center_m: [2.5, 0.0],
            walls: true,
            ceiling: true,
            floor_friction: 0.8,
        }
    }
}

/// An extra box in the world (clutter, an obstacle, a wall).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BoxSpec {
    /// Name for reports (optional).
    pub name: String,
    /// World position of the box's centre, metres.
    pub center_m: [f64; 3],
    /// Full extents (x, y, z) before the yaw, metres.
    pub size_m: [f64; 3],
    /// Rotation about +z, degrees.
    pub yaw_deg: f64,
}

impl Default for BoxSpec {
    fn default() -> Self {
        Self { name: String::new(), center_m: [0.0, 0.0, 0.1], size_m: [0.2, 0.2, 0.2], yaw_deg: 0.0 }
    }
}

/// Something left on a tread or on the floor (a shoe, a parcel, a bag), a box placed in the
/// flight's frame: along its ascent and across it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ObjectSpec {
    /// Name for reports (optional).
    pub name: String,
    /// The tread it stands on (1 = the lowest step); 0: the floor.
    pub step: u32,
    /// Its centre's distance along the ascent from that tread's front edge (its nose), or on
    /// the floor from the first riser (negative: before it), metres.
    pub along_m: f64,
    /// Its centre's offset across the flight from its middle line, left positive, metres.
    pub across_m: f64,
    /// Full extents (along, across, height) before the yaw, metres.
    pub size_m: [f64; 3],
    /// Rotation about +z from the ascent, degrees.
    pub yaw_deg: f64,
}

impl Default for ObjectSpec {
    fn default() -> Self {
        // A shoe box on the lowest tread, in its middle.
        Self {
            name: String::new(),
            step: 1,
            along_m: 0.15,
            across_m: 0.0,
            size_m: [0.3, 0.2, 0.12],
            yaw_deg: 0.0,
        }
    }
}

impl ObjectSpec {
    /// Its footprint's corners (x, y) and the height of its base, in the world, counter-
    /// clockwise; metres.
    pub fn placed(&self, st: &StaircaseSpec) -> ([[f64; 2]; 4], f64) {
        let (a, base_z_m) = match st.layout().get((self.step as usize).wrapping_sub(1)) {
            Some(step) if self.step > 0 => (step.nose_m(st.nosing_m) + self.along_m, step.height_m),
            _ => (self.along_m, 0.0),
        };
        let yaw = st.yaw_rad();
        let (u, w) = ([yaw.cos(), yaw.sin()], [-yaw.sin(), yaw.cos()]);
        let c = [
            st.start_m[0] + u[0] * a + w[0] * self.across_m,
            st.start_m[1] + u[1] * a + w[1] * self.across_m,
        ];
        let turn = yaw + self.yaw_deg.to_radians();
        let (ct, sn) = (turn.cos(), turn.sin());
        let (hx, hy) = (self.size_m[0] / 2.0, self.size_m[1] / 2.0);
        let at = |x: f64, y: f64| [c[0] + x * ct - y * sn, c[1] + x * sn + y * ct];
        ([at(-hx, -hy), at(hx, -hy), at(hx, hy), at(-hx, hy)], base_z_m)
    }
}

/// Where the robot stands at the start: the floor point midway between its feet.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RobotStart {
    /// World (x, y), metres.
    pub position_m: [f64; 2],
    /// Heading about +z, degrees.
    pub yaw_deg: f64,
}

impl Default for RobotStart {
    fn default() -> Self {
        Self { position_m: [0.0, 0.0], yaw_deg: 0.0 }
    }
}

/// The paper's sensor (§3): a Hokuyo UTM-30LX-EW tilted by a Dynamixel MX-64 on the robot's head.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LidarSpec {
    /// Servo tilt axis origin in the robot's head frame, metres.
    pub mount_xyz_m: [f64; 3],
    /// Servo base orientation in the head frame (roll, pitch, yaw), degrees.
    pub mount_rpy_deg: [f64; 3],
    /// Scanner optical centre from the tilt axis, in the tilted frame, metres (Fig. 2: the
    /// centre of the scanner is off the servo's axis).
    pub axis_to_optical_m: [f64; 3],
    /// Tilt where a sweep taken standing starts, degrees (positive pitches the scan plane
    /// down; a sweep taken walking runs level last, [`crate::sensor::TiltSweep::level_last`]).
    pub tilt_start_deg: f64,
    /// Tilt where a sweep taken standing ends, degrees (§3: a 60 degree sweep).
    pub tilt_end_deg: f64,
    /// Servo speed during the sweep, degrees per second.
    pub tilt_speed_dps: f64,
    /// Servo speed back to where a sweep starts, between two passes, degrees per second: a
    /// head that sweeps as the robot walks casts no row for that long (the hardware head's
    /// `[sweep] return_speed_dps` defaults to it). Default 30, well under the MX-64's
    /// no-load 63 rpm (378 deg/s), gentle on the scanner's mount and cable.
    pub tilt_return_speed_dps: f64,
    /// Servo encoder resolution, ticks per revolution (MX-64: 4096).
    pub servo_ticks_per_rev: u32,
    /// Scanner field of view, degrees (UTM-30LX-EW: 270).
    pub fov_deg: f64,
    /// Angle between beams, degrees (UTM-30LX-EW: 0.25).
    pub resolution_deg: f64,
    /// Time of one mirror revolution, one row, seconds (UTM-30LX-EW: 0.025).
    pub row_period_s: f64,
    /// Shortest range reported, metres.
    pub range_min_m: f64,
    /// Longest range reported, metres.
    pub range_max_m: f64,
    /// Standard deviation of the Gaussian range noise, metres (data sheet: 10 mm repeatability
    /// below 10 m); 0 for none.
    pub noise_sigma_m: f64,
    /// Probability that a beam returns nothing, in [0, 1).
    pub dropout_probability: f64,
}

impl Default for LidarSpec {
    fn default() -> Self {
        Self {
            mount_xyz_m: [0.0, 0.0, 0.07],
            mount_rpy_deg: [0.0, 0.0, 0.0],
            axis_to_optical_m: [0.0, 0.0, 0.035],
            tilt_start_deg: 10.0,
            tilt_end_deg: 70.0,
            tilt_speed_dps: 10.0,
            tilt_return_speed_dps: 30.0,
            servo_ticks_per_rev: 4096,
            fov_deg: 270.0,
            resolution_deg: 0.25,
            row_period_s: 0.025,
            range_min_m: 0.1,
            range_max_m: 30.0,
            noise_sigma_m: 0.01,
            dropout_probability: 0.0,
        }
    }
}

impl Scenario {
    /// Parses and validates a scenario from TOML text; `origin` names the source in errors.
    pub fn from_toml_str(text: &str, origin: &str) -> Result<Self, ScenarioError> {
        let scenario: Scenario =
            toml::from_str(text).map_err(|e| ScenarioError::from_toml(origin, text, &e))?;
        scenario.validate().map_err(|issue| issue.locate(origin, text))?;
        Ok(scenario)
    }

    /// Reads, parses and validates a scenario file. Its name defaults to the file stem.
    pub fn load(path: &Path) -> Result<Self, ScenarioError> {
        let origin = path.display().to_string();
        let text = std::fs::read_to_string(path)
            .map_err(|source| ScenarioError::Read { path: origin.clone(), source })?;
        let mut scenario = Self::from_toml_str(&text, &origin)?;
        if !text_sets_key(&text, "name") {
            if let Some(stem) = path.file_stem() {
                scenario.name = stem.to_string_lossy().into_owned();
            }
        }
        Ok(scenario)
    }

    /// The scenario as TOML (every field, defaults included), for records and `--help` users.
    /// Fails only for a scenario validation refuses (a seed beyond TOML's integers).
    pub fn to_toml_string(&self) -> Result<String, toml::ser::Error> {
        toml::to_string_pretty(self)
    }
}

/// Whether the top-level table of a TOML text sets `key`.
fn text_sets_key(text: &str, key: &str) -> bool {
    toml::from_str::<toml::Table>(text).map(|t| t.contains_key(key)).unwrap_or(false)
}
