//! The stabilizer (issue 18): the robot's own sensors measure what MuJoCo's contacts exert;
//! the wrench distribution meets the net wrench inside every cone; with the stabilizer the
//! climbs keep their loaded feet well inside the friction cone; a step higher than perceived
//! is met by the compliant touchdown.

// Test helpers unwrap: a panic there is the test failing.
#![allow(clippy::unwrap_used)]

mod common;

use common::{settled_exp1, step_tops_moved};
use mujoco_rs::prelude::MjtObjBase;
use nalgebra::{Isometry3, Point3, Vector3, Vector6};
use stairbench::cancel::Cancel;
use stairbench::climb::{CheckKind, Execution, Nobody, StopReason};
use stairbench::control::distribution::{
    distribute, net_wrench, regularization_weights, DistributionError, Distributor, Support,
};
use stairbench::control::{FootSensor, StabilizerParams, TickRecord};
use stairbench::params::ClimbParams;
use stairbench::planning::contact::Contact;
use stairbench::planning::{PlanParams, PlanRequest};
use stairbench::robot::{hrp4, GRAVITY_M_S2};
use stairbench::scenario::Scenario;
use stairbench::scene::Scene;
use stairbench::sim::checks::{CheckParams, Ids, Monitor};
use stairbench::sim::execute::execute;
use stairbench::sim::sensors::{SensorParams, SimSensors};
use stairbench::sim::{climb_scenario, World};

/// The ankle force/torque sensors, read without noise and turned into the ground's wrench on
/// each sole, equal the sum of MuJoCo's contact forces on that foot (force within 0.5 N,
/// centre of pressure within 2 mm), standing and with the weight shifted to one foot.
#[test]
fn the_ankle_sensors_measure_the_contact_forces() {
    // A floor of friction 0.45: the checks read each contact's true coefficient (issue 19:
    // they judged every surface against the plan's 0.7).
    let mut scenario = Scenario::default();
    scenario.room.floor_friction = 0.45;
    let scene = Scene::from_scenario(&scenario).unwrap();
    let model = hrp4::model().unwrap();
    let mut world = World::for_scene(&scene).unwrap();
    let quiet = SensorParams {
        force_noise_n: 0.0,
        torque_noise_nm: 0.0,
        accel_noise_m_s2: 0.0,
        gyro_noise_rad_s: 0.0,
        encoder_noise_rad: 0.0,
        ..SensorParams::default()
    };
    let mut sensors = SimSensors::new(&world, [hrp4::R_SOLE, hrp4::L_SOLE], &quiet).unwrap();
    let soles = hrp4::sole_frames(&model).unwrap();
    let feet = soles.map(|s| FootSensor::of(&model, s).unwrap());
    let body = |f: usize| world.body_id(&model.links()[model.frames()[f].link].name).unwrap();
    let ids = Ids {
        feet_bodies: [body(soles[0]), body(soles[1])],
        sole_sites: [world.site_id(hrp4::R_SOLE).unwrap(), world.site_id(hrp4::L_SOLE).unwrap()],
        root_body: world.body_id(&model.root().name).unwrap(),
    };
    let (checks, plan) = (CheckParams::default(), Default::default());
    let mut mon = Monitor::new(&world, ids, &scene, hrp4::sole_half_m(&model).unwrap(), &checks, &plan);
    // Standing, then the left hip rolled so the weight moves toward one foot.
    for phase in 0..2 {
        if phase == 1 {
            let hip = model.joint_id("L_HIP_R").unwrap();
            world.data_mut().ctrl_mut()[hip] += 0.03;
        }
        for _ in 0..600 {
            world.data_mut().step();
        }
        let m = sensors.read(&world);
        let loads = mon.contacts(&world, 0.0, None);
        assert_eq!(loads.surface_mu, [0.45; 2], "the floor's own friction");
        let mut total = 0.0;
        for k in 0..2 {
            let sole = world.site_pose(mon.ids.sole_sites[k]);
            let link = model.frames()[soles[k]].link;
            let link_rotation = sole.rotation * feet[k].sole_in_link.rotation.inverse();
            let w = feet[k].ground_wrench(&m.ft[k], &link_rotation, &Vector3::zeros());
            let force = sole.rotation * w.force_n;
            println!("phase {phase} foot {k}: sensors {force:?}, contacts {:?}", loads.force[k]);
            assert!((force - loads.force[k]).norm() < 0.5, "foot {k} (link {link})");
            let cop = w.cop_m(20.0).expect("loaded");
            let cop_world = sole * Point3::new(cop[0], cop[1], 0.0);
            let contacts_cop = loads.moment[k] / loads.normal_n[k];
            assert!(
                (cop_world.coords.xy() - contacts_cop.xy()).norm() < 0.002,
                "{cop_world:?} {contacts_cop:?}"
            );
            total += force.z;
        }
        let weight = model.total_mass_kg() * 9.81;
        assert!((total - weight).abs() < 0.01 * weight, "the feet carry the robot: {total} N of {weight} N");
    }
}

/// A foot in the air reads no ground once its inertia is removed: the robot dropped from a
/// metre above the floor, its left knee swung by its servo, the left ankle's sensor
/// (MuJoCo's, without noise) turned into the ground's wrench with the foot's centre of mass
/// acceleration (MuJoCo's own, `mj_objectAcceleration`) reads under 0.5 N at every step,
/// and a torque about the sole's centre no larger than the foot's own turning explains
/// (its rotational inertia, neglected, times its angular acceleration and speed squared).
/// Taking only the fall's acceleration (the leg's own swing left out) reads newtons, and
/// more torque than that: the foot's acceleration is what the reading holds.
#[test]
fn a_moving_foot_in_the_air_reads_no_ground_with_its_inertia_removed() {
    let scene = Scene::from_scenario(&Scenario::default()).unwrap();
    let model = hrp4::model().unwrap();
    let mut world = World::for_scene(&scene).unwrap();
    let quiet = SensorParams { force_noise_n: 0.0, torque_noise_nm: 0.0, ..SensorParams::default() };
    let mut sensors = SimSensors::new(&world, [hrp4::R_SOLE, hrp4::L_SOLE], &quiet).unwrap();
    let left = hrp4::sole_frames(&model).unwrap()[1];
    let foot = FootSensor::of(&model, left).unwrap();
    let body = world.body_id(&model.links()[foot.link].name).unwrap();
    let site = world.site_id(hrp4::L_SOLE).unwrap();
    world.data_mut().qpos_mut()[2] += 1.0;
    world.data_mut().forward();
    let knee = model.joint_id("L_KNEE_P").unwrap();
    let bent_rad = world.data().ctrl()[knee];
    // The foot's largest principal moment of inertia (HRP-4's foot: 0.0041 kg m^2).
    let inertia_kg_m2 = model.links()[foot.link].inertia.symmetric_eigenvalues().max();
    let (mut worst_n, mut without_swing_n, mut worst_torque, mut without_swing_torque) =
        (0.0_f64, 0.0_f64, 0.0_f64, 0.0_f64);
    for _ in 0..150 {
        // The knee's set point swings it by 0.2 rad and back in 0.2 s, as a swing's would.
        let t = world.data().time();
        world.data_mut().ctrl_mut()[knee] = bent_rad + 0.1 * (1.0 - (std::f64::consts::TAU * t / 0.2).cos());
        // The step's sensors and accelerations are of the state it started from.
        world.data_mut().step();
        let sole = world.site_pose(site);
        assert!(sole.translation.z > 0.3, "the foot stays in the air");
        let rotation = sole.rotation * foot.sole_in_link.rotation.inverse();
        let ft = sensors.read(&world).ft[1];
        // The specific force (acceleration less gravity) of the foot's centre of mass.
        let specific = world.data().object_acceleration(MjtObjBase::mjOBJ_BODY, body, false);
        let accel = Vector3::new(specific[3], specific[4], specific[5] - GRAVITY_M_S2);
        let ground = foot.ground_wrench(&ft, &rotation, &accel);
        worst_n = worst_n.max(ground.force_n.norm());
        let spin = world.data().object_velocity(MjtObjBase::mjOBJ_BODY, body, false);
        let turning_nm = inertia_kg_m2
            * (Vector3::new(specific[0], specific[1], specific[2]).norm()
                + Vector3::new(spin[0], spin[1], spin[2]).norm_squared());
        // 0.01 N m of slack, a tenth of the sensor's torque noise.
        worst_torque = worst_torque.max(ground.torque_nm.norm() / (turning_nm + 0.01));
        let falling = foot.ground_wrench(&ft, &rotation, &Vector3::new(0.0, 0.0, -GRAVITY_M_S2));
        without_swing_n = without_swing_n.max(falling.force_n.norm());
        without_swing_torque = without_swing_torque.max(falling.torque_nm.norm() / (turning_nm + 0.01));
    }
    println!(
        "in the air: {worst_n:.2} N with the foot's acceleration, {without_swing_n:.2} N with the fall's only; torque at most {worst_torque:.2} / {without_swing_torque:.2} of the turning's"
    );
    assert!(worst_n < 0.5, "{worst_n} N read in the air");
    assert!(worst_torque <= 1.0, "a torque {worst_torque} times what the foot's turning explains");
    assert!(
        without_swing_n > 2.0 && without_swing_torque > 1.0,
        "the swing moved the foot too little to test: {without_swing_n} N, {without_swing_torque} of the turning's"
    );
}

fn sole(x: f64, y: f64, z: f64) -> Contact {
    Contact::new(Isometry3::translation(x, y, z), 0.12, 0.065, 0.7).unwrap()
}

/// The distribution meets the net wrench of a CoM anywhere between the feet (to 0.5 % of
/// the weight: the regularization's price), keeps each foot's wrench in its cone, shares the
/// normal force by where the CoM is, and leaves no internal tangential force between them.
#[test]
fn the_distribution_meets_the_net_wrench_inside_the_cones() {
    let p = StabilizerParams::default();
    let (r, l) = (sole(0.0, -0.09, 0.0), sole(0.25, 0.09, 0.15));
    let weight = 380.0;
    let wanted = Vector6::new(0.0, 0.0, weight, 0.0, 0.0, 0.0);
    for s in [0.0, 0.3, 0.5, 0.8, 1.0] {
        // The CoM at fraction s from the right sole to the left, 0.75 m up.
        let at = r.pose().translation.vector.lerp(&l.pose().translation.vector, s);
        let com = Point3::new(at.x, at.y, 0.75);
        let supports =
            [Support { contact: r.clone(), share: 1.0 - s }, Support { contact: l.clone(), share: s }];
        let w = distribute(&supports, &wanted, &com, &p).unwrap();
        let net = net_wrench(&[&r, &l], &w, &com);
        println!("s {s}: {:?} {:?} net {net:?}", w[0], w[1]);
        assert!((net - wanted).fixed_rows::<3>(0).norm() < 0.005 * weight, "net force met: {net:?}");
        assert!((net - wanted).fixed_rows::<3>(3).norm() < 1.0, "net moment met: {net:?}");
        for (c, x) in [&r, &l].iter().zip(&w) {
            let faces = c.local_faces() * x.to_vector();
            assert!(faces.iter().all(|v| *v <= 1e-6), "inside the cone: {faces:?}");
        }
        assert!((w[0].force_n.z - (1.0 - s) * weight).abs() < 0.05 * weight, "s {s}: {}", w[0].force_n.z);
        for x in &w {
            assert!(x.force_n.xy().norm() < 1.0, "no internal tangential force: {:?}", x.force_n);
        }
    }
    // One foot: the wrench is the wanted one moved to the sole (the only one there is).
    let one = distribute(
        &[Support { contact: r.clone(), share: 1.0 }],
        &wanted,
        &Point3::new(0.01, -0.08, 0.75),
        &p,
    )
    .unwrap();
    assert!((one[0].force_n - Vector3::new(0.0, 0.0, weight)).norm() < 1.0);
    assert!((one[0].cop_m(1.0).unwrap()[0] - 0.01).abs() < 1e-3);
}

/// The distribution's QP written again, densely, straight to clarabel: minimize
/// w_net |G x - w|^2 + w_p (pressure)^2 + w_t |tangential|^2 + w_a |torques|^2 subject to
/// each foot's 16 faces.
fn dense_distribution(
    supports: &[Support],
    wanted: &Vector6<f64>,
    com: &Point3<f64>,
    p: &StabilizerParams,
) -> Vec<f64> {
    use clarabel::algebra::CscMatrix;
    use clarabel::solver::{DefaultSettingsBuilder, DefaultSolver, IPSolver, SupportedConeT};
    let n = 6 * supports.len();
    let mut g = nalgebra::DMatrix::zeros(6, n);
    for (i, s) in supports.iter().enumerate() {
        // Column j of the map: the world wrench about the CoM of a unit local wrench j.
        for j in 0..6 {
            let mut unit = nalgebra::Vector6::zeros();
            unit[j] = 1.0;
            let w = net_wrench(&[&s.contact], &[stairbench::control::SoleWrench::from_vector(&unit)], com);
            g.view_mut((0, 6 * i + j), (6, 1)).copy_from(&w);
        }
    }
    let mut h = g.transpose() * &g * p.weight_net_wrench;
    let c = -(g.transpose() * wanted) * p.weight_net_wrench;
    for i in 0..supports.len() {
        for (j, w) in regularization_weights(p).iter().enumerate() {
            h[(6 * i + j, 6 * i + j)] += w;
        }
    }
    if supports.len() == 2 {
        let rho = supports[0].share;
        let mut row = nalgebra::DVector::zeros(n);
        row[2] = 1.0 - rho;
        row[8] = -rho;
        h += &row * row.transpose() * p.weight_pressure;
    }
    h += nalgebra::DMatrix::identity(n, n) * 1e-9;
    let mut a = nalgebra::DMatrix::zeros(16 * supports.len(), n);
    for (i, s) in supports.iter().enumerate() {
        a.view_mut((16 * i, 6 * i), (16, 6)).copy_from(&s.contact.local_faces());
    }
    let rows = |m: &nalgebra::DMatrix<f64>| -> Vec<Vec<f64>> {
        (0..m.nrows()).map(|r| m.row(r).iter().copied().collect()).collect()
    };
    let upper = nalgebra::DMatrix::from_fn(n, n, |r, col| if r <= col { 2.0 * h[(r, col)] } else { 0.0 });
    let pm = CscMatrix::from(rows(&upper).iter());
    let am = CscMatrix::from(rows(&a).iter());
    let q: Vec<f64> = (2.0 * c).iter().copied().collect();
    let b = vec![0.0; a.nrows()];
    let cones = [SupportedConeT::NonnegativeConeT(a.nrows())];
    let settings = DefaultSettingsBuilder::default()
        .verbose(false)
        .tol_gap_abs(1e-10)
        .tol_gap_rel(1e-10)
        .build()
        .unwrap();
    let mut solver = DefaultSolver::new(&pm, &q, &am, &b, &cones, settings).unwrap();
    solver.solve();
    solver.solution.x.clone()
}

/// A stream of ticks as a stance gives them: both soles down, one loaded and the other
/// unloaded (about to lift, or just down: its share 0, its wrench at its cone's apex, where
/// all its faces bind), the CoM circling 1.5 cm about the loaded sole's centre, then the
/// same over the other sole. A kept [`Distributor`] gives each tick the wrenches a fresh
/// solve gives (within 0.5 N and 0.05 N m, as the test below: the interior-point solver
/// stops at its tolerance, the active sets at the optimum), and
/// where a fresh solve's few active-set guesses from no face do not reach the faces that
/// bind, and the interior-point solver takes the QP, the kept one's guesses from the last
/// tick's faces do.
#[test]
fn a_kept_distributor_gives_what_a_fresh_solve_gives_by_active_sets() {
    let p = StabilizerParams::default();
    let weight = 380.0;
    // Two soles of HRP-4's size 21 cm apart in x and 20 cm in y, as a step's stance.
    let (r, l) = (sole(0.0, 0.1, 0.0), sole(0.21, -0.1, 0.0));
    let wanted = Vector6::new(0.0, 0.0, weight, 0.0, 0.0, 0.0);
    let mut kept = Distributor::default();
    let mut fresh_by_clarabel = 0;
    const TICKS: usize = 200;
    for (loaded, share) in [(&r, 1.0), (&l, 0.0)] {
        for tick in 0..TICKS {
            let phase = tick as f64 / TICKS as f64 * std::f64::consts::TAU;
            let at = loaded.pose().translation.vector;
            let com = Point3::new(at.x + 0.015 * phase.cos(), at.y + 0.015 * phase.sin(), 0.73);
            let supports =
                [Support { contact: r.clone(), share }, Support { contact: l.clone(), share: 1.0 - share }];
            let mut once = Distributor::default();
            let a =
                once.distribute(&supports, &wanted, &com, &p).unwrap_or_else(|e| panic!("tick {tick}: {e}"));
            fresh_by_clarabel += once.interior_point_qps();
            let b =
                kept.distribute(&supports, &wanted, &com, &p).unwrap_or_else(|e| panic!("tick {tick}: {e}"));
            for (wa, wb) in a.iter().zip(&b) {
                let d = wa.to_vector() - wb.to_vector();
                assert!(
                    d.fixed_rows::<3>(0).amax() < 0.5 && d.fixed_rows::<3>(3).amax() < 0.05,
                    "tick {tick}: {d:?}"
                );
            }
        }
    }
    let kept_by_clarabel = kept.interior_point_qps();
    assert!(
        fresh_by_clarabel > TICKS / 2 && kept_by_clarabel * 10 < fresh_by_clarabel,
        "the interior-point solver took {kept_by_clarabel} of {} QPs kept, {fresh_by_clarabel} fresh",
        2 * TICKS
    );
}

/// On random stances (two soles at random places, heights and yaws, the CoM anywhere over
/// the segment between them): the distribution equals the same QP written densely and
/// solved by clarabel alone (within 0.5 N, 0.05 N m), lies in the cones and meets the net
/// wrench; a CoM beyond the feet is reported as infeasible, not guessed.
#[test]
fn the_distribution_matches_an_independent_solve_on_random_stances() {
    use rand::{Rng, SeedableRng};
    let p = StabilizerParams::default();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(18);
    let weight = 380.0;
    let wanted = Vector6::new(0.0, 0.0, weight, 0.0, 0.0, 0.0);
    for case in 0..200 {
        let pose = |rng: &mut rand_chacha::ChaCha8Rng, y: f64| {
            Isometry3::new(
                Vector3::new(
                    rng.random_range(-0.1..0.35),
                    y + rng.random_range(-0.03..0.03),
                    rng.random_range(0.0..0.25),
                ),
                Vector3::z() * rng.random_range(-0.3..0.3),
            )
        };
        let (pr, pl) = (pose(&mut rng, -0.1), pose(&mut rng, 0.1));
        let r = Contact::new(pr, 0.12, 0.065, 0.7).unwrap();
        let l = Contact::new(pl, 0.12, 0.065, 0.7).unwrap();
        let s: f64 = rng.random_range(0.05..0.95);
        let at = pr.translation.vector.lerp(&pl.translation.vector, s);
        let com = Point3::new(at.x, at.y, at.z + 0.75);
        let supports =
            [Support { contact: r.clone(), share: 1.0 - s }, Support { contact: l.clone(), share: s }];
        let ours = distribute(&supports, &wanted, &com, &p).unwrap_or_else(|e| panic!("case {case}: {e}"));
        let dense = dense_distribution(&supports, &wanted, &com, &p);
        for (i, w) in ours.iter().enumerate() {
            let v = w.to_vector();
            for j in 0..6 {
                let tol = if j < 3 { 0.5 } else { 0.05 };
                assert!(
                    (v[j] - dense[6 * i + j]).abs() < tol,
                    "case {case}, foot {i}, axis {j}: {} against {}",
                    v[j],
                    dense[6 * i + j]
                );
            }
            let faces = supports[i].contact.local_faces() * v;
            assert!(faces.iter().all(|f| *f <= 1e-6), "case {case}: in the cone");
        }
        let net = net_wrench(&[&r, &l], &ours, &com);
        assert!((net - wanted).fixed_rows::<3>(0).norm() < 0.01 * weight, "case {case}: {net:?}");
    }
    // The CoM 30 cm beside both feet: no wrench in the cones holds it.
    let (r, l) = (sole(0.0, -0.09, 0.0), sole(0.25, 0.09, 0.0));
    let supports = [Support { contact: r, share: 0.5 }, Support { contact: l, share: 0.5 }];
    let far = distribute(&supports, &wanted, &Point3::new(0.1, 0.4, 0.75), &p);
    assert!(matches!(far, Err(DistributionError::Infeasible { .. })), "{far:?}");
    // Nothing in contact and weight to hold: infeasible too.
    assert!(matches!(
        distribute(&[], &wanted, &Point3::origin(), &p),
        Err(DistributionError::Infeasible { .. })
    ));
}

fn exp1_climb(stabilizer: bool, seed: u64) -> stairbench::climb::ClimbReport {
    let mut p = ClimbParams::default();
    p.stabilizer.enabled = stabilizer;
    let s = Scenario { seed, ..Scenario::default() };
    climb_scenario(&s, p.loop_params(), &p.sim(), &mut Nobody, &Cancel::never()).unwrap()
}

/// With the stabilizer, every loaded foot of Exp. 1 stays within half the friction cone on
/// the noise draw that failed the friction check open loop (seed 3: 34 N on 49 N at step 3).
/// Issue 18's goal; over seeds 0-19 the largest ratio is 0.26 since the approach slowed to
/// 0.025 m/s (at 0.05 m/s the touchdown impacts reached 0.36-0.38 on a few seeds).
#[test]
fn with_the_stabilizer_exp1_uses_at_most_half_the_friction_cone() {
    let r = exp1_climb(true, 3);
    let mu = Scenario::default().staircase.friction;
    for c in &r.cycles {
        println!(
            "cycle {}: friction {:.2}, violations {:?}",
            c.cycle, c.execution.max_friction_ratio, c.execution.violations
        );
        assert!(c.execution.violations.is_empty());
        assert!(c.execution.max_friction_ratio <= 0.5 * mu, "{} of 0.7", c.execution.max_friction_ratio);
        assert!(c.execution.control.is_some_and(|k| k.ticks > 0), "the stabilizer ran");
    }
    assert!(r.success);
}

/// Exp. 1's first stances, planned on steps perceived `error_m` higher than they are (a
/// perception error made on purpose), executed in the true world.
fn with_perceived_height_off_by(error_m: f64, stabilizer: bool) -> Execution {
    let (scene, model, mut world, q0) = settled_exp1();
    let rects = step_tops_moved(&scene, Vector3::new(0.0, 0.0, error_m));
    let planned =
        PlanRequest::new(&model, &q0, &rects, &PlanParams::default()).max_stances(Some(3)).climb().unwrap();
    assert_eq!(planned.stances.last().unwrap().step, Some(0), "the third stance is on step 1");
    let mut p = ClimbParams::default();
    p.stabilizer.enabled = stabilizer;
    let ex = execute(&mut world, &model, &scene, &planned, &p.sim(), &mut Nobody, &Cancel::never()).unwrap();
    for v in &ex.violations {
        println!("stabilizer {stabilizer}: t = {:.3} s {}: {}", v.t_s, v.check.kind(), v.check);
    }
    println!("friction {:.2}, touchdowns {:?}", ex.max_friction_ratio, ex.touchdowns);
    ex
}

#[test]
fn a_step_higher_than_perceived_is_absorbed_by_the_compliant_touchdown() {
    let on = with_perceived_height_off_by(-0.015, true);
    assert!(on.pass() && on.violations.is_empty(), "{:?}", on.violations);
    // Open loop the servos push the sole on to its planned height, 1.5 cm into the tread:
    // the landing is thrown off its target and the robot does not keep its balance.
    let off = with_perceived_height_off_by(-0.015, false);
    assert!(!off.pass(), "open loop, the same error is reported");
    let kinds: Vec<CheckKind> = off.violations.iter().map(|v| v.check.kind()).collect();
    assert!(
        [CheckKind::Strike, CheckKind::Friction, CheckKind::Touchdown, CheckKind::Slip, CheckKind::Fall]
            .iter()
            .any(|k| kinds.contains(k)),
        "{kinds:?}"
    );
}

/// Each landing in `ticks` (stamp, tick): the seconds its foot read under `light_n` between its
/// touchdown (held from then on) and the moment it first carried `loaded_n`.
fn time_light_after_touchdown_s(ticks: &[(f64, TickRecord)], light_n: f64, loaded_n: f64) -> Vec<f64> {
    let mut out = Vec::new();
    for k in 0..2 {
        let mut on: Option<(f64, bool)> = None;
        for (i, (_, t)) in ticks.iter().enumerate() {
            let dt = ticks.get(i + 1).map_or(0.0, |n| n.0 - ticks[i].0);
            match (t.held_m[k], &mut on) {
                (Some(_), None) => on = Some((0.0, false)),
                (None, Some((light, _))) => {
                    out.push(*light);
                    on = None;
                }
                _ => {}
            }
            if let Some((light, loaded)) = &mut on {
                let fz = t.measured[k].force_n.z;
                *loaded |= fz > loaded_n;
                if !*loaded && fz < light_n {
                    *light += dt;
                }
            }
        }
        out.extend(on.map(|o| o.0));
    }
    out
}

/// A landed foot stays on the ground until its weight comes: held where it touched, a foot
/// whose touch was its own inertia or a bounce hovered for about a second while the weight
/// was still on the other foot (ci case 157: 0-7 N for 0.9-1.0 s at every right touchdown),
/// and the press that then set it down was a second impact (41 N normal with 22 N
/// tangential). Exp. 1's first three stances on the true steps, every landing: at most
/// 0.3 s under half the touchdown force before the foot carries the contact force (the
/// touch can be read a tick early, from the foot's own inertia as its descent slows, up to
/// 6 mm above the tread at x 2, as measured before a free foot's commanded inertia was
/// taken off its reading: the landing law, going down at the approach's landing speed
/// while it reads nothing, meets the tread in about 0.25 s; at 15 mm/s it took 0.35 s;
/// held there, the foot read nothing for 0.85 s).
#[test]
fn a_landed_foot_stays_on_the_ground_until_its_weight_comes() {
    use stairbench::climb::{Event, Watch};
    let (scene, model, mut world, q0) = settled_exp1();
    let rects = step_tops_moved(&scene, Vector3::zeros());
    let planned =
        PlanRequest::new(&model, &q0, &rects, &PlanParams::default()).max_stances(Some(3)).climb().unwrap();
    let p = ClimbParams::default();
    let mut ticks = Vec::new();
    let mut watch = Watch(|e: &Event| {
        if let Event::Control { stamp_s, tick } = e {
            ticks.push((*stamp_s, (*tick).clone()));
        }
    });
    let ex = execute(&mut world, &model, &scene, &planned, &p.sim(), &mut watch, &Cancel::never()).unwrap();
    assert!(ex.pass(), "{:?}", ex.violations);
    let light = time_light_after_touchdown_s(
        &ticks,
        p.stabilizer.touchdown_force_n / 2.0,
        p.stabilizer.contact_force_n,
    );
    println!("seconds light after each touchdown: {light:?}");
    assert!(light.len() >= 2, "the plan's swings landed: {light:?}");
    assert!(light.iter().all(|&s| s <= 0.3), "{light:?}");
}

/// Every touch the stabilizer reads is the ground's: each time it takes a foot for landed
/// (held where it touched), MuJoCo's contacts press that foot within 20 ms. Exp. 1 climbed
/// at the default timing and at x 1.83. A free foot's commanded braking taken off its
/// reading (the whole commanded acceleration), or none of its acceleration, reads touches
/// in the air (CHANGELOG, sixty-second session; see
/// `a_free_foots_inertia_is_not_read_as_a_touch`).
#[test]
fn every_touch_the_stabilizer_reads_is_the_grounds() {
    use stairbench::climb::Event;
    #[derive(Default)]
    struct Touches {
        /// (stamp, each foot's true normal force, N).
        normals: Vec<(f64, [f64; 2])>,
        /// (stamp, foot) of each touch read.
        touches: Vec<(f64, usize)>,
        held: [bool; 2],
    }
    impl stairbench::climb::Observer for Touches {
        fn event(&mut self, event: &Event) {
            match event {
                Event::State { stamp_s, state } => {
                    self.normals.push((*stamp_s, state.foot_forces_n.map(|f| f.z)));
                }
                Event::Control { stamp_s, tick } => {
                    for k in 0..2 {
                        let held = tick.held_m[k].is_some();
                        if held && !self.held[k] {
                            self.touches.push((*stamp_s, k));
                        }
                        self.held[k] = held;
                    }
                }
                _ => {}
            }
        }
    }
    for speedup in [1.0, 1.83] {
        let mut params = ClimbParams::default();
        params.plan = params.plan.faster(speedup);
        let mut watch = Touches::default();
        let report = stairbench::sim::climb_scenario(
            &Scenario::default(),
            params.loop_params(),
            &params.sim(),
            &mut watch,
            &Cancel::never(),
        )
        .unwrap();
        assert!(report.success, "x {speedup}: {:?}", report.stop);
        assert!(watch.touches.len() >= 10, "x {speedup}: the swings landed: {:?}", watch.touches);
        for &(t, k) in &watch.touches {
            let pressed = watch.normals.iter().any(|&(s, n)| s >= t - 0.005 && s <= t + 0.02 && n[k] > 1.0);
            assert!(pressed, "x {speedup}: foot {k}'s touch read at {t:.3} s had no contact within 20 ms");
        }
    }
}

/// A step 1.5 cm lower than perceived: the swing ends in the air; the foot goes on down to
/// the ground and the plan waits for it before moving the CoM over it.
#[test]
fn a_step_lower_than_perceived_is_sought_and_waited_for() {
    let on = with_perceived_height_off_by(0.015, true);
    assert!(on.pass() && on.violations.is_empty(), "{:?}", on.violations);
    assert!(on.min_margin_m > 0.0, "the CoM never left the polygon of the feet down: {}", on.min_margin_m);
}

/// The same plan (Exp. 1's first three stances on the true steps) executed with the
/// stabilizer and without: the largest friction ratio drops by at least 30 %.
#[test]
fn on_the_same_plan_the_stabilizer_lowers_the_friction_ratio_by_30_percent() {
    let on = with_perceived_height_off_by(0.0, true);
    let off = with_perceived_height_off_by(0.0, false);
    println!("friction ratio: on {:.2}, off {:.2}", on.max_friction_ratio, off.max_friction_ratio);
    assert!(on.pass() && off.pass());
    assert!(on.max_friction_ratio <= 0.7 * off.max_friction_ratio);
}

/// A foot held where its sensors say it landed may be centimetres from where the IK had it
/// (the servos lag a fast swing). The online IK moves the contact there at a capped speed:
/// uncapped, the drift correction (40/s times the error) asked the legs for metres per
/// second against 1 rad/s joint limits and the QP had no solution (8 of the ci suite's 200
/// cases ended in that error, 4 cm off).
#[test]
fn a_contact_moved_by_centimetres_is_reached_without_an_infeasible_ik() {
    use stairbench::planning::motion::{IkParams, Targets, Tracker};
    use stairbench::planning::Foot;
    use stairbench::robot::kinematics::Kinematics;
    let (_, model, _, q0) = settled_exp1();
    let mut kin = Kinematics::new(&model);
    kin.update(&q0).unwrap();
    let soles = hrp4::sole_frames(&model).unwrap();
    let com = kin.com();
    let mut moved = kin.frame_pose(soles[0]);
    moved.translation.vector += Vector3::new(0.06, -0.05, 0.0);
    let support = [(Foot::Right, moved), (Foot::Left, kin.frame_pose(soles[1]))];
    let targets =
        Targets { com, com_velocity: Vector3::zeros(), swing: None, support: &support, lifting: [false; 2] };
    let uncapped = IkParams {
        max_contact_correction_m_s: f64::INFINITY,
        max_contact_correction_rad_s: f64::INFINITY,
        ..IkParams::default()
    };
    let mut t = Tracker::new(&model, &q0, &[], Default::default(), &uncapped).unwrap();
    assert!(t.tick(&targets, 0.005).is_err(), "the uncapped correction should be infeasible");
    let mut t = Tracker::new(&model, &q0, &[], Default::default(), &IkParams::default()).unwrap();
    for _ in 0..300 {
        t.tick(&targets, 0.005).unwrap();
    }
    let reached = t.kinematics().frame_pose(soles[0]).translation.vector;
    assert!((reached - moved.translation.vector).norm() < 1e-3, "sole at {reached:?}, wanted {moved:?}");
}

/// The robust suite's softest ankle bush (`robust-0053`, 500 N m/rad): the body rolls over
/// its compliant support ankle in single support and sways on it. With the sway's washout at
/// 0.15 (`lean_washout_gain`, off by default, see its doc; its input low-passed by the
/// default `lean_washout_filter_s`) the climb is clean at x 1, x 1.33 and x 2 the
/// quasi-static timing (x 2 the default); with the defaults, at x 1.33. Without the washout
/// the body falls at x 1, the lean's integral alone leaning it out; with neither
/// compensation it falls at x 1.33, and with the integral's sign turned too.
#[test]
fn the_lean_compensation_keeps_a_soft_ankled_body_over_its_sole() {
    let s = Scenario::load(std::path::Path::new("tests/fixtures/soft-ankle-bush.toml")).unwrap();
    let climb = |faster: f64, rate_per_s: f64, washout_gain: f64| {
        let p = ClimbParams {
            plan: stairbench::planning::PlanParams::quasi_static().faster(faster),
            stabilizer: StabilizerParams {
                lean_follow_rate_per_s: rate_per_s,
                lean_washout_gain: washout_gain,
                ..StabilizerParams::default()
            },
            ..ClimbParams::default()
        };
        climb_scenario(&s, p.loop_params(), &p.sim(), &mut Nobody, &Cancel::never()).unwrap()
    };
    let fell = |c: &stairbench::climb::ClimbReport| {
        matches!(c.stop, Some(StopReason::Fell { .. } | StopReason::FellStanding { .. }))
    };
    let (rate, washout) = (StabilizerParams::default().lean_follow_rate_per_s, 0.15);
    for faster in [1.0, 1.33, 2.0] {
        let kept = climb(faster, rate, washout);
        for c in &kept.cycles {
            println!(
                "x {faster}: cycle {}: margin {:?} m, violations {:?}",
                c.cycle, c.execution.min_margin_m, c.execution.violations
            );
        }
        assert!(kept.success && kept.steps_climbed == kept.steps_total, "x {faster}: {:?}", kept.stop);
    }
    let default = climb(1.33, rate, StabilizerParams::default().lean_washout_gain);
    assert!(
        default.success && default.steps_climbed == default.steps_total,
        "the defaults at x 1.33: {:?}",
        default.stop
    );
    let unwashed = climb(1.0, rate, 0.0);
    println!("x 1 without the washout: {:?}", unwashed.stop);
    assert!(
        fell(&unwashed),
        "without the washout this body fell at x 1; if it climbs now, say why: {:?}",
        unwashed.stop
    );
    let without = climb(1.33, 0.0, 0.0);
    println!("x 1.33 without either: {:?}", without.stop);
    assert!(fell(&without), "without the compensation this body fell at x 1.33: {:?}", without.stop);
    let turned = climb(1.33, -rate, 0.0);
    println!("x 1.33, the integral's sign turned: {:?}", turned.stop);
    assert!(fell(&turned), "turned, the body should fall, and be seen to: {:?}", turned.stop);
}

/// A plan ends at rest; the body does not: it lags the plan's last weight shift. The
/// stabilizer holds the plan's last instant until the base is still, so the servos take
/// over a still body and the stand before the next sweep starts still (regression
/// `a-plan-ending-mid-sway-slid-a-sole`); with the hold off, the same plan leaves the body
/// moving when it hands over.
#[test]
fn the_stabilizer_hands_the_servos_a_still_body_at_the_plans_end() {
    let still = ClimbParams::default().run;
    let execute_with = |max_end_hold_s: f64| {
        let (scene, model, mut world, q0) = settled_exp1();
        let rects = step_tops_moved(&scene, Vector3::zeros());
        let plan = PlanParams::quasi_static().faster(2.0);
        let planned = PlanRequest::new(&model, &q0, &rects, &plan).max_stances(Some(3)).climb().unwrap();
        let mut p = ClimbParams { plan, ..ClimbParams::default() };
        p.stabilizer.max_end_hold_s = max_end_hold_s;
        let ex =
            execute(&mut world, &model, &scene, &planned, &p.sim(), &mut Nobody, &Cancel::never()).unwrap();
        let speed_m_s = world.data().qvel()[..3].iter().map(|v| v * v).sum::<f64>().sqrt();
        println!(
            "end hold {max_end_hold_s} s: executed {:.3} s of a {:.3} s plan, base at {speed_m_s:.4} m/s, violations {:?}",
            ex.sim_s,
            planned.duration_s(),
            ex.violations
        );
        assert!(ex.pass(), "{:?}", ex.violations);
        (ex.sim_s, speed_m_s)
    };
    let (cut_s, cut_speed_m_s) = execute_with(0.0);
    assert!(
        cut_speed_m_s > still.still_speed_m_s,
        "cut at the plan's end the body is still moving: {cut_speed_m_s}"
    );
    let max_end_hold_s = StabilizerParams::default().max_end_hold_s;
    let (executed_s, speed_m_s) = execute_with(max_end_hold_s);
    assert!(speed_m_s <= still.still_speed_m_s, "held, the body is handed over still: {speed_m_s} m/s");
    let held_s = executed_s - cut_s;
    assert!(
        held_s >= still.still_s && held_s < max_end_hold_s,
        "held {held_s} s: still for still_s, short of the limit"
    );
}
