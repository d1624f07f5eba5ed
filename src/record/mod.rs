//! Recording every stage to MCAP (JSON encoding), and reading it back ([`replay`]).
//!
//! Log times are the simulation's clock (the real robot's clock for hardware sources), in
//! nanoseconds. Where one of Foxglove's well-known schemas fits, it is used, so the files open
//! in Foxglove as they are ([`foxglove`]); the bench's own schemas are documented here, in one
//! place. Topics:
//!
//! | topic | schema | one message per |
//! |---|---|---|
//! | `/world` | `foxglove.SceneUpdate` | run: the world's boxes (floor, steps, walls, clutter) |
//! | `/lidar/sweep` | `stairbench.Sweep` | sweep: `stamp_s`, `rows`, `lidar` (the scenario's lidar table), `mount_to_world` (`translation` [x, y, z] m, `rotation` [w, x, y, z]) |
//! | `/lidar/scan` | `foxglove.LaserScan` | row, with the raw reading as extra fields: `stairbench_stamp_s`, `stairbench_tilt_rad` (servo), `stairbench_gravity_mount` [x, y, z] (IMU) |
//! | `/cloud` | `foxglove.PointCloud` | assembled sweep (x, y, z float32, world frame) |
//! | `/perception/supervoxels` | `foxglove.PointCloud` | perception: voxels after Filter 2 with `supervoxel` and `cluster` (uint32, 4294967295 = none) |
//! | `/perception/rectangles` | `foxglove.SceneUpdate` | perception: one outline per step rectangle |
//! | `/perception/result` | `stairbench.Perception` | perception: `segments` (`corners` [[x, y, z] x 4] m, `normal`, `height_m`, `voxel_count`), `timings_ms`, `counts`; or `segments` [] and `error` when it found nothing |
//! | `/plan` | `stairbench.Plan` | plan: its inputs `q0` (qpos) and `steps` (the known steps ahead, as in `/perception/result`), `stances` (`right`, `left`: sole `position` m and `yaw_rad`), `segments` (`phase`, `stance`, `duration_s`, `com_start`, `com_end`, `polygon` [[x, y]], `margin_m`, `swing`), `duration_s`, `tracking` |
//! | `/plan/scene` | `foxglove.SceneUpdate` | plan: stability polygons, CoM path, foot targets |
//! | `/plan/trajectory` | `stairbench.JointTrajectory` | plan: q(t) as planned, `rate_hz`, `names` (joints), `t_s` [..] (from the plan's start), `q` [[qpos]..] (base position, quaternion w x y z, joints), `com` [[x, y, z]..] planned CoM |
//! | `/robot/joints` | `stairbench.JointState` | 100 Hz: `names`, `positions_rad`, base `position` and `orientation` [w, x, y, z], `foot_forces_n` [[x, y, z] right, left], `margin_m` (CoM in the polygon of the real contacts; null without one), `max_torque_ratio` |
//! | `/tf` | `foxglove.FrameTransform` | 100 Hz: world to the robot's base |
//! | `/checks` | `stairbench.Violation` | violation: `t_s` (plan clock), `check`, `detail` |
//! | `/run/cycle` | `stairbench.Cycle` | cycle of `run`: its report (as `run --json` writes it) |
//!
//! Metadata record `stairbench` holds the command, the version and the scenario's name; the
//! scenario and the parameters are attached as TOML (`scenario.toml`, `params.toml`).
//!
//! Chunks are closed after every sweep, plan and cycle, so a run stopped by Ctrl-C or killed
//! leaves every closed chunk readable; a clean stop (or a panic, which unwinds) writes the
//! summary and index.

pub mod foxglove;
pub mod replay;
pub mod viewer;

use crate::cloud::PointCloud;
use crate::perception::{Perception, PlaneSegment};
use crate::planning::Plan;
use crate::robot::model::{RobotModel, Q_JOINTS};
use crate::scene::{Scene, SurfaceRole};
use crate::sensor::{ScanRow, Sweep};
use crate::sim::climb::CycleReport;
use crate::sim::execute::Violation;
use crate::sim::observe::{Observer, RobotState};
use mcap::records::MessageHeader;
use nalgebra::{Isometry3, Point3};
use serde_json::{json, Value};
use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

/// Why recording failed.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    /// The file.
    #[error("cannot write {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// The MCAP writer.
    #[error("MCAP: {0}")]
    Mcap(String),
}

impl From<mcap::McapError> for RecordError {
    fn from(e: mcap::McapError) -> Self {
        Self::Mcap(e.to_string())
    }
}

/// Period of `/robot/joints` and `/tf`, seconds.
const STATE_PERIOD_S: f64 = 0.01;

/// What the writing thread is asked to do.
enum Cmd {
    Message(MessageHeader, Vec<u8>),
    Metadata(mcap::records::Metadata),
    Attach(String, String, Vec<u8>),
    Flush,
}

/// Writes the topics of the module's table to an MCAP file. Messages are serialized on the
/// caller's thread and compressed and written by a thread of their own, so recording costs
/// the simulation little. Errors while recording are kept (the first one) and reported by
/// [`Recorder::finish`], so a failing disk does not stop a run.
pub struct Recorder {
    tx: Option<std::sync::mpsc::SyncSender<Cmd>>,
    thread: Option<std::thread::JoinHandle<Result<(), RecordError>>>,
    channels: HashMap<&'static str, u16>,
    sequence: u32,
    joint_names: Vec<String>,
    last_state_s: f64,
    messages: u64,
}

/// The topics, their schema names and schemas.
fn topics() -> Vec<(&'static str, String, String)> {
    let own = |name: &str, doc: &str| {
        (name.to_string(), format!(r#"{{"title":"{name}","description":"{doc}","type":"object"}}"#))
    };
    let fox = |name: &str, schema: String| (name.to_string(), schema);
    let list = [
        ("/world", fox("foxglove.SceneUpdate", foxglove::scene_update_schema())),
        (
            "/lidar/sweep",
            own(
                "stairbench.Sweep",
                "A lidar sweep: lidar spec and mount pose; its rows follow on /lidar/scan",
            ),
        ),
        ("/lidar/scan", fox("foxglove.LaserScan", foxglove::laser_scan_schema())),
        ("/cloud", fox("foxglove.PointCloud", foxglove::point_cloud_schema())),
        ("/perception/supervoxels", fox("foxglove.PointCloud", foxglove::point_cloud_schema())),
        ("/perception/rectangles", fox("foxglove.SceneUpdate", foxglove::scene_update_schema())),
        (
            "/perception/result",
            own("stairbench.Perception", "Step rectangles, timings and counts of one perception run"),
        ),
        ("/plan", own("stairbench.Plan", "Footholds, segments with polygons and CoM waypoints, tracking")),
        ("/plan/scene", fox("foxglove.SceneUpdate", foxglove::scene_update_schema())),
        ("/plan/trajectory", own("stairbench.JointTrajectory", "The planned q(t) and CoM at the IK's rate")),
        ("/robot/joints", own("stairbench.JointState", "Joint positions, base pose and foot forces")),
        ("/tf", fox("foxglove.FrameTransform", foxglove::frame_transform_schema())),
        ("/checks", own("stairbench.Violation", "A violated check of the execution")),
        ("/run/cycle", own("stairbench.Cycle", "One scan-plan-execute cycle's report")),
    ];
    list.into_iter().map(|(t, (n, s))| (t, n, s)).collect()
}

/// The writing thread: every command until the recorder hangs up, then the summary.
fn write_all(
    mut w: mcap::Writer<BufWriter<File>>,
    rx: std::sync::mpsc::Receiver<Cmd>,
) -> Result<(), RecordError> {
    let mut first: Option<RecordError> = None;
    for cmd in rx {
        let r = match cmd {
            Cmd::Message(header, data) => w.write_to_known_channel(&header, &data),
            Cmd::Metadata(m) => w.write_metadata(&m),
            Cmd::Attach(name, media_type, data) => w.attach(&mcap::Attachment {
                log_time: 0,
                create_time: 0,
                name,
                media_type,
                data: std::borrow::Cow::Owned(data),
            }),
            Cmd::Flush => w.flush(),
        };
        if let Err(e) = r {
            first.get_or_insert(e.into());
        }
    }
    let end = w.finish().map(|_| ()).map_err(RecordError::from);
    match first {
        Some(e) => Err(e),
        None => end,
    }
}

impl Recorder {
    /// A new file at `path` (replaced if it exists), LZ4-compressed chunks of at most 4 MiB
    /// (LZ4 rather than zstd: zstd cost the run 25 % of its wall time, LZ4 under 10 %).
    pub fn create(path: &Path, model: &RobotModel) -> Result<Self, RecordError> {
        let io = |source| RecordError::Io { path: path.display().to_string(), source };
        let file = File::create(path).map_err(io)?;
        let mut w = mcap::WriteOptions::new()
            .profile("")
            .library(format!("stairbench {}", env!("CARGO_PKG_VERSION")))
            .chunk_size(Some(4 << 20))
            .compression(Some(mcap::Compression::Lz4))
            .create(BufWriter::new(file))?;
        let mut channels = HashMap::new();
        for (topic, name, schema) in topics() {
            let schema_id = w.add_schema(&name, "jsonschema", schema.as_bytes())?;
            channels.insert(topic, w.add_channel(schema_id, topic, "json", &BTreeMap::new())?);
        }
        let (tx, rx) = std::sync::mpsc::sync_channel(1024);
        let thread = std::thread::Builder::new()
            .name("mcap-writer".into())
            .spawn(move || write_all(w, rx))
            .map_err(io)?;
        Ok(Self {
            tx: Some(tx),
            thread: Some(thread),
            channels,
            sequence: 0,
            joint_names: model.joints().iter().map(|j| j.name.clone()).collect(),
            last_state_s: f64::NEG_INFINITY,
            messages: 0,
        })
    }

    fn send(&mut self, cmd: Cmd) {
        // A send fails only when the writing thread has ended (on an error it reports).
        if let Some(tx) = &self.tx {
            if tx.send(cmd).is_err() {
                self.tx = None;
            }
        }
    }

    /// Records `name` as a metadata record.
    pub fn metadata(&mut self, name: &str, fields: BTreeMap<String, String>) {
        self.send(Cmd::Metadata(mcap::records::Metadata { name: name.into(), metadata: fields }));
    }

    /// Attaches a file's contents.
    pub fn attach(&mut self, name: &str, media_type: &str, data: &[u8]) {
        self.send(Cmd::Attach(name.into(), media_type.into(), data.to_vec()));
    }

    /// Writes `msg` on `topic` (one of the module's table) at `stamp_s`.
    pub fn log(&mut self, topic: &'static str, stamp_s: f64, msg: &Value) {
        let Some(&channel_id) = self.channels.get(topic) else { return };
        let ns = (stamp_s.max(0.0) * 1e9).round() as u64;
        self.sequence = self.sequence.wrapping_add(1);
        let header = MessageHeader { channel_id, sequence: self.sequence, log_time: ns, publish_time: ns };
        // Serializing a serde_json::Value cannot fail.
        let data = serde_json::to_vec(msg).unwrap_or_default();
        self.messages += 1;
        self.send(Cmd::Message(header, data));
    }

    /// Closes the current chunk, so what is written so far survives a crash.
    pub fn flush(&mut self) {
        self.send(Cmd::Flush);
    }

    /// Writes the summary and closes the file: the messages written, or the first error met
    /// while recording.
    pub fn finish(mut self) -> Result<u64, RecordError> {
        self.tx = None;
        let done = self.thread.take().map(|t| t.join());
        match done {
            Some(Ok(Err(e))) => Err(e),
            Some(Err(_)) => Err(RecordError::Mcap("the writing thread panicked".into())),
            _ => Ok(self.messages),
        }
    }

    /// One row of the lidar.
    pub fn scan_row(&mut self, row: &ScanRow, sweep: &Sweep) {
        let lidar = &sweep.lidar;
        let n = lidar.beams();
        let mut msg = json!({
            "timestamp": foxglove::time(row.stamp_s),
            "frame_id": "lidar_mount",
            "pose": foxglove::pose(&lidar.scanner_in_mount(row.tilt_rad)),
            "start_angle": lidar.beam_angle_rad(0),
            "end_angle": lidar.beam_angle_rad(n.saturating_sub(1)),
            "ranges": row.ranges_m,
            "intensities": [],
        });
        msg["stairbench_stamp_s"] = json!(row.stamp_s);
        msg["stairbench_tilt_rad"] = json!(row.tilt_rad);
        msg["stairbench_gravity_mount"] =
            json!([row.gravity_mount.x, row.gravity_mount.y, row.gravity_mount.z]);
        self.log("/lidar/scan", row.stamp_s, &msg);
    }
}

fn xyz(p: &Point3<f64>) -> [f64; 3] {
    [p.x, p.y, p.z]
}

fn isometry(p: &Isometry3<f64>) -> Value {
    let t = p.translation.vector;
    let q = p.rotation;
    json!({ "translation": [t.x, t.y, t.z], "rotation": [q.w, q.i, q.j, q.k] })
}

/// The `/plan` message of `plan`, made on `steps` from `stamp_s` (replay compares these).
pub fn plan_json(stamp_s: f64, steps: &[PlaneSegment], plan: &Plan) -> Value {
    let foot = |p: &Isometry3<f64>| json!({ "position": xyz(&Point3::from(p.translation.vector)), "yaw_rad": p.rotation.euler_angles().2 });
    let stances: Vec<Value> = plan
        .stances
        .iter()
        .map(|s| json!({ "right": foot(&s.right), "left": foot(&s.left), "step": s.step }))
        .collect();
    let segments: Vec<Value> = plan
        .segments
        .iter()
        .map(|s| {
            json!({
                "phase": s.phase,
                "stance": s.stance,
                "duration_s": s.duration_s,
                "com_start": xyz(&s.com_start),
                "com_end": xyz(&s.com_end),
                "polygon": s.polygon.iter().map(|p| [p.x, p.y]).collect::<Vec<_>>(),
                "margin_m": s.margin_m,
                "swing": s.swing.as_ref().map(|w| format!("{:?}", w.foot)),
            })
        })
        .collect();
    let q0 = plan.trajectory.samples.first().map(|s| s.q.clone()).unwrap_or_default();
    let msg = json!({
        "start_s": stamp_s,
        "q0": q0,
        "steps": steps,
        "stances": stances,
        "segments": segments,
        "duration_s": plan.duration_s(),
        "tracking": plan.tracking,
    });
    msg
}

impl Drop for Recorder {
    /// Without [`Recorder::finish`] (a panic unwinding, say), the file still gets its summary.
    fn drop(&mut self) {
        self.tx = None;
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Observer for Recorder {
    fn scene(&mut self, scene: &Scene) {
        let cubes: Vec<Value> = scene
            .boxes()
            .iter()
            .map(|b| {
                let h = b.half_extents_m();
                let rgba = match b.role() {
                    SurfaceRole::Step(_) => [0.65, 0.45, 0.3, 1.0],
                    SurfaceRole::Floor => [0.55, 0.55, 0.5, 1.0],
                    _ => [0.8, 0.8, 0.78, 0.2],
                };
                foxglove::cube(b.pose(), [2.0 * h.x, 2.0 * h.y, 2.0 * h.z], rgba)
            })
            .collect();
        self.log("/world", 0.0, &foxglove::scene_update(vec![foxglove::entity(0.0, "world", vec![], cubes)]));
    }

    fn sweep(&mut self, stamp_s: f64, sweep: &Sweep) {
        let msg = json!({
            "stamp_s": stamp_s,
            "rows": sweep.rows.len(),
            "lidar": sweep.lidar.spec(),
            "mount_to_world": isometry(&sweep.mount_to_world),
        });
        self.log("/lidar/sweep", stamp_s, &msg);
        for row in &sweep.rows {
            self.scan_row(row, sweep);
        }
        self.log(
            "/tf",
            stamp_s,
            &foxglove::frame_transform(stamp_s, "world", "lidar_mount", &sweep.mount_to_world),
        );
        self.flush();
    }

    fn cloud(&mut self, stamp_s: f64, cloud: &PointCloud) {
        self.log("/cloud", stamp_s, &foxglove::point_cloud(stamp_s, cloud.points(), &[]));
    }

    fn perception(&mut self, stamp_s: f64, r: &Perception) {
        let d = &r.detail;
        let cluster: Vec<u32> = d
            .supervoxels
            .labels
            .iter()
            .map(|&s| d.clusters.of_supervoxel.get(s as usize).copied().unwrap_or(u32::MAX))
            .collect();
        let cloud = foxglove::point_cloud(
            stamp_s,
            &d.voxels.positions,
            &[("supervoxel", &d.supervoxels.labels), ("cluster", &cluster)],
        );
        self.log("/perception/supervoxels", stamp_s, &cloud);
        let outlines: Vec<Value> = r
            .segments
            .iter()
            .enumerate()
            .map(|(i, s)| {
                let line = foxglove::line_loop(s.corners(), [1.0, 0.85, 0.1, 1.0], 0.01);
                foxglove::entity(stamp_s, &format!("step_{}", i + 1), vec![line], vec![])
            })
            .collect();
        self.log("/perception/rectangles", stamp_s, &foxglove::scene_update(outlines));
        let msg = json!({ "segments": r.segments, "timings_ms": r.timings, "counts": r.counts });
        self.log("/perception/result", stamp_s, &msg);
    }

    fn perception_failed(&mut self, stamp_s: f64, why: &str) {
        self.log("/perception/rectangles", stamp_s, &foxglove::scene_update(vec![]));
        self.log("/perception/result", stamp_s, &json!({ "segments": [], "error": why }));
    }

    fn plan(&mut self, stamp_s: f64, steps: &[PlaneSegment], plan: &Plan) {
        let msg = plan_json(stamp_s, steps, plan);
        self.log("/plan", stamp_s, &msg);
        let samples = &plan.trajectory.samples;
        let trajectory = json!({
            "rate_hz": plan.trajectory.rate_hz,
            "names": self.joint_names,
            "t_s": samples.iter().map(|s| s.t_s).collect::<Vec<_>>(),
            "q": samples.iter().map(|s| &s.q).collect::<Vec<_>>(),
            "com": samples.iter().map(|s| xyz(&s.com)).collect::<Vec<_>>(),
        });
        self.log("/plan/trajectory", stamp_s, &trajectory);
        let mut entities = Vec::new();
        let mut t = stamp_s;
        for (i, s) in plan.segments.iter().enumerate() {
            let lines = vec![
                foxglove::line_strip(&s.polygon_ring(), [0.2, 0.4, 1.0, 1.0], 0.005),
                foxglove::line_strip(&[s.com_start, s.com_end], [1.0, 0.2, 0.2, 1.0], 0.008),
            ];
            entities.push(foxglove::entity(t, &format!("segment_{i}"), lines, vec![]));
            t += s.duration_s;
        }
        let targets: Vec<Value> = plan
            .stances
            .iter()
            .flat_map(|s| [s.right, s.left])
            .map(|p| foxglove::cube(&p, [0.24, 0.13, 0.005], [0.2, 0.9, 0.3, 0.6]))
            .collect();
        entities.push(foxglove::entity(stamp_s, "footholds", vec![], targets));
        self.log("/plan/scene", stamp_s, &foxglove::scene_update(entities));
        self.flush();
    }

    fn state(&mut self, stamp_s: f64, state: &RobotState) {
        let q = state.q;
        if stamp_s - self.last_state_s < STATE_PERIOD_S - 1e-9 || q.len() < Q_JOINTS {
            return;
        }
        self.last_state_s = stamp_s;
        let msg = json!({
            "names": self.joint_names,
            "positions_rad": &q[Q_JOINTS..],
            "position": [q[0], q[1], q[2]],
            "orientation": [q[3], q[4], q[5], q[6]],
            "foot_forces_n": state.foot_forces_n.iter().map(|f| [f.x, f.y, f.z]).collect::<Vec<_>>(),
            "margin_m": state.margin_m.is_finite().then_some(state.margin_m),
            "max_torque_ratio": state.max_torque_ratio,
        });
        self.log("/robot/joints", stamp_s, &msg);
        let base = Isometry3::from_parts(
            nalgebra::Translation3::new(q[0], q[1], q[2]),
            nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q[3], q[4], q[5], q[6])),
        );
        self.log("/tf", stamp_s, &foxglove::frame_transform(stamp_s, "world", "base", &base));
    }

    fn violation(&mut self, stamp_s: f64, v: &Violation) {
        let msg = serde_json::to_value(v).unwrap_or(Value::Null);
        self.log("/checks", stamp_s, &msg);
    }

    fn cycle(&mut self, stamp_s: f64, c: &CycleReport) {
        let msg = serde_json::to_value(c).unwrap_or(Value::Null);
        self.log("/run/cycle", stamp_s, &msg);
        self.flush();
    }
}
