//! The robot's kinematic tree, read from a URDF (urdf-rs): links in depth-first order with
//! their joints, inertias and collision shapes, plus the fixed frames (soles, lidar mount).
//!
//! Fixed joints are folded into frames on their parent link, as MuJoCo's URDF import would
//! fuse them. The configuration is a free-flyer base followed by the revolute joints in
//! depth-first order, MuJoCo's layout: q = [x y z, qw qx qy qz, joints], v = [linear velocity
//! (world), angular velocity (base frame), joint rates].

use nalgebra::{Isometry3, Matrix3, Translation3, Unit, UnitQuaternion, Vector3};
use std::collections::HashMap;

/// Why a robot description was refused.
#[derive(Debug, thiserror::Error)]
pub enum RobotError {
    /// The URDF is not valid XML or not URDF.
    #[error("cannot read the URDF: {0}")]
    Urdf(String),
    /// The URDF is readable but not a robot this bench can use.
    #[error("unusable robot description: {0}")]
    Invalid(String),
    /// A name the caller asked for is not in the model.
    #[error("the robot has no {kind} named `{name}`")]
    Unknown {
        /// "joint" or "frame".
        kind: &'static str,
        /// The name asked for.
        name: String,
    },
}

/// A collision shape in its link's frame.
#[derive(Debug, Clone, PartialEq)]
pub enum Shape {
    /// Box with full sizes x, y, z, metres.
    Box([f64; 3]),
    /// Cylinder along the local z axis (a capsule in the simulator): radius, length, metres.
    Cylinder {
        /// Radius, metres.
        radius_m: f64,
        /// Length, metres.
        length_m: f64,
    },
    /// Sphere of this radius, metres.
    Sphere(f64),
}

/// A collision geometry of a link.
#[derive(Debug, Clone, PartialEq)]
pub struct Collision {
    /// Placement in the link frame.
    pub placement: Isometry3<f64>,
    /// The shape.
    pub shape: Shape,
}

/// One link (body) of the tree.
#[derive(Debug, Clone)]
pub struct Link {
    /// URDF name.
    pub name: String,
    /// Parent link (`None` for the root).
    pub parent: Option<usize>,
    /// The joint moving this link relative to its parent (`None` for the root).
    pub joint: Option<usize>,
    /// Joint frame in the parent link frame at zero joint angle.
    pub placement: Isometry3<f64>,
    /// Joint axis in the link frame (unit).
    pub axis: Unit<Vector3<f64>>,
    /// Mass, kg.
    pub mass_kg: f64,
    /// Centre of mass in the link frame, metres.
    pub com_m: Vector3<f64>,
    /// Rotational inertia about the centre of mass, in the link frame, kg m^2.
    pub inertia: Matrix3<f64>,
    /// Collision shapes.
    pub collisions: Vec<Collision>,
}

/// One revolute joint.
#[derive(Debug, Clone)]
pub struct Joint {
    /// Name (HRP-4's, e.g. `R_KNEE_P`).
    pub name: String,
    /// The link it moves.
    pub link: usize,
    /// Lower position limit, rad.
    pub lower_rad: f64,
    /// Upper position limit, rad.
    pub upper_rad: f64,
    /// Torque limit, N m.
    pub effort_nm: f64,
    /// Velocity limit, rad/s.
    pub velocity_rad_s: f64,
}

/// A fixed frame on a link (sole centre, lidar mount, ...).
#[derive(Debug, Clone)]
pub struct Frame {
    /// Name.
    pub name: String,
    /// The link carrying it.
    pub link: usize,
    /// Placement in the link frame.
    pub placement: Isometry3<f64>,
}

/// Index of the first joint coordinate in q (after the free-flyer's 7).
pub const Q_JOINTS: usize = 7;
/// Index of the first joint rate in v (after the free-flyer's 6).
pub const V_JOINTS: usize = 6;

/// The floating base's pose in configuration `q` (position, then quaternion w x y z; at least
/// 7 values).
pub fn base_pose(q: &[f64]) -> Isometry3<f64> {
    let rotation = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q[3], q[4], q[5], q[6]));
    Isometry3::from_parts(Translation3::new(q[0], q[1], q[2]), rotation)
}

/// Sets the floating base's rotation in configuration `q` (quaternion w x y z at 3..7).
pub fn set_base_rotation(q: &mut [f64], rotation: &UnitQuaternion<f64>) {
    q[3..7].copy_from_slice(&[rotation.w, rotation.i, rotation.j, rotation.k]);
}

/// Sets the floating base's pose in configuration `q` (position at 0..3, rotation at 3..7).
pub fn set_base_pose(q: &mut [f64], pose: &Isometry3<f64>) {
    q[..3].copy_from_slice(pose.translation.vector.as_slice());
    set_base_rotation(q, &pose.rotation);
}

/// Scales the base's quaternion in `q` back to unit length (after an interpolation).
pub fn normalize_base_rotation(q: &mut [f64]) {
    let norm = q[3..7].iter().map(|v| v * v).sum::<f64>().sqrt();
    q[3..7].iter_mut().for_each(|v| *v /= norm);
}

/// A floating-base kinematic tree. Valid once built: links in depth-first order (a parent
/// before its children), one root, positive masses, unit axes, finite figures.
#[derive(Debug, Clone)]
pub struct RobotModel {
    name: String,
    links: Vec<Link>,
    joints: Vec<Joint>,
    frames: Vec<Frame>,
    joint_index: HashMap<String, usize>,
    frame_index: HashMap<String, usize>,
    total_mass_kg: f64,
}

/// A link waiting in the depth-first walk: its name, the moving link it hangs on, the joint
/// to it, and its placement relative to that link.
type Pending<'a> = (&'a str, Option<usize>, Option<&'a urdf_rs::Joint>, Isometry3<f64>);

fn pose_of(o: &urdf_rs::Pose) -> Isometry3<f64> {
    let [x, y, z] = o.xyz.0;
    let [r, p, yw] = o.rpy.0;
    Isometry3::from_parts(Translation3::new(x, y, z), UnitQuaternion::from_euler_angles(r, p, yw))
}

fn finite(xs: &[f64]) -> bool {
    xs.iter().all(|x| x.is_finite())
}

impl RobotModel {
    /// Reads a URDF text. Revolute and continuous joints become joints, fixed joints become
    /// frames; other joint types and mesh geometry are refused.
    pub fn from_urdf_str(text: &str) -> Result<Self, RobotError> {
        let urdf = urdf_rs::read_from_string(text).map_err(|e| RobotError::Urdf(e.to_string()))?;
        let bad = |s: String| RobotError::Invalid(s);
        let by_name: HashMap<&str, &urdf_rs::Link> =
            urdf.links.iter().map(|l| (l.name.as_str(), l)).collect();
        let mut children: HashMap<&str, Vec<&urdf_rs::Joint>> = HashMap::new();
        let mut has_parent: HashMap<&str, bool> = HashMap::new();
        for j in &urdf.joints {
            for end in [&j.parent.link, &j.child.link] {
                if !by_name.contains_key(end.as_str()) {
                    return Err(bad(format!("joint `{}` names an unknown link `{end}`", j.name)));
                }
            }
            if has_parent.insert(j.child.link.as_str(), true).is_some() {
                return Err(bad(format!("link `{}` has two parent joints", j.child.link)));
            }
            children.entry(j.parent.link.as_str()).or_default().push(j);
        }
        let roots: Vec<&str> =
            urdf.links.iter().map(|l| l.name.as_str()).filter(|n| !has_parent.contains_key(n)).collect();
        let [root] = roots[..] else {
            return Err(bad(format!("expected one root link, found {}: {roots:?}", roots.len())));
        };
        let mut model = RobotModel {
            name: urdf.name.clone(),
            links: Vec::new(),
            joints: Vec::new(),
            frames: Vec::new(),
            joint_index: HashMap::new(),
            frame_index: HashMap::new(),
            total_mass_kg: 0.0,
        };
        // Depth-first, children in file order (MuJoCo's body order for the generated MJCF).
        // Fixed children become frames of the nearest moving ancestor.
        let mut stack: Vec<Pending> = vec![(root, None, None, Isometry3::identity())];
        while let Some((name, parent, joint, offset)) = stack.pop() {
            let l = by_name[name];
            let index = match joint.map(|j| &j.joint_type) {
                Some(urdf_rs::JointType::Fixed) => {
                    let link = parent.ok_or_else(|| bad("fixed root".into()))?;
                    if l.inertial.mass.value > 0.0 {
                        return Err(bad(format!("fixed link `{name}` has mass; merge it into its parent")));
                    }
                    model.frame_index.insert(name.to_string(), model.frames.len());
                    model.frames.push(Frame { name: name.to_string(), link, placement: offset });
                    link
                }
                None | Some(urdf_rs::JointType::Revolute | urdf_rs::JointType::Continuous) => {
                    model.push_link(l, parent, joint, offset)?
                }
                Some(other) => {
                    return Err(bad(format!(
                        "joint `{}` is {other:?}; only revolute and fixed are supported",
                        joint.map_or("", |j| j.name.as_str())
                    )));
                }
            };
            if let Some(kids) = children.get(name) {
                for j in kids.iter().rev() {
                    // A fixed joint's child hangs on `index` at the composed placement.
                    let base = if matches!(joint.map(|j| &j.joint_type), Some(urdf_rs::JointType::Fixed)) {
                        offset
                    } else {
                        Isometry3::identity()
                    };
                    stack.push((j.child.link.as_str(), Some(index), Some(j), base * pose_of(&j.origin)));
                }
            }
        }
        if model.links.len() + model.frames.len() != urdf.links.len() {
            return Err(bad("some links are not connected to the root".into()));
        }
        model.total_mass_kg = model.links.iter().map(|l| l.mass_kg).sum();
        if model.total_mass_kg <= 0.0 {
            return Err(bad("the robot has no mass".into()));
        }
        Ok(model)
    }

    fn push_link(
        &mut self,
        l: &urdf_rs::Link,
        parent: Option<usize>,
        joint: Option<&urdf_rs::Joint>,
        placement: Isometry3<f64>,
    ) -> Result<usize, RobotError> {
        let bad = |s: String| RobotError::Invalid(s);
        let index = self.links.len();
        let m = l.inertial.mass.value;
        let i = &l.inertial.inertia;
        let io = pose_of(&l.inertial.origin);
        let local = Matrix3::new(i.ixx, i.ixy, i.ixz, i.ixy, i.iyy, i.iyz, i.ixz, i.iyz, i.izz);
        let r = io.rotation.to_rotation_matrix();
        let inertia = r.matrix() * local * r.matrix().transpose();
        let ok = m > 0.0
            && m.is_finite()
            && finite(inertia.as_slice())
            && finite(io.translation.vector.as_slice());
        if !ok {
            return Err(bad(format!("link `{}` needs a positive, finite mass and inertia", l.name)));
        }
        let mut collisions = Vec::new();
        for c in &l.collision {
            let shape = match &c.geometry {
                urdf_rs::Geometry::Box { size } => Shape::Box(size.0),
                urdf_rs::Geometry::Cylinder { radius, length }
                | urdf_rs::Geometry::Capsule { radius, length } => {
                    Shape::Cylinder { radius_m: *radius, length_m: *length }
                }
                urdf_rs::Geometry::Sphere { radius } => Shape::Sphere(*radius),
                urdf_rs::Geometry::Mesh { .. } => {
                    return Err(bad(format!("link `{}`: mesh collisions are not supported", l.name)))
                }
            };
            collisions.push(Collision { placement: pose_of(&c.origin), shape });
        }
        let mut axis = Vector3::z_axis();
        let mut joint_id = None;
        if let Some(j) = joint {
            axis = Unit::try_new(Vector3::from(j.axis.xyz.0), 1e-9)
                .ok_or_else(|| bad(format!("joint `{}` has a zero axis", j.name)))?;
            let (lo, hi) = match j.joint_type {
                urdf_rs::JointType::Continuous => (f64::NEG_INFINITY, f64::INFINITY),
                _ => (j.limit.lower, j.limit.upper),
            };
            if lo > hi || j.limit.effort <= 0.0 || j.limit.velocity <= 0.0 {
                return Err(bad(format!(
                    "joint `{}` needs lower <= upper and positive effort and velocity limits",
                    j.name
                )));
            }
            joint_id = Some(self.joints.len());
            self.joint_index.insert(j.name.clone(), self.joints.len());
            self.joints.push(Joint {
                name: j.name.clone(),
                link: index,
                lower_rad: lo,
                upper_rad: hi,
                effort_nm: j.limit.effort,
                velocity_rad_s: j.limit.velocity,
            });
        }
        self.links.push(Link {
            name: l.name.clone(),
            parent,
            joint: joint_id,
            placement,
            axis,
            mass_kg: m,
            com_m: io.translation.vector,
            inertia,
            collisions,
        });
        Ok(index)
    }

    /// The robot's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The root link (the floating base).
    pub fn root(&self) -> &Link {
        &self.links[0]
    }

    /// Links, a parent before its children.
    pub fn links(&self) -> &[Link] {
        &self.links
    }

    /// Revolute joints, in configuration order.
    pub fn joints(&self) -> &[Joint] {
        &self.joints
    }

    /// Fixed frames.
    pub fn frames(&self) -> &[Frame] {
        &self.frames
    }

    /// Total mass, kg.
    pub fn total_mass_kg(&self) -> f64 {
        self.total_mass_kg
    }

    /// Length of the configuration vector q.
    pub fn nq(&self) -> usize {
        Q_JOINTS + self.joints.len()
    }

    /// Length of the velocity vector v.
    pub fn nv(&self) -> usize {
        V_JOINTS + self.joints.len()
    }

    /// Index of a joint by name.
    pub fn joint_id(&self, name: &str) -> Result<usize, RobotError> {
        self.joint_index
            .get(name)
            .copied()
            .ok_or_else(|| RobotError::Unknown { kind: "joint", name: name.into() })
    }

    /// Index of the link joint `name` moves (its child link).
    pub fn joint_link(&self, name: &str) -> Result<usize, RobotError> {
        self.joint_id(name).map(|j| self.joints[j].link)
    }

    /// Index of a frame by name.
    pub fn frame_id(&self, name: &str) -> Result<usize, RobotError> {
        self.frame_index
            .get(name)
            .copied()
            .ok_or_else(|| RobotError::Unknown { kind: "frame", name: name.into() })
    }

    /// Half length (x) and half width (y) of the sole at frame `frame`, metres: the box
    /// collision of the frame's link whose bottom face the frame lies on, centred (within
    /// 1 mm) and parallel to it. The contact rectangle of every stability polygon and check.
    pub fn sole_half_m(&self, frame: usize) -> Result<[f64; 2], RobotError> {
        let f = &self.frames[frame];
        let link = &self.links[f.link];
        link.collisions
            .iter()
            .find_map(|c| {
                let Shape::Box([x, y, z]) = c.shape else { return None };
                let bottom = c.placement * nalgebra::Point3::new(0.0, 0.0, -z / 2.0);
                let on = (bottom - nalgebra::Point3::from(f.placement.translation.vector)).norm() < 1e-3;
                let parallel = c.placement.rotation.angle_to(&f.placement.rotation) < 1e-6;
                (on && parallel).then_some([x / 2.0, y / 2.0])
            })
            .ok_or_else(|| {
                RobotError::Invalid(format!(
                    "frame `{}` lies on no box collision of link `{}`: the sole's size is unknown",
                    f.name, link.name
                ))
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn link(name: &str, mass: &str) -> String {
        format!(
            r#"<link name="{name}"><inertial><origin xyz="0 0 0" rpy="0 0 0"/><mass value="{mass}"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>"#
        )
    }

    fn joint(name: &str, parent: &str, child: &str, kind: &str) -> String {
        format!(
            r#"<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/><origin xyz="0 0 0.1" rpy="0 0 0"/><axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="10" velocity="1"/></joint>"#
        )
    }

    fn robot(body: &str) -> String {
        format!(r#"<?xml version="1.0"?><robot name="t">{body}</robot>"#)
    }

    #[test]
    fn reads_a_small_tree_with_a_fixed_frame() {
        let text = robot(&format!(
            "{}{}<link name=\"tip\"/>{}{}",
            link("base", "1"),
            link("arm", "2"),
            joint("J", "base", "arm", "revolute"),
            joint("tip_frame", "arm", "tip", "fixed")
        ));
        let m = RobotModel::from_urdf_str(&text).unwrap();
        assert_eq!((m.links().len(), m.joints().len(), m.frames().len()), (2, 1, 1));
        assert_eq!(m.total_mass_kg(), 3.0);
        assert_eq!(m.frames()[0].link, 1);
        assert!((m.frames()[0].placement.translation.z - 0.1).abs() < 1e-12);
        assert_eq!(m.nq(), 8);
        assert!(matches!(m.joint_id("nope"), Err(RobotError::Unknown { .. })));
    }

    #[test]
    fn refuses_bad_descriptions_with_reasons() {
        let cases = [
            ("not xml", "cannot read the URDF"),
            (&robot(&format!("{}{}", link("a", "1"), link("b", "1"))), "one root"),
            (&robot(&format!("{}{}", link("a", "1"), joint("J", "a", "ghost", "revolute"))), "unknown link"),
            (
                &robot(&format!("{}{}{}", link("a", "1"), link("b", "0"), joint("J", "a", "b", "revolute"))),
                "positive",
            ),
            (
                &robot(&format!("{}{}{}", link("a", "1"), link("b", "1"), joint("J", "a", "b", "prismatic"))),
                "only revolute",
            ),
            (
                &robot(&format!(
                    "{}{}{}",
                    link("a", "1"),
                    link("b", "NaN"),
                    joint("J", "a", "b", "revolute")
                )),
                "positive",
            ),
        ];
        for (text, want) in cases {
            let e = RobotModel::from_urdf_str(text).expect_err(want).to_string();
            assert!(e.contains(want), "{e:?} should say {want:?}");
        }
    }
}
