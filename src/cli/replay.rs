//! `stairbench replay FILE.mcap`: reruns perception on the recorded lidar rows (not the
//! recorded cloud) of every sweep, merges the steps as the closed loop does, replans (as many
//! stances as were planned) from the recorded configuration, and compares the rectangles and the plan with those recorded at
//! the time. With the recorded parameters they must be equal (exit 1 otherwise); `--set` or
//! `--params` reruns with other parameters and prints the difference.

use anyhow::{bail, Context, Result};
use clap::Args;
use stairbench::climb::{add_view, feet_height_m, moved_view, plan_next};
use stairbench::params::ClimbParams;
use stairbench::perception::step_map::StepMap;
use stairbench::perception::surroundings::Surroundings;
use stairbench::perception::PerceptionError;
use stairbench::perception::{perceive, PlaneSegment};
use stairbench::planning::clearance::SeenPoints;
use stairbench::record::messages::{PerceptionMsg, PlanMsg};
use stairbench::record::replay::{read, RecordedSweep};
use stairbench::sensor::AssembleParams;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;

/// Arguments of `stairbench replay`.
#[derive(Debug, Args)]
pub struct ReplayArgs {
    /// The recording (from `run --record` or `scan --record`).
    file: PathBuf,
    /// Parameters as TOML (as for `run --params`), instead of the recorded ones.
    #[arg(long)]
    params: Option<PathBuf>,
    /// Change one parameter, e.g. `--set perception.k=15` (repeatable; applied after
    /// --params or the recorded parameters).
    #[arg(long = "set", value_name = "PATH=VALUE")]
    set: Vec<String>,
}

/// Corners of the recorded segments, metres.
fn recorded_corners(m: &PerceptionMsg) -> Vec<[[f64; 3]; 4]> {
    m.segments.iter().map(corners_of).collect()
}

fn corners_of(s: &PlaneSegment) -> [[f64; 3]; 4] {
    s.corners().map(|p| [p.x, p.y, p.z])
}

/// The largest corner distance between two lists of rectangles, metres (`None` when their
/// counts differ).
fn difference_m(a: &[[[f64; 3]; 4]], b: &[[[f64; 3]; 4]]) -> Option<f64> {
    (a.len() == b.len()).then(|| {
        a.iter()
            .zip(b)
            .flat_map(|(x, y)| x.iter().zip(y))
            .map(|(p, q)| ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt())
            .fold(0.0, f64::max)
    })
}

/// The parameters to replay with: the file's `--params`, else the recorded ones, else the
/// defaults; then every `--set`.
fn parameters(a: &ReplayArgs, recorded: Option<&[u8]>) -> Result<ClimbParams> {
    let text = match (&a.params, recorded) {
        (Some(p), _) => std::fs::read_to_string(p).with_context(|| format!("cannot read {}", p.display()))?,
        (None, Some(bytes)) => String::from_utf8_lossy(bytes).into_owned(),
        (None, None) => toml::to_string(&ClimbParams::default())?,
    };
    let mut doc: toml_edit::DocumentMut = text.parse().context("the parameters are not TOML")?;
    for s in &a.set {
        let Some((path, value)) = s.split_once('=') else { bail!("--set {s}: expected PATH=VALUE") };
        let value: toml_edit::Value =
            value.trim().parse().with_context(|| format!("--set {s}: `{value}` is not a TOML value"))?;
        // The paper's symbols for the fields that have one (Table 1's k, say).
        let path = match path.trim() {
            "perception.k" => "perception.normal_neighbours",
            p => p,
        };
        let keys: Vec<&str> = path.split('.').collect();
        let (last, tables) = keys.split_last().context("empty --set path")?;
        let mut item = doc.as_item_mut();
        for k in tables {
            item = &mut item[*k];
            if item.is_none() {
                *item = toml_edit::table();
            }
        }
        item[*last] = toml_edit::value(value);
    }
    toml::from_str(&doc.to_string()).context("the parameters do not fit (unknown field or wrong type)")
}

/// Runs `stairbench replay`.
pub fn run(a: ReplayArgs) -> Result<ExitCode> {
    let rec = read(&a.file)?;
    let counts: Vec<String> = rec.counts.iter().map(|(t, n)| format!("{t} {n}")).collect();
    println!("{}: {}", a.file.display(), counts.join(", "));
    if let Some(d) = &rec.damage {
        println!("warning: {d}; replaying the {} complete sweeps before it", rec.sweeps.len());
    }
    if rec.sweeps.is_empty() {
        bail!("{}: no complete lidar sweep to replay", a.file.display());
    }
    let changed = a.params.is_some() || !a.set.is_empty();
    let params = parameters(&a, rec.attachments.get("params.toml").map(Vec::as_slice))?;
    let model = stairbench::robot::hrp4::model()?;
    let mut map = StepMap::default();
    let mut around = Surroundings::default();
    // The floor the climb started from, as the loop took it: the feet at the first plan.
    let start_floor_z_m = rec
        .sweeps
        .iter()
        .find_map(|s| s.plan.as_ref())
        .map_or(f64::NAN, |first| feet_height_m(&model, &first.q0));
    let (mut differ, mut compared) = (0, 0);
    for (i, RecordedSweep { stamp_s, sweep, perception, plan: planned, trajectory, .. }) in
        rec.sweeps.iter().enumerate()
    {
        let mut cloud = sweep.assemble(&AssembleParams::default())?;
        let now = perceive(&cloud, &params.perception);
        let found: Vec<[[f64; 3]; 4]> =
            now.as_ref().map(|r| r.segments.iter().map(corners_of).collect()).unwrap_or_default();
        let then = perception.as_ref().map(recorded_corners);
        let recorded_error = perception.as_ref().and_then(|m| m.error.as_deref());
        compared += usize::from(then.is_some());
        let verdict = match (&then, &now) {
            (None, _) => "no recorded perception to compare".to_string(),
            (Some(_), Err(e)) if recorded_error.is_some() => {
                format!("same: no staircase, then and now ({e})")
            }
            (Some(t), Ok(_)) => match difference_m(t, &found) {
                Some(0.0) => "same rectangles".to_string(),
                Some(d) => {
                    differ += 1;
                    format!("DIFFERENT: corners move by up to {:.1} mm", d * 1e3)
                }
                None => {
                    differ += 1;
                    format!("DIFFERENT: {} rectangles, recorded {}", found.len(), t.len())
                }
            },
            (Some(t), Err(e)) => {
                differ += 1;
                format!("DIFFERENT: {e} (recorded {} rectangles)", t.len())
            }
        };
        println!(
            "sweep {} at t = {stamp_s:.2} s: {} rows, {} points -> {} rectangles: {verdict}",
            i + 1,
            sweep.rows.len(),
            cloud.len(),
            found.len()
        );
        // The loop's next steps: the step map's next input, planned from the recorded pose.
        let mut seen = match now {
            Ok(r) => r.segments,
            Err(PerceptionError::NoStaircase(_)) => Vec::new(),
            Err(_) => continue,
        };
        // On the robot's own estimate the loop registered each view on the step map and moved
        // it (the robot with it: the recorded plan starts there): so does the replay.
        if let Some(offset) = params.estimate.enabled.then(|| map.register(&seen, &params.step_map)).flatten()
        {
            let (moved, moved_cloud) = moved_view(&offset, seen, &mut sweep.clone());
            seen = moved;
            if let Some(c) = moved_cloud {
                cloud = c;
            }
        }
        let Some(then) = planned else {
            // No plan followed this sweep (the top, or a refusal): the view still enters the map.
            map.update(seen, &params.step_map);
            continue;
        };
        if then.q0.len() != model.nq() {
            differ += 1;
            println!("  plan: DIFFERENT: the recorded plan has no usable start configuration");
            continue;
        }
        add_view(&mut around, &cloud, &model, &then.q0, &params.surroundings);
        let surfaces = Arc::new(SeenPoints::new(around.points(&params.surroundings)));
        let next = map.next_input(
            seen,
            feet_height_m(&model, &then.q0),
            params.plan.gait.min_tread_m,
            &params.step_map,
        );
        if let Some(top) = &next.deferred {
            println!(
                "  step map: the step at {:.3} m, seen {:.3} m deep, and any above it are left for a closer look",
                top.height_m(),
                top.depth_m()
            );
        }
        let verdict =
            // As many stances as were planned then (the loop plans a few per scan, a rehearsal
            // all it sees).
            match plan_next(
                &model,
                &then.q0,
                &next,
                surfaces,
                then.stances.len(),
                start_floor_z_m,
                &params.plan,
            ) {
                Err(e) => {
                    differ += 1;
                    format!("DIFFERENT: refused now ({})", e.message)
                }
                Ok((p, closer_look)) => {
                    if let Some(r) = closer_look {
                        println!("  plan: a walk to look again (from here, {})", r.message);
                    }
                    let now = PlanMsg::of(then.start_s, &next.ahead, &p);
                    let same_q = trajectory.as_ref().is_none_or(|t| {
                        t.q.len() == p.trajectory.samples.len()
                            && t.q.iter().zip(&p.trajectory.samples).all(|(a, b)| *a == b.q)
                    });
                    match now.differs_from(then) {
                        None if !same_q => {
                            differ += 1;
                            "DIFFERENT q(t): the same footholds and segments, another joint trajectory"
                                .to_string()
                        }
                        None => format!(
                            "same plan: {} stances, {:.1} s of motion, q(t){}",
                            p.stances.len(),
                            p.duration_s(),
                            if trajectory.is_some() { " equal" } else { " not recorded" }
                        ),
                        Some(k) => {
                            differ += 1;
                            format!(
                                "DIFFERENT {k}: {:.1} s of motion now, {:.1} s recorded",
                                now.duration_s, then.duration_s
                            )
                        }
                    }
                }
            };
        println!("  plan: {verdict}");
    }
    if changed {
        println!("{differ} differences over {} sweeps with the changed parameters", rec.sweeps.len());
        return Ok(ExitCode::SUCCESS);
    }
    if differ > 0 || rec.damage.is_some() {
        println!("replay differs from the recording or the file is damaged");
        return Ok(ExitCode::from(1));
    }
    if compared == 0 {
        println!("the recording holds sweeps only (as `scan --record` writes): nothing to compare");
        return Ok(ExitCode::SUCCESS);
    }
    println!("replay equals the recording");
    Ok(ExitCode::SUCCESS)
}
