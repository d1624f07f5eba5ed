//! A compiled MuJoCo world (model + data) built from a [`Scene`] and a robot fragment, with
//! thread-safe ray casting for the simulated lidar (the world is a [`RayCaster`]), the robot's
//! joints read by their MuJoCo addresses (a body with ankle bushes has more joints than its
//! model), and the servos' set points sent through the body's [`Actuation`] at every step.

use super::box_rays::BoxRays;
use super::plant::{Plant, ServoLine};
use crate::robot::model::{Q_JOINTS, V_JOINTS};
use crate::robot::{self, hrp4};
use crate::scene::mjcf::{world_xml_with, RobotFragment, WorldOptions, ROBOT_GEOM_GROUP};
use crate::scene::Scene;
use crate::sensor::{RayCaster, RayHit};
use mujoco_rs::mujoco_c::{mjNGROUP, mj_ray};
use mujoco_rs::prelude::{MjData, MjModel, MjtObjBase};
use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};
use std::borrow::Cow;
use std::sync::Arc;

/// Why a world could not be built or queried.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// MuJoCo refused the generated MJCF (a bug of the generator, or a bad robot fragment).
    #[error("MuJoCo could not compile the world: {0}")]
    Compile(String),
    /// A frame the bench needs is missing from the model.
    #[error("the world has no site named `{0}`")]
    MissingSite(String),
    /// A body the bench needs is missing from the model.
    #[error("the world has no body named `{0}`")]
    MissingBody(String),
    /// A sensor the bench needs is missing from the model.
    #[error("the world has no sensor named `{0}`")]
    MissingSensor(String),
    /// A parameter the simulation cannot use (named in the message).
    #[error("unusable simulation parameter: {0}")]
    Params(String),
    /// The stabilizer could not be set up for a plan.
    #[error("the stabilizer could not start: {0}")]
    StabilizerSetup(#[from] crate::planning::PlanError),
    /// The stabilizer's online IK found no solution during an execution.
    #[error("the stabilizer's IK failed at t = {t_s:.3} s of the plan: {error}")]
    Stabilizer {
        /// Plan time of the tick, seconds.
        t_s: f64,
        /// The QP's failure.
        error: crate::planning::ik::IkError,
    },
    /// The robot model could not be placed in the world.
    #[error(transparent)]
    Robot(#[from] crate::robot::RobotError),
}

/// The MuJoCo model and data of one world. `data` holds the current state; ray casts read it.
pub struct World {
    model: Arc<MjModel>,
    data: MjData<Arc<MjModel>>,
    xml: String,
    lidar_groups: [u8; mjNGROUP as usize],
    /// The static boxes the lidar's rays meet, when those are all it can meet (else `mj_ray`
    /// casts them).
    box_rays: Option<BoxRays>,
    /// Each actuated joint's qpos and qvel address (the actuators are in the model's joint
    /// order), and whether they are the model's own order after the free joint.
    qpos_adr: Vec<usize>,
    dof_adr: Vec<usize>,
    model_order: bool,
    /// The servos' delay and play, when the body has any.
    line: Option<ServoLine>,
}

impl World {
    /// Compiles the world of `scene` with `robot` in it and runs forward kinematics once.
    pub fn new(scene: &Scene, robot: &RobotFragment) -> Result<Self, SimError> {
        Self::with_options(scene, robot, &WorldOptions::default())
    }

    /// [`World::new`] built as `options` say: the world's boxes laid out in the body tree
    /// (the same physics, see [`crate::scene::mjcf::BoxBodies`]), the physics step.
    pub fn with_options(
        scene: &Scene,
        robot: &RobotFragment,
        options: &WorldOptions,
    ) -> Result<Self, SimError> {
        Self::from_xml(world_xml_with(scene, robot, options))
    }

    /// The world of `scene` with the bench's robot, the HRP-4-class model, standing in
    /// half-sitting with its feet at the scene's start. This is the one place that chooses
    /// the robot.
    pub fn for_scene(scene: &Scene) -> Result<Self, SimError> {
        Self::for_scene_options(scene, &WorldOptions::default())
    }

    /// [`World::for_scene`] built as `options` say.
    pub fn for_scene_options(scene: &Scene, options: &WorldOptions) -> Result<Self, SimError> {
        let model = hrp4::model()?;
        Self::with_plant_options(scene, &Plant::nominal(&model), options)
    }

    /// [`World::for_scene`] with the robot's body `plant` (drawn for the bench's model).
    pub fn with_plant(scene: &Scene, plant: &Plant) -> Result<Self, SimError> {
        Self::with_plant_options(scene, plant, &WorldOptions::default())
    }

    /// [`World::with_plant`] built as `options` say.
    pub fn with_plant_options(
        scene: &Scene,
        plant: &Plant,
        options: &WorldOptions,
    ) -> Result<Self, SimError> {
        let model = hrp4::model()?;
        let q = hrp4::half_sitting_at(&model, &scene.robot_start())?;
        let soles = [hrp4::R_SOLE, hrp4::L_SOLE];
        let robot = robot::mjcf::fragment_varied(&model, &q, &soles, &plant.body)?;
        let mut world = Self::with_options(scene, &robot, options)?;
        let a = &plant.actuation;
        if a.latency_s > 0.0 || a.backlash_rad > 0.0 {
            let dt = world.model.opt().timestep;
            world.line = Some(ServoLine::new(a, dt, world.data.ctrl()));
        }
        Ok(world)
    }

    /// Compiles an MJCF text (geoms of group 2 are treated as the robot's).
    pub fn from_xml(xml: String) -> Result<Self, SimError> {
        let model = MjModel::from_xml_string(&xml).map_err(|e| SimError::Compile(e.to_string()))?;
        let model = Arc::new(model);
        let mut data = MjData::new(model.clone());
        if model.ffi().nkey > 0 {
            // The robot's initial state (keyframe 0 exists, so this cannot fail).
            let _ = data.reset_keyframe(0);
        }
        data.forward();
        let mut lidar_groups = [1u8; mjNGROUP as usize];
        lidar_groups[ROBOT_GEOM_GROUP] = 0;
        let joints: Vec<usize> = model.actuator_trnid().iter().map(|t| t[0] as usize).collect();
        let qpos_adr: Vec<usize> = joints.iter().map(|&j| model.jnt_qposadr()[j] as usize).collect();
        let dof_adr: Vec<usize> = joints.iter().map(|&j| model.jnt_dofadr()[j] as usize).collect();
        let model_order = qpos_adr.iter().enumerate().all(|(a, &q)| q == Q_JOINTS + a)
            && dof_adr.iter().enumerate().all(|(a, &v)| v == V_JOINTS + a);
        let box_rays = BoxRays::of(&model, &data, &lidar_groups);
        Ok(Self { model, data, xml, lidar_groups, box_rays, qpos_adr, dof_adr, model_order, line: None })
    }

    /// Actuated joint `a`'s angle, rad.
    pub fn joint_q(&self, a: usize) -> f64 {
        self.data.qpos()[self.qpos_adr[a]]
    }

    /// Actuated joint `a`'s speed, rad/s.
    pub fn joint_qd(&self, a: usize) -> f64 {
        self.data.qvel()[self.dof_adr[a]]
    }

    /// The robot's configuration in its model's layout: the free joint, then the actuated
    /// joints in order (a bush's angles, which no encoder reads, left out).
    pub fn configuration(&self) -> Cow<'_, [f64]> {
        let n = Q_JOINTS + self.qpos_adr.len();
        match self.model_order {
            true => Cow::Borrowed(&self.data.qpos()[..n]),
            false => {
                let mut q = Vec::with_capacity(n);
                self.configuration_into(&mut q);
                Cow::Owned(q)
            }
        }
    }

    /// [`World::configuration`] written into `q` (its earlier contents dropped), for a loop
    /// that reads it at every physics step without allocating.
    pub fn configuration_into(&self, q: &mut Vec<f64>) {
        let qpos = self.data.qpos();
        q.clear();
        q.extend_from_slice(&qpos[..Q_JOINTS]);
        match self.model_order {
            true => q.extend_from_slice(&qpos[Q_JOINTS..Q_JOINTS + self.qpos_adr.len()]),
            false => q.extend(self.qpos_adr.iter().map(|&i| qpos[i])),
        }
    }

    /// The servos' set points the controller sent last (those in force).
    pub fn set_points(&self) -> &[f64] {
        match &self.line {
            Some(line) => line.sent(),
            None => self.data.ctrl(),
        }
    }

    /// The controller sends the servos' set points (they reach the servos through the body's
    /// latency and play, if any).
    pub fn send_set_points(&mut self, set_points: &[f64]) {
        match &mut self.line {
            Some(line) => line.send(set_points),
            None => self.data.ctrl_mut().copy_from_slice(set_points),
        }
    }

    /// One physics step, the set points due applied first.
    pub fn step(&mut self) {
        if let Some(line) = &mut self.line {
            line.read_joints(self.data.qpos(), &self.qpos_adr);
            line.apply(self.data.ctrl_mut());
        }
        self.data.step();
    }

    /// The compiled model.
    pub fn model(&self) -> &MjModel {
        &self.model
    }

    /// The simulation state.
    pub fn data(&self) -> &MjData<Arc<MjModel>> {
        &self.data
    }

    /// The simulation state, mutable (step it, set joints; call `forward` before ray casts).
    pub fn data_mut(&mut self) -> &mut MjData<Arc<MjModel>> {
        &mut self.data
    }

    /// The MJCF text the world was compiled from.
    pub fn xml(&self) -> &str {
        &self.xml
    }

    /// Id of a site by name.
    pub fn site_id(&self, name: &str) -> Result<usize, SimError> {
        self.model
            .name_to_id(MjtObjBase::mjOBJ_SITE, name)
            .ok_or_else(|| SimError::MissingSite(name.to_string()))
    }

    /// Id of a body by name.
    pub fn body_id(&self, name: &str) -> Result<usize, SimError> {
        self.model
            .name_to_id(MjtObjBase::mjOBJ_BODY, name)
            .ok_or_else(|| SimError::MissingBody(name.to_string()))
    }

    /// Address of a sensor's first value in the sensor data, by name.
    pub fn sensor_adr(&self, name: &str) -> Result<usize, SimError> {
        let id = self
            .model
            .name_to_id(MjtObjBase::mjOBJ_SENSOR, name)
            .ok_or_else(|| SimError::MissingSensor(name.to_string()))?;
        Ok(self.model.sensor_adr()[id] as usize)
    }

    /// World pose of a site, from the last forward kinematics.
    pub fn site_pose(&self, site: usize) -> Isometry3<f64> {
        let p = self.data.site_xpos()[site];
        let m = self.data.site_xmat()[site];
        let r = Rotation3::from_matrix_unchecked(Matrix3::from_row_slice(&m));
        Isometry3::from_parts(Translation3::new(p[0], p[1], p[2]), UnitQuaternion::from_rotation_matrix(&r))
    }

    /// Each actuator's position gain kp and damping gain kv (MuJoCo's `position` servo:
    /// force = kp (ctrl - q) - kv qd).
    pub fn servo_gains(&self) -> (Vec<f64>, Vec<f64>) {
        let m = &self.model;
        let nu = m.ffi().nu as usize;
        let (gp, bp) = (m.actuator_gainprm(), m.actuator_biasprm());
        ((0..nu).map(|a| gp[a][0]).collect(), (0..nu).map(|a| -bp[a][2]).collect())
    }

    /// Whether the lidar's rays are cast by [`BoxRays`] (the world is static boxes).
    pub fn casts_by_boxes(&self) -> bool {
        self.box_rays.is_some()
    }

    /// Geom group of geom `id`.
    pub fn geom_group(&self, id: usize) -> usize {
        self.model.geom_group()[id] as usize
    }

    /// Name of geom `id` (empty when unnamed).
    pub fn geom_name(&self, id: usize) -> &str {
        self.model.id_to_name(MjtObjBase::mjOBJ_GEOM, id).unwrap_or("")
    }
}

impl RayCaster for World {
    /// Casts one ray from `origin` along the unit vector `dir` against every geom except the
    /// robot's, as of the last forward kinematics: `mj_ray`'s answer (by [`BoxRays`] where the
    /// world is static boxes). Thread-safe: reads the state only.
    fn ray(&self, origin: &Point3<f64>, dir: &Vector3<f64>) -> Option<RayHit> {
        match &self.box_rays {
            Some(boxes) => boxes
                .ray(&[origin.x, origin.y, origin.z], &[dir.x, dir.y, dir.z])
                .map(|(distance_m, geom)| RayHit { distance_m, geom }),
            None => self.ray_by_mujoco(origin, dir),
        }
    }
}

impl World {
    /// [`RayCaster::ray`] by MuJoCo's `mj_ray` over every geom, whatever the world holds.
    pub fn ray_by_mujoco(&self, origin: &Point3<f64>, dir: &Vector3<f64>) -> Option<RayHit> {
        let pnt = [origin.x, origin.y, origin.z];
        let vec = [dir.x, dir.y, dir.z];
        let mut geom = -1i32;
        // SAFETY: mj_ray reads the model and the data only (both const in its C signature);
        // the pointers are valid for the call, the group array has mjNGROUP entries and the
        // normal output may be null.
        let dist = unsafe {
            mj_ray(
                self.model.ffi(),
                self.data.ffi(),
                &pnt,
                &vec,
                self.lidar_groups.as_ptr(),
                true,
                -1,
                &mut geom,
                std::ptr::null_mut(),
            )
        };
        (geom >= 0 && dist >= 0.0).then_some(RayHit { distance_m: dist, geom: geom as usize })
    }
}
