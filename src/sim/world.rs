//! A compiled MuJoCo world (model + data) built from a [`Scene`] and a robot fragment, with
//! thread-safe ray casting for the simulated lidar (the world is a [`RayCaster`]).

use crate::robot::{self, hrp4};
use crate::scene::mjcf::{world_xml, RobotFragment, ROBOT_GEOM_GROUP};
use crate::scene::Scene;
use crate::sensor::{RayCaster, RayHit};
use mujoco_rs::mujoco_c::{mjNGROUP, mj_ray};
use mujoco_rs::prelude::{MjData, MjModel, MjtObjBase};
use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};
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
}

impl World {
    /// Compiles the world of `scene` with `robot` in it and runs forward kinematics once.
    pub fn new(scene: &Scene, robot: &RobotFragment) -> Result<Self, SimError> {
        let xml = world_xml(scene, robot);
        Self::from_xml(xml)
    }

    /// The world of `scene` with the bench's robot, the HRP-4-class model, standing in
    /// half-sitting with its feet at the scene's start. This is the one place that chooses
    /// the robot.
    pub fn for_scene(scene: &Scene) -> Result<Self, SimError> {
        let model = hrp4::model()?;
        let q = hrp4::half_sitting_at(&model, &scene.robot_start())?;
        Self::new(scene, &robot::mjcf::fragment(&model, &q, &[hrp4::R_SOLE, hrp4::L_SOLE])?)
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
        Ok(Self { model, data, xml, lidar_groups })
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
    /// robot's, as of the last forward kinematics. Thread-safe: reads the state only.
    fn ray(&self, origin: &Point3<f64>, dir: &Vector3<f64>) -> Option<RayHit> {
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
