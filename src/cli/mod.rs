//! Subcommands of the binary and the helpers they share (scenario lookup, progress bars,
//! recordings).

pub mod bench;
pub mod emulate;
pub mod perceive;
pub mod plan;
pub mod polygon;
pub mod regress;
pub mod rehearse;
pub mod replay;
pub mod run;
pub mod scan;
pub mod scene;

use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use stairbench::scenario::Scenario;
use std::path::{Path, PathBuf};

/// Overrides of a scenario's lidar noise, for the commands that scan one.
#[derive(Debug, Clone, clap::Args)]
pub struct NoiseArgs {
    /// Override the range noise, millimetres (0 for a noise-free scan; scenario input only).
    #[arg(long)]
    noise_mm: Option<f64>,
    /// Override the scenario's random seed (the noise drawn in every scan): the same
    /// staircase through another noise draw, to check a result is not luck.
    #[arg(long)]
    seed: Option<u64>,
}

impl NoiseArgs {
    /// `scenario` with the overrides given (it is validated when its world is built).
    pub fn apply(&self, scenario: &mut Scenario) {
        if let Some(mm) = self.noise_mm {
            scenario.lidar.noise_sigma_m = mm / 1000.0;
        }
        if let Some(seed) = self.seed {
            scenario.seed = seed;
        }
    }
}

/// Folder searched for a scenario given by name (`exp2` → `scenarios/exp2.toml`).
const SCENARIO_DIR: &str = "scenarios";

/// The climb parameters of `path` (a TOML file as `run --params` takes), or the defaults.
pub fn climb_params(path: Option<&Path>) -> Result<stairbench::params::ClimbParams> {
    let Some(p) = path else { return Ok(Default::default()) };
    let text = std::fs::read_to_string(p).with_context(|| format!("cannot read {}", p.display()))?;
    let params: stairbench::params::ClimbParams =
        toml::from_str(&text).with_context(|| format!("{}: not climb parameters", p.display()))?;
    params.validate().map_err(|e| anyhow::anyhow!("{}: {e}", p.display()))?;
    Ok(params)
}

/// `params` with the planned motion `speedup` times faster (`--speedup`: the CoM's and the
/// foot's speeds, the shortest segment and swing piece, the IK's joint speed bound).
pub fn speed_up(params: &mut stairbench::params::ClimbParams, speedup: f64) -> Result<()> {
    anyhow::ensure!(
        speedup.is_finite() && speedup > 0.0,
        "--speedup must be a positive number, got {speedup}"
    );
    params.plan = params.plan.faster(speedup);
    Ok(())
}

/// The scenario named on the command line: a path, a name in `scenarios/`, or (none) the
/// built-in default, the paper's Exp. 1.
pub fn load_scenario(arg: Option<&Path>) -> Result<Scenario> {
    let Some(arg) = arg else { return Ok(Scenario::default()) };
    let path = resolve_scenario(arg)?;
    Scenario::load(&path).map_err(anyhow::Error::from)
}

fn resolve_scenario(arg: &Path) -> Result<PathBuf> {
    if arg.exists() {
        return Ok(arg.to_path_buf());
    }
    let by_name = Path::new(SCENARIO_DIR).join(arg).with_extension("toml");
    if arg.components().count() == 1 && by_name.exists() {
        return Ok(by_name);
    }
    let known: Vec<String> = std::fs::read_dir(SCENARIO_DIR)
        .map(|d| {
            d.filter_map(|e| e.ok())
                .map(|e| e.path())
                .filter(|p| p.extension().is_some_and(|x| x == "toml"))
                .filter_map(|p| p.file_stem().map(|s| s.to_string_lossy().into_owned()))
                .collect()
        })
        .unwrap_or_default();
    if known.is_empty() {
        bail!("no scenario file {}", arg.display());
    }
    let mut known = known;
    known.sort();
    bail!("no scenario file {} (scenarios by name: {})", arg.display(), known.join(", "))
}

/// A progress bar on stderr (hidden when stderr is not a terminal or `quiet`).
pub fn progress_bar(total: u64, what: &str, quiet: bool) -> ProgressBar {
    if quiet {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(total);
    bar.set_style(
        ProgressStyle::with_template("{msg:>10} [{bar:40}] {pos}/{len} {elapsed_precise} eta {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    bar.set_message(what.to_string());
    bar
}

/// Creates the parent folder of an output file.
pub fn ensure_parent(path: &Path) -> Result<()> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    Ok(())
}

/// Opens a recording for `command` on `scenario` with `params` (attached as TOML).
pub fn start_recording(
    path: &Path,
    command: &str,
    scenario: &Scenario,
    params: &impl serde::Serialize,
) -> Result<stairbench::record::Recorder> {
    let attached = ("scenario.toml", toml::to_string(scenario)?);
    open_recording(path, command, &scenario.name, attached, toml::to_string(params)?)
}

/// Opens a recording of the hardware path: the hardware file and the parameters attached.
pub fn start_hardware_recording(
    path: &Path,
    command: &str,
    hardware: &stairbench::sensor::hardware::HardwareConfig,
    params: &impl serde::Serialize,
) -> Result<stairbench::record::Recorder> {
    let attached = ("hardware.toml", toml::to_string(hardware)?);
    open_recording(path, command, "hardware", attached, toml::to_string(params)?)
}

/// A new recording: the command, version and `source` as metadata, `attached` (a file name
/// and its TOML) and the parameters as attachments.
fn open_recording(
    path: &Path,
    command: &str,
    source: &str,
    attached: (&str, String),
    params_toml: String,
) -> Result<stairbench::record::Recorder> {
    ensure_parent(path)?;
    let model = stairbench::robot::hrp4::model()?;
    let mut rec = stairbench::record::Recorder::create(path, &model)?;
    let meta = [
        ("command".to_string(), command.to_string()),
        ("version".to_string(), env!("CARGO_PKG_VERSION").to_string()),
        ("scenario".to_string(), source.to_string()),
    ];
    rec.metadata("stairbench", meta.into_iter().collect());
    rec.attach(attached.0, "application/toml", attached.1.as_bytes());
    rec.attach("params.toml", "application/toml", params_toml.as_bytes());
    Ok(rec)
}

/// One sweep of the real sensor head of the hardware file `path` (or of `stairbench emulate`),
/// with a progress bar; Ctrl-C stops it. A sweep cut short is recorded as far as it went
/// (when recording) and is an error naming the row and the cause.
pub fn hardware_sweep(
    path: &Path,
    quiet: bool,
    mut recorder: Option<&mut stairbench::record::Recorder>,
) -> Result<(stairbench::sensor::hardware::HardwareConfig, stairbench::sensor::Sweep)> {
    use stairbench::robot::hrp4::standing_head_pose;
    use stairbench::sensor::hardware::{HardwareConfig, HardwareSource};
    use stairbench::sensor::{SensorError, Source};
    let cfg = HardwareConfig::load(path)?;
    let cancel = stairbench::cancel::Cancel::new();
    let on_signal = cancel.clone();
    if ctrlc::set_handler(move || on_signal.cancel()).is_err() {
        eprintln!("warning: Ctrl-C will not stop the sweep cleanly");
    }
    let mut source = HardwareSource::new(&cfg, standing_head_pose()?, |m| eprintln!("{m}"));
    let bar = progress_bar(0, "sweep", quiet);
    let result = source.sweep(&cancel, &mut |done, total| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    });
    bar.finish_and_clear();
    if let Some(n) = source.last_stats().map(|s| s.servo_corrupt_replies).filter(|&n| n > 0) {
        eprintln!("servo: {n} replies came garbled (checksum failed) and were asked for again");
    }
    match result {
        Ok(sweep) => {
            if let Some(rec) = recorder.as_deref_mut() {
                let stamp_s = sweep.rows.last().map_or(0.0, |r| r.stamp_s);
                rec.sweep(stamp_s, &sweep);
            }
            Ok((cfg, sweep))
        }
        Err(SensorError::Cut { partial, why }) => {
            if let Some(rec) = recorder {
                let stamp_s = partial.rows.last().map_or(0.0, |r| r.stamp_s);
                rec.sweep(stamp_s, &partial);
                eprintln!("the {} rows received are in the recording", partial.rows.len());
            }
            bail!("the sweep was cut after {} rows: {why}", partial.rows.len())
        }
        Err(e) => Err(e.into()),
    }
}

/// The `[plant]` presets, at the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum PlantArg {
    /// The model exactly.
    Nominal,
    /// A body like a real HRP-4 against its model.
    Hrp4Like,
}

impl PlantArg {
    /// The scenario's preset.
    pub fn preset(self) -> stairbench::scenario::PlantPreset {
        match self {
            Self::Nominal => stairbench::scenario::PlantPreset::Nominal,
            Self::Hrp4Like => stairbench::scenario::PlantPreset::Hrp4Like,
        }
    }

    /// Its name in files.
    pub fn name(self) -> &'static str {
        match self {
            Self::Nominal => "nominal",
            Self::Hrp4Like => "hrp4-like",
        }
    }
}
