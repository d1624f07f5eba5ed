//! Rerun (issue 7): a one-cycle run saved as .rrd passes `rerun rrd verify` from the matching
//! rerun-sdk Python package (installed by the test set-up in third_party/venv), and holds the
//! entities the issue names.

use stairbench::cancel::Cancel;
use stairbench::params::ClimbParams;
use stairbench::record::viewer::{RerunLogger, Sink};
use stairbench::robot::hrp4;
use stairbench::scenario::Scenario;
use stairbench::sim::climb_scenario;
use std::path::Path;
use std::process::Command;

#[test]
fn a_saved_rrd_of_a_run_verifies_with_rerun_and_holds_every_stage() {
    let path = Path::new(env!("CARGO_TARGET_TMPDIR")).join("one_cycle.rrd");
    let _ = std::fs::remove_file(&path);
    let model = hrp4::model().unwrap();
    let mut p = ClimbParams::default();
    p.run.max_cycles = 1;
    let mut viewer = RerunLogger::new(&Sink::Save(path.clone()), &model).unwrap();
    let r = climb_scenario(&Scenario::default(), p.loop_params(), &p.sim(), &mut viewer, &Cancel::never())
        .unwrap();
    assert_eq!(r.cycles.len(), 1);
    viewer.finish().unwrap();
    let size = std::fs::metadata(&path).unwrap().len();
    println!("{} bytes", size);
    assert!(size > 100_000, "a run's worth of data");
    let rerun = Path::new(env!("CARGO_MANIFEST_DIR")).join("third_party/venv/bin/rerun");
    assert!(rerun.exists(), "run `make setup` first: it installs rerun-sdk into third_party/venv");
    let verify = Command::new(&rerun).args(["rrd", "verify"]).arg(&path).output().unwrap();
    println!("{}{}", String::from_utf8_lossy(&verify.stdout), String::from_utf8_lossy(&verify.stderr));
    assert!(verify.status.success(), "rerun rrd verify failed");
    // The entities, as Rerun itself lists them.
    let stats = Command::new(&rerun).args(["rrd", "print", "--verbose"]).arg(&path).output().unwrap();
    let text = String::from_utf8_lossy(&stats.stdout);
    for entity in [
        "/world/boxes",
        "/lidar/row",
        "/perception/cloud",
        "/perception/supervoxels",
        "/perception/rectangles",
        "/plan/polygons",
        "/plan/com_path",
        "/plan/footholds",
        "/robot/boxes",
        "/robot/capsules",
        "/metrics/margin_mm",
        "/metrics/torque_ratio",
    ] {
        assert!(text.contains(entity), "{entity} missing from the recording");
    }
}
