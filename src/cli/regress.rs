//! `stairbench regress SUITE`: a suite's generated staircases climbed in parallel, each run a
//! line of `results.jsonl` as it ends, then JUnit, capability maps, a summary and, with
//! `--baseline`, the regressions; exit 1 on any failing case or regression. `regress merge`
//! joins the results of a suite's shards.

use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand};
use stairbench::params::ClimbParams;
use stairbench::regress::results::CaseResult;
use stairbench::regress::runner::{self, Options, SuiteInfo};
use stairbench::regress::shard::{self, Shard};
use stairbench::regress::summary::{self, Tolerances};
use stairbench::regress::{bench_robot, generate, junit, maps, results, suite};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

/// Folder searched for a suite given by name.
const SUITE_DIR: &str = "scenarios/suites";

/// Arguments of `stairbench regress`.
#[derive(Debug, Args)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct RegressArgs {
    #[command(subcommand)]
    command: Option<RegressCommand>,
    /// The suite: a file, or a name in scenarios/suites/ (smoke, ci, envelope, wide, real, robust, regressions).
    #[arg(required = true)]
    suite: Option<PathBuf>,
    /// Output folder: results.jsonl, junit.xml, cases/<id>.toml, the maps (default
    /// out/regress/<suite>).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Noise draws per case (default: the suite's `seeds`, else 1); a case passes only when
    /// every draw passes (see --min-rate).
    #[arg(long)]
    seeds: Option<usize>,
    /// Let a case pass when at least this fraction of its draws pass (the report says so).
    #[arg(long, default_value_t = 1.0)]
    min_rate: f64,
    /// Climbs at once (default: the machine's cores). With more than one, each climb's
    /// parallel parts (the lidar's rows, perception) run on its own share of the cores
    /// (the same results on any number of threads). The runs expected to take longest (most
    /// steps to climb) start first, so that few long climbs are left at the end.
    #[arg(long)]
    jobs: Option<usize>,
    /// Wall-time limit of one run, seconds (it is then cancelled: verdict `timeout`).
    #[arg(long, default_value_t = 600.0)]
    timeout: f64,
    /// Skip the runs already in the output's results.jsonl (after a kill).
    #[arg(long)]
    resume: bool,
    /// Compare with an earlier results.jsonl: newly failing cases are regressions (exit 1).
    #[arg(long, value_name = "OLD.jsonl")]
    baseline: Option<PathBuf>,
    /// Keep an MCAP recording of every failing run in this folder (none of the passing).
    #[arg(long, value_name = "DIR")]
    record_failures: Option<PathBuf>,
    /// Run shard M of N (1-based): the cases whose id hashes there. Without it, read from
    /// CI_NODE_INDEX/CI_NODE_TOTAL (GitLab), SLURM_ARRAY_TASK_ID/_MIN/_COUNT (Slurm) or
    /// JOB_COMPLETION_INDEX (Kubernetes, with --shards).
    #[arg(long, value_name = "M/N")]
    shard: Option<String>,
    /// Shards in all, for a Kubernetes Indexed Job's JOB_COMPLETION_INDEX.
    #[arg(long)]
    shards: Option<usize>,
    /// Also map the verdicts over these two parameters (repeatable), e.g. --map yaw_deg,noise_mm
    /// (rise x tread is always mapped, and so are the two fields of a suite's [grid]).
    #[arg(long, value_name = "X,Y")]
    map: Vec<String>,
    /// Climb parameters as TOML (as for `run --params`).
    #[arg(long)]
    params: Option<PathBuf>,
    /// Every case's planned motion this many times faster (as `run --speedup`): the suite's
    /// verdicts, friction and seconds per stair at a faster timing. The parameters go to
    /// OUT/params.toml, and each run's reproduce command carries them.
    #[arg(long, default_value_t = 1.0)]
    speedup: f64,
    /// Every case in this simulated body (`nominal` or `hrp4-like`, as for `run --plant`):
    /// sets each case's [plant] preset, the errors a case sets itself stay. Each draw's body
    /// comes from its noise seed.
    #[arg(long, value_name = "PRESET")]
    plant: Option<super::PlantArg>,
    /// Generate and write the cases, print them, run nothing.
    #[arg(long)]
    list: bool,
    /// No progress bar and no line per run.
    #[arg(short, long)]
    quiet: bool,
}

#[derive(Debug, Subcommand)]
enum RegressCommand {
    /// Merge the results.jsonl of a suite's shards; fails when a run is missing or twice.
    Merge(MergeArgs),
}

#[derive(Debug, Args)]
struct MergeArgs {
    /// The shards' results.jsonl files.
    #[arg(required = true)]
    files: Vec<PathBuf>,
    /// Write the merged JUnit report here.
    #[arg(long)]
    junit: Option<PathBuf>,
    /// Write the merged results here (JSON Lines).
    #[arg(long)]
    out: Option<PathBuf>,
    /// As for `regress`.
    #[arg(long, default_value_t = 1.0)]
    min_rate: f64,
}

/// Runs `stairbench regress`.
pub fn run(a: RegressArgs) -> Result<ExitCode> {
    if let Some(RegressCommand::Merge(m)) = a.command {
        return merge(m);
    }
    let Some(suite_arg) = a.suite.as_deref() else { bail!("give a suite (a file or a name in {SUITE_DIR})") };
    anyhow::ensure!(
        a.min_rate > 0.0 && a.min_rate <= 1.0,
        "--min-rate must be in (0, 1], got {}",
        a.min_rate
    );
    anyhow::ensure!(a.timeout > 0.0, "--timeout must be positive");
    let suite = suite::load(&resolve(suite_arg)?)?;
    let mut params: ClimbParams = super::climb_params(a.params.as_deref())?;
    super::speed_up(&mut params, a.speedup)?;
    let robot = bench_robot(&params.plan.gait)?;
    let seeds = a.seeds.unwrap_or(suite.seeds).max(1);
    let (all, cases) = select_cases(&a, &suite, &robot, seeds)?;
    let out = a.out.clone().unwrap_or_else(|| Path::new("out/regress").join(&suite.name));
    if a.list {
        return list(&out, &cases, &params);
    }
    std::fs::create_dir_all(&out).with_context(|| format!("cannot create {}", out.display()))?;
    let params_file = if a.params.is_some() || a.speedup != 1.0 {
        let path = out.join("params.toml");
        std::fs::write(&path, toml::to_string(&params)?)
            .with_context(|| format!("cannot write {}", path.display()))?;
        Some(path)
    } else {
        None
    };
    let jobs = a.jobs.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get())).max(1);
    let opt = Options {
        jobs,
        timeout_s: a.timeout,
        seeds,
        out: out.clone(),
        resume: a.resume,
        record_failures: a.record_failures.clone(),
        params,
        params_file,
    };
    let info = SuiteInfo {
        name: suite.name.clone(),
        hash: suite.hash.clone(),
        seed: suite.seed,
        cases_total: all.len(),
    };
    let progress = Progress::new(a.quiet);
    let started = Instant::now();
    let ran = runner::run(&info, &cases, &opt, &|r, done, total| progress.done(r, done, total))?;
    progress.bar.finish_and_clear();
    let pace = summary::Pace { runs: ran.ran_here, elapsed_s: started.elapsed().as_secs_f64(), jobs };
    let results = ran.results;
    print!("{}", summary::text(&results, a.min_rate, Some(pace), 10));
    // A grid over two fields other than rise x tread is mapped over them too.
    let mut maps = a.map.clone();
    if let [(x, _), (y, _)] = suite.grid.as_slice() {
        if (x.as_str(), y.as_str()) != ("rise_m", "tread_m") && !maps.contains(&format!("{x},{y}")) {
            maps.push(format!("{x},{y}"));
        }
    }
    write_reports(&out, &suite.name, &results, &robot, &maps)?;
    let mut regressions = 0;
    if let Some(base) = &a.baseline {
        let before = results::read(base)?;
        let tol = Tolerances::default();
        let c = summary::compare(&before, &results, a.min_rate, &tol);
        print!("{}", summary::comparison_text(&c, &tol));
        regressions = c.newly_failing.len();
    }
    let failing = summary::by_case(&results).iter().filter(|c| !c.passes(a.min_rate)).count();
    println!("results: {}", out.join("results.jsonl").display());
    Ok(if failing > 0 || regressions > 0 { ExitCode::from(1) } else { ExitCode::SUCCESS })
}

/// The suite's cases (all of them, each in `--plant`'s body if given) and those of this
/// shard; says what was generated, each to be run `seeds` times.
fn select_cases(
    a: &RegressArgs,
    suite: &suite::Suite,
    robot: &generate::Robot,
    seeds: usize,
) -> Result<(Vec<generate::Case>, Vec<generate::Case>)> {
    let mut all = generate::cases(suite, robot)?;
    if let Some(p) = a.plant {
        for c in &mut all {
            c.scenario.plant.preset = p.preset();
            c.values.insert("plant".into(), suite::Val::Text(p.name().into()));
        }
    }
    let shard = match &a.shard {
        Some(s) => Some(Shard::parse(s, "--shard")?),
        None => Shard::from_env(&|k| std::env::var(k).ok(), a.shards)?,
    };
    let cases: Vec<generate::Case> =
        all.iter().filter(|c| shard.is_none_or(|s| s.owns(&c.id))).cloned().collect();
    let redraws: usize = all.iter().map(|c| c.redraws).sum();
    println!(
        "suite {} (seed {}, hash {}): {} cases ({} redrawn {redraws} times in all: the world could not hold them){}; {} here x {seeds} noise draws",
        suite.name,
        suite.seed,
        suite.hash,
        all.len(),
        all.iter().filter(|c| c.redraws > 0).count(),
        shard.map(|s| format!(", shard {s}")).unwrap_or_default(),
        cases.len()
    );
    Ok((all, cases))
}

/// `--list`: writes the case files and prints a line per case.
fn list(out: &Path, cases: &[generate::Case], params: &ClimbParams) -> Result<ExitCode> {
    runner::write_cases(out, cases, params)?;
    for c in cases {
        let e = c.scenario.expect.as_ref();
        println!(
            "{}  {:?}  {}  {}",
            c.id,
            e.map(|e| e.outcome),
            describe(c),
            e.map(|e| e.reason.as_str()).unwrap_or("")
        );
    }
    println!("case files written to {}", out.join("cases").display());
    Ok(ExitCode::SUCCESS)
}

/// The progress bar and a line per run as runs end.
struct Progress {
    bar: indicatif::ProgressBar,
    passed: AtomicUsize,
    failed: AtomicUsize,
    quiet: bool,
}

impl Progress {
    fn new(quiet: bool) -> Self {
        let bar = super::progress_bar(0, "regress", quiet);
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{msg} [{bar:30}] {pos}/{len} elapsed {elapsed_precise} eta {eta}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
            .progress_chars("=> "),
        );
        Self { bar, passed: AtomicUsize::new(0), failed: AtomicUsize::new(0), quiet }
    }

    /// Run `r` ended, `done` of `total`.
    fn done(&self, r: &CaseResult, done: usize, total: usize) {
        let bar = &self.bar;
        bar.set_length(total as u64);
        bar.set_position(done as u64);
        let counter = if r.pass { &self.passed } else { &self.failed };
        counter.fetch_add(1, Ordering::Relaxed);
        bar.set_message(format!(
            "pass {} fail {}",
            self.passed.load(Ordering::Relaxed),
            self.failed.load(Ordering::Relaxed)
        ));
        if self.quiet {
            return;
        }
        // A line per run: above the bar on a terminal, as plain lines in a CI log.
        let line = format!(
            "{} {} draw {} {:<24} {:>5.1} s  {}",
            if r.pass { "  ok  " } else { "  FAIL" },
            r.id,
            r.seed_index,
            r.verdict,
            r.wall_s,
            if r.pass { String::new() } else { r.message.clone().unwrap_or_default() }
        );
        if bar.is_hidden() {
            println!("{line}");
        } else {
            bar.println(line);
        }
    }
}

/// A case's main figures in a line.
fn describe(c: &generate::Case) -> String {
    let s = &c.scenario.staircase;
    format!(
        "{} steps x {:.3} m rise x {:.3} m tread, {:.2} m wide, yaw {:.0} deg, {} boxes{}{}",
        s.steps,
        s.rise_m,
        s.tread_m,
        s.width_m,
        s.yaw_deg,
        c.scenario.boxes.len(),
        if s.missing_steps.is_empty() {
            String::new()
        } else {
            format!(", step {:?} missing", s.missing_steps)
        },
        if c.params.is_some() { ", its own climb parameters" } else { "" }
    )
}

/// JUnit and the maps of `results` in `out`.
fn write_reports(
    out: &Path,
    suite: &str,
    results: &[CaseResult],
    robot: &generate::Robot,
    extra_maps: &[String],
) -> Result<()> {
    let cases_dir = out.join("cases");
    let scenario_of = |id: &str| std::fs::read_to_string(cases_dir.join(format!("{id}.toml"))).ok();
    let junit_path = out.join("junit.xml");
    junit::write(&junit_path, suite, results, &scenario_of).map_err(anyhow::Error::msg)?;
    println!("JUnit: {}", junit_path.display());
    let g = &robot.gait;
    let mut wanted = vec![("rise_m".to_string(), "tread_m".to_string())];
    for m in extra_maps {
        let Some((x, y)) = m.split_once(',') else { bail!("--map {m}: expected two parameters, X,Y") };
        for k in [x, y] {
            anyhow::ensure!(suite::field(k).is_some(), "--map {m}: `{k}` is not a suite field");
        }
        wanted.push((x.to_string(), y.to_string()));
    }
    for (x, y) in wanted {
        let mut limits = Vec::new();
        for (axis, key) in [('x', &x), ('y', &y)] {
            match key.as_str() {
                "rise_m" => {
                    limits.push((axis, g.max_rise_m, format!("max rise {:.2} m (plan.gait)", g.max_rise_m)))
                }
                "tread_m" => limits.push((
                    axis,
                    g.min_tread_m,
                    format!("min tread {:.2} m (plan.gait)", g.min_tread_m),
                )),
                _ => {}
            }
        }
        let path = out.join(format!("map_{x}_{y}.png"));
        match maps::draw(&path, &format!("{suite}: verdict over {x} x {y}"), results, &x, &y, &limits) {
            Ok(()) => println!("map: {}", path.display()),
            Err(e) => eprintln!("warning: {e}"),
        }
    }
    Ok(())
}

/// `regress merge`.
fn merge(m: MergeArgs) -> Result<ExitCode> {
    let mut parts = Vec::new();
    for f in &m.files {
        parts.push(results::read(f)?);
    }
    let merged = shard::merge(parts)?;
    let suite = merged.first().map(|r| r.suite.clone()).unwrap_or_default();
    println!("merged {} runs of suite {suite} from {} shards", merged.len(), m.files.len());
    if let Some(path) = &m.out {
        super::ensure_parent(path)?;
        let mut text = String::new();
        for r in &merged {
            text += &serde_json::to_string(r)?;
            text.push('\n');
        }
        std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))?;
        println!("results: {}", path.display());
    }
    if let Some(path) = &m.junit {
        super::ensure_parent(path)?;
        let dirs: Vec<PathBuf> =
            m.files.iter().map(|f| f.parent().unwrap_or(Path::new(".")).join("cases")).collect();
        let scenario_of =
            |id: &str| dirs.iter().find_map(|d| std::fs::read_to_string(d.join(format!("{id}.toml"))).ok());
        junit::write(path, &suite, &merged, &scenario_of).map_err(anyhow::Error::msg)?;
        println!("JUnit: {}", path.display());
    }
    print!("{}", summary::text(&merged, m.min_rate, None, 10));
    let failing = summary::by_case(&merged).iter().filter(|c| !c.passes(m.min_rate)).count();
    Ok(if failing > 0 { ExitCode::from(1) } else { ExitCode::SUCCESS })
}

/// A suite argument: a file, or a name in scenarios/suites/.
fn resolve(arg: &Path) -> Result<PathBuf> {
    if arg.exists() {
        return Ok(arg.to_path_buf());
    }
    let by_name = Path::new(SUITE_DIR).join(arg).with_extension("toml");
    if arg.components().count() == 1 && by_name.exists() {
        return Ok(by_name);
    }
    let Ok(dir) = std::fs::read_dir(SUITE_DIR) else {
        let here = std::env::current_dir().map_or_else(|_| ".".into(), |d| d.display().to_string());
        bail!(
            "no suite file {}, and no {SUITE_DIR}/ in {here} to find it by name: run from the project's root, or give the suite file's path",
            arg.display()
        )
    };
    let mut known: Vec<String> = dir
        .filter_map(|e| e.ok())
        .filter_map(|e| e.path().file_stem().map(|s| s.to_string_lossy().into_owned()))
        .collect();
    known.sort();
    bail!("no suite file {} (suites by name: {})", arg.display(), known.join(", "))
}
