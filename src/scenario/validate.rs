//! Validation of a parsed scenario, and the errors that name the offending field and line.

use super::Scenario;

/// Why a scenario file was refused.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    /// The file could not be read.
    #[error("cannot read scenario {path}: {source}")]
    Read {
        /// The file's path.
        path: String,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The file is not valid TOML, has an unknown key, or a value of the wrong type.
    #[error("{origin}{}: {message}", line_suffix(*line))]
    Syntax {
        /// The file's name.
        origin: String,
        /// 1-based line, when known.
        line: Option<usize>,
        /// What the parser said.
        message: String,
    },
    /// A value is out of its valid range.
    #[error("{origin}{}: invalid `{field}`: {reason}", line_suffix(*line))]
    Invalid {
        /// The file's name.
        origin: String,
        /// 1-based line, when the file sets the field.
        line: Option<usize>,
        /// Dotted path of the field, e.g. `staircase.rise_m`.
        field: String,
        /// What is wrong with it.
        reason: String,
    },
}

fn line_suffix(line: Option<usize>) -> String {
    line.map(|l| format!(":{l}")).unwrap_or_default()
}

/// A field that failed validation, before its line is known.
#[derive(Debug, Clone, PartialEq)]
pub struct Issue {
    /// Dotted path, with `[i]` for array entries (`boxes[0].size_m`).
    pub field: String,
    /// What is wrong.
    pub reason: String,
}

impl Issue {
    /// Attaches the source name and the line that sets the field.
    pub fn locate(self, origin: &str, text: &str) -> ScenarioError {
        ScenarioError::Invalid {
            origin: origin.to_string(),
            line: line_of_field(text, &self.field),
            field: self.field,
            reason: self.reason,
        }
    }
}

impl ScenarioError {
    pub(super) fn from_toml(origin: &str, text: &str, e: &toml::de::Error) -> Self {
        let line = e.span().map(|s| line_of_offset(text, s.start));
        let message = e.message().trim();
        // Name the field whose value the parser refused (a wrong type, a negative count).
        let field = e.span().and_then(|s| field_at_offset(text, s.start));
        let message = match field {
            Some(f) if !message.contains(&f) => format!("`{f}`: {message}"),
            _ => message.to_string(),
        };
        Self::Syntax { origin: origin.to_string(), line, message }
    }
}

fn line_of_offset(text: &str, offset: usize) -> usize {
    text[..offset.min(text.len())].bytes().filter(|&b| b == b'\n').count() + 1
}

/// The 1-based line where `field` (a dotted path, `[i]` for array entries) is set.
fn line_of_field(text: &str, field: &str) -> Option<usize> {
    let doc = toml_edit::ImDocument::parse(text.to_string()).ok()?;
    let parts: Vec<&str> = field.split('.').collect();
    let span = span_of(doc.as_item(), &parts, None)?;
    Some(line_of_offset(text, span.start))
}

/// The dotted path of the key whose value (or key) covers byte `offset` of the text.
fn field_at_offset(text: &str, offset: usize) -> Option<String> {
    let doc = toml_edit::ImDocument::parse(text.to_string()).ok()?;
    let mut path = Vec::new();
    field_in(doc.as_item(), offset, &mut path).then(|| path.join("."))
}

fn field_in(item: &toml_edit::Item, offset: usize, path: &mut Vec<String>) -> bool {
    if let Some(tables) = item.as_array_of_tables() {
        for (i, t) in tables.iter().enumerate() {
            if let Some(last) = path.last_mut() {
                last.push_str(&format!("[{i}]"));
            }
            if field_in(&toml_edit::Item::Table(t.clone()), offset, path) {
                return true;
            }
            if let Some(last) = path.last_mut() {
                let cut = last.rfind('[').unwrap_or(last.len());
                last.truncate(cut);
            }
        }
        return false;
    }
    let Some(table) = item.as_table_like() else { return false };
    for (key, value) in table.iter() {
        path.push(key.to_string());
        let covers = |r: Option<Span>| r.is_some_and(|r| r.contains(&offset));
        let key_span = table.get_key_value(key).and_then(|(k, _)| k.span());
        if field_in(value, offset, path)
            || (!value.is_table_like() && (covers(value.span()) || covers(key_span)))
        {
            return true;
        }
        path.pop();
    }
    false
}

/// The span of the deepest key of `path` found below `item` (the last one found wins).
fn span_of(item: &toml_edit::Item, path: &[&str], found: Option<Span>) -> Option<Span> {
    let Some((part, rest)) = path.split_first() else { return found };
    let (key, index) = match part.split_once('[') {
        Some((k, i)) => (k, i.trim_end_matches(']').parse::<usize>().ok()),
        None => (*part, None),
    };
    let Some((k, v)) = item.as_table_like().and_then(|t| t.get_key_value(key)) else { return found };
    let found = k.span().or(found);
    match (index, v.as_array_of_tables()) {
        (Some(i), Some(tables)) => match tables.get(i) {
            Some(t) => {
                let found = t.span().or(found);
                let entry = toml_edit::Item::Table(t.clone());
                span_of(&entry, rest, found)
            }
            None => found,
        },
        _ => span_of(v, rest, found),
    }
}

type Span = std::ops::Range<usize>;

fn check(issues: &mut Vec<Issue>, ok: bool, field: &str, reason: impl Into<String>) {
    if !ok {
        issues.push(Issue { field: field.to_string(), reason: reason.into() });
    }
}

fn finite(issues: &mut Vec<Issue>, field: &str, values: &[f64]) -> bool {
    let ok = values.iter().all(|v| v.is_finite());
    check(issues, ok, field, "must be a finite number (not NaN or infinite)");
    ok
}

fn positive(issues: &mut Vec<Issue>, field: &str, v: f64) {
    if finite(issues, field, &[v]) {
        check(issues, v > 0.0, field, format!("must be > 0, got {v}"));
    }
}

fn non_negative(issues: &mut Vec<Issue>, field: &str, v: f64) {
    if finite(issues, field, &[v]) {
        check(issues, v >= 0.0, field, format!("must be >= 0, got {v}"));
    }
}

impl Scenario {
    /// Checks every field; returns the first problem found (in file order).
    pub fn validate(&self) -> Result<(), Issue> {
        match self.issues().into_iter().next() {
            Some(issue) => Err(issue),
            None => Ok(()),
        }
    }

    /// Every problem with the scenario, in file order.
    pub fn issues(&self) -> Vec<Issue> {
        let mut v = Vec::new();
        check(
            &mut v,
            i64::try_from(self.seed).is_ok(),
            "seed",
            format!("{} is beyond TOML's integers (at most {})", self.seed, i64::MAX),
        );
        let s = &self.staircase;
        check(&mut v, s.steps >= 1, "staircase.steps", "must be at least 1");
        check(&mut v, s.steps <= 200, "staircase.steps", format!("{} steps is more than 200", s.steps));
        positive(&mut v, "staircase.rise_m", s.rise_m);
        positive(&mut v, "staircase.tread_m", s.tread_m);
        positive(&mut v, "staircase.width_m", s.width_m);
        finite(&mut v, "staircase.yaw_deg", &[s.yaw_deg]);
        finite(&mut v, "staircase.start_m", &s.start_m);
        non_negative(&mut v, "staircase.landing_m", s.landing_m);
        positive(&mut v, "staircase.friction", s.friction);
        for (k, &m) in s.missing_steps.iter().enumerate() {
            let top = s.steps.saturating_sub(1);
            check(
                &mut v,
                (1..=top).contains(&m),
                "staircase.missing_steps",
                format!("step {m} is not a step below the top (1 to {top})"),
            );
            check(
                &mut v,
                !s.missing_steps[..k].contains(&m),
                "staircase.missing_steps",
                format!("step {m} is listed twice"),
            );
        }
        self.flight_issues(&mut v);

        let r = &self.room;
        if finite(&mut v, "room.size_m", &r.size_m) {
            check(&mut v, r.size_m.iter().all(|&x| x > 0.0), "room.size_m", "every size must be > 0");
        }
        finite(&mut v, "room.center_m", &r.center_m);
        positive(&mut v, "room.floor_friction", r.floor_friction);

        for (i, b) in self.boxes.iter().enumerate() {
            finite(&mut v, &format!("boxes[{i}].center_m"), &b.center_m);
            let f = format!("boxes[{i}].size_m");
            if finite(&mut v, &f, &b.size_m) {
                check(&mut v, b.size_m.iter().all(|&x| x > 0.0), &f, "every size must be > 0");
            }
            finite(&mut v, &format!("boxes[{i}].yaw_deg"), &[b.yaw_deg]);
        }

        finite(&mut v, "robot.position_m", &self.robot.position_m);
        finite(&mut v, "robot.yaw_deg", &[self.robot.yaw_deg]);

        let l = &self.lidar;
        finite(&mut v, "lidar.mount_xyz_m", &l.mount_xyz_m);
        finite(&mut v, "lidar.mount_rpy_deg", &l.mount_rpy_deg);
        finite(&mut v, "lidar.axis_to_optical_m", &l.axis_to_optical_m);
        if finite(&mut v, "lidar.tilt_start_deg", &[l.tilt_start_deg]) {
            check(&mut v, l.tilt_start_deg.abs() <= 90.0, "lidar.tilt_start_deg", "must be within +/-90");
        }
        if finite(&mut v, "lidar.tilt_end_deg", &[l.tilt_end_deg]) {
            check(&mut v, l.tilt_end_deg.abs() <= 90.0, "lidar.tilt_end_deg", "must be within +/-90");
            check(
                &mut v,
                l.tilt_end_deg != l.tilt_start_deg,
                "lidar.tilt_end_deg",
                "must differ from tilt_start_deg (a sweep needs a range)",
            );
        }
        positive(&mut v, "lidar.tilt_speed_dps", l.tilt_speed_dps);
        positive(&mut v, "lidar.tilt_return_speed_dps", l.tilt_return_speed_dps);
        check(&mut v, l.servo_ticks_per_rev >= 4, "lidar.servo_ticks_per_rev", "must be at least 4");
        if finite(&mut v, "lidar.fov_deg", &[l.fov_deg]) {
            check(&mut v, l.fov_deg > 0.0 && l.fov_deg <= 360.0, "lidar.fov_deg", "must be in (0, 360]");
        }
        if finite(&mut v, "lidar.resolution_deg", &[l.resolution_deg]) {
            check(
                &mut v,
                l.resolution_deg > 0.0 && l.resolution_deg <= l.fov_deg.abs(),
                "lidar.resolution_deg",
                "must be > 0 and at most the field of view",
            );
            if l.resolution_deg > 0.0 && l.fov_deg.is_finite() {
                let beams = l.fov_deg / l.resolution_deg;
                check(
                    &mut v,
                    beams <= 100_000.0,
                    "lidar.resolution_deg",
                    "gives more than 100000 beams a row",
                );
            }
        }
        positive(&mut v, "lidar.row_period_s", l.row_period_s);
        positive(&mut v, "lidar.range_min_m", l.range_min_m);
        if finite(&mut v, "lidar.range_max_m", &[l.range_max_m]) {
            check(&mut v, l.range_max_m > l.range_min_m, "lidar.range_max_m", "must exceed range_min_m");
        }
        non_negative(&mut v, "lidar.noise_sigma_m", l.noise_sigma_m);
        if finite(&mut v, "lidar.dropout_probability", &[l.dropout_probability]) {
            let p = l.dropout_probability;
            check(&mut v, (0.0..1.0).contains(&p), "lidar.dropout_probability", "must be in [0, 1)");
        }
        if l.tilt_speed_dps > 0.0 && l.row_period_s > 0.0 && l.tilt_speed_dps.is_finite() {
            let rows = (l.tilt_end_deg - l.tilt_start_deg).abs() / l.tilt_speed_dps / l.row_period_s;
            check(
                &mut v,
                rows <= 100_000.0,
                "lidar.tilt_speed_dps",
                format!("a sweep of {rows:.0} rows is too long (at most 100000)"),
            );
        }
        if let Some(m) = self.expect.as_ref().and_then(|e| e.max_estimate_error_m) {
            positive(&mut v, "expect.max_estimate_error_m", m);
        }
        for (field, reason) in self.plant.issues() {
            check(&mut v, false, &field, reason);
        }
        if v.is_empty() {
            self.world_issues(&mut v);
        }
        v
    }

    /// The per-step lists, nosings, open risers, handrails and objects of the flight.
    fn flight_issues(&self, v: &mut Vec<Issue>) {
        let s = &self.staircase;
        let n = s.steps as usize;
        for (key, list) in [("rises_m", &s.rises_m), ("treads_m", &s.treads_m), ("frictions", &s.frictions)] {
            let field = format!("staircase.{key}");
            check(
                v,
                list.is_empty() || list.len() == n,
                &field,
                format!("has {} values for {n} steps (one a step, lowest first, or none)", list.len()),
            );
            if finite(v, &field, list) {
                check(v, list.iter().all(|&x| x > 0.0), &field, "every value must be > 0");
            }
        }
        let least_rise = (0..n).map(|i| s.rise_of(i)).fold(f64::INFINITY, f64::min);
        let least_tread = (0..n).map(|i| s.tread_of(i)).fold(f64::INFINITY, f64::min);
        non_negative(v, "staircase.nosing_m", s.nosing_m);
        check(
            v,
            s.nosing_m < least_tread / 2.0,
            "staircase.nosing_m",
            format!("{:.3} m projects more than half the shortest tread ({least_tread:.3} m)", s.nosing_m),
        );
        positive(v, "staircase.nosing_thickness_m", s.nosing_thickness_m);
        if s.nosing_m > 0.0 {
            check(
                v,
                s.nosing_thickness_m < least_rise,
                "staircase.nosing_thickness_m",
                format!("{:.3} m is not below the lowest rise ({least_rise:.3} m)", s.nosing_thickness_m),
            );
        }
        positive(v, "staircase.tread_thickness_m", s.tread_thickness_m);
        if s.risers == super::Risers::Open {
            check(
                v,
                s.tread_thickness_m < least_rise,
                "staircase.tread_thickness_m",
                format!(
                    "{:.3} m slabs leave no gap under the lowest rise ({least_rise:.3} m)",
                    s.tread_thickness_m
                ),
            );
        }
        positive(v, "staircase.handrail_height_m", s.handrail_height_m);
        for (i, o) in self.objects.iter().enumerate() {
            let f = |k: &str| format!("objects[{i}].{k}");
            check(
                v,
                o.step as usize <= n,
                &f("step"),
                format!("step {} is not one of the flight's {n} (0: the floor)", o.step),
            );
            check(
                v,
                !s.missing_steps.contains(&o.step),
                &f("step"),
                format!("step {} is missing from the flight", o.step),
            );
            if finite(v, &f("size_m"), &o.size_m) {
                check(v, o.size_m.iter().all(|&x| x > 0.0), &f("size_m"), "every size must be > 0");
            }
            finite(v, &f("yaw_deg"), &[o.yaw_deg]);
            if finite(v, &f("along_m"), &[o.along_m]) && o.step >= 1 && o.step as usize <= n {
                let depth = s.layout()[o.step as usize - 1].going_m + s.nosing_m;
                check(
                    v,
                    (0.0..=depth).contains(&o.along_m),
                    &f("along_m"),
                    format!(
                        "{:.3} m is off step {}'s tread (0 to {depth:.3} m from its nose)",
                        o.along_m, o.step
                    ),
                );
            }
            if finite(v, &f("across_m"), &[o.across_m]) && o.step >= 1 {
                check(
                    v,
                    o.across_m.abs() <= s.width_m / 2.0,
                    &f("across_m"),
                    format!("{:.3} m is off the {:.3} m wide tread", o.across_m, s.width_m),
                );
            }
        }
    }

    /// Whether the world can be built as described: the flight inside the room and under its
    /// ceiling with headroom for the robot on the top step, the robot starting on free floor.
    fn world_issues(&self, v: &mut Vec<Issue>) {
        let (s, r) = (&self.staircase, &self.room);
        let half = [r.size_m[0] / 2.0, r.size_m[1] / 2.0];
        let inside = |p: &[f64; 2], margin: f64| {
            (0..2).all(|k| (p[k] - r.center_m[k]).abs() <= half[k] - margin + 1e-9)
        };
        let room = format!(
            "x in [{:.2}, {:.2}], y in [{:.2}, {:.2}] m",
            r.center_m[0] - half[0],
            r.center_m[0] + half[0],
            r.center_m[1] - half[1],
            r.center_m[1] + half[1]
        );
        if r.walls {
            let corners = s.footprint_m();
            if !inside(&s.start_m, 0.0) {
                check(v, false, "staircase.start_m", format!("the flight starts outside the room ({room})"));
            } else if let Some(c) = [corners[0], corners[3]].iter().find(|c| !inside(c, 0.0)) {
                let why = format!(
                    "the flight is wider than the room: its corner ({:.2}, {:.2}) m is outside ({room})",
                    c[0], c[1]
                );
                check(v, false, "staircase.width_m", why);
            } else if let Some(c) = [corners[1], corners[2]].iter().find(|c| !inside(c, 0.0)) {
                let why = format!(
                    "the flight runs out of the room: its far corner ({:.2}, {:.2}) m is outside ({room})",
                    c[0], c[1]
                );
                check(v, false, "staircase.steps", why);
            }
            check(
                v,
                inside(&self.robot.position_m, ROBOT_RADIUS_M),
                "robot.position_m",
                format!("the robot must stand inside the room, {ROBOT_RADIUS_M} m from the walls ({room})"),
            );
        }
        if r.ceiling {
            let top = s.top_m();
            check(
                v,
                top + ROBOT_HEADROOM_M <= r.size_m[2],
                "staircase.steps",
                format!(
                    "the top step at {top:.2} m leaves a robot standing on it no headroom under the {:.2} m ceiling (it needs {ROBOT_HEADROOM_M} m)",
                    r.size_m[2]
                ),
            );
        }
        let p = self.robot.position_m;
        let flight = distance_to_rect(&p, &s.footprint_m());
        check(
            v,
            flight >= ROBOT_RADIUS_M,
            "robot.position_m",
            format!("the robot starts {flight:.2} m from the staircase's footprint: its feet need {ROBOT_RADIUS_M} m of free floor"),
        );
        for (i, b) in self.boxes.iter().enumerate() {
            let (c, sn) = (b.yaw_deg.to_radians().cos(), b.yaw_deg.to_radians().sin());
            let at = |x: f64, y: f64| [b.center_m[0] + x * c - y * sn, b.center_m[1] + x * sn + y * c];
            let (hx, hy) = (b.size_m[0] / 2.0, b.size_m[1] / 2.0);
            let rect = [at(-hx, -hy), at(hx, -hy), at(hx, hy), at(-hx, hy)];
            let d = distance_to_rect(&p, &rect);
            check(v, d >= ROBOT_RADIUS_M, "robot.position_m", format!("the robot starts {d:.2} m from boxes[{i}]: its feet need {ROBOT_RADIUS_M} m of free floor"));
        }
        for (i, o) in self.objects.iter().enumerate() {
            let d = distance_to_rect(&p, &o.placed(s).0);
            check(v, d >= ROBOT_RADIUS_M, "robot.position_m", format!("the robot starts {d:.2} m from objects[{i}]: its feet need {ROBOT_RADIUS_M} m of free floor"));
        }
    }
}

/// Room the robot's feet take on the floor around its start, metres (HRP-4's soles, 0.24 m
/// long, about 0.2 m apart: a circle of 0.2 m holds them).
pub const ROBOT_RADIUS_M: f64 = 0.2;

/// Height a robot standing on the top step needs below the ceiling, metres (HRP-4 stands
/// 1.51 m tall, the lidar on its head: models/hrp4/README.md).
pub const ROBOT_HEADROOM_M: f64 = 1.6;

/// Distance from `p` to the convex quadrilateral `rect` (counter-clockwise), 0 inside.
fn distance_to_rect(p: &[f64; 2], rect: &[[f64; 2]; 4]) -> f64 {
    let mut outside = false;
    let mut nearest = f64::INFINITY;
    for k in 0..4 {
        let (a, b) = (rect[k], rect[(k + 1) % 4]);
        let (ex, ey) = (b[0] - a[0], b[1] - a[1]);
        let (px, py) = (p[0] - a[0], p[1] - a[1]);
        if ex * py - ey * px < 0.0 {
            outside = true;
        }
        let t = ((px * ex + py * ey) / (ex * ex + ey * ey).max(1e-18)).clamp(0.0, 1.0);
        nearest = nearest.min(((px - t * ex).powi(2) + (py - t * ey).powi(2)).sqrt());
    }
    if outside {
        nearest
    } else {
        0.0
    }
}
