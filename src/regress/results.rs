//! One line of `results.jsonl`: a case under one noise draw, appended the moment it ends (a
//! killed run loses no finished case). Everything the tables, JUnit, the maps, the baseline
//! comparison and a merge of shards need is in it.

use super::suite::Val;
use super::verdict::Verdict;
use crate::climb::{ClimbReport, StageTimes, StopReason, Violation};
use crate::scenario::ExpectedOutcome;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::io::{BufRead, Write};
use std::path::Path;

/// A case's result under one noise draw.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CaseResult {
    /// The suite's name.
    pub suite: String,
    /// The suite file's hash (shards of one suite agree on it).
    pub suite_hash: String,
    /// Cases in the whole suite (every shard).
    pub cases_total: usize,
    /// Noise draws per case.
    pub seeds: usize,
    /// The case's id, `<suite>-0042`.
    pub id: String,
    /// The case's index in the suite.
    pub index: usize,
    /// The explicit case's name, if any.
    pub name: Option<String>,
    /// Which noise draw (0-based).
    pub seed_index: usize,
    /// Its lidar noise seed.
    pub noise_seed: u64,
    /// The drawn fields.
    pub params: BTreeMap<String, Val>,
    /// The expected outcome.
    pub expect: ExpectedOutcome,
    /// Why.
    pub expect_reason: String,
    /// The verdict.
    pub verdict: Verdict,
    /// Whether it passes.
    pub pass: bool,
    /// Why the loop stopped, as data.
    pub stop: Option<StopReason>,
    /// The first violated check, as data.
    pub first_violation: Option<Violation>,
    /// The failure in one line (stop reason or first violation), for tables and JUnit.
    pub message: Option<String>,
    /// Smallest CoM margin, metres (`None` without an execution).
    pub min_margin_m: Option<f64>,
    /// Largest torque demand over its limit.
    pub max_torque_ratio: f64,
    /// Its joint.
    pub torque_joint: String,
    /// Largest friction ratio a loaded foot used.
    pub max_friction_ratio: f64,
    /// Largest error of the robot's own estimate of its base's position at a sweep, metres
    /// (`None` when the loop read the true pose; absent from results written before the
    /// estimate).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_estimate_error_m: Option<f64>,
    /// Largest error of its yaw, radians (absolute; `None` likewise).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_estimate_yaw_rad: Option<f64>,
    /// Largest true speed of the base at which the robot judged itself still at a plan's
    /// end, m/s (`ClimbReport::max_still_true_speed_m_s`; `None` likewise, or in results
    /// written before it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_still_true_speed_m_s: Option<f64>,
    /// Simulated seconds of motion per stair (the cycles that went up a step; `None` when
    /// none did, or in results written before it was kept).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub s_per_stair: Option<f64>,
    /// The same cycles' seconds with the standing before each plan counted (the settle, and
    /// a sweep taken standing; perception and planning not), `None` likewise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub s_per_stair_with_stand: Option<f64>,
    /// Plans made again on a look taken standing, the plan from a sweep taken walking
    /// refused (`CycleReport::looked_again_standing`; 0 in results written before it).
    #[serde(default)]
    pub looked_again_standing: usize,
    /// The largest moment about the vertical a plan of the run asked of the contacts, N m
    /// (`ClimbReport::max_plan_yaw_moment_nm`; `None` without a plan, or in results written
    /// before it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_plan_yaw_moment_nm: Option<f64>,
    /// Steps climbed.
    pub steps_climbed: usize,
    /// Steps of the flight.
    pub steps_total: usize,
    /// Cycles run.
    pub cycles: usize,
    /// Simulated time, seconds.
    pub sim_s: f64,
    /// Wall time, seconds.
    pub wall_s: f64,
    /// Wall time by stage, seconds.
    pub stage_times: StageTimes,
    /// The command that reproduces this run alone.
    pub reproduce: String,
    /// The bench's error, when it failed to run the case.
    pub error: Option<String>,
}

impl CaseResult {
    /// The key of this run in a suite: its case and noise draw.
    pub fn key(&self) -> (String, usize) {
        (self.id.clone(), self.seed_index)
    }

    /// Fills the figures of a climb's report.
    pub fn with_report(mut self, r: &ClimbReport) -> Self {
        let margin = r.min_margin_m();
        let (torque, joint) = r.max_torque();
        self.stop = r.stop.clone();
        self.first_violation = r.first_violation().cloned();
        self.min_margin_m = margin.is_finite().then_some(margin);
        self.max_torque_ratio = torque;
        self.torque_joint = joint.to_string();
        self.max_friction_ratio = r.max_friction_ratio();
        self.max_estimate_error_m = r.max_estimate_error_m();
        self.max_estimate_yaw_rad = r.max_estimate_yaw_rad();
        self.max_still_true_speed_m_s = r.max_still_true_speed_m_s();
        self.s_per_stair = r.seconds_per_stair();
        self.s_per_stair_with_stand = r.seconds_per_stair_with_stand();
        self.looked_again_standing = r.looked_again_standing.len();
        self.max_plan_yaw_moment_nm = r.max_plan_yaw_moment_nm();
        self.steps_climbed = r.steps_climbed;
        self.steps_total = r.steps_total;
        self.cycles = r.cycles.len();
        self.sim_s = r.sim_s;
        self.stage_times = r.stage_times();
        self
    }
}

/// Why a results file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum ResultsError {
    /// The file.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// A line is not a result.
    #[error("{path}:{line}: not a case result ({reason})")]
    Line {
        /// The file.
        path: String,
        /// 1-based line.
        line: usize,
        /// Why.
        reason: String,
    },
}

/// Every result of a JSON Lines file. A last line cut short by a kill is skipped (it was never
/// a finished case); any other bad line is an error naming it.
pub fn read(path: &Path) -> Result<Vec<CaseResult>, ResultsError> {
    let name = path.display().to_string();
    let file = std::fs::File::open(path).map_err(|source| ResultsError::Io { path: name.clone(), source })?;
    let lines: Vec<String> = std::io::BufReader::new(file)
        .lines()
        .collect::<Result<_, _>>()
        .map_err(|source| ResultsError::Io { path: name.clone(), source })?;
    let mut out = Vec::new();
    for (i, line) in lines.iter().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        match serde_json::from_str::<CaseResult>(line) {
            Ok(r) => out.push(r),
            Err(_) if i + 1 == lines.len() && !line.ends_with('}') => {}
            Err(e) => return Err(ResultsError::Line { path: name, line: i + 1, reason: e.to_string() }),
        }
    }
    Ok(out)
}

/// Appends results to a JSON Lines file, one line each, flushed at once.
pub struct Appender {
    file: std::fs::File,
}

impl Appender {
    /// Opens `path` for appending (created if missing). A last line cut short by a kill
    /// gets its line ended, so the next result starts on a line of its own.
    pub fn open(path: &Path) -> std::io::Result<Self> {
        let ends_mid_line = std::fs::read(path).ok().is_some_and(|b| !b.is_empty() && !b.ends_with(b"\n"));
        let mut file = std::fs::OpenOptions::new().create(true).append(true).open(path)?;
        if ends_mid_line {
            file.write_all(b"\n")?;
        }
        Ok(Self { file })
    }

    /// Writes one result and flushes it to the file.
    pub fn append(&mut self, r: &CaseResult) -> std::io::Result<()> {
        let mut line = serde_json::to_vec(r).map_err(std::io::Error::other)?;
        line.push(b'\n');
        self.file.write_all(&line)?;
        self.file.flush()
    }
}
