//! Showing a climb in Rerun (spawned viewer, a viewer at a URL, or an .rrd file), on the
//! `sim_time` timeline: the world's boxes, each lidar row as it arrives, the cloud, the voxels
//! coloured by supervoxel, the step rectangles, the stability polygons, the CoM path and the
//! foot targets, the robot's collision shapes posed, and plots of the CoM margin and the
//! largest torque ratio. Entity paths:
//!
//! `world/boxes`, `lidar/row`, `perception/cloud`, `perception/supervoxels`,
//! `perception/rectangles`, `plan/polygons`, `plan/com_path`, `plan/footholds`,
//! `robot/boxes`, `robot/capsules`, `robot/com`, `metrics/margin_mm`,
//! `metrics/torque_ratio`, `checks`.

use crate::climb::{Event, Observer, RobotState, Violation};
use crate::cloud::PointCloud;
use crate::control::TickRecord;
use crate::perception::PerceptionError;
use crate::perception::{Perception, PlaneSegment};
use crate::planning::Plan;
use crate::robot::model::{RobotModel, Shape};
use crate::robot::Kinematics;
use crate::scene::{Scene, SurfaceRole};
use crate::sensor::{assemble, AssembleParams, Sweep};
use nalgebra::{Isometry3, Point3, UnitQuaternion};

/// Where the recording goes.
#[derive(Debug, Clone)]
pub enum Sink {
    /// Spawn a viewer (the `rerun` binary on the PATH).
    Spawn,
    /// Stream to a viewer at this URL (`rerun+http://127.0.0.1:9876/proxy`, say).
    Connect(String),
    /// Save to an .rrd file.
    Save(std::path::PathBuf),
}

/// Why Rerun could not be started.
#[derive(Debug, thiserror::Error)]
#[error("Rerun: {0}")]
pub struct RerunError(String);

/// Period of the robot's pose and the plots, seconds.
const STATE_PERIOD_S: f64 = 1.0 / 30.0;

/// Logs a climb to Rerun.
pub struct RerunLogger<'m> {
    rec: rerun::RecordingStream,
    kin: Kinematics<'m>,
    last_state_s: f64,
    errors: usize,
    sole_half_m: [f64; 2],
}

fn p3(p: &Point3<f64>) -> [f32; 3] {
    [p.x as f32, p.y as f32, p.z as f32]
}

fn quat(q: &UnitQuaternion<f64>) -> rerun::Quaternion {
    rerun::Quaternion::from_xyzw([q.i as f32, q.j as f32, q.k as f32, q.w as f32])
}

/// A colour per label (golden-ratio hues), grey for none.
fn label_colour(label: u32) -> rerun::Color {
    if label == u32::MAX {
        return rerun::Color::from_rgb(128, 128, 128);
    }
    let h = (label as f64 * 0.618_033_988_75).fract() * 6.0;
    let x = (1.0 - (h % 2.0 - 1.0).abs()) * 255.0;
    let (r, g, b) = match h as u32 {
        0 => (255.0, x, 0.0),
        1 => (x, 255.0, 0.0),
        2 => (0.0, 255.0, x),
        3 => (0.0, x, 255.0),
        4 => (x, 0.0, 255.0),
        _ => (255.0, 0.0, x),
    };
    rerun::Color::from_rgb(r as u8, g as u8, b as u8)
}

impl<'m> RerunLogger<'m> {
    /// A logger for `model`'s robot writing to `sink`.
    pub fn new(sink: &Sink, model: &'m RobotModel) -> Result<Self, RerunError> {
        let builder = rerun::RecordingStreamBuilder::new("stairbench");
        let rec = match sink {
            Sink::Spawn => builder.spawn(),
            Sink::Connect(url) => builder.connect_grpc_opts(url.clone()),
            Sink::Save(path) => builder.save(path),
        }
        .map_err(|e| RerunError(e.to_string()))?;
        let sole_half_m = crate::robot::hrp4::sole_half_m(model).map_err(|e| RerunError(e.to_string()))?[0];
        Ok(Self { rec, kin: Kinematics::new(model), last_state_s: f64::NEG_INFINITY, errors: 0, sole_half_m })
    }

    /// Logs `what` at `path`, counting failures (a viewer that went away must not stop a
    /// run; [`RerunLogger::finish`] reports them).
    fn log(&mut self, path: &str, what: &impl rerun::AsComponents) {
        if self.rec.log(path, what).is_err() {
            self.errors += 1;
        }
    }

    fn at(&self, stamp_s: f64) {
        self.rec.set_duration_secs("sim_time", stamp_s);
    }

    /// Flushes everything to the sink; the number of log calls that failed.
    pub fn finish(self) -> Result<(), RerunError> {
        self.rec.flush_blocking().map_err(|e| RerunError(e.to_string()))?;
        match self.errors {
            0 => Ok(()),
            n => Err(RerunError(format!("{n} log calls failed"))),
        }
    }

    fn outlines(segments: &[PlaneSegment]) -> rerun::LineStrips3D {
        rerun::LineStrips3D::new(segments.iter().map(|s| {
            let c = s.corners();
            [c[0], c[1], c[2], c[3], c[0]].iter().map(p3).collect::<Vec<_>>()
        }))
    }
}

impl RerunLogger<'_> {
    fn scene(&mut self, scene: &Scene) {
        let boxes: Vec<_> = scene.boxes().iter().filter(|b| b.role() != SurfaceRole::Ceiling).collect();
        let centres: Vec<[f32; 3]> =
            boxes.iter().map(|b| p3(&Point3::from(b.pose().translation.vector))).collect();
        let halves: Vec<[f32; 3]> =
            boxes.iter().map(|b| b.half_extents_m().map(|v| v as f32).into()).collect();
        let colours: Vec<rerun::Color> = boxes
            .iter()
            .map(|b| match b.role() {
                SurfaceRole::Step(_) => rerun::Color::from_rgb(166, 115, 77),
                SurfaceRole::Floor => rerun::Color::from_rgb(140, 140, 128),
                _ => rerun::Color::from_unmultiplied_rgba(200, 200, 200, 60),
            })
            .collect();
        let arch = rerun::Boxes3D::from_centers_and_half_sizes(centres, halves)
            .with_quaternions(boxes.iter().map(|b| quat(&b.pose().rotation)))
            .with_colors(colours);
        if self.rec.log_static("world/boxes", &arch).is_err() {
            self.errors += 1;
        }
    }

    fn sweep(&mut self, _stamp_s: f64, sweep: &Sweep) {
        // Each row on its own, as it arrived (its raw tilt, no fit across rows).
        let raw = AssembleParams { tilt_fit_half_window_rows: 0 };
        for k in 0..sweep.rows.len() {
            let Ok(row) = assemble(&sweep.rows[k..=k], &sweep.lidar, &sweep.mount_to_world, &raw) else {
                continue;
            };
            self.at(sweep.rows[k].stamp_s);
            let pts: Vec<[f32; 3]> = row.points().iter().map(|p| [p.x, p.y, p.z]).collect();
            self.log("lidar/row", &rerun::Points3D::new(pts).with_radii([0.008]));
        }
    }

    fn cloud(&mut self, stamp_s: f64, cloud: &PointCloud) {
        self.at(stamp_s);
        let pts: Vec<[f32; 3]> = cloud.points().iter().map(|p| [p.x, p.y, p.z]).collect();
        self.log("perception/cloud", &rerun::Points3D::new(pts).with_radii([0.004]));
    }

    fn perception(&mut self, stamp_s: f64, r: &Perception) {
        self.at(stamp_s);
        let d = &r.detail;
        let pts: Vec<[f32; 3]> = d.voxels.positions.iter().map(|p| [p.x, p.y, p.z]).collect();
        let colours: Vec<rerun::Color> = d.supervoxels.labels.iter().map(|&l| label_colour(l)).collect();
        self.log(
            "perception/supervoxels",
            &rerun::Points3D::new(pts).with_colors(colours).with_radii([0.01]),
        );
        let outlines = Self::outlines(&r.segments).with_colors([rerun::Color::from_rgb(255, 217, 26)]);
        self.log("perception/rectangles", &outlines);
    }

    fn perception_failed(&mut self, stamp_s: f64, error: &PerceptionError) {
        self.at(stamp_s);
        self.log("perception/rectangles", &rerun::Clear::flat());
        self.log("checks", &rerun::TextLog::new(format!("perception: {error}")));
    }

    fn plan(&mut self, stamp_s: f64, _steps: &[PlaneSegment], plan: &Plan) {
        self.at(stamp_s);
        let polygons = rerun::LineStrips3D::new(
            plan.segments.iter().map(|s| s.polygon_ring().iter().map(p3).collect::<Vec<_>>()),
        )
        .with_colors([rerun::Color::from_rgb(51, 102, 255)]);
        self.log("plan/polygons", &polygons);
        let mut path: Vec<[f32; 3]> =
            plan.segments.first().map(|s| vec![p3(&s.com_start)]).unwrap_or_default();
        path.extend(plan.segments.iter().map(|s| p3(&s.com_end)));
        self.log(
            "plan/com_path",
            &rerun::LineStrips3D::new([path]).with_colors([rerun::Color::from_rgb(255, 51, 51)]),
        );
        let feet: Vec<Isometry3<f64>> = plan.stances.iter().flat_map(|s| [s.right, s.left]).collect();
        let targets = rerun::Boxes3D::from_centers_and_half_sizes(
            feet.iter().map(|f| p3(&Point3::from(f.translation.vector))),
            feet.iter().map(|_| [self.sole_half_m[0] as f32, self.sole_half_m[1] as f32, 0.003]),
        )
        .with_quaternions(feet.iter().map(|f| quat(&f.rotation)))
        .with_colors([rerun::Color::from_unmultiplied_rgba(51, 230, 77, 150)]);
        self.log("plan/footholds", &targets);
    }

    fn state(&mut self, stamp_s: f64, state: &RobotState) {
        if stamp_s - self.last_state_s < STATE_PERIOD_S - 1e-9 || self.kin.update(state.q).is_err() {
            return;
        }
        self.last_state_s = stamp_s;
        self.at(stamp_s);
        let model = self.kin.model();
        let (mut box_c, mut box_h, mut box_q) = (Vec::new(), Vec::new(), Vec::new());
        let (mut cap_t, mut cap_q, mut cap_l, mut cap_r) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for (l, link) in model.links().iter().enumerate() {
            let pose = self.kin.link_pose(l);
            for c in &link.collisions {
                let at = pose * c.placement;
                match c.shape {
                    Shape::Box(size) => {
                        box_c.push(p3(&Point3::from(at.translation.vector)));
                        box_h.push(size.map(|v| (v / 2.0) as f32));
                        box_q.push(quat(&at.rotation));
                    }
                    Shape::Cylinder { radius_m, length_m } => {
                        let start = at * Point3::new(0.0, 0.0, -length_m / 2.0);
                        cap_t.push(p3(&start));
                        cap_q.push(quat(&at.rotation));
                        cap_l.push(length_m as f32);
                        cap_r.push(radius_m as f32);
                    }
                    Shape::Sphere(r) => {
                        cap_t.push(p3(&Point3::from(at.translation.vector)));
                        cap_q.push(quat(&at.rotation));
                        cap_l.push(0.0);
                        cap_r.push(r as f32);
                    }
                }
            }
        }
        let grey = rerun::Color::from_rgb(191, 199, 217);
        self.log(
            "robot/boxes",
            &rerun::Boxes3D::from_centers_and_half_sizes(box_c, box_h)
                .with_quaternions(box_q)
                .with_colors([grey]),
        );
        self.log(
            "robot/capsules",
            &rerun::Capsules3D::from_lengths_and_radii(cap_l, cap_r)
                .with_translations(cap_t)
                .with_quaternions(cap_q)
                .with_colors([grey]),
        );
        let com = self.kin.com();
        self.log("robot/com", &rerun::Points3D::new([p3(&com)]).with_radii([0.02]));
        if state.margin_m.is_finite() {
            self.log("metrics/margin_mm", &rerun::Scalars::single(state.margin_m * 1e3));
        }
        self.log("metrics/torque_ratio", &rerun::Scalars::single(state.max_torque_ratio));
    }

    /// The stabilizer's wanted and measured forces per foot (normal and tangential), as plots.
    fn control(&mut self, stamp_s: f64, tick: &TickRecord) {
        self.at(stamp_s);
        for (k, foot) in ["right", "left"].iter().enumerate() {
            let m = &tick.measured[k].force_n;
            self.log(&format!("control/{foot}/normal_n/measured"), &rerun::Scalars::single(m.z));
            self.log(
                &format!("control/{foot}/tangential_n/measured"),
                &rerun::Scalars::single(m.xy().norm()),
            );
            if let Some(w) = &tick.wanted[k] {
                let w = &w.force_n;
                self.log(&format!("control/{foot}/normal_n/wanted"), &rerun::Scalars::single(w.z));
                self.log(
                    &format!("control/{foot}/tangential_n/wanted"),
                    &rerun::Scalars::single(w.xy().norm()),
                );
            }
        }
    }

    fn violation(&mut self, stamp_s: f64, v: &Violation) {
        self.at(stamp_s);
        self.log("checks", &rerun::TextLog::new(format!("{}: {}", v.check.kind(), v.check)));
    }
}

impl Observer for RerunLogger<'_> {
    fn event(&mut self, event: &Event) {
        match *event {
            Event::Scene(scene) => self.scene(scene),
            Event::Sweep { stamp_s, sweep } => self.sweep(stamp_s, sweep),
            Event::Cloud { stamp_s, cloud } => self.cloud(stamp_s, cloud),
            Event::Perception { stamp_s, result } => self.perception(stamp_s, result),
            Event::PerceptionFailed { stamp_s, error } => self.perception_failed(stamp_s, error),
            Event::Plan { stamp_s, steps, plan } => self.plan(stamp_s, steps, plan),
            Event::State { stamp_s, state } => self.state(stamp_s, state),
            Event::Violation { stamp_s, violation } => self.violation(stamp_s, violation),
            Event::Control { stamp_s, tick } => self.control(stamp_s, tick),
            Event::View { .. } | Event::Cycle { .. } => {}
        }
    }
}
