//! `stairbench replay FILE.mcap`: reruns perception on the recorded lidar rows (not the
//! recorded cloud) of every sweep, merges the steps as the closed loop does, replans (as many
//! stances as were planned) from the recorded configuration, and compares the rectangles and the plan with those recorded at
//! the time. With the recorded parameters they must be equal (exit 1 otherwise); `--set` or
//! `--params` reruns with other parameters and prints the difference.

use anyhow::{bail, Context, Result};
use clap::Args;
use stairbench::params::ClimbParams;
use stairbench::record::compare::{replay, PerceptionVerdict, PlanVerdict, SweepReplay};
use stairbench::record::replay::read;
use std::path::PathBuf;
use std::process::ExitCode;

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
    let replayed = replay(&rec, &params, &model)?;
    for (i, r) in replayed.iter().enumerate() {
        print_sweep(i + 1, r);
    }
    let differ: usize = replayed
        .iter()
        .map(|r| {
            usize::from(r.perception.differs())
                + usize::from(r.plan.as_ref().is_some_and(PlanVerdict::differs))
        })
        .sum();
    let compared = replayed.iter().filter(|r| r.perception != PerceptionVerdict::NotRecorded).count();
    if changed {
        println!("{differ} differences over {} sweeps with the changed parameters", rec.sweeps.len());
        return Ok(ExitCode::SUCCESS);
    }
    // A view no plan followed, before the last, was a look set aside; without `/run/view` the
    // replay cannot take it as the loop did.
    let last = rec.sweeps.len().saturating_sub(1);
    let unknown_view =
        rec.sweeps.iter().take(last).any(|s| s.perception.is_some() && s.plan.is_none() && s.view.is_none());
    if unknown_view {
        println!(
            "note: a look set aside to look again standing has no /run/view (recorded before it was): its view was taken into the step map alone, and the plans after it may differ"
        );
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

/// Prints sweep `n`'s replay.
fn print_sweep(n: usize, r: &SweepReplay) {
    let verdict = match &r.perception {
        PerceptionVerdict::NotRecorded => "no recorded perception to compare".to_string(),
        PerceptionVerdict::SameNoStaircase(e) => format!("same: no staircase, then and now ({e})"),
        PerceptionVerdict::SameRectangles => "same rectangles".to_string(),
        PerceptionVerdict::Moved(d) => format!("DIFFERENT: corners move by up to {:.1} mm", d * 1e3),
        PerceptionVerdict::Count { now, then } => format!("DIFFERENT: {now} rectangles, recorded {then}"),
        PerceptionVerdict::FailedNow { error, then } => {
            format!("DIFFERENT: {error} (recorded {then} rectangles)")
        }
    };
    println!(
        "sweep {n} at t = {:.2} s: {} rows, {} points -> {} rectangles: {verdict}",
        r.stamp_s, r.rows, r.points, r.rectangles
    );
    if let Some([height_m, depth_m]) = r.deferred {
        println!(
            "  step map: the step at {height_m:.3} m, seen {depth_m:.3} m deep, and any above it are left for a closer look"
        );
    }
    if let Some(why) = &r.closer_look {
        println!("  plan: a walk to look again (from here, {why})");
    }
    let Some(plan) = &r.plan else { return };
    let verdict = match plan {
        PlanVerdict::NoStartConfiguration => {
            "DIFFERENT: the recorded plan has no usable start configuration".to_string()
        }
        PlanVerdict::RefusedNow(why) => format!("DIFFERENT: refused now ({why})"),
        PlanVerdict::OtherTrajectory => {
            "DIFFERENT q(t): the same footholds and segments, another joint trajectory".to_string()
        }
        PlanVerdict::Same { stances, duration_s, q_recorded } => format!(
            "same plan: {stances} stances, {duration_s:.1} s of motion, q(t){}",
            if *q_recorded { " equal" } else { " not recorded" }
        ),
        PlanVerdict::Different { what, now_s, then_s } => {
            format!("DIFFERENT {what}: {now_s:.1} s of motion now, {then_s:.1} s recorded")
        }
    };
    println!("  plan: {verdict}");
}
