//! The hardware path (issue 17) against the sensor-head emulator: the real SCIP 2.0 and
//! Dynamixel drivers, over TCP and pseudo-terminals, sweep the emulated head; the cloud and the
//! steps match the simulated path's; each fault is a clear error and nothing received is lost.

// Test helpers unwrap: a panic there is the test failing.
#![allow(clippy::unwrap_used)]

mod common;

use stairbench::cancel::Cancel;
use stairbench::perception::{metrics, perceive, PerceptionParams};
use stairbench::robot::hrp4::standing_head_pose;
use stairbench::scenario::Scenario;
use stairbench::sensor::dynamixel::Protocol;
use stairbench::sensor::hardware::{HardwareConfig, HardwareSource};
use stairbench::sensor::{AssembleParams, SensorError, Source};
use stairbench::sim::emulator::{
    Emulator, EmulatorConfig, LidarFaults, LidarPort, SensorClock, ServoFaults, ServoSpec,
};
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
    let sweep = swept(src.sweep(&Cancel::never(), &mut |_, _| {}));
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
    let again = swept(src.sweep(&Cancel::never(), &mut |_, _| {}));
    assert!(again.rows.len() > 200);
}

/// A config for `emu` with a quick sweep (10 to 40 deg at 30 deg/s: 1 s, 40 rows).
fn quick(emu: &Emulator, protocol: Protocol) -> HardwareConfig {
    let mut c = config(emu, protocol);
    c.sweep.tilt_end_deg = 40.0;
    c.sweep.tilt_speed_dps = 30.0;
    c.lidar.reply_timeout_s = 0.3;
    c
}

fn emulator(cfg: EmulatorConfig) -> Emulator {
    Emulator::start(&scenario(), cfg).unwrap()
}

fn sweep_of(cfg: &HardwareConfig) -> Result<stairbench::sensor::Sweep, SensorError> {
    HardwareSource::new(cfg, standing_head_pose().unwrap(), log).sweep(&Cancel::never(), &mut |_, _| {})
}

/// `why` names the scan of the stream that failed, just after the `rows` kept (the rows are the
/// scans within the sweep's tilt range: one or two before it are not kept).
fn names_the_scan_after(why: &str, rows: usize) -> bool {
    (rows + 1..=rows + 3).any(|k| why.contains(&format!("scan {k} of the stream")))
}

/// The sweep, or a panic with the error's message (not the partial sweep's every range).
fn swept(r: Result<stairbench::sensor::Sweep, SensorError>) -> stairbench::sensor::Sweep {
    r.unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn protocol_2_and_a_usb_lidar_on_a_pseudo_terminal_sweep_too() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let servo = ServoSpec { protocol: Protocol::Two, ..ServoSpec::default() };
    let emu = emulator(EmulatorConfig { lidar: LidarPort::Pty, servo, ..EmulatorConfig::default() });
    let sweep = swept(sweep_of(&quick(&emu, Protocol::Two)));
    assert!((36..=42).contains(&sweep.rows.len()), "{} rows", sweep.rows.len());
    let tilts: Vec<f64> = sweep.rows.iter().map(|r| r.tilt_rad.to_degrees()).collect();
    assert!(tilts.windows(2).all(|w| w[1] >= w[0]), "the tilt grows through the sweep");
    assert!(tilts[0] < 12.0 && *tilts.last().unwrap() > 38.0, "{tilts:?}");
}

#[test]
fn a_cable_pulled_mid_sweep_keeps_the_rows_received_and_says_which_row() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    for port in [LidarPort::Tcp("127.0.0.1:0".into()), LidarPort::Pty] {
        let faults = LidarFaults { cut_after_scans: Some(20), ..LidarFaults::default() };
        let emu = emulator(EmulatorConfig {
            lidar: port.clone(),
            lidar_faults: faults,
            ..EmulatorConfig::default()
        });
        let Err(SensorError::Cut { partial, why }) = sweep_of(&quick(&emu, Protocol::One)) else {
            panic!("{port:?}: the sweep must be cut")
        };
        println!("{port:?}: {} rows kept: {why}", partial.rows.len());
        assert!((15..=20).contains(&partial.rows.len()), "the rows before the cut are kept");
        assert!(names_the_scan_after(&why, partial.rows.len()), "{why}");
        assert!(why.contains("failed") || why.contains("closed") || why.contains("gone"), "{why}");
    }
}

/// `scan --hardware --record` with the cable pulled: the command fails naming the row, and the
/// recording holds the rows received, which `replay` reads back.
#[test]
fn a_cut_sweep_is_recorded_as_far_as_it_went_and_replays() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let faults = LidarFaults { cut_after_scans: Some(40), ..LidarFaults::default() };
    let emu = emulator(EmulatorConfig { lidar_faults: faults, ..EmulatorConfig::default() });
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("cut-recording");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let (hw, rec) = (dir.join("head.toml"), dir.join("cut.mcap"));
    std::fs::write(&hw, toml::to_string(&config(&emu, Protocol::One)).unwrap()).unwrap();
    let bin = env!("CARGO_BIN_EXE_stairbench");
    let out = std::process::Command::new(bin)
        .args(["scan", "--quiet", "--hardware", hw.to_str().unwrap(), "-o"])
        .arg(dir.join("cloud.ply"))
        .arg("--record")
        .arg(&rec)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    let rows: usize = err
        .split("the sweep was cut after ")
        .nth(1)
        .and_then(|t| t.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("the error names the rows: {err}"));
    assert!((30..=40).contains(&rows) && names_the_scan_after(&err, rows), "{err}");
    assert!(!dir.join("cloud.ply").exists(), "no cloud from a cut sweep");
    let replay = std::process::Command::new(bin).arg("replay").arg(&rec).output().unwrap();
    let text = String::from_utf8_lossy(&replay.stdout);
    assert_eq!(replay.status.code(), Some(0), "{text}{}", String::from_utf8_lossy(&replay.stderr));
    assert!(
        text.contains(&format!("/lidar/scan {rows}")) && text.contains(&format!("{rows} rows")),
        "{text}"
    );
}

#[test]
fn garbled_bytes_lose_their_scan_and_a_stream_of_them_ends_the_sweep() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let some = LidarFaults { garble_every: Some(5), ..LidarFaults::default() };
    let emu = emulator(EmulatorConfig { lidar_faults: some, ..EmulatorConfig::default() });
    let sweep = swept(sweep_of(&quick(&emu, Protocol::One)));
    assert!((26..=36).contains(&sweep.rows.len()), "one scan in five lost: {} rows", sweep.rows.len());
    drop(emu);
    let all = LidarFaults { garble_every: Some(1), ..LidarFaults::default() };
    let emu = emulator(EmulatorConfig { lidar_faults: all, ..EmulatorConfig::default() });
    let Err(SensorError::Cut { partial, why }) = sweep_of(&quick(&emu, Protocol::One)) else { panic!("cut") };
    assert!(partial.rows.is_empty() && why.contains("check character"), "{why}");
}

#[test]
fn a_status_of_error_is_named_with_its_meaning() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let faults = LidarFaults { md_status: Some(*b"50"), ..LidarFaults::default() };
    let emu = emulator(EmulatorConfig { lidar_faults: faults, ..EmulatorConfig::default() });
    let e = sweep_of(&quick(&emu, Protocol::One)).map(|s| s.rows.len()).expect_err("refused").to_string();
    assert!(e.contains("status 50") && e.contains("hardware trouble"), "{e}");
}

#[test]
fn a_lidar_that_stops_sending_times_out_and_the_sweep_keeps_its_rows() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let faults = LidarFaults { silent_after_scans: Some(10), ..LidarFaults::default() };
    let emu = emulator(EmulatorConfig { lidar_faults: faults, ..EmulatorConfig::default() });
    let Err(SensorError::Cut { partial, why }) = sweep_of(&quick(&emu, Protocol::One)) else { panic!("cut") };
    assert!(
        (5..=10).contains(&partial.rows.len()) && why.contains("did not answer"),
        "{} rows: {why}",
        partial.rows.len()
    );
}

#[test]
fn a_servo_that_is_silent_overloaded_or_on_another_baud_rate_or_protocol_is_named() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let run = |servo: ServoSpec, protocol: Protocol| {
        let emu = emulator(EmulatorConfig { servo, ..EmulatorConfig::default() });
        sweep_of(&quick(&emu, protocol))
    };
    let silent =
        ServoSpec { faults: ServoFaults { silent: true, ..ServoFaults::default() }, ..ServoSpec::default() };
    let e = run(silent, Protocol::One).map(|s| s.rows.len()).expect_err("silent").to_string();
    assert!(e.contains("did not answer a ping"), "{e}");
    let slow = ServoSpec { baud: 57_600, ..ServoSpec::default() };
    let e = run(slow, Protocol::One).map(|s| s.rows.len()).expect_err("wrong baud").to_string();
    assert!(e.contains("no packet") && e.contains("baud rate"), "{e}");
    let two = ServoSpec { protocol: Protocol::Two, ..ServoSpec::default() };
    let e = run(two, Protocol::One).map(|s| s.rows.len()).expect_err("wrong protocol").to_string();
    assert!(e.contains("did not answer a ping"), "{e}");
    // Overloaded 1.5 s after the emulator starts (during the sweep): the sweep is cut, the error says overload.
    let hot = ServoSpec {
        faults: ServoFaults { overload_after_s: Some(1.5), ..ServoFaults::default() },
        ..ServoSpec::default()
    };
    let emu = emulator(EmulatorConfig { servo: hot, ..EmulatorConfig::default() });
    let mut cfg = quick(&emu, Protocol::One);
    cfg.sweep.tilt_speed_dps = 15.0;
    match sweep_of(&cfg) {
        Err(SensorError::Cut { partial, why }) => {
            println!("{} rows kept: {why}", partial.rows.len());
            assert!(why.contains("overload"), "{why}");
        }
        Err(e) => assert!(e.to_string().contains("overload"), "{e}"),
        Ok(s) => panic!("an overloaded servo swept {} rows", s.rows.len()),
    }
}

#[test]
fn a_lidar_that_never_answers_is_an_error_naming_its_address() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let emu = emulator(EmulatorConfig::default());
    let mut cfg = quick(&emu, Protocol::One);
    // Nothing listens there: the connection is refused.
    let free = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().to_string();
    cfg.lidar.address = Some(free.clone());
    cfg.lidar.connect_tries = 2;
    cfg.lidar.retry_delay_s = 0.05;
    let e = sweep_of(&cfg).map(|s| s.rows.len()).expect_err("refused").to_string();
    assert!(e.contains(&free) && e.contains("2 tries"), "{e}");
    // A port that accepts and says nothing.
    let mute = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    cfg.lidar.address = Some(mute.local_addr().unwrap().to_string());
    let e = sweep_of(&cfg).map(|s| s.rows.len()).expect_err("mute").to_string();
    assert!(e.contains("did not answer `VV`") && e.contains(&cfg.lidar.address.clone().unwrap()), "{e}");
}

#[test]
fn the_sensor_clock_wrapping_during_a_sweep_changes_nothing() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    // The 24-bit millisecond counter wraps 2.5 s after the emulator starts: mid-sweep.
    let clock = SensorClock { start_ms: (1 << 24) - 2_500, drift: 0.0 };
    let emu = emulator(EmulatorConfig { clock, ..EmulatorConfig::default() });
    let sweep = swept(sweep_of(&quick(&emu, Protocol::One)));
    let stamps: Vec<f64> = sweep.rows.iter().map(|r| r.stamp_s).collect();
    assert!(
        stamps.windows(2).all(|w| (w[1] - w[0] - 0.025).abs() < 0.002),
        "rows 25 ms apart across the wrap"
    );
    assert!((36..=42).contains(&sweep.rows.len()));
}

/// `stairbench run --hardware`: the rehearsal writes the trajectory only when it passes.
#[test]
fn a_rehearsal_on_the_perceived_world_writes_the_trajectory_only_when_it_passes() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("rehearsal");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let rehearse = |s: &Scenario, name: &str, extra: &[&str]| {
        let emu = Emulator::start(s, EmulatorConfig::default()).unwrap();
        let hw = dir.join(format!("{name}.toml"));
        std::fs::write(&hw, toml::to_string(&config(&emu, Protocol::One)).unwrap()).unwrap();
        let (traj, rec) = (dir.join(format!("{name}.csv")), dir.join(format!("{name}.mcap")));
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_stairbench"))
            .args([
                "run",
                "--hardware",
                hw.to_str().unwrap(),
                "--trajectory",
                traj.to_str().unwrap(),
                "--record",
                rec.to_str().unwrap(),
            ])
            .args(extra)
            .output()
            .unwrap();
        println!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
        (out.status.code(), traj.exists(), rec.exists(), String::from_utf8_lossy(&out.stdout).into_owned())
    };
    // Exp. 1: the rehearsal runs to its end; the trajectory and the recording are written if
    // and only if it passed. (Whether it passes may vary from run to run: the emulated servo's
    // timing changes the cloud a little. Passes are checked for a whole trajectory.)
    let (code, traj, rec, text) = rehearse(&scenario(), "exp1", &[]);
    assert!(text.contains("perceived 3 steps") && text.contains("rehearsal: 3 of 3 steps"), "{text}");
    let passed = text.contains("REHEARSAL PASSED");
    assert_eq!((code, traj, rec), (Some(if passed { 0 } else { 1 }), passed, passed), "{text}");
    if passed {
        let q = std::fs::read_to_string(dir.join("exp1.csv")).unwrap();
        let last_t_s: f64 = q.lines().last().and_then(|l| l.split(',').next()?.parse().ok()).unwrap();
        let samples = q.lines().count() - 1;
        // Exp. 1's whole climb, five stances of five segments: tens of seconds at any timing
        // the planner allows (not a single stance's few).
        assert!(q.starts_with("t_s,x,y,z,qw") && last_t_s > 30.0, "a whole climb: {last_t_s} s");
        assert!(samples as f64 >= 100.0 * last_t_s, "100 Hz over the climb: {samples} in {last_t_s} s");
        // The recording replays: the same steps and the same plan from the recorded rows.
        let replay = std::process::Command::new(env!("CARGO_BIN_EXE_stairbench"))
            .arg("replay")
            .arg(dir.join("exp1.mcap"))
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&replay.stdout);
        assert!(replay.status.success() && text.contains("replay equals the recording"), "{text}");
    } else {
        assert!(
            text.contains("REHEARSAL FAILED") && text.contains("  t = "),
            "a failure names its check: {text}"
        );
    }
    // A climb the planner refuses: nothing written.
    let mut high = scenario();
    high.staircase.rise_m = 0.40;
    let (code, traj, rec, text) = rehearse(&high, "high", &[]);
    assert_eq!(code, Some(1));
    assert!(!traj && !rec, "nothing written for a refused climb");
    assert!(text.contains("REFUSED") && text.contains("higher than the legs can climb"), "{text}");
    // A plan that fails in the rehearsal: soles that grip less than even the stabilized climb
    // needs (friction 0.1 in the rehearsal's world, which the checks judge by; the stabilizer
    // keeps a loaded foot at 0.15-0.25 of its normal force, and the same rehearsal on 0.2
    // passes at 0.16) slip at the first step-up. Nothing written.
    let slippery = dir.join("slippery.params.toml");
    std::fs::write(&slippery, "[run]\nrehearsal_friction = 0.1\n").unwrap();
    let (code, traj, rec, text) =
        rehearse(&scenario(), "slippery", &["--params", slippery.to_str().unwrap()]);
    assert_eq!(code, Some(1), "{text}");
    assert!(!traj && !rec, "nothing written for a failed rehearsal");
    assert!(text.contains("REHEARSAL FAILED") && text.contains("friction"), "{text}");
}

/// The floor's slope in `cloud`, degrees: a least-squares plane through the points before the
/// first step (`x` under `before_x_m`) within 10 cm of the ground's height.
fn floor_slope_deg(cloud: &stairbench::cloud::PointCloud, before_x_m: f64, ground_m: f64) -> f64 {
    let (mut m, mut v) = (nalgebra::Matrix3::<f64>::zeros(), nalgebra::Vector3::<f64>::zeros());
    for p in cloud.points() {
        let (x, y, z) = (f64::from(p.x), f64::from(p.y), f64::from(p.z));
        if x < before_x_m && (z - ground_m).abs() < 0.1 {
            let row = nalgebra::Vector3::new(x, y, 1.0);
            m += row * row.transpose();
            v += row * z;
        }
    }
    let abc = m.lu().solve(&v).expect("floor points");
    abc.x.hypot(abc.y).atan().to_degrees()
}

/// A sensor head on a tripod or pitched and rolled away from where the robot model puts it:
/// the hardware path is told only the gravity an IMU on its servo base reads, and assembles
/// in the robot's standing head pose all the same. The rises come out within 1 cm of the
/// world's and the floor level within 0.5 deg.
#[test]
fn a_head_off_the_robot_is_levelled_by_the_gravity_it_measures() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let s = scenario();
    let scene = common::scene_of(&s);
    let truth: Vec<f64> = scene.steps().iter().map(|st| st.height_m).collect();
    // (x, y, z) m and (roll, pitch, yaw) deg of the head frame, a metre behind where the robot
    // would stand (the floor before the first riser in view); the stairs are ahead on +x.
    let poses = [
        ([-1.0, 0.0, 1.4], [0.0, 0.0, 0.0]),
        ([-0.9, 0.05, 1.2], [0.0, -10.0, 0.0]),
        ([0.0, 0.0, 1.5], [0.0, 20.0, 0.0]), // pitched down: nearer, the top tread in view
        ([-1.0, 0.0, 1.4], [5.0, 5.0, 3.0]),
        ([-1.1, 0.0, 1.4], [-5.0, 0.0, -3.0]),
    ];
    for (xyz, rpy) in poses {
        let [r, p, y] = rpy.map(f64::to_radians);
        let head = nalgebra::Isometry3::from_parts(
            nalgebra::Translation3::new(xyz[0], xyz[1], xyz[2]),
            nalgebra::UnitQuaternion::from_euler_angles(r, p, y),
        );
        let emu = emulator(EmulatorConfig { head_to_world: Some(head), ..EmulatorConfig::default() });
        let mut cfg = config(&emu, Protocol::One);
        cfg.gravity.mount = Some(emu.gravity_mount(&s.lidar).into());
        let sweep = swept(
            HardwareSource::new(&cfg, standing_head_pose().unwrap(), log)
                .sweep(&Cancel::never(), &mut |_, _| {}),
        );
        let cloud = sweep.assemble(&AssembleParams::default()).unwrap();
        let found =
            perceive(&cloud, &PerceptionParams::default()).unwrap_or_else(|e| panic!("{xyz:?} {rpy:?}: {e}"));
        let heights: Vec<f64> = found.segments.iter().map(|r| r.height_m() - found.ground_m).collect();
        println!(
            "head at {xyz:?} m, {rpy:?} deg: heights {heights:.3?} m above the ground, truth {truth:.3?}"
        );
        assert_eq!(heights.len(), truth.len(), "{xyz:?} {rpy:?}: every step found");
        for (i, (h, t)) in heights.iter().zip(&truth).enumerate() {
            assert!((h - t).abs() < 0.01, "{xyz:?} {rpy:?}: step {} at {h:.3} m, truth {t:.3} m", i + 1);
        }
        let first_x = found.segments[0].corners().iter().map(|c| c.x).fold(f64::INFINITY, f64::min);
        let slope = floor_slope_deg(&cloud, first_x - 0.05, found.ground_m);
        println!("  floor slope {slope:.3} deg");
        assert!(slope < 0.5, "{xyz:?} {rpy:?}: the floor is pitched {slope:.2} deg");
    }
}

/// A noisy bus garbles a servo reply now and then: the request is sent again, the sweep goes
/// on, and its stats count the garbled replies; a servo whose every reply is garbled is an
/// error that says a checksum failed.
#[test]
fn a_garbled_servo_reply_is_asked_again_and_counted() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    for protocol in [Protocol::One, Protocol::Two] {
        let noisy = ServoSpec {
            protocol,
            faults: ServoFaults { garble_every: Some(9), ..ServoFaults::default() },
            ..ServoSpec::default()
        };
        let emu = emulator(EmulatorConfig { servo: noisy, ..EmulatorConfig::default() });
        let mut src = HardwareSource::new(&quick(&emu, protocol), standing_head_pose().unwrap(), log);
        let sweep = swept(src.sweep(&Cancel::never(), &mut |_, _| {}));
        let stats = src.last_stats().expect("stats");
        println!(
            "{protocol:?}: {} rows, {} garbled replies asked again",
            sweep.rows.len(),
            stats.servo_corrupt_replies
        );
        assert!((36..=45).contains(&sweep.rows.len()), "{} rows", sweep.rows.len());
        assert!(stats.servo_corrupt_replies > 0, "every 9th reply is garbled");
        let garbled = ServoSpec {
            protocol,
            faults: ServoFaults { garble_every: Some(1), ..ServoFaults::default() },
            ..ServoSpec::default()
        };
        let emu = emulator(EmulatorConfig { servo: garbled, ..EmulatorConfig::default() });
        let e = sweep_of(&quick(&emu, protocol)).map(|s| s.rows.len()).expect_err("all garbled").to_string();
        assert!(e.contains("checksum failed") && e.contains("a ping"), "{e}");
    }
}
