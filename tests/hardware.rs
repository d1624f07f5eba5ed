//! The hardware path (issue 17) against the sensor-head emulator: the real SCIP 2.0 and
//! Dynamixel drivers, over TCP and pseudo-terminals, sweep the emulated head; the cloud and the
//! steps match the simulated path's; each fault is a clear error and nothing received is lost.

mod common;

use stairbench::cancel::Cancel;
use stairbench::perception::{metrics, perceive, PerceptionParams};
use stairbench::scenario::Scenario;
use stairbench::sensor::dynamixel::Protocol;
use stairbench::sensor::hardware::{standing_head_pose, HardwareConfig, HardwareSource};
use stairbench::sensor::{AssembleParams, Source};
use stairbench::sim::emulator::{Emulator, EmulatorConfig};
use std::sync::Mutex;

static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

/// Exp. 1 (its sweep: 60 deg at 10 deg/s, 6 s, 240 rows).
fn scenario() -> Scenario {
    Scenario::default()
}

fn config(emu: &Emulator, protocol: Protocol) -> HardwareConfig {
    let mut text = String::new();
    match (&emu.lidar_address, &emu.lidar_pty) {
        (Some(a), _) => text += &format!("[lidar]\naddress = \"{a}\"\n"),
        (None, Some(p)) => text += &format!("[lidar]\nserial = \"{p}\"\n"),
        _ => unreachable!("the emulator has a lidar port"),
    }
    text += &format!(
        "[servo]\nserial = \"{}\"\nbaud = 1000000\nid = 1\nprotocol = {}\n[sweep]\ntilt_start_deg = 10.0\ntilt_end_deg = 70.0\ntilt_speed_dps = 10.0\n",
        emu.servo_pty,
        u8::from(protocol)
    );
    HardwareConfig::parse(&text, "test.toml").unwrap()
}

fn log(m: &str) {
    println!("{m}");
}

#[test]
fn the_hardware_path_against_the_emulator_sees_the_steps_the_simulated_path_sees() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let s = scenario();
    let emu =
        Emulator::start(&s, EmulatorConfig { start_tilt_deg: 0.0, ..EmulatorConfig::default() }).unwrap();
    let cfg = config(&emu, Protocol::One);
    let mut src = HardwareSource::new(&cfg, standing_head_pose().unwrap(), log);
    let sweep = src.sweep(&Cancel::never(), &mut |_, _| {}).unwrap();
    println!("{} rows", sweep.rows.len());
    assert!((230..=245).contains(&sweep.rows.len()), "about 240 rows of 25 ms over the 6 s sweep");
    let cloud = sweep.assemble(&AssembleParams::default()).unwrap();
    let scene = common::scene_of(&s);
    let found = perceive(&cloud, &PerceptionParams::default()).unwrap();
    let score = metrics::score(&found.segments, scene.steps(), 0.02);
    let sim = stairbench::sim::scan_scenario(&s, &mut |_, _| {}).unwrap();
    let sim_found =
        perceive(&sim.sweep.assemble(&AssembleParams::default()).unwrap(), &PerceptionParams::default())
            .unwrap();
    let sim_score = metrics::score(&sim_found.segments, scene.steps(), 0.02);
    println!("hardware path: {score:?}\nsimulated path: {sim_score:?}");
    assert_eq!(score.found, 3);
    assert_eq!(score.found, sim_score.found, "the same steps found");
    for (h, m) in score.steps.iter().zip(&sim_score.steps) {
        assert!(h.iou > 0.7 && (h.iou - m.iou).abs() < 0.1, "IoU {} against {}", h.iou, m.iou);
    }
    let heights: Vec<f64> = found.segments.iter().map(|r| r.height_m()).collect();
    for (i, truth) in scene.steps().iter().enumerate() {
        assert!((heights[i] - truth.height_m).abs() < 0.01, "step {}: {} m", i + 1, heights[i]);
    }
    // A second sweep on the same connections.
    let again = src.sweep(&Cancel::never(), &mut |_, _| {}).unwrap();
    assert!(again.rows.len() > 200);
}
