//! The generator: a suite's cases as scenarios. Case `i` draws its fields from a random
//! stream seeded by (suite seed, `i`) alone, so a case is the same whatever the suite's size
//! or the shard that runs it. A draw the world cannot hold (the flight out of the room or
//! through the ceiling, the robot starting in a step or a box, a box beside the flight that
//! cuts into it) is drawn again from the same stream; the suite counts these redraws. A case
//! from a scenario file is read as it stands.

use super::expect::expect;
use super::suite::{fnv1a, Default as FieldDefault, Dist, Field, Kind, Suite, Val, FIELDS};
use crate::planning::footholds::GaitParams;
use crate::scenario::{
    BoxSpec, ExpectSpec, Handrails, ObjectSpec, PlantErrors, PlantPreset, Risers, Scenario,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::collections::BTreeMap;

/// Most tries to draw a buildable case.
const MAX_TRIES: usize = 1000;
/// Free floor kept around the robot's start and the flight, metres.
const ROOM_MARGIN_M: f64 = 1.0;
/// Half width of the corridor the robot walks to the flight, kept free of clutter, metres.
const CORRIDOR_HALF_M: f64 = 0.4;

/// One generated case.
#[derive(Debug, Clone)]
pub struct Case {
    /// Its id, `<suite>-0042`.
    pub id: String,
    /// Its index in the suite.
    pub index: usize,
    /// The explicit case's name, if it is one.
    pub name: Option<String>,
    /// The value of every field, as drawn.
    pub values: BTreeMap<String, Val>,
    /// Draws the world could not hold before this one.
    pub redraws: usize,
    /// The scenario (its seed is noise draw 0's; its expectation filled in).
    pub scenario: Scenario,
    /// The climb parameters the suite sets for this case, laid over the run's
    /// ([`crate::regress::suite::CaseSpec::params`]).
    pub params: Option<toml::Table>,
}

/// Why a suite's cases could not be generated.
#[derive(Debug, thiserror::Error)]
pub enum GenerateError {
    /// No draw of the case's fields made a world.
    #[error("{id}: no buildable draw in {MAX_TRIES} tries; the last was refused because {reason}")]
    NoDraw {
        /// The case.
        id: String,
        /// Why the last draw was refused.
        reason: String,
    },
    /// The case's scenario file could not be read.
    #[error("{id}: {error}")]
    Scenario {
        /// The case.
        id: String,
        /// What is wrong with the file.
        error: String,
    },
}

/// The robot the expectations are for: the planner's gait limits and where its feet stand.
#[derive(Debug, Clone)]
pub struct Robot {
    /// The planner's declared limits.
    pub gait: GaitParams,
    /// Each sole's distance from the robot's middle line, metres.
    pub feet_half_spacing_m: f64,
}

/// A case index's own random stream.
fn stream(seed: u64, index: usize, salt: u64) -> ChaCha8Rng {
    let mut bytes = seed.to_le_bytes().to_vec();
    bytes.extend_from_slice(&(index as u64).to_le_bytes());
    bytes.extend_from_slice(&salt.to_le_bytes());
    ChaCha8Rng::seed_from_u64(fnv1a(&bytes))
}

/// The salt of a case's stream for the body's (`[plant]`) fields.
const PLANT_SALT: u64 = 0x0050_4c41_4e54;

/// Whether a suite field sets the simulated body (`plant` and the `[plant]` errors).
fn is_plant_field(key: &str) -> bool {
    key == "plant" || PlantErrors::NOMINAL.fields().iter().any(|(name, _)| *name == key)
}

/// The lidar noise seed of noise draw `draw` of case `index` (below 2^63: a TOML integer).
pub fn noise_seed(suite_seed: u64, index: usize, draw: usize) -> u64 {
    stream(suite_seed, index, 1 + draw as u64).random::<u64>() >> 1
}

/// Every case of `suite`, in order: the drawn ones, the grid's, the explicit ones.
pub fn cases(suite: &Suite, robot: &Robot) -> Result<Vec<Case>, GenerateError> {
    let drawn = (0..suite.cases).map(|_| Plan::default());
    let grid = grid_combinations(&suite.grid).into_iter().map(|combo| Plan {
        fixed: combo.into_iter().map(|(k, v)| (k, Dist::Value(v))).collect(),
        ..Plan::default()
    });
    let explicit = suite.explicit.iter().map(|c| Plan {
        name: Some(c.name.clone()),
        fixed: c.fields.clone(),
        by_hand: c.expect.clone(),
        file: c.scenario.clone(),
        params: c.params.clone(),
    });
    drawn
        .chain(grid)
        .chain(explicit)
        .enumerate()
        .map(|(index, plan)| match &plan.file {
            Some(file) => from_file(suite, robot, index, &plan, file),
            None => one(suite, robot, index, &plan),
        })
        .collect()
}

/// What a case starts from: its name, the fields it fixes (or the scenario file that is
/// the case), an expectation set by hand, the climb parameters it sets.
#[derive(Debug, Clone, Default)]
struct Plan {
    name: Option<String>,
    fixed: BTreeMap<String, Dist>,
    by_hand: Option<(crate::scenario::ExpectedOutcome, String)>,
    file: Option<std::path::PathBuf>,
    params: Option<toml::Table>,
}

/// A case's description: its suite, seed and hash, its index and name, and where it came from.
fn description(suite: &Suite, index: usize, name: Option<&str>, from: &str) -> String {
    let name = name.map(|n| format!(" `{n}`")).unwrap_or_default();
    format!("suite {} (seed {}, hash {}), case {index}{name}: {from}", suite.name, suite.seed, suite.hash)
}

/// The expectation set by the suite's hand.
fn by_hand_spec((outcome, why): &(crate::scenario::ExpectedOutcome, String)) -> ExpectSpec {
    ExpectSpec::new(*outcome, format!("set by the suite: {why}"))
}

/// A case that is a scenario file as it stands, its own seed noise draw 0's; its
/// expectation the suite's (with the file's bound on the estimate), else the file's, else
/// the one the ground truth gives.
fn from_file(
    suite: &Suite,
    robot: &Robot,
    index: usize,
    plan: &Plan,
    file: &std::path::Path,
) -> Result<Case, GenerateError> {
    let id = format!("{}-{index:04}", suite.name);
    let mut scenario =
        Scenario::load(file).map_err(|e| GenerateError::Scenario { id: id.clone(), error: e.to_string() })?;
    let expected = match (&plan.by_hand, scenario.expect.take()) {
        (Some(hand), own) => ExpectSpec {
            max_estimate_error_m: own.and_then(|o| o.max_estimate_error_m),
            ..by_hand_spec(hand)
        },
        (None, Some(own)) => own,
        (None, None) if plan.params.as_ref().is_some_and(super::suite::sets_gait) => {
            let error = "its params set plan.gait and neither the suite nor the file states its expect (the outcome is otherwise drawn from the run's gait limits, not the case's)";
            return Err(GenerateError::Scenario { id, error: error.to_string() });
        }
        (None, None) => expect(&scenario, &robot.gait, robot.feet_half_spacing_m),
    };
    scenario.expect = Some(expected);
    scenario.description = description(suite, index, plan.name.as_deref(), &file.display().to_string());
    // The suite fields a file states plainly, for the maps and the reports.
    let st = &scenario.staircase;
    let values = BTreeMap::from([
        ("steps".to_string(), Val::Int(i64::from(st.steps))),
        ("rise_m".to_string(), Val::Float(st.rise_m)),
        ("tread_m".to_string(), Val::Float(st.tread_m)),
        ("width_m".to_string(), Val::Float(st.width_m)),
        ("yaw_deg".to_string(), Val::Float(st.yaw_deg)),
        ("noise_mm".to_string(), Val::Float(scenario.lidar.noise_sigma_m * 1e3)),
        ("nosing_m".to_string(), Val::Float(st.nosing_m)),
    ]);
    Ok(Case { id, index, name: plan.name.clone(), values, redraws: 0, scenario, params: plan.params.clone() })
}

/// Every combination of the grid's values, the first key varying slowest.
fn grid_combinations(grid: &[(String, Vec<Val>)]) -> Vec<Vec<(String, Val)>> {
    if grid.is_empty() {
        return Vec::new();
    }
    grid.iter().fold(vec![Vec::new()], |acc, (k, vals)| {
        acc.iter()
            .flat_map(|prefix| {
                vals.iter().map(move |v| {
                    let mut p = prefix.clone();
                    p.push((k.clone(), v.clone()));
                    p
                })
            })
            .collect()
    })
}

fn one(suite: &Suite, robot: &Robot, index: usize, plan: &Plan) -> Result<Case, GenerateError> {
    let Plan { name, fixed, by_hand, params, .. } = plan;
    let id = format!("{}-{index:04}", suite.name);
    let mut rng = stream(suite.seed, index, 0);
    // The body's fields from their own stream: a suite that gains them keeps its staircases.
    let mut plant_rng = stream(suite.seed, index, PLANT_SALT);
    let mut reason = String::new();
    for redraws in 0..MAX_TRIES {
        let mut values = BTreeMap::new();
        for f in FIELDS.iter().filter(|f| f.key != "blondel_m") {
            let dist = fixed.get(f.key).or_else(|| suite.draw.get(f.key));
            // A field with no default (the body's errors: the preset's) is absent unless set.
            if dist.is_none() && matches!(f.default, FieldDefault::Num(x) if x.is_nan()) {
                continue;
            }
            let rng = if is_plant_field(f.key) { &mut plant_rng } else { &mut rng };
            values.insert(f.key.to_string(), draw(f, dist, rng));
        }
        // The step rule constrains the drawn cases; a grid or an explicit case sets its
        // rise and tread itself, and only its own `blondel_m` applies to it.
        let blondel = match (name.is_some() || !fixed.is_empty(), fixed.get("blondel_m")) {
            (true, own) => own,
            (false, _) => suite.draw.get("blondel_m"),
        };
        match build(&id, &values, blondel, &mut rng) {
            Ok(mut scenario) => {
                scenario.seed = noise_seed(suite.seed, index, 0);
                let expected = match by_hand {
                    Some(hand) => by_hand_spec(hand),
                    None => expect(&scenario, &robot.gait, robot.feet_half_spacing_m),
                };
                scenario.expect = Some(expected);
                scenario.description =
                    description(suite, index, name.as_deref(), &format!("drawn after {redraws} redraws"));
                return Ok(Case {
                    id,
                    index,
                    name: name.clone(),
                    values,
                    redraws,
                    scenario,
                    params: params.clone(),
                });
            }
            Err(why) => reason = why,
        }
    }
    Err(GenerateError::NoDraw { id, reason })
}

/// A value of `f` from `dist` (its default when the suite leaves it out).
fn draw(f: &Field, dist: Option<&Dist>, rng: &mut ChaCha8Rng) -> Val {
    let default = || match f.default {
        FieldDefault::Num(x) => match f.kind {
            Kind::Int { .. } => Val::Int(x as i64),
            _ => Val::Float(x),
        },
        FieldDefault::Flag(b) => Val::Bool(b),
        FieldDefault::Word(w) => Val::Text(w.to_string()),
    };
    match dist {
        None => default(),
        Some(Dist::Value(v)) => v.clone(),
        Some(Dist::List(vals)) => vals[rng.random_range(0..vals.len())].clone(),
        Some(Dist::Range { min, max }) => match f.kind {
            Kind::Int { .. } => Val::Int(rng.random_range(min.round() as i64..=max.round() as i64)),
            _ => Val::Float(min + (max - min) * rng.random::<f64>()),
        },
    }
}

fn num(values: &BTreeMap<String, Val>, key: &str) -> f64 {
    values.get(key).and_then(Val::as_f64).unwrap_or(f64::NAN)
}

/// The scenario of one draw, or why the world cannot hold it.
fn build(
    id: &str,
    v: &BTreeMap<String, Val>,
    blondel: Option<&Dist>,
    rng: &mut ChaCha8Rng,
) -> Result<Scenario, String> {
    let (rise, tread) = (num(v, "rise_m"), num(v, "tread_m"));
    let step_rule = 2.0 * rise + tread;
    let blondel_ok = match blondel {
        None => true,
        Some(Dist::Range { min, max }) => (*min..=*max).contains(&step_rule),
        Some(Dist::Value(x)) => x.as_f64().is_some_and(|x| (step_rule - x).abs() <= 0.01),
        Some(Dist::List(xs)) => xs.iter().filter_map(Val::as_f64).any(|x| (step_rule - x).abs() <= 0.01),
    };
    if !blondel_ok {
        return Err(format!("2 x rise + tread = {step_rule:.3} m is outside blondel_m"));
    }
    let mut s = Scenario { name: id.to_string(), ..Scenario::default() };
    let st = &mut s.staircase;
    st.steps = num(v, "steps") as u32;
    st.rise_m = rise;
    st.tread_m = tread;
    st.width_m = num(v, "width_m");
    st.yaw_deg = num(v, "yaw_deg");
    st.landing_m = num(v, "landing_m");
    st.friction = num(v, "friction");
    let missing = num(v, "missing_step") as u32;
    if missing > 0 {
        st.missing_steps = vec![missing];
    }
    let yaw = st.yaw_rad();
    let (u, w) = ([yaw.cos(), yaw.sin()], [-yaw.sin(), yaw.cos()]);
    // The robot at the origin; the flight's first riser `start_m` ahead along the ascent, its
    // middle line `lateral_m` to the robot's right (the robot is left of it by that much).
    let (start, lateral) = (num(v, "start_m"), num(v, "lateral_m"));
    st.start_m = [u[0] * start - w[0] * lateral, u[1] * start - w[1] * lateral];
    s.robot.position_m = [0.0, 0.0];
    s.robot.yaw_deg = st.yaw_deg + num(v, "heading_deg");
    s.lidar.noise_sigma_m = num(v, "noise_mm") / 1000.0;
    s.lidar.dropout_probability = num(v, "dropout");
    if v.get("plant") == Some(&Val::Text("hrp4-like".into())) {
        s.plant.preset = PlantPreset::Hrp4Like;
    }
    for (name, _) in PlantErrors::NOMINAL.fields() {
        let x = num(v, name);
        if x.is_finite() {
            s.plant.set(name, x);
        }
    }

    let origin = s.staircase.start_m;
    let at = move |a: f64, l: f64| [origin[0] + u[0] * a + w[0] * l, origin[1] + u[1] * a + w[1] * l];
    let (length, half_width, top) = (s.staircase.length_m(), s.staircase.width_m / 2.0, s.staircase.top_m());
    if v.get("stairwell") == Some(&Val::Bool(true)) {
        let gap = num(v, "stairwell_gap_m");
        let height = top + 2.0;
        for (side, name) in [(1.0, "stairwell_left"), (-1.0, "stairwell_right")] {
            let c = at(length / 2.0, side * (half_width + gap + 0.05));
            s.boxes.push(BoxSpec {
                name: name.into(),
                center_m: [c[0], c[1], height / 2.0],
                size_m: [length, 0.1, height],
                yaw_deg: s.staircase.yaw_deg,
            });
        }
    }
    let flight = s.staircase.footprint_m();
    let size = num(v, "box_size_m");
    let place = match v.get("box_place") {
        Some(Val::Text(p)) => p.clone(),
        _ => "beside".into(),
    };
    for k in 0..num(v, "boxes") as usize {
        let side = if rng.random::<bool>() { 1.0 } else { -1.0 };
        let gap = 0.05 + 0.25 * rng.random::<f64>();
        let turn = s.staircase.yaw_deg + 30.0 * (2.0 * rng.random::<f64>() - 1.0);
        let c = match place.as_str() {
            "beside" => at(length * rng.random::<f64>(), side * (half_width + gap + size / 2.0)),
            "ahead" => {
                let a = -start + (start - 0.1) * rng.random::<f64>();
                at(a, lateral + side * (CORRIDOR_HALF_M + gap + size / 2.0))
            }
            _ => at(
                -start - (0.4 + gap + size / 2.0 + 0.8 * rng.random::<f64>()),
                lateral + side * 0.5 * rng.random::<f64>(),
            ),
        };
        let b = BoxSpec {
            name: format!("clutter_{}", k + 1),
            center_m: [c[0], c[1], 0.4 * size],
            size_m: [size, 0.8 * size, 0.8 * size],
            yaw_deg: turn,
        };
        if place != "behind" && overlaps(&box_footprint(&b), &flight) {
            return Err(format!("clutter box {} {place} the flight cuts into it", k + 1));
        }
        if place == "ahead" && overlaps(&box_footprint(&b), &corridor(&s, CORRIDOR_HALF_M)) {
            return Err(format!("clutter box {} ahead stands on the robot's path", k + 1));
        }
        s.boxes.push(b);
    }
    real_features(&mut s, v, rng)?;
    fit_room(&mut s);
    let issues = s.issues();
    match issues.first() {
        Some(i) => Err(format!("`{}` {}", i.field, i.reason)),
        None => Ok(s),
    }
}

fn word<'a>(values: &'a BTreeMap<String, Val>, key: &str, default: &'a str) -> &'a str {
    match values.get(key) {
        Some(Val::Text(w)) => w,
        _ => default,
    }
}

/// Sizes (along, across, height) of the objects a suite can leave on treads, metres: a
/// shoe, a parcel (a shoe box), a bag, a person standing.
fn object_size_m(kind: &str) -> [f64; 3] {
    match kind {
        "shoe" => [0.30, 0.12, 0.11],
        "bag" => [0.35, 0.25, 0.40],
        "person" => [0.30, 0.50, 1.70],
        _ => [0.32, 0.20, 0.12],
    }
}

/// The features of real stairs a suite draws (nosings, open risers, uneven rises and
/// treads, handrails, objects on treads), drawn after everything else so that a suite
/// without them draws exactly as before. Each consumes the case's stream only when on.
fn real_features(s: &mut Scenario, v: &BTreeMap<String, Val>, rng: &mut ChaCha8Rng) -> Result<(), String> {
    let st = &mut s.staircase;
    st.nosing_m = num(v, "nosing_m");
    st.nosing_thickness_m = num(v, "nosing_thickness_m");
    st.tread_thickness_m = num(v, "tread_thickness_m");
    st.risers = if word(v, "risers", "closed") == "open" { Risers::Open } else { Risers::Closed };
    st.handrails = match word(v, "handrails", "none") {
        "left" => Handrails::Left,
        "right" => Handrails::Right,
        "both" => Handrails::Both,
        _ => Handrails::None,
    };
    st.handrail_height_m = num(v, "handrail_height_m");
    let n = st.steps as usize;
    let jitter = num(v, "rise_jitter_m");
    let odd = word(v, "odd_step", "none");
    if jitter > 0.0 || odd != "none" {
        let mut rises: Vec<f64> = (0..n)
            .map(|_| st.rise_m + if jitter > 0.0 { jitter * (rng.random::<f64>() - 0.5) } else { 0.0 })
            .collect();
        match odd {
            "bottom" => rises[0] += num(v, "odd_rise_m"),
            "top" => rises[n - 1] += num(v, "odd_rise_m"),
            _ => {}
        }
        if rises.iter().any(|&r| r <= 0.02) {
            return Err(format!(
                "a rise of {:.3} m is not a step",
                rises.iter().fold(f64::INFINITY, |a, &b| a.min(b))
            ));
        }
        st.rises_m = rises;
    }
    let tread_jitter = num(v, "tread_jitter_m");
    if tread_jitter > 0.0 {
        st.treads_m = (0..n).map(|_| st.tread_m + tread_jitter * (rng.random::<f64>() - 0.5)).collect();
    }
    let kind = word(v, "object_kind", "parcel");
    let place = word(v, "object_place", "anywhere").to_string();
    let size_m = object_size_m(kind);
    let on = num(v, "object_step") as u32;
    for k in 0..num(v, "objects") as usize {
        let step = if on > 0 { on.min(st.steps) } else { rng.random_range(1..=st.steps) };
        let layout = st.layout()[step as usize - 1];
        let depth = layout.going_m + st.nosing_m;
        // A person stands facing down the flight; a thing lies roughly along the tread.
        let turn = if kind == "person" { 0.0 } else { 20.0 * (2.0 * rng.random::<f64>() - 1.0) };
        let (len, wid) = (size_m[0], size_m[1]);
        let half_w = st.width_m / 2.0;
        let free = (half_w - wid / 2.0).max(0.0);
        let across = match place.as_str() {
            "lane" => {
                let side = if rng.random::<bool>() { 1.0 } else { -1.0 };
                side * (0.1 + 0.04 * (2.0 * rng.random::<f64>() - 1.0)).min(free)
            }
            "side" => {
                let side = if rng.random::<bool>() { 1.0 } else { -1.0 };
                side * free
            }
            _ => free * (2.0 * rng.random::<f64>() - 1.0),
        };
        let along = (depth - len.min(depth)) * rng.random::<f64>() + len.min(depth) / 2.0;
        s.objects.push(ObjectSpec {
            name: format!("{kind}_{}", k + 1),
            step,
            along_m: along.min(depth),
            across_m: across,
            size_m,
            yaw_deg: turn,
        });
    }
    Ok(())
}

/// A box's footprint, counter-clockwise.
fn box_footprint(b: &BoxSpec) -> [[f64; 2]; 4] {
    let (c, s) = (b.yaw_deg.to_radians().cos(), b.yaw_deg.to_radians().sin());
    let at = |x: f64, y: f64| [b.center_m[0] + x * c - y * s, b.center_m[1] + x * s + y * c];
    let (hx, hy) = (b.size_m[0] / 2.0, b.size_m[1] / 2.0);
    [at(-hx, -hy), at(hx, -hy), at(hx, hy), at(-hx, hy)]
}

/// The floor the robot walks from its start to the first riser, `half_m` either side.
fn corridor(s: &Scenario, half_m: f64) -> [[f64; 2]; 4] {
    let p = s.robot.position_m;
    let q = s.staircase.start_m;
    let l = ((q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2)).sqrt().max(1e-9);
    let n = [-(q[1] - p[1]) / l * half_m, (q[0] - p[0]) / l * half_m];
    [
        [p[0] - n[0], p[1] - n[1]],
        [q[0] - n[0], q[1] - n[1]],
        [q[0] + n[0], q[1] + n[1]],
        [p[0] + n[0], p[1] + n[1]],
    ]
}

/// Whether two convex quadrilaterals overlap (separating axes).
fn overlaps(a: &[[f64; 2]; 4], b: &[[f64; 2]; 4]) -> bool {
    let separated = |p: &[[f64; 2]; 4], q: &[[f64; 2]; 4]| {
        (0..4).any(|k| {
            let (e0, e1) = (p[k], p[(k + 1) % 4]);
            let n = [e0[1] - e1[1], e1[0] - e0[0]];
            let proj = |r: &[f64; 2]| n[0] * r[0] + n[1] * r[1];
            let (pmin, pmax) =
                p.iter().map(proj).fold((f64::INFINITY, f64::NEG_INFINITY), |m, x| (m.0.min(x), m.1.max(x)));
            let (qmin, qmax) =
                q.iter().map(proj).fold((f64::INFINITY, f64::NEG_INFINITY), |m, x| (m.0.min(x), m.1.max(x)));
            pmax < qmin || qmax < pmin
        })
    };
    !separated(a, b) && !separated(b, a)
}

/// Sizes the room to hold the robot, the flight and every box with free floor around them,
/// and the robot standing on the top step under its ceiling.
fn fit_room(s: &mut Scenario) {
    let mut pts: Vec<[f64; 2]> = s.staircase.footprint_m().to_vec();
    let r = crate::scenario::ROBOT_RADIUS_M;
    let p = s.robot.position_m;
    pts.extend([[p[0] - r, p[1] - r], [p[0] + r, p[1] + r]]);
    for b in &s.boxes {
        pts.extend(box_footprint(b));
    }
    let lo = pts.iter().fold([f64::INFINITY; 2], |m, q| [m[0].min(q[0]), m[1].min(q[1])]);
    let hi = pts.iter().fold([f64::NEG_INFINITY; 2], |m, q| [m[0].max(q[0]), m[1].max(q[1])]);
    let top = s.staircase.top_m() + crate::scenario::ROBOT_HEADROOM_M + 0.5;
    for o in &s.objects {
        pts.extend(o.placed(&s.staircase).0);
    }
    let tallest = s.boxes.iter().map(|b| b.center_m[2] + b.size_m[2] / 2.0 + 0.1).fold(0.0, f64::max);
    let handrail = if s.staircase.handrails == Handrails::None { 0.0 } else { s.staircase.handrail_height_m };
    let tallest = s
        .objects
        .iter()
        .map(|o| o.placed(&s.staircase).1 + o.size_m[2] + 0.1)
        .fold(tallest, f64::max)
        .max(s.staircase.top_m() + handrail + 0.1);
    s.room.center_m = [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0];
    s.room.size_m =
        [hi[0] - lo[0] + 2.0 * ROOM_MARGIN_M, hi[1] - lo[1] + 2.0 * ROOM_MARGIN_M, top.max(tallest).max(3.0)];
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::regress::suite::parse;

    fn robot() -> Robot {
        Robot { gait: GaitParams::default(), feet_half_spacing_m: 0.1013 }
    }

    #[test]
    fn a_case_is_the_same_whatever_the_suite_size_and_redraws_are_counted() {
        let text = |n: usize| {
            format!("seed = 5\ncases = {n}\n[draw]\nsteps = {{ min = 3, max = 6 }}\nrise_m = {{ min = 0.12, max = 0.18 }}\nboxes = {{ min = 0, max = 2 }}\nbox_place = [\"beside\", \"ahead\", \"behind\"]\n")
        };
        let small = cases(&parse(&text(3), "a", "t").expect("valid"), &robot()).expect("drawn");
        let big = cases(&parse(&text(10), "b", "t").expect("valid"), &robot()).expect("drawn");
        for (a, b) in small.iter().zip(&big) {
            assert_eq!(a.values, b.values);
            assert_eq!(a.scenario.staircase, b.scenario.staircase);
        }
        assert_eq!(big.len(), 10);
        assert!(big.iter().all(|c| c.scenario.validate().is_ok()));
        assert!(big.iter().all(|c| c.id.starts_with("t-00")));
    }

    /// A suite that gains the body's fields keeps its staircases and clutter: the body is
    /// drawn from a stream of its own.
    #[test]
    fn drawing_the_body_changes_no_staircase() {
        let base = "seed = 5\ncases = 12\n[draw]\nsteps = { min = 3, max = 6 }\nboxes = { min = 0, max = 2 }\nbox_place = [\"beside\", \"ahead\"]\n";
        let with =
            format!("{base}plant = [\"nominal\", \"hrp4-like\"]\nlatency_s = {{ min = 0.0, max = 0.02 }}\n");
        let a = cases(&parse(base, "a", "t").expect("valid"), &robot()).expect("drawn");
        let b = cases(&parse(&with, "b", "t").expect("valid"), &robot()).expect("drawn");
        let mut bodies = std::collections::BTreeSet::new();
        for (a, b) in a.iter().zip(&b) {
            assert_eq!(a.scenario.staircase, b.scenario.staircase);
            assert_eq!(a.scenario.boxes, b.scenario.boxes);
            assert!(a.scenario.plant.errors().is_nominal());
            bodies.insert(format!("{:?}", b.scenario.plant.preset));
            assert!((0.0..=0.02).contains(&b.scenario.plant.errors().latency_s));
        }
        assert_eq!(bodies.len(), 2, "both presets drawn: {bodies:?}");
    }

    #[test]
    fn an_impossible_suite_is_an_error_naming_the_case_and_why() {
        // 2 x rise + tread = 2.5 m is far beyond any step the default fields draw.
        let s = parse("cases = 1\n[draw]\nblondel_m = 2.5\n", "s", "x").expect("valid");
        let e = cases(&s, &robot()).expect_err("never buildable");
        let GenerateError::NoDraw { id, reason } = &e else { panic!("{e}") };
        assert_eq!(id, "x-0000");
        assert!(reason.contains("blondel"), "{e}");
        // A case from a scenario file that is not there: an error naming the case and file.
        let s = parse("[[case]]\nname = \"gone\"\nscenario = \"no/such.toml\"\n", "s", "x").expect("valid");
        let e = cases(&s, &robot()).expect_err("no file").to_string();
        assert!(e.contains("x-0000") && e.contains("no/such.toml"), "{e}");
    }

    /// A suite's expectation set by hand on a scenario file's case keeps the file's bound on
    /// the estimate (the incident that the bound guards is the file's).
    #[test]
    fn an_expectation_by_hand_keeps_the_files_bound_on_the_estimate() {
        use crate::scenario::{ExpectSpec, ExpectedOutcome, Scenario};
        let file = std::env::temp_dir().join(format!("stairbench-bound-{}.toml", std::process::id()));
        let scenario = Scenario {
            expect: Some(ExpectSpec {
                outcome: ExpectedOutcome::Either,
                reason: "the file's".into(),
                before_step: None,
                max_estimate_error_m: Some(0.025),
            }),
            ..Scenario::default()
        };
        std::fs::write(&file, scenario.to_toml_string().expect("toml")).expect("written");
        let text = format!(
            "[[case]]\nname = \"b\"\nscenario = {:?}\nexpect = \"climb\"\nexpect_reason = \"the suite's\"\n",
            file.display().to_string()
        );
        let c = cases(&parse(&text, "s", "x").expect("valid"), &robot());
        let _ = std::fs::remove_file(&file);
        let e = c.expect("drawn")[0].scenario.expect.clone().expect("an expectation");
        assert_eq!((e.outcome, e.max_estimate_error_m), (ExpectedOutcome::Climb, Some(0.025)));
        assert!(e.reason.contains("the suite's"), "{}", e.reason);
    }

    /// A scenario file's case that sets its own gait limits is judged by the expect the file
    /// or the suite states; with neither it is refused (the run's limits are not the case's).
    #[test]
    fn a_files_case_with_its_own_gait_needs_an_expect_stated() {
        use crate::scenario::{ExpectSpec, ExpectedOutcome, Scenario};
        let dir = std::env::temp_dir();
        let bare = dir.join(format!("stairbench-gait-bare-{}.toml", std::process::id()));
        let stated = dir.join(format!("stairbench-gait-stated-{}.toml", std::process::id()));
        std::fs::write(&bare, Scenario::default().to_toml_string().expect("toml")).expect("written");
        let own = ExpectSpec::new(ExpectedOutcome::Refuse, "the file's".into());
        let with = Scenario { expect: Some(own), ..Scenario::default() };
        std::fs::write(&stated, with.to_toml_string().expect("toml")).expect("written");
        let case = |f: &std::path::Path| {
            let text = format!(
                "[[case]]\nname = \"g\"\nscenario = {:?}\nparams = {{ plan = {{ gait = {{ max_rise_m = 0.15 }} }} }}\n",
                f.display().to_string()
            );
            cases(&parse(&text, "s", "x").expect("valid"), &robot())
        };
        let (refused, kept) = (case(&bare), case(&stated));
        let _ = (std::fs::remove_file(&bare), std::fs::remove_file(&stated));
        let e = refused.expect_err("no expect stated").to_string();
        assert!(e.contains("x-0000") && e.contains("plan.gait"), "{e}");
        let e = kept.expect("the file states its expect")[0].scenario.expect.clone().expect("kept");
        assert_eq!(e.outcome, ExpectedOutcome::Refuse);
    }

    #[test]
    fn grids_give_every_combination_and_expectations_follow_the_limits() {
        let s = parse("[grid]\nrise_m = [0.15, 0.40]\ntread_m = [0.18, 0.30]\n", "g", "g").expect("valid");
        let c = cases(&s, &robot()).expect("drawn");
        assert_eq!(c.len(), 4);
        let outcome = |i: usize| c[i].scenario.expect.as_ref().map(|e| e.outcome);
        use crate::scenario::ExpectedOutcome::*;
        assert_eq!(
            [outcome(0), outcome(1), outcome(2), outcome(3)],
            [Some(Refuse), Some(Climb), Some(Refuse), Some(Refuse)]
        );
    }

    #[test]
    fn clutter_beside_the_flight_never_cuts_into_it() {
        let s = parse(
            "cases = 40\nseed = 3\n[draw]\nboxes = 3\nbox_size_m = { min = 0.3, max = 0.8 }\n",
            "c",
            "c",
        )
        .expect("valid");
        for case in cases(&s, &robot()).expect("drawn") {
            let flight = case.scenario.staircase.footprint_m();
            for b in &case.scenario.boxes {
                assert!(!overlaps(&box_footprint(b), &flight), "{}: {b:?}", case.id);
            }
        }
    }
}
