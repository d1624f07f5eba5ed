//! What a suite's results say: each case over its noise draws (its success rate; it passes
//! when the rate reaches the minimum, all draws by default), the counts per verdict class, the
//! worst cases with the commands that reproduce them, where the wall time went, and the
//! comparison with a baseline's results (newly failing, newly passing, metrics that moved
//! beyond their tolerances).

use super::results::CaseResult;
use super::verdict::Verdict;
use std::collections::BTreeMap;
use std::fmt::Write;

/// A case over its noise draws.
#[derive(Debug, Clone)]
pub struct CaseSummary<'a> {
    /// Its id.
    pub id: &'a str,
    /// Its runs, one per draw.
    pub runs: Vec<&'a CaseResult>,
}

impl CaseSummary<'_> {
    /// Passing draws over draws.
    pub fn rate(&self) -> f64 {
        self.runs.iter().filter(|r| r.pass).count() as f64 / self.runs.len().max(1) as f64
    }

    /// Whether the case passes at `min_rate`.
    pub fn passes(&self, min_rate: f64) -> bool {
        self.rate() >= min_rate - 1e-12
    }

    /// The run that says most about the case: its first failing draw, else its first.
    pub fn worst(&self) -> &CaseResult {
        self.runs.iter().find(|r| !r.pass).or(self.runs.first()).copied().expect("a case has runs")
    }

    /// The smallest margin over the draws, metres.
    pub fn min_margin_m(&self) -> Option<f64> {
        self.runs.iter().filter_map(|r| r.min_margin_m).reduce(f64::min)
    }

    /// The largest torque ratio over the draws.
    pub fn max_torque_ratio(&self) -> f64 {
        self.runs.iter().map(|r| r.max_torque_ratio).fold(0.0, f64::max)
    }

    /// The largest friction ratio over the draws.
    pub fn max_friction_ratio(&self) -> f64 {
        self.runs.iter().map(|r| r.max_friction_ratio).fold(0.0, f64::max)
    }

    /// Wall time over the draws, seconds.
    pub fn wall_s(&self) -> f64 {
        self.runs.iter().map(|r| r.wall_s).sum()
    }
}

/// The results grouped by case, in suite order.
pub fn by_case(results: &[CaseResult]) -> Vec<CaseSummary<'_>> {
    let mut map: BTreeMap<usize, CaseSummary> = BTreeMap::new();
    for r in results {
        map.entry(r.index).or_insert_with(|| CaseSummary { id: &r.id, runs: Vec::new() }).runs.push(r);
    }
    map.into_values().collect()
}

/// Runs per verdict class.
pub fn counts(results: &[CaseResult]) -> BTreeMap<Verdict, usize> {
    let mut c = BTreeMap::new();
    for r in results {
        *c.entry(r.verdict).or_insert(0) += 1;
    }
    c
}

/// How fast a `regress` process ran its runs: the runs it made itself (not those resumed
/// from an earlier process), its wall time, and the climbs it ran at once.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pace {
    /// Runs made by this process.
    pub runs: usize,
    /// Its wall time, seconds.
    pub elapsed_s: f64,
    /// Climbs run at once.
    pub jobs: usize,
}

/// The terminal summary of `results`; `pace` (none for merged shards) gives the runs per
/// hour, and the `worst` failing cases are listed.
pub fn text(results: &[CaseResult], min_rate: f64, pace: Option<Pace>, worst: usize) -> String {
    let mut t = String::new();
    let cases = by_case(results);
    let passing = cases.iter().filter(|c| c.passes(min_rate)).count();
    let _ = writeln!(t, "\n{} runs of {} cases; per verdict class:", results.len(), cases.len());
    let c = counts(results);
    for v in Verdict::ALL {
        let n = c.get(&v).copied().unwrap_or(0);
        if n > 0 {
            let _ = writeln!(t, "  {v:<26} {n:>5}{}", if v.pass() { "" } else { "  FAIL" });
        }
    }
    let rate_note = if min_rate < 1.0 {
        format!(" (a case passes when at least {:.0} % of its draws pass: --min-rate relaxes the rule that all must)", min_rate * 100.0)
    } else {
        String::new()
    };
    let _ = writeln!(t, "cases passing: {passing} of {}{rate_note}", cases.len());
    let flaky: Vec<&CaseSummary> = cases.iter().filter(|c| c.rate() > 0.0 && c.rate() < 1.0).collect();
    if !flaky.is_empty() {
        let list: Vec<String> = flaky.iter().map(|c| format!("{} {:.0} %", c.id, c.rate() * 100.0)).collect();
        let _ = writeln!(t, "passing on some noise draws only: {}", list.join(", "));
    }
    let mut failing: Vec<&CaseSummary> = cases.iter().filter(|c| !c.passes(min_rate)).collect();
    failing.sort_by_key(|c| c.worst().verdict);
    if !failing.is_empty() {
        let _ = writeln!(
            t,
            "\nfailing cases (worst first, {} of {} shown):",
            failing.len().min(worst),
            failing.len()
        );
        for c in failing.iter().take(worst) {
            let r = c.worst();
            let _ = writeln!(
                t,
                "  {}{}: {} (expected {:?}) {}\n      {}\n      reproduce: {}",
                r.id,
                r.name.as_deref().map(|n| format!(" {n}")).unwrap_or_default(),
                r.verdict,
                r.expect,
                format_params(r),
                r.message.as_deref().unwrap_or("-"),
                r.reproduce
            );
        }
    }
    let sum = |f: fn(&CaseResult) -> f64| results.iter().map(f).sum::<f64>();
    let (scan, perceive, plan, execute, wall) = (
        sum(|r| r.stage_times.scan_s),
        sum(|r| r.stage_times.perceive_s),
        sum(|r| r.stage_times.plan_s),
        sum(|r| r.stage_times.execute_s),
        sum(|r| r.wall_s),
    );
    let (physics, control) = (sum(|r| r.stage_times.physics_s), sum(|r| r.stage_times.control_s));
    let pct = |x: f64| 100.0 * x / wall.max(1e-9);
    let _ = writeln!(
        t,
        "\nwall time {wall:.0} s over the runs: scan {:.0} %, perceive {:.0} %, plan {:.0} %, simulate with checks {:.0} % (physics {:.0} %, stabilizer {:.0} %, checks and the loop {:.0} %), other {:.0} %; {:.0} s simulated",
        pct(scan),
        pct(perceive),
        pct(plan),
        pct(execute),
        pct(physics),
        pct(control),
        pct(execute - physics - control),
        pct(wall - scan - perceive - plan - execute),
        sum(|r| r.sim_s)
    );
    let spread = |f: fn(&CaseResult) -> Option<f64>| {
        let mut v: Vec<f64> = results.iter().filter_map(f).collect();
        v.sort_by(f64::total_cmp);
        (!v.is_empty()).then(|| (v[v.len() / 2], v[0], v[v.len() - 1], v.len()))
    };
    if let Some((median, least, most, n)) = spread(|r| r.s_per_stair) {
        let _ = writeln!(
            t,
            "seconds of motion per stair: median {median:.1} s, {least:.1} to {most:.1} s over the {n} runs that went up a step"
        );
    }
    if let Some((median, least, most, _)) = spread(|r| r.s_per_stair_with_stand) {
        let _ = writeln!(
            t,
            "seconds per stair with the settle and the standing sweep before each plan: median {median:.1} s, {least:.1} to {most:.1} s"
        );
    }
    if let Some((median, _, most, n)) = spread(|r| r.max_still_true_speed_m_s) {
        let _ = writeln!(
            t,
            "the body's true speed where the robot judged itself still at a plan's end: median {:.1} mm/s, at most {:.1} mm/s over {n} runs (the largest of each)",
            median * 1e3,
            most * 1e3
        );
    }
    let again: Vec<usize> = results.iter().map(|r| r.looked_again_standing).filter(|&n| n > 0).collect();
    if !again.is_empty() {
        let _ = writeln!(
            t,
            "plans made again on a look taken standing (the plan from a sweep taken walking refused): {} in {} runs",
            again.iter().sum::<usize>(),
            again.len()
        );
    }
    if let Some(p) = pace.filter(|p| p.elapsed_s > 0.0 && p.runs > 0) {
        let resumed = results.len().saturating_sub(p.runs);
        let _ = writeln!(
            t,
            "{} runs in {:.0} s with {} at once: {:.0} runs per hour{}",
            p.runs,
            p.elapsed_s,
            p.jobs,
            p.runs as f64 * 3600.0 / p.elapsed_s,
            if resumed > 0 {
                format!(" ({resumed} more resumed from the results already there)")
            } else {
                String::new()
            }
        );
    }
    t
}

/// The case's drawn figures that matter most, for a table line.
pub fn format_params(r: &CaseResult) -> String {
    let keys = [
        "steps",
        "rise_m",
        "tread_m",
        "width_m",
        "yaw_deg",
        "heading_deg",
        "boxes",
        "box_place",
        "stairwell",
        "landing_m",
        "noise_mm",
        "friction",
    ];
    let mut parts: Vec<String> =
        keys.iter().filter_map(|k| r.params.get(*k).map(|v| format!("{k}={}", short(v)))).collect();
    // The features of real stairs, only where a case has them.
    let real = [
        "nosing_m",
        "risers",
        "rise_jitter_m",
        "odd_step",
        "odd_rise_m",
        "handrails",
        "objects",
        "object_kind",
        "object_place",
    ];
    for k in real {
        let (Some(v), Some(f)) = (r.params.get(k), super::suite::field(k)) else { continue };
        let default = match f.default {
            super::suite::Default::Num(x) => v.as_f64() == Some(x),
            super::suite::Default::Word(w) => matches!(v, super::suite::Val::Text(t) if t == w),
            super::suite::Default::Flag(b) => v == &super::suite::Val::Bool(b),
        };
        if !default {
            parts.push(format!("{k}={}", short(v)));
        }
    }
    format!("[{}]", parts.join(" "))
}

fn short(v: &super::suite::Val) -> String {
    match v {
        super::suite::Val::Float(x) => format!("{x:.3}"),
        other => other.to_string(),
    }
}

/// Tolerances of the baseline comparison.
#[derive(Debug, Clone, Copy)]
pub struct Tolerances {
    /// A CoM margin smaller by more than this moved, metres.
    pub margin_m: f64,
    /// A torque ratio larger by more than this moved.
    pub torque_ratio: f64,
    /// A friction ratio larger by more than this moved.
    pub friction_ratio: f64,
    /// A wall time longer by more than this fraction (and 2 s) moved.
    pub wall_fraction: f64,
}

impl Default for Tolerances {
    fn default() -> Self {
        Self { margin_m: 0.005, torque_ratio: 0.05, friction_ratio: 0.05, wall_fraction: 0.5 }
    }
}

/// What changed against a baseline.
#[derive(Debug, Clone, Default)]
pub struct Comparison {
    /// Cases that passed in the baseline and fail now: regressions.
    pub newly_failing: Vec<String>,
    /// Cases that failed in the baseline and pass now.
    pub newly_passing: Vec<String>,
    /// Metrics beyond their tolerances: one line each.
    pub moved: Vec<String>,
    /// Cases of one side only.
    pub unmatched: Vec<String>,
}

/// Compares `now` with `before`, case by case.
pub fn compare(before: &[CaseResult], now: &[CaseResult], min_rate: f64, tol: &Tolerances) -> Comparison {
    let old: BTreeMap<&str, CaseSummary> = by_case(before).into_iter().map(|c| (c.id, c)).collect();
    let mut out = Comparison::default();
    let mut seen = std::collections::BTreeSet::new();
    for c in by_case(now) {
        seen.insert(c.id);
        let Some(o) = old.get(c.id) else {
            out.unmatched.push(format!("{}: not in the baseline", c.id));
            continue;
        };
        let w = c.worst();
        match (o.passes(min_rate), c.passes(min_rate)) {
            (true, false) => out.newly_failing.push(format!(
                "{}: was {}, now {}: {} (reproduce: {})",
                c.id,
                o.worst().verdict,
                w.verdict,
                w.message.as_deref().unwrap_or("-"),
                w.reproduce
            )),
            (false, true) => {
                out.newly_passing.push(format!("{}: was {}, now {}", c.id, o.worst().verdict, w.verdict))
            }
            _ => {}
        }
        if let (Some(a), Some(b)) = (o.min_margin_m(), c.min_margin_m()) {
            if a - b > tol.margin_m {
                out.moved.push(format!("{}: CoM margin {:.1} -> {:.1} mm", c.id, a * 1e3, b * 1e3));
            }
        }
        let (a, b) = (o.max_torque_ratio(), c.max_torque_ratio());
        if b - a > tol.torque_ratio {
            out.moved.push(format!("{}: torque ratio {a:.2} -> {b:.2}", c.id));
        }
        let (a, b) = (o.max_friction_ratio(), c.max_friction_ratio());
        if b - a > tol.friction_ratio {
            out.moved.push(format!("{}: friction ratio {a:.2} -> {b:.2}", c.id));
        }
        let (a, b) = (o.wall_s(), c.wall_s());
        if b > a * (1.0 + tol.wall_fraction) && b - a > 2.0 {
            out.moved.push(format!("{}: wall time {a:.1} -> {b:.1} s", c.id));
        }
    }
    for id in old.keys().filter(|id| !seen.contains(*id)) {
        out.unmatched.push(format!("{id}: in the baseline only"));
    }
    out
}

/// The comparison as text.
pub fn comparison_text(c: &Comparison, tol: &Tolerances) -> String {
    let mut t = format!(
        "\nagainst the baseline: {} newly failing (regressions), {} newly passing, {} metrics moved (margin by {} mm, torque or friction ratio by {}, wall time by {:.0} %)\n",
        c.newly_failing.len(),
        c.newly_passing.len(),
        c.moved.len(),
        tol.margin_m * 1e3,
        tol.torque_ratio,
        tol.wall_fraction * 100.0
    );
    for (title, lines) in [
        ("REGRESSION", &c.newly_failing),
        ("fixed", &c.newly_passing),
        ("moved", &c.moved),
        ("unmatched", &c.unmatched),
    ] {
        for l in lines {
            t += &format!("  {title}: {l}\n");
        }
    }
    t
}
