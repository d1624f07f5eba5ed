//! Recording every stage to MCAP (JSON encoding), reading it back ([`replay`]), and replaying
//! it through the loop's pieces against what was recorded ([`compare`]).
//!
//! Log times are the simulation's clock (the real robot's clock for hardware sources), in
//! nanoseconds. Where one of Foxglove's well-known schemas fits, it is used, so the files open
//! in Foxglove as they are ([`foxglove`]); the bench's own messages are the types of
//! [`messages`] (one per topic, shared by the writer and the reader). Topics:
//!
//! | topic | schema | one message per |
//! |---|---|---|
//! | `/world` | `foxglove.SceneUpdate` | run: the world's boxes (floor, steps, walls, clutter) |
//! | `/lidar/sweep` | `stairbench.Sweep` | sweep: `stamp_s`, `rows`, `lidar` (the scenario's lidar table), `mount_to_world` (`translation` [x, y, z] m, `rotation` [w, x, y, z]) |
//! | `/lidar/scan` | `foxglove.LaserScan` | row, with the raw reading as extra fields: `stairbench_stamp_s`, `stairbench_tilt_rad` (servo), `stairbench_gravity_mount` [x, y, z] (IMU), and `stairbench_mount_to_world` (as `mount_to_world`) where the head moved during the sweep |
//! | `/cloud` | `foxglove.PointCloud` | assembled sweep (x, y, z float32, world frame) |
//! | `/perception/supervoxels` | `foxglove.PointCloud` | perception: voxels after Filter 2 with `supervoxel` and `cluster` (uint32, 4294967295 = none) |
//! | `/perception/rectangles` | `foxglove.SceneUpdate` | perception: one outline per step rectangle |
//! | `/perception/result` | `stairbench.Perception` | perception ([`messages::PerceptionMsg`]): `segments` (`corners` [[x, y, z] x 4] m, `normal`, `height_m`, `voxel_count`), `timings_ms`, `counts`; or `segments` [], `no_staircase` (where it stopped, as data) and `error` when it found nothing |
//! | `/plan` | `stairbench.Plan` | plan ([`messages::PlanMsg`], also `plan --json`): its inputs `q0` (qpos) and `steps` (the known steps ahead, as in `/perception/result`), `stances` (`step` from 1, `right`, `left`: sole `position` m and `yaw_rad`), `segments` (`phase`, `stance` from 1, `duration_s`, `com_start`, `com_end`, `polygon` [[x, y]], `margin_m`, `support`, `swing`), `duration_s`, `min_margin_m`, `tracking`, `rate_hz`, `samples` |
//! | `/plan/scene` | `foxglove.SceneUpdate` | plan: stability polygons, CoM path, foot targets |
//! | `/plan/trajectory` | `stairbench.JointTrajectory` | plan: q(t) as planned, `rate_hz`, `names` (joints), `t_s` [..] (from the plan's start), `q` [[qpos]..] (base position, quaternion w x y z, joints), `com` [[x, y, z]..] planned CoM |
//! | `/robot/joints` | `stairbench.JointState` | 100 Hz: `names`, `positions_rad`, base `position` and `orientation` [w, x, y, z], `foot_forces_n` [[x, y, z] right, left], `margin_m` (CoM in the polygon of the real contacts; null without one), `max_torque_ratio` |
//! | `/tf` | `foxglove.FrameTransform` | 100 Hz: world to the robot's base |
//! | `/checks` | `stairbench.Violation` | violation ([`crate::climb::Violation`]): `t_s` (plan clock), `cycle`, `check` (its kind), the check's figures, `detail` |
//! | `/run/cycle` | `stairbench.Cycle` | cycle of `run`: its report (as `run --json` writes it) |
//! | `/run/view` | `stairbench.View` | view ([`messages::ViewMsg`]): `stamp_s`, `q` (qpos), the configuration the sweep's view was taken into the step map and the surroundings from (after a registration's correction); `set_aside` (the look set aside to look again standing: its steps left the map again); `replay` takes a view no plan followed from them |
//!
//! Metadata record `stairbench` holds the command, the version and the scenario's name; the
//! scenario and the parameters are attached as TOML (`scenario.toml`, `params.toml`).
//!
//! Chunks are closed after every sweep, plan and cycle, so a run stopped by Ctrl-C or killed
//! leaves every closed chunk readable; a clean stop (or a panic, which unwinds) writes the
//! summary and index.

pub mod compare;
pub mod foxglove;
pub mod messages;
pub mod replay;
pub mod viewer;

use crate::climb::{Event, Observer, RobotState};
use crate::cloud::PointCloud;
use crate::perception::{Perception, PerceptionError, PlaneSegment};
use crate::planning::Plan;
use crate::robot::model::{base_pose, RobotModel, Q_JOINTS};
use crate::scene::{Scene, SurfaceRole};
use crate::sensor::{ScanRow, Sweep};
use foxglove::{CubePrimitive, FrameTransform, LaserScan, LinePrimitive, SceneEntity, SceneUpdate, Time};
use mcap::records::MessageHeader;
use messages::{JointStateMsg, PerceptionMsg, PlanMsg, SweepMsg, TrajectoryMsg, ViewMsg};
use serde::Serialize;
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
    /// The robot model (its joint names and soles are recorded).
    #[error(transparent)]
    Robot(#[from] crate::robot::RobotError),
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
    sole_half_m: [f64; 2],
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
        (
            "/control",
            own(
                "stairbench.ControlTick",
                "A stabilizer tick: per foot the wanted and measured ground wrench, the admittance offsets with the sway's tilt; the CoM's error, the lean and tilt the IMU sees",
            ),
        ),
        ("/run/cycle", own("stairbench.Cycle", "One scan-plan-execute cycle's report")),
        ("/run/view", own("stairbench.View", "The configuration a view was taken from, and whether its look was set aside")),
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
        let sole_half_m = crate::robot::hrp4::sole_half_m(model)?[0];
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
            sole_half_m,
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
    pub fn log(&mut self, topic: &'static str, stamp_s: f64, msg: &impl Serialize) {
        let Some(&channel_id) = self.channels.get(topic) else { return };
        let ns = (stamp_s.max(0.0) * 1e9).round() as u64;
        self.sequence = self.sequence.wrapping_add(1);
        let header = MessageHeader { channel_id, sequence: self.sequence, log_time: ns, publish_time: ns };
        // The messages are plain data (maps with string keys): serializing cannot fail.
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
        let g = row.gravity_mount;
        let msg = LaserScan {
            timestamp: Time::of(row.stamp_s),
            frame_id: "lidar_mount".into(),
            pose: foxglove::Pose::of(&lidar.scanner_in_mount(row.tilt_rad)),
            start_angle: lidar.beam_angle_rad(0),
            end_angle: lidar.beam_angle_rad(n.saturating_sub(1)),
            ranges: row.ranges_m.clone(),
            intensities: Vec::new(),
            stairbench_stamp_s: row.stamp_s,
            stairbench_tilt_rad: row.tilt_rad,
            stairbench_gravity_mount: [g.x, g.y, g.z],
            stairbench_mount_to_world: row.mount_to_world.as_ref().map(messages::PoseMsg::of),
        };
        self.log("/lidar/scan", row.stamp_s, &msg);
    }

    /// The world's boxes (floor, steps, walls, clutter).
    fn scene(&mut self, scene: &Scene) {
        let cubes: Vec<CubePrimitive> = scene
            .boxes()
            .iter()
            .map(|b| {
                let h = b.half_extents_m();
                let rgba = match b.role() {
                    SurfaceRole::Step(_) => [0.65, 0.45, 0.3, 1.0],
                    SurfaceRole::Floor => [0.55, 0.55, 0.5, 1.0],
                    _ => [0.8, 0.8, 0.78, 0.2],
                };
                CubePrimitive::new(b.pose(), [2.0 * h.x, 2.0 * h.y, 2.0 * h.z], rgba)
            })
            .collect();
        self.log("/world", 0.0, &SceneUpdate::of(vec![SceneEntity::new(0.0, "world", vec![], cubes)]));
    }

    /// A sweep: its header, every row, the mount's frame; the chunk is closed after it.
    pub fn sweep(&mut self, stamp_s: f64, sweep: &Sweep) {
        self.log("/lidar/sweep", stamp_s, &SweepMsg::of(stamp_s, sweep));
        for row in &sweep.rows {
            self.scan_row(row, sweep);
        }
        self.log(
            "/tf",
            stamp_s,
            &FrameTransform::new(
                stamp_s,
                "world",
                "lidar_mount",
                &crate::sensor::assemble::mount_in_cloud(&sweep.rows, &sweep.mount_to_world),
            ),
        );
        self.flush();
    }

    /// An assembled cloud.
    pub fn cloud(&mut self, stamp_s: f64, cloud: &PointCloud) {
        self.log("/cloud", stamp_s, &foxglove::PointCloud::new(stamp_s, cloud.points(), &[]));
    }

    fn perception(&mut self, stamp_s: f64, r: &Perception) {
        let d = &r.detail;
        let cluster: Vec<u32> = d
            .supervoxels
            .labels
            .iter()
            .map(|&s| d.clusters.of_supervoxel.get(s as usize).copied().unwrap_or(u32::MAX))
            .collect();
        let cloud = foxglove::PointCloud::new(
            stamp_s,
            &d.voxels.positions,
            &[("supervoxel", &d.supervoxels.labels), ("cluster", &cluster)],
        );
        self.log("/perception/supervoxels", stamp_s, &cloud);
        let outlines: Vec<SceneEntity> = r
            .segments
            .iter()
            .enumerate()
            .map(|(i, s)| {
                let line = LinePrimitive::closed(s.corners(), [1.0, 0.85, 0.1, 1.0], 0.01);
                SceneEntity::new(stamp_s, &format!("step_{}", i + 1), vec![line], vec![])
            })
            .collect();
        self.log("/perception/rectangles", stamp_s, &SceneUpdate::of(outlines));
        self.log("/perception/result", stamp_s, &PerceptionMsg::of(Ok(r)));
    }

    fn perception_failed(&mut self, stamp_s: f64, error: &PerceptionError) {
        self.log("/perception/rectangles", stamp_s, &SceneUpdate::of(vec![]));
        self.log("/perception/result", stamp_s, &PerceptionMsg::of(Err(error)));
    }

    fn plan(&mut self, stamp_s: f64, steps: &[PlaneSegment], plan: &Plan) {
        self.log("/plan", stamp_s, &PlanMsg::of(stamp_s, steps, plan));
        self.log("/plan/trajectory", stamp_s, &TrajectoryMsg::of(plan, &self.joint_names));
        let mut entities = Vec::new();
        let mut t = stamp_s;
        for (i, s) in plan.segments.iter().enumerate() {
            let lines = vec![
                LinePrimitive::open(&s.polygon_ring(), [0.2, 0.4, 1.0, 1.0], 0.005),
                LinePrimitive::open(&[s.com_start, s.com_end], [1.0, 0.2, 0.2, 1.0], 0.008),
            ];
            entities.push(SceneEntity::new(t, &format!("segment_{i}"), lines, vec![]));
            t += s.duration_s;
        }
        let targets: Vec<CubePrimitive> = plan
            .stances
            .iter()
            .flat_map(|s| [s.right, s.left])
            .map(|p| {
                CubePrimitive::new(
                    &p,
                    [2.0 * self.sole_half_m[0], 2.0 * self.sole_half_m[1], 0.005],
                    [0.2, 0.9, 0.3, 0.6],
                )
            })
            .collect();
        entities.push(SceneEntity::new(stamp_s, "footholds", vec![], targets));
        self.log("/plan/scene", stamp_s, &SceneUpdate::of(entities));
        self.flush();
    }

    fn state(&mut self, stamp_s: f64, state: &RobotState) {
        let q = state.q;
        if stamp_s - self.last_state_s < STATE_PERIOD_S - 1e-9 || q.len() < Q_JOINTS {
            return;
        }
        self.last_state_s = stamp_s;
        let msg = JointStateMsg {
            names: self.joint_names.clone(),
            positions_rad: q[Q_JOINTS..].to_vec(),
            position: [q[0], q[1], q[2]],
            orientation: [q[3], q[4], q[5], q[6]],
            foot_forces_n: state.foot_forces_n.iter().map(|f| [f.x, f.y, f.z]).collect(),
            margin_m: state.margin_m.is_finite().then_some(state.margin_m),
            max_torque_ratio: state.max_torque_ratio,
        };
        self.log("/robot/joints", stamp_s, &msg);
        self.log("/tf", stamp_s, &FrameTransform::new(stamp_s, "world", "base", &base_pose(q)));
    }
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
    fn event(&mut self, event: &Event) {
        match *event {
            Event::Scene(scene) => self.scene(scene),
            Event::Sweep { stamp_s, sweep } => self.sweep(stamp_s, sweep),
            Event::Cloud { stamp_s, cloud } => self.cloud(stamp_s, cloud),
            Event::View { stamp_s, q, set_aside } => {
                self.log("/run/view", stamp_s, &ViewMsg { stamp_s, q: q.to_vec(), set_aside });
            }
            Event::Perception { stamp_s, result } => self.perception(stamp_s, result),
            Event::PerceptionFailed { stamp_s, error } => self.perception_failed(stamp_s, error),
            Event::Plan { stamp_s, steps, plan } => self.plan(stamp_s, steps, plan),
            Event::State { stamp_s, state } => self.state(stamp_s, state),
            Event::Violation { stamp_s, violation } => self.log("/checks", stamp_s, violation),
            Event::Control { stamp_s, tick } => self.log("/control", stamp_s, tick),
            Event::Cycle { stamp_s, report } => {
                self.log("/run/cycle", stamp_s, report);
                self.flush();
            }
        }
    }
}
