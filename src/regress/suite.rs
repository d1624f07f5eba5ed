//! Suite files (`scenarios/suites/*.toml`): how `regress` generates its cases. A suite has a
//! seed, a count of cases drawn from `[draw]`, optionally a `[grid]` (every combination of
//! its listed values) and explicit `[[case]]`s. Every key of `[draw]`, a grid or a case is
//! one of [`FIELDS`], given as a value (`rise_m = 0.18`), a list to draw from
//! (`landing_m = [0.0, 1.0]`) or a range (`rise_m = { min = 0.102, max = 0.178 }`).
//! A `[[case]]` may instead be a scenario file whole (`scenario = "dir/name.toml"`, beside
//! the suite; its noise seed is the case's draw 0): an incident kept as it ran.
//! Unknown keys, wrong types, negative sizes and a min above its max are errors naming the
//! field and its line.

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fmt;
use std::path::Path;
use toml_edit::{ImDocument, Item, Value as TomlValue};

/// One drawn value.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Val {
    /// A yes/no.
    Bool(bool),
    /// A count.
    Int(i64),
    /// A length, an angle, a coefficient.
    Float(f64),
    /// A word (a clutter box's place).
    Text(String),
}

impl Val {
    /// The value as a number (booleans and words are not).
    pub fn as_f64(&self) -> Option<f64> {
        match self {
            Val::Int(i) => Some(*i as f64),
            Val::Float(f) => Some(*f),
            _ => None,
        }
    }
}

impl fmt::Display for Val {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Val::Bool(b) => write!(f, "{b}"),
            Val::Int(i) => write!(f, "{i}"),
            Val::Float(x) => write!(f, "{x}"),
            Val::Text(s) => write!(f, "{s}"),
        }
    }
}

/// How a field's value is chosen.
#[derive(Debug, Clone, PartialEq)]
pub enum Dist {
    /// Always this value.
    Value(Val),
    /// One of these, uniformly.
    List(Vec<Val>),
    /// Uniformly in [min, max] (integers inclusive).
    Range {
        /// Lowest.
        min: f64,
        /// Highest.
        max: f64,
    },
}

/// What kind of value a field takes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Kind {
    /// An integer in [lo, hi].
    Int {
        /// Lowest allowed.
        lo: i64,
        /// Highest allowed.
        hi: i64,
    },
    /// A number in [lo, hi].
    Float {
        /// Lowest allowed.
        lo: f64,
        /// Highest allowed.
        hi: f64,
    },
    /// true or false.
    Bool,
    /// One of these words.
    Word(&'static [&'static str]),
}

/// A field a suite can set.
#[derive(Debug, Clone, Copy)]
pub struct Field {
    /// Its key.
    pub key: &'static str,
    /// Its kind and bounds.
    pub kind: Kind,
    /// What it sets.
    pub doc: &'static str,
    /// Its value when the suite does not set it.
    pub default: Default,
}

/// A field's default value.
#[derive(Debug, Clone, Copy)]
pub enum Default {
    /// A number.
    Num(f64),
    /// A yes/no.
    Flag(bool),
    /// A word.
    Word(&'static str),
}

/// Places a clutter box can be drawn in.
pub const PLACES: &[&str] = &["beside", "ahead", "behind"];

/// Every field of a suite, in the order cases draw them (a new field goes at the end, so
/// the draws of the others stay put).
pub const FIELDS: &[Field] = &[
    Field { key: "steps", kind: Kind::Int { lo: 1, hi: 200 }, doc: "steps of the flight", default: Default::Num(4.0) },
    Field { key: "rise_m", kind: Kind::Float { lo: 0.01, hi: 1.0 }, doc: "rise of each step, m", default: Default::Num(0.17) },
    Field { key: "tread_m", kind: Kind::Float { lo: 0.05, hi: 2.0 }, doc: "tread of each step, m", default: Default::Num(0.29) },
    Field { key: "width_m", kind: Kind::Float { lo: 0.1, hi: 5.0 }, doc: "width of the flight, m", default: Default::Num(1.0) },
    Field { key: "yaw_deg", kind: Kind::Float { lo: -180.0, hi: 180.0 }, doc: "direction of ascent in the world, deg", default: Default::Num(0.0) },
    Field { key: "heading_deg", kind: Kind::Float { lo: -90.0, hi: 90.0 }, doc: "the robot's heading relative to the ascent, deg", default: Default::Num(0.0) },
    Field { key: "start_m", kind: Kind::Float { lo: 0.2, hi: 5.0 }, doc: "distance from the robot to the first riser, along the ascent, m", default: Default::Num(0.6) },
    Field { key: "lateral_m", kind: Kind::Float { lo: -2.0, hi: 2.0 }, doc: "the robot's offset from the flight's middle line (left positive), m", default: Default::Num(0.0) },
    Field { key: "landing_m", kind: Kind::Float { lo: 0.0, hi: 3.0 }, doc: "extra depth of the top step, m", default: Default::Num(0.0) },
    Field { key: "friction", kind: Kind::Float { lo: 0.05, hi: 2.0 }, doc: "friction coefficient of the steps", default: Default::Num(0.8) },
    Field { key: "noise_mm", kind: Kind::Float { lo: 0.0, hi: 100.0 }, doc: "lidar range noise sigma, mm", default: Default::Num(10.0) },
    Field { key: "dropout", kind: Kind::Float { lo: 0.0, hi: 0.5 }, doc: "probability a beam returns nothing", default: Default::Num(0.0) },
    Field { key: "boxes", kind: Kind::Int { lo: 0, hi: 10 }, doc: "clutter boxes", default: Default::Num(0.0) },
    Field { key: "box_size_m", kind: Kind::Float { lo: 0.05, hi: 2.0 }, doc: "edge of a clutter box, m", default: Default::Num(0.4) },
    Field { key: "box_place", kind: Kind::Word(PLACES), doc: "where a clutter box goes: beside the flight, on the floor ahead (off the robot's path), behind the robot", default: Default::Word("beside") },
    Field { key: "stairwell", kind: Kind::Bool, doc: "walls along both sides of the flight", default: Default::Flag(false) },
    Field { key: "stairwell_gap_m", kind: Kind::Float { lo: 0.0, hi: 1.0 }, doc: "gap between the flight's sides and the stairwell walls, m", default: Default::Num(0.0) },
    Field { key: "missing_step", kind: Kind::Int { lo: 0, hi: 199 }, doc: "a step left out of the flight (1 = lowest; 0 = none)", default: Default::Num(0.0) },
    Field { key: "blondel_m", kind: Kind::Float { lo: 0.0, hi: 3.0 }, doc: "a constraint, not a field: 2 x rise + tread must lie in this range (a value or a range), else the case is redrawn", default: Default::Num(f64::NAN) },
    Field { key: "nosing_m", kind: Kind::Float { lo: 0.0, hi: 0.1 }, doc: "projection of each tread's nosing past the riser below, m", default: Default::Num(0.0) },
    Field { key: "nosing_thickness_m", kind: Kind::Float { lo: 0.005, hi: 0.1 }, doc: "thickness of the nosing, m", default: Default::Num(0.03) },
    Field { key: "risers", kind: Kind::Word(RISERS), doc: "closed (solid steps) or open (tread slabs with gaps)", default: Default::Word("closed") },
    Field { key: "tread_thickness_m", kind: Kind::Float { lo: 0.01, hi: 0.2 }, doc: "thickness of an open-riser tread slab, m", default: Default::Num(0.04) },
    Field { key: "rise_jitter_m", kind: Kind::Float { lo: 0.0, hi: 0.1 }, doc: "each rise drawn within +/- half this of rise_m (the largest minus the smallest at most this), m", default: Default::Num(0.0) },
    Field { key: "odd_step", kind: Kind::Word(ODD_STEPS), doc: "a step whose rise differs from the others by odd_rise_m: the bottom, the top or none", default: Default::Word("none") },
    Field { key: "odd_rise_m", kind: Kind::Float { lo: -0.1, hi: 0.1 }, doc: "how much the odd step's rise differs (a floor finish, a slab), m", default: Default::Num(0.0) },
    Field { key: "tread_jitter_m", kind: Kind::Float { lo: 0.0, hi: 0.1 }, doc: "each tread drawn within +/- half this of tread_m, m", default: Default::Num(0.0) },
    Field { key: "handrails", kind: Kind::Word(HANDRAILS), doc: "handrails on the flight's sides: none, left, right, both", default: Default::Word("none") },
    Field { key: "handrail_height_m", kind: Kind::Float { lo: 0.5, hi: 1.5 }, doc: "height of a handrail above the nosing line, m", default: Default::Num(0.9) },
    Field { key: "objects", kind: Kind::Int { lo: 0, hi: 5 }, doc: "objects left on the treads", default: Default::Num(0.0) },
    Field { key: "object_kind", kind: Kind::Word(OBJECT_KINDS), doc: "what an object is (its size): shoe, parcel, bag, person", default: Default::Word("parcel") },
    Field { key: "object_place", kind: Kind::Word(OBJECT_PLACES), doc: "where across the tread an object stands: in a foot's lane, at the tread's side, anywhere", default: Default::Word("anywhere") },
    Field { key: "object_step", kind: Kind::Int { lo: 0, hi: 200 }, doc: "the step an object stands on (1 = lowest; 0: any, drawn)", default: Default::Num(0.0) },
    Field { key: "plant", kind: Kind::Word(PLANT_PRESETS), doc: "the simulated body's preset ([plant] preset): nominal (the model exactly) or hrp4-like", default: Default::Word("nominal") },
    Field { key: "mass_error", kind: Kind::Float { lo: 0.0, hi: 0.5 }, doc: "[plant] each link's mass off by up to this fraction (unset: the preset's)", default: Default::Num(f64::NAN) },
    Field { key: "com_error_m", kind: Kind::Float { lo: 0.0, hi: 0.05 }, doc: "[plant] each link's CoM off by up to this along each axis, m (unset: the preset's)", default: Default::Num(f64::NAN) },
    Field { key: "inertia_error", kind: Kind::Float { lo: 0.0, hi: 0.5 }, doc: "[plant] each link's inertia off by up to this fraction (unset: the preset's)", default: Default::Num(f64::NAN) },
    Field { key: "joint_friction_nm", kind: Kind::Float { lo: 0.0, hi: 50.0 }, doc: "[plant] dry friction of every joint, N m (unset: the preset's)", default: Default::Num(f64::NAN) },
    Field { key: "backlash_rad", kind: Kind::Float { lo: 0.0, hi: 0.05 }, doc: "[plant] play of every joint's drive, rad (unset: the preset's)", default: Default::Num(f64::NAN) },
    Field { key: "latency_s", kind: Kind::Float { lo: 0.0, hi: 0.05 }, doc: "[plant] delay from sensing to actuation, s (unset: the preset's)", default: Default::Num(f64::NAN) },
    Field { key: "ankle_stiffness_nm_per_rad", kind: Kind::Float { lo: 0.0, hi: 1.0e6 }, doc: "[plant] stiffness of the bush under each ankle, N m/rad; 0 rigid (unset: the preset's)", default: Default::Num(f64::NAN) },
    Field { key: "ankle_damping_nms_per_rad", kind: Kind::Float { lo: 0.0, hi: 1.0e4 }, doc: "[plant] damping of that bush, N m s/rad (unset: the preset's)", default: Default::Num(f64::NAN) },
    Field { key: "servo_gain_error", kind: Kind::Float { lo: 0.0, hi: 0.5 }, doc: "[plant] each servo's gains off by up to this fraction (unset: the preset's)", default: Default::Num(f64::NAN) },
];

/// The `[plant]` presets a suite can draw.
pub const PLANT_PRESETS: &[&str] = &["nominal", "hrp4-like"];

/// Kinds of risers.
pub const RISERS: &[&str] = &["closed", "open"];
/// Which step's rise differs from the others.
pub const ODD_STEPS: &[&str] = &["none", "bottom", "top"];
/// Sides with a handrail.
pub const HANDRAILS: &[&str] = &["none", "left", "right", "both"];
/// Objects left on treads, each with its size (along, across, height), metres: a shoe, a
/// parcel (a shoe box), a bag, a person standing (shoulders 0.5 m wide, 1.7 m tall).
pub const OBJECT_KINDS: &[&str] = &["shoe", "parcel", "bag", "person"];
/// Where across a tread an object is drawn.
pub const OBJECT_PLACES: &[&str] = &["lane", "side", "anywhere"];

/// The field named `key`.
pub fn field(key: &str) -> Option<&'static Field> {
    FIELDS.iter().find(|f| f.key == key)
}

/// An explicit case of a suite.
#[derive(Debug, Clone, PartialEq)]
pub struct CaseSpec {
    /// Its name (in reports beside its id).
    pub name: String,
    /// Its fields (drawn when given as lists or ranges).
    pub fields: BTreeMap<String, Dist>,
    /// An expectation set by hand (`climb`, `refuse`, `either`), with its reason.
    pub expect: Option<(crate::scenario::ExpectedOutcome, String)>,
    /// A scenario file that is the case whole, its noise seed included (a regression kept
    /// as it happened), instead of fields; relative to the suite file's folder.
    pub scenario: Option<std::path::PathBuf>,
    /// Climb parameters this case runs under, laid over the run's (`regress --params`) as
    /// [`crate::params::ClimbParams::with_overrides`] lays them: an incident that happened
    /// with a setting kept with it (`params = { run = { sweep_while_moving = true } }`).
    pub params: Option<toml::Table>,
}

/// A parsed, checked suite.
#[derive(Debug, Clone)]
pub struct Suite {
    /// Its name (case ids are `<name>-0042`).
    pub name: String,
    /// Seed of every draw.
    pub seed: u64,
    /// Cases drawn from `draw`.
    pub cases: usize,
    /// Noise draws per case when the command line does not say.
    pub seeds: usize,
    /// The distributions of the drawn cases (fields not set take their default).
    pub draw: BTreeMap<String, Dist>,
    /// The grid: every combination of these values (with `draw` for the other fields).
    pub grid: Vec<(String, Vec<Val>)>,
    /// Explicit cases, after the drawn and the grid's.
    pub explicit: Vec<CaseSpec>,
    /// FNV-1a hash of the file's text (shards of one suite must agree on it).
    pub hash: String,
}

/// Why a suite file was refused.
#[derive(Debug, thiserror::Error)]
pub enum SuiteError {
    /// The file could not be read.
    #[error("cannot read suite {path}: {source}")]
    Read {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// The file is wrong at a field.
    #[error("{origin}{}: `{field}`: {reason}", .line.map(|l| format!(":{l}")).unwrap_or_default())]
    Invalid {
        /// The file.
        origin: String,
        /// 1-based line, when known.
        line: Option<usize>,
        /// The field (dotted path).
        field: String,
        /// What is wrong.
        reason: String,
    },
}

/// 64-bit FNV-1a of `bytes`, as 16 hex digits: stable across runs, machines and versions
/// (unlike the standard library's hasher).
pub fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325_u64, |h, &b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3))
}

/// Reads a suite from `text`; `origin` names it in errors, `stem` is its default name.
pub fn parse(text: &str, origin: &str, stem: &str) -> Result<Suite, SuiteError> {
    let doc = ImDocument::parse(text.to_string()).map_err(|e| SuiteError::Invalid {
        origin: origin.into(),
        line: e.span().map(|s| line_of(text, s.start)),
        field: "(file)".into(),
        reason: e.message().trim().to_string(),
    })?;
    let p = Parser { text, origin };
    let mut suite = Suite {
        name: stem.to_string(),
        seed: 0,
        cases: 0,
        seeds: 1,
        draw: BTreeMap::new(),
        grid: Vec::new(),
        explicit: Vec::new(),
        hash: format!("{:016x}", fnv1a(text.as_bytes())),
    };
    for (key, item) in doc.iter() {
        let span = item.span();
        match key {
            "name" => suite.name = p.string(key, item)?,
            "seed" => suite.seed = p.int(key, item, 0, i64::MAX)? as u64,
            "cases" => suite.cases = p.int(key, item, 0, 1_000_000)? as usize,
            "seeds" => suite.seeds = p.int(key, item, 1, 1000)? as usize,
            "draw" => suite.draw = p.fields("draw", item)?,
            "grid" => suite.grid = p.grid(item)?,
            "case" => {
                let Some(cases) = item.as_array_of_tables() else {
                    return Err(p.error("case", span, "must be [[case]] tables"));
                };
                for (i, t) in cases.iter().enumerate() {
                    suite.explicit.push(p.case(i, t)?);
                }
            }
            _ => {
                return Err(p.error(
                    key,
                    doc.key(key).and_then(|k| k.span()).or(span),
                    "unknown key (name, seed, cases, seeds, [draw], [grid], [[case]])",
                ))
            }
        }
    }
    let ok_name = !suite.name.is_empty()
        && suite.name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-');
    if !ok_name {
        return Err(p.error("name", doc.get("name").and_then(Item::span), "letters, digits, _ and - only"));
    }
    if suite.cases == 0 && suite.grid.is_empty() && suite.explicit.is_empty() {
        return Err(p.error("cases", None, "the suite has no case: set cases, a [grid] or [[case]]s"));
    }
    Ok(suite)
}

/// Reads a suite file.
pub fn load(path: &Path) -> Result<Suite, SuiteError> {
    let origin = path.display().to_string();
    let text =
        std::fs::read_to_string(path).map_err(|source| SuiteError::Read { path: origin.clone(), source })?;
    let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let mut suite = parse(&text, &origin, &stem)?;
    // Scenario files are read from beside the suite, and are part of what its hash covers.
    let mut hashed = text.into_bytes();
    for case in &mut suite.explicit {
        if let Some(file) = &mut case.scenario {
            *file = path.parent().unwrap_or(Path::new(".")).join(&*file);
            let body = std::fs::read(&*file)
                .map_err(|source| SuiteError::Read { path: file.display().to_string(), source })?;
            hashed.extend_from_slice(&body);
        }
    }
    suite.hash = format!("{:016x}", fnv1a(&hashed));
    Ok(suite)
}

fn line_of(text: &str, offset: usize) -> usize {
    text[..offset.min(text.len())].bytes().filter(|&b| b == b'\n').count() + 1
}

struct Parser<'a> {
    text: &'a str,
    origin: &'a str,
}

impl Parser<'_> {
    fn error(
        &self,
        field: &str,
        span: Option<std::ops::Range<usize>>,
        reason: impl Into<String>,
    ) -> SuiteError {
        SuiteError::Invalid {
            origin: self.origin.into(),
            line: span.map(|s| line_of(self.text, s.start)),
            field: field.into(),
            reason: reason.into(),
        }
    }

    fn string(&self, key: &str, item: &Item) -> Result<String, SuiteError> {
        item.as_str().map(str::to_string).ok_or_else(|| self.error(key, item.span(), "must be a string"))
    }

    fn int(&self, key: &str, item: &Item, lo: i64, hi: i64) -> Result<i64, SuiteError> {
        match item.as_integer() {
            Some(v) if (lo..=hi).contains(&v) => Ok(v),
            Some(v) => Err(self.error(key, item.span(), format!("{v} is outside {lo}..={hi}"))),
            None => Err(self.error(key, item.span(), "must be an integer")),
        }
    }

    /// One value of field `f` (at `path`).
    fn val(&self, path: &str, f: &Field, v: &TomlValue) -> Result<Val, SuiteError> {
        let bad = |why: String| self.error(path, v.span(), why);
        match f.kind {
            Kind::Int { lo, hi } => match v.as_integer() {
                Some(i) if (lo..=hi).contains(&i) => Ok(Val::Int(i)),
                Some(i) => Err(bad(format!("{i} is outside {lo}..={hi}"))),
                None => Err(bad("must be an integer".into())),
            },
            Kind::Float { lo, hi } => {
                let x = v.as_float().or_else(|| v.as_integer().map(|i| i as f64));
                match x {
                    Some(x) if x.is_finite() && x >= lo && x <= hi => Ok(Val::Float(x)),
                    Some(x) if x < 0.0 && lo >= 0.0 => {
                        Err(bad(format!("{x} is negative: a size or rate must be >= {lo}")))
                    }
                    Some(x) => Err(bad(format!("{x} is outside {lo}..={hi}"))),
                    None => Err(bad("must be a number".into())),
                }
            }
            Kind::Bool => v.as_bool().map(Val::Bool).ok_or_else(|| bad("must be true or false".into())),
            Kind::Word(words) => match v.as_str() {
                Some(w) if words.contains(&w) => Ok(Val::Text(w.into())),
                _ => Err(bad(format!("must be one of {}", words.join(", ")))),
            },
        }
    }

    /// A field's distribution: a value, a list, or `{ min, max }`.
    fn dist(&self, path: &str, f: &Field, item: &Item) -> Result<Dist, SuiteError> {
        if let Some(t) = item.as_table_like() {
            let mut min = None;
            let mut max = None;
            for (k, v) in t.iter() {
                let here = format!("{path}.{k}");
                let Some(value) = v.as_value() else {
                    return Err(self.error(&here, v.span(), "must be a number"));
                };
                match k {
                    "min" => min = Some((self.val(&here, f, value)?, v.span())),
                    "max" => max = Some((self.val(&here, f, value)?, v.span())),
                    _ => {
                        return Err(self.error(
                            &here,
                            v.span().or(item.span()),
                            "a range has only min and max",
                        ))
                    }
                }
            }
            let (Some((lo, _)), Some((hi, hi_span))) = (min, max) else {
                return Err(self.error(path, item.span(), "a range needs both min and max"));
            };
            let (Some(lo), Some(hi)) = (lo.as_f64(), hi.as_f64()) else {
                return Err(self.error(path, item.span(), "only numbers have ranges"));
            };
            if lo > hi {
                return Err(self.error(
                    &format!("{path}.max"),
                    hi_span,
                    format!("max {hi} is below min {lo}"),
                ));
            }
            return Ok(Dist::Range { min: lo, max: hi });
        }
        let Some(v) = item.as_value() else {
            return Err(self.error(path, item.span(), "must be a value, a list or a range"));
        };
        if let Some(list) = v.as_array() {
            if list.is_empty() {
                return Err(self.error(path, v.span(), "an empty list has nothing to draw"));
            }
            let vals = list.iter().map(|x| self.val(path, f, x)).collect::<Result<Vec<_>, _>>()?;
            return Ok(Dist::List(vals));
        }
        Ok(Dist::Value(self.val(path, f, v)?))
    }

    /// The fields of a table (`[draw]`, a `[[case]]`): every key must be one of [`FIELDS`].
    fn fields(&self, table: &str, item: &Item) -> Result<BTreeMap<String, Dist>, SuiteError> {
        let Some(t) = item.as_table_like() else {
            return Err(self.error(table, item.span(), "must be a table"));
        };
        let mut out = BTreeMap::new();
        for (k, v) in t.iter() {
            let path = format!("{table}.{k}");
            let f = field(k).ok_or_else(|| {
                let known: Vec<&str> = FIELDS.iter().map(|f| f.key).collect();
                self.error(
                    &path,
                    t.key(k).and_then(|k| k.span()).or(v.span()),
                    format!("unknown field (fields: {})", known.join(", ")),
                )
            })?;
            out.insert(k.to_string(), self.dist(&path, f, v)?);
        }
        Ok(out)
    }

    fn grid(&self, item: &Item) -> Result<Vec<(String, Vec<Val>)>, SuiteError> {
        let fields = self.fields("grid", item)?;
        let mut out = Vec::new();
        for (k, d) in fields {
            match d {
                Dist::List(v) => out.push((k, v)),
                Dist::Value(v) => out.push((k, vec![v])),
                Dist::Range { .. } => {
                    let span = item.as_table_like().and_then(|t| t.get(&k)).and_then(Item::span);
                    return Err(self.error(&format!("grid.{k}"), span, "a grid lists its values"));
                }
            }
        }
        Ok(out)
    }

    fn case(&self, i: usize, t: &toml_edit::Table) -> Result<CaseSpec, SuiteError> {
        let at = format!("case[{i}]");
        let mut name = format!("case{i}");
        let mut expect = None;
        let mut reason = String::new();
        let mut scenario = None;
        let mut params = None;
        let mut rest = toml_edit::Table::new();
        for (k, v) in t.iter() {
            match k {
                "name" => name = self.string(&format!("{at}.name"), v)?,
                "scenario" => scenario = Some((self.string(&format!("{at}.scenario"), v)?, v.span())),
                "expect" => {
                    let w = self.string(&format!("{at}.expect"), v)?;
                    let outcome: crate::scenario::ExpectedOutcome =
                        serde_json::from_value(serde_json::json!(w)).map_err(|_| {
                            self.error(&format!("{at}.expect"), v.span(), "must be climb, refuse or either")
                        })?;
                    expect = Some(outcome);
                }
                "expect_reason" => reason = self.string(&format!("{at}.expect_reason"), v)?,
                "params" => params = Some(self.params(&format!("{at}.params"), v)?),
                _ => {
                    rest.insert(k, v.clone());
                }
            }
        }
        if let (Some((_, span)), false) = (&scenario, rest.is_empty()) {
            let keys: Vec<&str> = rest.iter().map(|(k, _)| k).collect();
            return Err(self.error(
                &format!("{at}.scenario"),
                span.clone(),
                format!(
                    "a case from a scenario file takes name, expect, expect_reason and params only, not {}",
                    keys.join(", ")
                ),
            ));
        }
        // A scenario file may state its own expect: judged when the file is read
        // (`generate::from_file`).
        if let (Some(p), None, None) = (&params, &expect, &scenario) {
            if sets_gait(p) {
                return Err(self.error(
                    &format!("{at}.params"),
                    t.get("params").and_then(Item::span),
                    "a case that sets its own plan.gait states its expect (the outcome is otherwise drawn from the run's gait limits, not the case's)",
                ));
            }
        }
        let fields = self.fields(&at, &Item::Table(rest))?;
        let scenario = scenario.map(|(path, _)| std::path::PathBuf::from(path));
        Ok(CaseSpec { name, fields, expect: expect.map(|e| (e, reason)), scenario, params })
    }

    /// A case's climb parameters: a table of a parameters file's fields, checked against
    /// the defaults (an unknown field or a broken rule is refused here, before any run).
    fn params(&self, field: &str, item: &Item) -> Result<toml::Table, SuiteError> {
        let mut doc = toml_edit::DocumentMut::new();
        let inline = item.as_value().and_then(toml_edit::Value::as_inline_table);
        if item.as_table().is_none() && inline.is_none() {
            return Err(self.error(
                field,
                item.span(),
                "must be a table of climb parameters, as a --params file holds",
            ));
        }
        doc.insert("p", item.clone());
        let parsed: Result<toml::Table, _> = toml::from_str(&doc.to_string());
        let table = match parsed.map(|mut t| t.remove("p")) {
            Ok(Some(toml::Value::Table(t))) => t,
            Ok(_) => return Err(self.error(field, item.span(), "must be a table of climb parameters")),
            Err(e) => {
                let e = e.to_string().trim().replace('\n', " ");
                return Err(self.error(
                    field,
                    item.span(),
                    format!("must be a table of climb parameters: {e}"),
                ));
            }
        };
        crate::params::ClimbParams::default()
            .with_overrides(&table)
            .map_err(|e| self.error(field, item.span(), format!("not climb parameters: {e}")))?;
        Ok(table)
    }
}

/// Whether a case's climb parameters set the planner's gait limits (`plan.gait`).
pub fn sets_gait(params: &toml::Table) -> bool {
    params.get("plan").and_then(toml::Value::as_table).is_some_and(|plan| plan.contains_key("gait"))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn err(text: &str) -> String {
        parse(text, "s.toml", "s").map(|_| ()).expect_err("refused").to_string()
    }

    #[test]
    fn a_suite_reads_values_lists_ranges_grids_and_cases() {
        let s = parse(
            "seed = 7\ncases = 3\n[draw]\nrise_m = { min = 0.1, max = 0.2 }\nlanding_m = [0.0, 1.0]\nsteps = 4\n\
             [grid]\ntread_m = [0.25, 0.3]\n[[case]]\nname = \"tall\"\nrise_m = 0.24\nexpect = \"climb\"\n",
            "s.toml",
            "mine",
        )
        .expect("valid");
        assert_eq!((s.name.as_str(), s.seed, s.cases, s.seeds), ("mine", 7, 3, 1));
        assert_eq!(s.draw["rise_m"], Dist::Range { min: 0.1, max: 0.2 });
        assert_eq!(s.draw["landing_m"], Dist::List(vec![Val::Float(0.0), Val::Float(1.0)]));
        assert_eq!(s.draw["steps"], Dist::Value(Val::Int(4)));
        assert_eq!(s.grid, vec![("tread_m".to_string(), vec![Val::Float(0.25), Val::Float(0.3)])]);
        assert_eq!(s.explicit[0].name, "tall");
        assert_eq!(s.explicit[0].fields["rise_m"], Dist::Value(Val::Float(0.24)));
    }

    #[test]
    fn wrong_suites_name_the_field_and_its_line() {
        let e = err("cases = 2\n[draw]\nrise_m = { min = 0.2, max = 0.1 }\n");
        assert!(e.contains("s.toml:3") && e.contains("draw.rise_m.max") && e.contains("below min"), "{e}");
        let e = err("cases = 2\n[draw]\n\nwidth_m = -1.0\n");
        assert!(e.contains("s.toml:4") && e.contains("draw.width_m") && e.contains("negative"), "{e}");
        let e = err("cases = 2\n[draw]\nrise = 0.2\n");
        assert!(e.contains("s.toml:3") && e.contains("draw.rise") && e.contains("unknown field"), "{e}");
        let e = err("cases = 2\ncolour = 1\n");
        assert!(e.contains("s.toml:2") && e.contains("colour"), "{e}");
        let e = err("cases = 2\n[draw]\nsteps = 2.5\n");
        assert!(e.contains("draw.steps") && e.contains("integer"), "{e}");
        let e = err("cases = 2\n[draw]\nbox_place = \"on the roof\"\n");
        assert!(e.contains("beside, ahead, behind"), "{e}");
        let e = err("[grid]\nrise_m = { min = 0.1, max = 0.2 }\n");
        assert!(e.contains("grid.rise_m") && e.contains("lists"), "{e}");
        assert!(err("seed = 1\n").contains("no case"));
        // A case from a scenario file is that file whole: no fields beside it.
        let e = err("[[case]]\nname = \"x\"\nscenario = \"a.toml\"\nrise_m = 0.2\n");
        assert!(e.contains("case[0].scenario") && e.contains("rise_m") && e.contains(":3"), "{e}");
        let s = parse("[[case]]\nname = \"x\"\nscenario = \"a.toml\"\nexpect = \"climb\"\n", "s.toml", "s")
            .unwrap();
        assert_eq!(s.explicit[0].scenario.as_deref(), Some(Path::new("a.toml")));
        assert!(err("cases = [").contains("s.toml:1"));
    }

    #[test]
    fn a_case_keeps_the_climb_parameters_it_sets_and_a_wrong_one_is_refused_at_its_line() {
        let inline = "[[case]]\nname = \"w\"\nscenario = \"a.toml\"\nparams = { run = { sweep_while_moving = true } }\n";
        let tables = "[[case]]\nname = \"w\"\nrise_m = 0.2\n[case.params.run]\nsweep_while_moving = true\n\
                      [case.params.plan.ik]\nbody_clearance_m = 0.04\n[[case]]\nname = \"plain\"\nrise_m = 0.2\n";
        let s = parse(inline, "s.toml", "s").unwrap();
        let p = s.explicit[0].params.as_ref().expect("kept");
        assert_eq!(p["run"]["sweep_while_moving"].as_bool(), Some(true));
        let s = parse(tables, "s.toml", "s").unwrap();
        let p = s.explicit[0].params.as_ref().expect("kept");
        assert_eq!(p["run"]["sweep_while_moving"].as_bool(), Some(true));
        assert_eq!(p["plan"]["ik"]["body_clearance_m"].as_float(), Some(0.04));
        assert_eq!(s.explicit[1].params, None, "the next case sets none");
        // Refused before any run: an unknown field, a wrong type, not a table.
        let e =
            err("[[case]]\nname = \"w\"\nrise_m = 0.2\nparams = { run = { sweep_while_movin = true } }\n");
        assert!(
            e.contains("s.toml:4") && e.contains("case[0].params") && e.contains("sweep_while_movin"),
            "{e}"
        );
        let e = err("[[case]]\nname = \"w\"\nrise_m = 0.2\n[case.params.run]\nmax_cycles = \"many\"\n");
        assert!(e.contains("case[0].params") && e.contains("not climb parameters"), "{e}");
        let e = err("[[case]]\nname = \"w\"\nrise_m = 0.2\nparams = 3\n");
        assert!(e.contains("s.toml:4") && e.contains("must be a table"), "{e}");
        // A case's own gait limits would not be the ones its outcome is drawn against: it
        // states its expect, or is refused.
        let gait =
            "[[case]]\nname = \"g\"\nrise_m = 0.2\nparams = { plan = { gait = { max_rise_m = 0.15 } } }\n";
        let e = err(gait);
        assert!(e.contains("s.toml:4") && e.contains("plan.gait") && e.contains("expect"), "{e}");
        let stated =
            gait.replace("rise_m = 0.2\n", "rise_m = 0.2\nexpect = \"refuse\"\nexpect_reason = \"x\"\n");
        assert!(parse(&stated, "s.toml", "s").is_ok(), "with its expect stated it is kept");
    }

    #[test]
    fn the_hash_is_fnv1a() {
        // The published test vectors of 64-bit FNV-1a.
        assert_eq!(fnv1a(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a(b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv1a(b"foobar"), 0x8594_4171_f739_67e8);
    }
}
