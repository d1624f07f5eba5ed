//! The HRP-4-class model (issue 4): its published figures, its kinematics against MuJoCo as
//! an independent implementation, standing still under its own servos, and the lidar mount's
//! view of the floor.

// Test helpers unwrap: a panic there is the test failing.
#![allow(clippy::unwrap_used)]

use nalgebra::{Matrix3xX, Matrix6xX, Point3, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use stairbench::robot::hrp4::{self, HEAD_TOP, LIDAR_MOUNT, L_SOLE, R_SOLE};
use stairbench::robot::model::{base_pose, set_base_rotation, Q_JOINTS, V_JOINTS};
use stairbench::robot::{Kinematics, RobotModel};
use stairbench::scenario::Scenario;
use stairbench::scene::Scene;
use stairbench::sensor::RayCaster;
use stairbench::sim::World;

fn model() -> RobotModel {
    hrp4::model().expect("the compiled-in URDF parses")
}

/// The Exp. 1 world with the robot in it, and the id of the robot's root body.
fn exp1_world(m: &RobotModel) -> (World, usize) {
    let scene = Scene::from_scenario(&Scenario::default()).unwrap();
    let world = World::for_scene(&scene).unwrap();
    let root = world.body_id(&m.root().name).unwrap();
    (world, root)
}

fn half_sitting_q(m: &RobotModel) -> Vec<f64> {
    let joints = hrp4::half_sitting_joints(m).unwrap();
    hrp4::standing_config(m, &joints, &nalgebra::Isometry3::identity()).unwrap()
}

#[test]
fn has_hrp4s_34_joints_and_names() {
    let m = model();
    assert_eq!(m.joints().len(), 34);
    for side in ["R", "L"] {
        for j in ["HIP_Y", "HIP_R", "HIP_P", "KNEE_P", "ANKLE_P", "ANKLE_R"] {
            m.joint_id(&format!("{side}_{j}")).unwrap();
        }
        for j in ["SHOULDER_P", "SHOULDER_R", "SHOULDER_Y", "ELBOW_P", "WRIST_Y", "WRIST_P", "WRIST_R"] {
            m.joint_id(&format!("{side}_{j}")).unwrap();
        }
        m.joint_id(&format!("{side}_HAND_J0")).unwrap();
        m.joint_id(&format!("{side}_HAND_J1")).unwrap();
    }
    for j in ["CHEST_P", "CHEST_Y", "NECK_Y", "NECK_P"] {
        m.joint_id(j).unwrap();
    }
    assert_eq!(m.nq(), 41);
    assert_eq!(m.nv(), 40);
}

#[test]
fn published_figures() {
    let m = model();
    assert!((m.total_mass_kg() - 39.0).abs() <= 0.5, "mass {}", m.total_mass_kg());
    let mut k = Kinematics::new(&m);
    // Standing straight (zero joints), soles on the floor.
    let zero = vec![0.0; m.joints().len()];
    let q0 = hrp4::standing_config(&m, &zero, &nalgebra::Isometry3::identity()).unwrap();
    k.update(&q0).unwrap();
    let height = k.frame_pose(m.frame_id(HEAD_TOP).unwrap()).translation.z;
    assert!((height - 1.51).abs() <= 0.03, "standing height {height}");
    let (r, l) = (m.frame_id(R_SOLE).unwrap(), m.frame_id(L_SOLE).unwrap());
    let gap = (k.frame_pose(r).translation.vector - k.frame_pose(l).translation.vector).norm();
    assert!((gap - 0.18).abs() <= 0.01, "feet {gap} m apart");
    // Stretched leg: hip joint to sole.
    let hip = k.link_pose(m.joint_link("R_HIP_P").unwrap()).translation.z;
    assert!((hip - 0.8).abs() <= 0.02, "stretched leg {hip}");

    let q = half_sitting_q(&m);
    k.update(&q).unwrap();
    let com = k.com();
    println!(
        "mass {:.3} kg, standing height {height:.3} m, feet {gap:.3} m apart, stretched leg {hip:.3} m, half-sitting CoM {:.3} m",
        m.total_mass_kg(),
        com.z
    );
    assert!((com.z - 0.78).abs() <= 0.03, "half-sitting CoM height {}", com.z);
    for f in [r, l] {
        let p = k.frame_pose(f);
        assert!(p.translation.z.abs() <= 0.001, "sole height {}", p.translation.z);
        let tilt = (p.rotation * Vector3::z()).angle(&Vector3::z());
        assert!(tilt <= 0.5f64.to_radians(), "sole tilt {} deg", tilt.to_degrees());
    }
    // The CoM is over the support polygon (between the feet).
    let mid = (k.frame_pose(r).translation.vector + k.frame_pose(l).translation.vector) / 2.0;
    assert!((com.x - mid.x).abs() < 0.05 && (com.y - mid.y).abs() < 0.03, "CoM {com} over {mid}");
}

fn random_q(m: &RobotModel, rng: &mut ChaCha8Rng) -> Vec<f64> {
    let mut q = vec![0.0; m.nq()];
    for v in q.iter_mut().take(3) {
        *v = rng.random_range(-1.0..1.0);
    }
    let rot = UnitQuaternion::from_euler_angles(
        rng.random_range(-3.0..3.0),
        rng.random_range(-1.5..1.5),
        rng.random_range(-3.0..3.0),
    );
    set_base_rotation(&mut q, &rot);
    for (i, j) in m.joints().iter().enumerate() {
        q[Q_JOINTS + i] = rng.random_range(j.lower_rad..=j.upper_rad);
    }
    q
}

/// MuJoCo's row-major 3 x nv block against rows `r0..r0+3` of ours.
fn max_diff_rows(mj: &[f64], ours: &nalgebra::DMatrix<f64>, r0: usize) -> f64 {
    let nv = ours.ncols();
    let mut worst = 0.0f64;
    for row in 0..3 {
        for c in 0..nv {
            worst = worst.max((mj[row * nv + c] - ours[(r0 + row, c)]).abs());
        }
    }
    worst
}

#[test]
fn kinematics_agree_with_mujoco_at_1000_configurations() {
    let m = model();
    let (mut world, root) = exp1_world(&m);
    let frames = [R_SOLE, L_SOLE, LIDAR_MOUNT];
    let sites: Vec<usize> = frames.iter().map(|f| world.site_id(f).unwrap()).collect();
    let ids: Vec<usize> = frames.iter().map(|f| m.frame_id(f).unwrap()).collect();
    let mut k = Kinematics::new(&m);
    let mut jac = Matrix6xX::zeros(m.nv());
    let mut jcom = Matrix3xX::zeros(m.nv());
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let (mut pose_err, mut jac_err, mut com_err, mut jcom_err) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for _ in 0..1000 {
        let q = random_q(&m, &mut rng);
        k.update(&q).unwrap();
        let data = world.data_mut();
        data.qpos_mut().copy_from_slice(&q);
        data.kinematics();
        data.com_pos();
        for (s, f) in sites.iter().zip(&ids) {
            let ours = k.frame_pose(*f);
            let theirs = world.site_pose(*s);
            pose_err = pose_err.max((ours.translation.vector - theirs.translation.vector).norm());
            pose_err = pose_err.max(ours.rotation.angle_to(&theirs.rotation));
            let (jp, jr) = world.data().jac_site(true, true, *s);
            k.frame_jacobian_into(*f, &mut jac);
            let dm = nalgebra::DMatrix::from_column_slice(6, m.nv(), jac.as_slice());
            jac_err = jac_err.max(max_diff_rows(&jp, &dm, 0)).max(max_diff_rows(&jr, &dm, 3));
        }
        let c = world.data().subtree_com()[root];
        com_err = com_err.max((k.com() - Point3::new(c[0], c[1], c[2])).norm());
        let jc = world.data_mut().jac_subtree_com(root);
        k.com_jacobian_into(&mut jcom);
        let dm = nalgebra::DMatrix::from_column_slice(3, m.nv(), jcom.as_slice());
        jcom_err = jcom_err.max(max_diff_rows(&jc, &dm, 0));
    }
    println!("max errors: pose {pose_err:.2e}, jacobian {jac_err:.2e}, com {com_err:.2e}, com jacobian {jcom_err:.2e}");
    assert!(pose_err < 1e-9, "frame poses differ by {pose_err}");
    assert!(jac_err < 1e-9, "frame Jacobians differ by {jac_err}");
    assert!(com_err < 1e-9, "CoM differs by {com_err}");
    assert!(jcom_err < 1e-9, "CoM Jacobians differ by {jcom_err}");
}

#[test]
fn jacobian_matches_finite_differences() {
    // An independent check of the free-flyer's angular convention too (base frame rates).
    let m = model();
    let mut k = Kinematics::new(&m);
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let q = random_q(&m, &mut rng);
    let f = m.frame_id(R_SOLE).unwrap();
    k.update(&q).unwrap();
    let p0 = k.frame_pose(f).translation.vector;
    let mut jac = k.new_frame_jacobian();
    k.frame_jacobian_into(f, &mut jac);
    let h = 1e-7;
    for dof in 0..m.nv() {
        let mut q1 = q.clone();
        if dof < 3 {
            q1[dof] += h;
        } else if dof < 6 {
            let rot = base_pose(&q).rotation;
            let mut w = Vector3::zeros();
            w[dof - 3] = h;
            let r1 = rot * UnitQuaternion::from_scaled_axis(w);
            set_base_rotation(&mut q1, &r1);
        } else {
            q1[Q_JOINTS + dof - V_JOINTS] += h;
        }
        k.update(&q1).unwrap();
        let d = (k.frame_pose(f).translation.vector - p0) / h;
        for row in 0..3 {
            assert!(
                (d[row] - jac[(row, dof)]).abs() < 1e-5,
                "dof {dof} row {row}: {} vs {}",
                d[row],
                jac[(row, dof)]
            );
        }
    }
}

#[test]
fn stands_in_half_sitting_for_10_seconds() {
    let m = model();
    let (mut world, root) = exp1_world(&m);
    let com0 = world.data().subtree_com()[root];
    let nu = world.model().ffi().nu as usize;
    assert_eq!(nu, 34);
    let (kp, kv) = world.servo_gains();
    let qadr: Vec<usize> = (0..nu).map(|a| Q_JOINTS + a).collect();
    let mut worst_ratio = 0.0f64;
    let steps = (10.0 / world.model().opt().timestep) as usize;
    for _ in 0..steps {
        world.data_mut().step();
        let d = world.data();
        for a in 0..nu {
            // The servo's unclamped demand must stay within the joint's torque limit:
            // MuJoCo clamps at forcerange, so checking its output would prove nothing.
            let demand = kp[a] * (d.ctrl()[a] - d.qpos()[qadr[a]]) - kv[a] * d.qvel()[V_JOINTS + a];
            worst_ratio = worst_ratio.max(demand.abs() / m.joints()[a].effort_nm);
        }
    }
    let com1 = world.data().subtree_com()[root];
    let drift =
        ((com1[0] - com0[0]).powi(2) + (com1[1] - com0[1]).powi(2) + (com1[2] - com0[2]).powi(2)).sqrt();
    println!(
        "CoM drift {:.2} mm, worst torque demand {:.0} % of the limit",
        drift * 1e3,
        worst_ratio * 100.0
    );
    assert!(drift < 0.01, "CoM drifted {drift} m");
    assert!(worst_ratio <= 1.0, "a servo asked for {:.0} % of its torque limit", worst_ratio * 100.0);
}

#[test]
fn lidar_mount_sees_the_floor_one_metre_ahead() {
    let mut s = Scenario::default();
    s.staircase.steps = 1;
    s.staircase.start_m = [4.0, 0.0]; // nothing but floor in front
    let scene = Scene::from_scenario(&s).unwrap();
    let world = World::for_scene(&scene).unwrap();
    let mount = world.site_pose(world.site_id(LIDAR_MOUNT).unwrap());
    let start = scene.robot_start().translation.vector;
    let target = Point3::new(start.x + 1.0, start.y, 0.0);
    let origin = Point3::from(mount.translation.vector);
    let dir = (target - origin).normalize();
    let hit = world.ray(&origin, &dir).expect("the ray from the lidar mount hits something");
    assert_eq!(world.geom_name(hit.geom), "floor");
    assert!((hit.distance_m - (target - origin).norm()).abs() < 1e-6);
}

#[test]
fn soles_and_only_soles_get_the_sole_friction() {
    use stairbench::robot::mjcf::{BODY_FRICTION, SOLE_FRICTION};
    let m = model();
    let (world, _) = exp1_world(&m);
    let sole_links: Vec<&str> = [R_SOLE, L_SOLE]
        .iter()
        .map(|f| m.links()[m.frames()[m.frame_id(f).unwrap()].link].name.as_str())
        .collect();
    let mut soles = 0;
    for g in 0..world.model().ffi().ngeom as usize {
        if world.geom_group(g) != stairbench::scene::mjcf::ROBOT_GEOM_GROUP {
            continue;
        }
        let name = world.geom_name(g);
        let on_sole = sole_links.iter().any(|l| name.starts_with(&format!("{l}_geom")));
        let friction = world.model().geom_friction()[g][0];
        let want = if on_sole { SOLE_FRICTION } else { BODY_FRICTION };
        assert_eq!(friction, want, "{name}");
        soles += usize::from(on_sole);
    }
    assert_eq!(soles, 2, "one box per sole");
}

/// The body's angular momentum about its CoM from two configurations a short time apart
/// (`robot::momentum`, link velocities by finite differences on our own kinematics) against
/// MuJoCo's own (`mj_subtreeVel`'s `subtree_angmom` of the robot's root, from its velocities),
/// at random configurations moving at random velocities.
#[test]
fn angular_momentum_agrees_with_mujoco_at_200_moving_configurations() {
    use stairbench::planning::ik::integrate;
    use stairbench::robot::momentum::centroidal_angular_momentum;
    let m = model();
    let (mut world, root) = exp1_world(&m);
    let (mut a, mut b) = (Kinematics::new(&m), Kinematics::new(&m));
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let h = 1e-5;
    let (mut worst, mut largest) = (0.0f64, 0.0f64);
    for _ in 0..200 {
        let q = random_q(&m, &mut rng);
        let qd: Vec<f64> = (0..m.nv())
            .map(|i| if i < 3 { rng.random_range(-0.3..0.3) } else { rng.random_range(-1.0..1.0) })
            .collect();
        let (mut qa, mut qb) = (q.clone(), q.clone());
        integrate(&mut qa, &qd, -h / 2.0);
        integrate(&mut qb, &qd, h / 2.0);
        a.update(&qa).unwrap();
        b.update(&qb).unwrap();
        let ours = centroidal_angular_momentum(&m, a.link_poses(), b.link_poses(), h);
        let data = world.data_mut();
        data.qpos_mut().copy_from_slice(&q);
        data.qvel_mut().copy_from_slice(&qd);
        data.kinematics();
        data.com_pos();
        data.com_vel();
        data.subtree_vel();
        let l = world.data().subtree_angmom()[root];
        let theirs = Vector3::new(l[0], l[1], l[2]);
        worst = worst.max((ours - theirs).norm());
        largest = largest.max(theirs.norm());
    }
    println!("angular momentum: largest {largest:.3} kg m^2/s, worst difference {worst:.2e}");
    assert!(largest > 0.5, "the random motions hardly moved: {largest}");
    assert!(worst < 1e-6 * largest.max(1.0), "angular momenta differ by {worst} (largest {largest})");
}

/// How far the right sole travels across (metres) while the robot, standing in half-sitting
/// in the Exp. 1 world built with `options`, is pushed sideways at the pelvis by `push_n`
/// for 3 s after a second to settle; with the largest ratio of the contacts' resultant
/// across to what the floor's friction holds, over the push.
fn sole_travel_under_a_push(options: &stairbench::scene::mjcf::WorldOptions, push_n: f64) -> (f64, f64) {
    let m = model();
    let scene = Scene::from_scenario(&Scenario::default()).unwrap();
    let mut world = World::for_scene_options(&scene, options).unwrap();
    let root = world.body_id(&m.root().name).unwrap();
    let sole = world.site_id(R_SOLE).unwrap();
    let dt = world.model().opt().timestep;
    for _ in 0..(1.0 / dt) as usize {
        world.data_mut().step();
    }
    let from = world.site_pose(sole).translation.vector;
    let mut ratio = 0.0f64;
    for _ in 0..(3.0 / dt) as usize {
        world.data_mut().xfrc_applied_mut()[root][1] = push_n;
        world.data_mut().step();
        // The contacts' resultant in the world, against the floor's cone (every contact is
        // a sole's on the floor).
        let d = world.data();
        let (mut total, mut mu) = (Vector3::zeros(), f64::INFINITY);
        for (ci, c) in d.contact().iter().enumerate() {
            let f = d.contact_force(ci);
            let axis = |r: usize| Vector3::new(c.frame[3 * r], c.frame[3 * r + 1], c.frame[3 * r + 2]);
            total += axis(0) * f[0] + axis(1) * f[1] + axis(2) * f[2];
            mu = mu.min(c.friction[0]);
        }
        ratio = ratio.max(total.xy().norm() / (mu * total.z.abs()));
    }
    let to = world.site_pose(sole).translation.vector;
    ((to - from).xy().norm(), ratio)
}

/// MuJoCo's friction holds a contact through its sliding speed alone (a reference
/// acceleration `-b v`, `b` inversely proportional to the time constant), so under a steady
/// push well inside the friction cone a sole creeps, and creeps about in proportion to that
/// time constant: with `PhysicsParams::sole_friction_timeconst_s` at a quarter of the
/// contacts' own 0.02 s, the soles (explicit pairs then) creep less than half as far, the
/// push held the same way. The reference is MuJoCo's own automatic contacts (the default),
/// which the pairs at 0.02 s reproduce.
#[test]
fn a_sole_held_with_a_shorter_friction_time_constant_creeps_less_under_a_steady_push() {
    use stairbench::scene::mjcf::WorldOptions;
    // A tenth of the robot's weight across: far inside the floor's friction (0.8).
    let push_n = 40.0;
    let (own_m, own_ratio) = sole_travel_under_a_push(&WorldOptions::default(), push_n);
    let held = WorldOptions { sole_friction_timeconst_s: Some(0.005), ..Default::default() };
    let (held_m, held_ratio) = sole_travel_under_a_push(&held, push_n);
    println!(
        "sole travel {:.1} um at the contacts' own time constant (friction ratio {:.2}), {:.1} um at 5 ms ({:.2})",
        own_m * 1e6,
        own_ratio,
        held_m * 1e6,
        held_ratio
    );
    assert!(own_ratio < 0.5 && held_ratio < 0.5, "the push must stay inside the cone");
    assert!(own_m > 20e-6, "the default contacts creep measurably: {own_m} m");
    assert!(held_m < 0.5 * own_m, "{held_m} m against {own_m} m");
    // The pairs at the contacts' own time constant are the automatic contacts: the same
    // travel, so what changed above is the time constant alone.
    let same = WorldOptions { sole_friction_timeconst_s: Some(0.02), ..Default::default() };
    let (same_m, _) = sole_travel_under_a_push(&same, push_n);
    assert!((same_m - own_m).abs() < 1e-9, "{same_m} m against {own_m} m");
}
