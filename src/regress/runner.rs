//! Running a suite's cases: in parallel (one climb per worker thread), each under a wall-time
//! limit (a cancellation when it runs over), each finished run appended at once to
//! `results.jsonl`, the runs already there skipped on `--resume`, and the failing runs kept as
//! MCAP recordings on request. Every case's scenario file is written first, so any run can be
//! reproduced alone with `stairbench run`.

use super::generate::{noise_seed, Case};
use super::results::{Appender, CaseResult};
use super::verdict::{strayed, verdict_of, Verdict};
use crate::cancel::Cancel;
use crate::climb::{Nobody, Observer, StageTimes};
use crate::params::ClimbParams;
use crate::record::Recorder;
use crate::scenario::{ExpectSpec, ExpectedOutcome};
use std::collections::{BTreeSet, VecDeque};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{channel, RecvTimeoutError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// How to run.
#[derive(Debug, Clone)]
pub struct Options {
    /// Climbs at once.
    pub jobs: usize,
    /// Wall-time limit of one run, seconds.
    pub timeout_s: f64,
    /// Noise draws per case.
    pub seeds: usize,
    /// Where everything goes.
    pub out: PathBuf,
    /// Skip the runs already in `out/results.jsonl` (else it starts afresh).
    pub resume: bool,
    /// Keep an MCAP recording of every failing run here.
    pub record_failures: Option<PathBuf>,
    /// Every parameter of the climbs.
    pub params: ClimbParams,
    /// The reproduce commands name this parameters file (when the parameters are not the
    /// defaults).
    pub params_file: Option<PathBuf>,
}

/// Why a suite could not be run.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// The output folder or a file in it.
    #[error("{path}: {source}")]
    Io {
        /// The path.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// The results already there.
    #[error(transparent)]
    Results(#[from] super::results::ResultsError),
    /// A case's climb parameters, laid over the run's, broke a rule.
    #[error("{id}: its params, laid over the run's: {reason}")]
    CaseParams {
        /// The case.
        id: String,
        /// Why.
        reason: String,
    },
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> RunError + '_ {
    move |source| RunError::Io { path: path.display().to_string(), source }
}

/// The scenario file of a case, under `out`.
pub fn case_file(out: &Path, id: &str) -> PathBuf {
    out.join("cases").join(format!("{id}.toml"))
}

/// The parameters file of a case that sets its own (`params` in the suite), under `out`.
pub fn case_params_file(out: &Path, id: &str) -> PathBuf {
    out.join("cases").join(format!("{id}.params.toml"))
}

/// The parameters `case` climbs under: the run's, with the case's own laid over them.
pub fn case_params(base: &ClimbParams, case: &Case) -> Result<ClimbParams, RunError> {
    match &case.params {
        None => Ok(base.clone()),
        Some(t) => {
            base.with_overrides(t).map_err(|reason| RunError::CaseParams { id: case.id.clone(), reason })
        }
    }
}

/// Writes every case's scenario file, and the parameters file of each that sets its own
/// (the run's `base` with the case's laid over them, whole: `stairbench run` reproduces it).
pub fn write_cases(out: &Path, cases: &[Case], base: &ClimbParams) -> Result<(), RunError> {
    let dir = out.join("cases");
    std::fs::create_dir_all(&dir).map_err(io(&dir))?;
    let other = |path: &Path, e: &dyn std::fmt::Display| RunError::Io {
        path: path.display().to_string(),
        source: std::io::Error::other(e.to_string()),
    };
    for c in cases {
        let path = case_file(out, &c.id);
        let toml = c.scenario.to_toml_string().map_err(|e| other(&path, &e))?;
        let mut params = String::new();
        if c.params.is_some() {
            let file = case_params_file(out, &c.id);
            let text = toml::to_string(&case_params(base, c)?).map_err(|e| other(&file, &e))?;
            std::fs::write(&file, text).map_err(io(&file))?;
            params = format!(" --params cases/{}.params.toml", c.id);
        }
        let expected = c.scenario.expect.as_ref().map(|e| format!("{:?}", e.outcome)).unwrap_or_default();
        let text = format!(
            "# {}\n# Expected: {expected}. Reproduce: stairbench run cases/{}.toml{params} (in the suite's output folder)\n{toml}",
            c.scenario.description, c.id
        );
        std::fs::write(&path, text).map_err(io(&path))?;
    }
    Ok(())
}

/// A run to do: a case under one noise draw, with the parameters it climbs under.
struct Job {
    case: Arc<(Case, ClimbParams)>,
    seed_index: usize,
}

/// The suite-level fields every result carries.
#[derive(Debug, Clone)]
pub struct SuiteInfo {
    /// Name.
    pub name: String,
    /// File hash.
    pub hash: String,
    /// Seed.
    pub seed: u64,
    /// Cases in the whole suite.
    pub cases_total: usize,
}

/// What [`run`] leaves: every result of the suite's runs here, and how many of them it ran.
#[derive(Debug, Clone)]
pub struct Ran {
    /// Every result, the resumed ones (read back from `results.jsonl`) included, in case
    /// and draw order.
    pub results: Vec<CaseResult>,
    /// How many of `results` this call ran (the rest were resumed): a rate of runs per hour
    /// counts only these against its wall time.
    pub ran_here: usize,
}

/// Runs `cases` (this shard's) under `opt`; `on_done(result, done, total)` sees each run as it
/// ends.
pub fn run(
    info: &SuiteInfo,
    cases: &[Case],
    opt: &Options,
    on_done: &(dyn Fn(&CaseResult, usize, usize) + Sync),
) -> Result<Ran, RunError> {
    std::fs::create_dir_all(&opt.out).map_err(io(&opt.out))?;
    write_cases(&opt.out, cases, &opt.params)?;
    let prepared = cases.iter().map(|c| Ok(Arc::new((c.clone(), case_params(&opt.params, c)?))));
    let prepared: Vec<Arc<(Case, ClimbParams)>> = prepared.collect::<Result<_, RunError>>()?;
    let results_path = opt.out.join("results.jsonl");
    let mut done: Vec<CaseResult> = Vec::new();
    if opt.resume && results_path.exists() {
        done = super::results::read(&results_path)?;
    } else if results_path.exists() {
        std::fs::remove_file(&results_path).map_err(io(&results_path))?;
    }
    if let Some(dir) = &opt.record_failures {
        std::fs::create_dir_all(dir).map_err(io(dir))?;
    }
    let have: BTreeSet<(String, usize)> = done.iter().map(CaseResult::key).collect();
    let jobs: Vec<Job> = prepared
        .iter()
        .flat_map(|c| (0..opt.seeds).map(move |k| Job { case: c.clone(), seed_index: k }))
        .filter(|j| !have.contains(&(j.case.0.id.clone(), j.seed_index)))
        .collect();
    let jobs = start_order(jobs);
    let total = jobs.len();
    let queue = Mutex::new(jobs);
    let appender = Mutex::new(Appender::open(&results_path).map_err(io(&results_path))?);
    let finished: Mutex<Vec<CaseResult>> = Mutex::new(Vec::new());
    let write_error: Mutex<Option<RunError>> = Mutex::new(None);
    let threads = threads_per_job(opt.jobs, rayon::current_num_threads());
    std::thread::scope(|scope| {
        for _ in 0..opt.jobs.max(1) {
            scope.spawn(|| {
                // The climb's parallel parts run on the worker's own threads; without a pool
                // of its own (one that cannot be built), on the process's.
                let pool = threads.and_then(|n| rayon::ThreadPoolBuilder::new().num_threads(n).build().ok());
                while let Some(job) = queue.lock().map(|mut q| q.pop_front()).unwrap_or(None) {
                    let result = match &pool {
                        Some(pool) => pool.install(|| run_one(info, &job, opt)),
                        None => run_one(info, &job, opt),
                    };
                    if let Ok(mut a) = appender.lock() {
                        if let Err(e) = a.append(&result) {
                            if let Ok(mut w) = write_error.lock() {
                                w.get_or_insert(RunError::Io {
                                    path: results_path.display().to_string(),
                                    source: e,
                                });
                            }
                        }
                    }
                    if let Ok(mut f) = finished.lock() {
                        f.push(result.clone());
                        on_done(&result, f.len(), total);
                    }
                }
            });
        }
    });
    if let Some(e) = write_error.into_inner().unwrap_or(None) {
        return Err(e);
    }
    let finished = finished.into_inner().unwrap_or_default();
    let ran_here = finished.len();
    done.extend(finished);
    done.sort_by_key(|r| (r.index, r.seed_index));
    Ok(Ran { results: done, ran_here })
}

/// The threads each of `jobs` climbs at once gets for its parallel parts (the lidar's rows,
/// perception), when the `cores` of the process's pool are to be shared among them: a pool
/// of its own of `cores / jobs` (at least one), so that the climbs do not queue their
/// parallel work behind one another's on one pool, nor wake each other's threads. `None`
/// for one climb at a time: it has the whole pool. The results are the same on any number
/// of threads: nothing a climb computes depends on how its parallel work is split
/// (perception's bands and the free space's chunks are fixed in number, the range noise's
/// chunks feed an exact median, and each lidar row draws its noise from its own seed).
fn threads_per_job(jobs: usize, cores: usize) -> Option<usize> {
    (jobs > 1).then(|| (cores / jobs).max(1))
}

/// `jobs` in the order they are started: the longest expected first ([`expected_cycles`]),
/// so that the climbs still running when the queue empties are short ones and the cores
/// are not left to one long climb at the end (longest processing time first, Graham 1969);
/// alike ones in case and draw order. The order changes no result: each run's seed is its
/// case's and draw's, and the results are written sorted.
fn start_order(mut jobs: Vec<Job>) -> VecDeque<Job> {
    jobs.sort_by_key(|j| std::cmp::Reverse(expected_cycles(&j.case.0.scenario)));
    VecDeque::from(jobs)
}

/// How many climbing cycles `scenario`'s run is expected to take: about one (or `k`) for a
/// climb expected to be refused from the floor (or before step `k`); else its steps and the
/// floor's two.
fn expected_cycles(scenario: &crate::scenario::Scenario) -> u32 {
    const FLOOR_CYCLES: u32 = 2;
    match &scenario.expect {
        Some(e) if e.outcome == ExpectedOutcome::Refuse => e.before_step.unwrap_or(1),
        _ => scenario.staircase.steps + FLOOR_CYCLES,
    }
}

/// The command that reproduces a run alone.
fn reproduce(opt: &Options, case: &Case, seed_index: usize, seed: u64) -> String {
    let mut cmd = format!("stairbench run {}", case_file(&opt.out, &case.id).display());
    if seed_index > 0 {
        cmd += &format!(" --seed {seed}");
    }
    if case.params.is_some() {
        cmd += &format!(" --params {}", case_params_file(&opt.out, &case.id).display());
    } else if let Some(p) = &opt.params_file {
        cmd += &format!(" --params {}", p.display());
    }
    cmd
}

/// One run: the climb under its time limit, its verdict, its recording kept if it failed.
fn run_one(info: &SuiteInfo, job: &Job, opt: &Options) -> CaseResult {
    let (case, params) = &*job.case;
    // Draw 0 is the case's own seed (a generated case's is noise_seed(.., 0); a scenario
    // file's, its own), the others drawn.
    let seed = match job.seed_index {
        0 => case.scenario.seed,
        k => noise_seed(info.seed, case.index, k),
    };
    let mut scenario = case.scenario.clone();
    scenario.seed = seed;
    let spec = scenario.expect.clone().unwrap_or(ExpectSpec::new(ExpectedOutcome::Climb, String::new()));
    let mut result = CaseResult {
        suite: info.name.clone(),
        suite_hash: info.hash.clone(),
        cases_total: info.cases_total,
        seeds: opt.seeds,
        id: case.id.clone(),
        index: case.index,
        name: case.name.clone(),
        seed_index: job.seed_index,
        noise_seed: seed,
        params: case.values.clone(),
        expect: spec.outcome,
        expect_reason: spec.reason.clone(),
        verdict: Verdict::Error,
        pass: false,
        stop: None,
        first_violation: None,
        message: None,
        min_margin_m: None,
        max_torque_ratio: 0.0,
        torque_joint: String::new(),
        max_friction_ratio: 0.0,
        max_estimate_error_m: None,
        max_estimate_yaw_rad: None,
        max_still_true_speed_m_s: None,
        s_per_stair: None,
        s_per_stair_with_stand: None,
        looked_again_standing: 0,
        max_plan_yaw_moment_nm: None,
        steps_climbed: 0,
        steps_total: scenario.staircase.steps as usize - scenario.staircase.missing_steps.len(),
        cycles: 0,
        sim_s: 0.0,
        wall_s: 0.0,
        stage_times: StageTimes::default(),
        reproduce: reproduce(opt, case, job.seed_index, seed),
        error: None,
    };
    let started = Instant::now();
    let cancel = Cancel::new();
    let timed_out = std::sync::atomic::AtomicBool::new(false);
    let recording =
        opt.record_failures.as_ref().map(|d| d.join(format!("{}-draw{}.mcap", case.id, job.seed_index)));
    let outcome = std::thread::scope(|scope| {
        let (stop_timer, wait) = channel::<()>();
        let limit = Duration::from_secs_f64(opt.timeout_s.max(0.0));
        let (cancel_t, timed_out_t) = (cancel.clone(), &timed_out);
        scope.spawn(move || {
            if let Err(RecvTimeoutError::Timeout) = wait.recv_timeout(limit) {
                timed_out_t.store(true, std::sync::atomic::Ordering::Relaxed);
                cancel_t.cancel();
            }
        });
        let climb = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            climb(&scenario, params, &recording, &cancel)
        }));
        drop(stop_timer);
        climb
    });
    result.wall_s = started.elapsed().as_secs_f64();
    let timed_out = timed_out.into_inner();
    match outcome {
        Ok(Ok(report)) => {
            result = result.with_report(&report);
            result.verdict = verdict_of(&spec, &report, timed_out);
            result.message = match result.verdict {
                Verdict::EstimateStrayed => strayed(&spec, &report),
                _ => report.why_failed(),
            };
        }
        Ok(Err(e)) => {
            result.error = Some(e.clone());
            result.message = Some(e);
        }
        Err(panic) => {
            let what = panic
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default();
            result.error = Some(format!("the climb panicked: {what}"));
            result.message = result.error.clone();
        }
    }
    if timed_out {
        result.verdict = Verdict::Timeout;
        result.message = Some(format!("ran over its {:.0} s wall-time limit", opt.timeout_s));
    }
    result.pass = result.verdict.pass();
    if let Some(path) = &recording {
        if result.pass {
            let _ = std::fs::remove_file(path);
        }
    }
    result
}

/// The climb of `scenario`, recorded to `recording` when given.
fn climb(
    scenario: &crate::scenario::Scenario,
    params: &ClimbParams,
    recording: &Option<PathBuf>,
    cancel: &Cancel,
) -> Result<crate::climb::ClimbReport, String> {
    let mut recorder = match recording {
        Some(path) => {
            let model = crate::robot::hrp4::model().map_err(|e| e.to_string())?;
            let mut r = Recorder::create(path, &model).map_err(|e| e.to_string())?;
            let meta = [
                ("command".to_string(), "regress".to_string()),
                ("scenario".to_string(), scenario.name.clone()),
            ];
            r.metadata("stairbench", meta.into_iter().collect());
            r.attach(
                "scenario.toml",
                "application/toml",
                scenario.to_toml_string().unwrap_or_default().as_bytes(),
            );
            r.attach(
                "params.toml",
                "application/toml",
                toml::to_string(params).unwrap_or_default().as_bytes(),
            );
            Some(r)
        }
        None => None,
    };
    let observer: &mut dyn Observer = match recorder.as_mut() {
        Some(r) => r,
        None => &mut Nobody,
    };
    let report = crate::sim::climb_scenario(scenario, params.loop_params(), &params.sim(), observer, cancel)
        .map_err(|e| e.to_string());
    if let Some(r) = recorder {
        r.finish().map_err(|e| e.to_string())?;
    }
    report
}

#[cfg(test)]
mod tests {
    use super::{start_order, threads_per_job, Job};
    use crate::params::ClimbParams;
    use crate::regress::generate::Case;
    use crate::scenario::{ExpectSpec, ExpectedOutcome, Scenario};
    use std::sync::Arc;

    /// The runs expected to take longest start first: a climb of many steps before one of
    /// few, a refusal before step `k` counted as `k` cycles, a refusal from the floor last;
    /// alike runs keep their case and draw order.
    #[test]
    fn a_suites_longest_runs_start_first() {
        let job = |id: &str, steps: u32, expect: Option<(ExpectedOutcome, Option<u32>)>, seed_index| {
            let mut scenario = Scenario::default();
            scenario.staircase.steps = steps;
            scenario.expect = expect.map(|(outcome, before_step)| ExpectSpec {
                before_step,
                ..ExpectSpec::new(outcome, String::new())
            });
            let case = Case {
                id: id.into(),
                index: 0,
                name: None,
                values: Default::default(),
                redraws: 0,
                scenario,
                params: None,
            };
            Job { case: Arc::new((case, ClimbParams::default())), seed_index }
        };
        let refuse = ExpectedOutcome::Refuse;
        let jobs = vec![
            job("three", 3, Some((ExpectedOutcome::Climb, None)), 0),
            job("refused-from-the-floor", 12, Some((refuse, None)), 0),
            job("twelve", 12, Some((ExpectedOutcome::Either, None)), 0),
            job("refused-before-4", 8, Some((refuse, Some(4))), 0),
            job("five", 5, None, 0),
            job("twelve", 12, Some((ExpectedOutcome::Either, None)), 1),
        ];
        let order: Vec<(String, usize)> =
            start_order(jobs).iter().map(|j| (j.case.0.id.clone(), j.seed_index)).collect();
        let expected = [
            ("twelve", 0),
            ("twelve", 1),
            ("five", 0),
            ("three", 0),
            ("refused-before-4", 0),
            ("refused-from-the-floor", 0),
        ];
        assert_eq!(order, expected.map(|(id, k)| (id.to_string(), k)));
    }

    #[test]
    fn climbs_at_once_share_the_cores_one_thread_each_at_least() {
        assert_eq!(threads_per_job(1, 16), None, "one climb at a time has the whole pool");
        assert_eq!(threads_per_job(2, 2), Some(1));
        assert_eq!(threads_per_job(2, 16), Some(8));
        assert_eq!(threads_per_job(3, 16), Some(5));
        assert_eq!(threads_per_job(16, 2), Some(1), "more climbs than cores: one thread each");
    }
}
