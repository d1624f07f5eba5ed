//! `bench robot`: the kinematics the IK calls at every tick (FK, every frame's Jacobian, CoM,
//! CoM Jacobian) against MuJoCo doing the same in the same process, on one core; and how fast
//! MuJoCo simulates the standing robot at 1 kHz, the world's boxes in bodies of their own and
//! all in the world body.

use super::{machine, median_s};
use anyhow::Result;
use nalgebra::{Matrix3xX, Matrix6xX};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use stairbench::robot::model::Q_JOINTS;
use stairbench::robot::{hrp4, Kinematics};
use stairbench::scenario::Scenario;
use stairbench::scene::mjcf::{BoxBodies, WorldOptions};
use stairbench::scene::Scene;
use stairbench::sim::plant::Plant;
use stairbench::sim::World;
use std::hint::black_box;
use std::time::Instant;

/// Configurations per timing run.
const CONFIGS: usize = 2000;
/// Simulated seconds of the standing run.
const STAND_S: f64 = 10.0;

/// Returns the Markdown table.
pub fn run(repeat: usize) -> Result<String> {
    let model = hrp4::model()?;
    let scene = Scene::from_scenario(&Scenario::default())?;
    let mut world = World::for_scene(&scene)?;
    let frames: Vec<usize> = (0..model.frames().len()).collect();
    let sites: Vec<usize> =
        model.frames().iter().map(|f| world.site_id(&f.name)).collect::<Result<_, _>>()?;
    let root = world.body_id(&model.root().name)?;
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let configs: Vec<Vec<f64>> = (0..CONFIGS)
        .map(|_| {
            let mut q = vec![0.0; model.nq()];
            q[3] = 1.0;
            for (i, j) in model.joints().iter().enumerate() {
                q[Q_JOINTS + i] = rng.random_range(j.lower_rad..=j.upper_rad);
            }
            q
        })
        .collect();
    let nv = model.nv();

    // Ours: allocation-free after these buffers.
    let mut kin = Kinematics::new(&model);
    let mut jac = Matrix6xX::zeros(nv);
    let mut jcom = Matrix3xX::zeros(nv);
    let ours_s = median_s(repeat, || {
        for q in &configs {
            kin.update(q).expect("valid configuration");
            for &f in &frames {
                kin.frame_jacobian_into(f, &mut jac);
                black_box(&jac);
            }
            black_box(kin.com());
            kin.com_jacobian_into(&mut jcom);
            black_box(&jcom);
        }
    }) / CONFIGS as f64;

    // MuJoCo: mj_kinematics, mj_comPos, mj_jacSite per frame, mj_jacSubtreeCom.
    let mut jp = vec![0.0; 3 * nv];
    let mut jr = vec![0.0; 3 * nv];
    let mut jc = vec![0.0; 3 * nv];
    let mj_s = median_s(repeat, || {
        for q in &configs {
            let d = world.data_mut();
            d.qpos_mut().copy_from_slice(q);
            d.kinematics();
            d.com_pos();
            for &s in &sites {
                // SAFETY: model and data are valid for the call, the buffers hold 3 x nv
                // numbers as mj_jacSite requires, and `s` is a site id of this model.
                unsafe {
                    mujoco_rs::mujoco_c::mj_jacSite(
                        world.model().ffi(),
                        world.data().ffi(),
                        jp.as_mut_ptr(),
                        jr.as_mut_ptr(),
                        s as i32,
                    )
                };
                black_box(&jp);
            }
            world.data_mut().jac_subtree_com_into(root, &mut jc);
            black_box(&jc);
        }
    }) / CONFIGS as f64;

    // Simulation speed, standing in half-sitting with the servos holding it: the world's
    // boxes each in a body of their own (the default) against all in the world body.
    let nominal = Plant::nominal(&model);
    let root_name = &model.root().name;
    // Every world is generated at the same time step.
    let timestep_s = world.model().opt().timestep;
    // Wall seconds of the standing run in `layout`.
    let stand_s = |layout: BoxBodies| -> Result<f64> {
        let mut stand =
            World::with_plant_options(&scene, &nominal, &WorldOptions { layout, ..Default::default() })?;
        let steps = (STAND_S / timestep_s).round() as usize;
        let t0 = Instant::now();
        for _ in 0..steps {
            stand.data_mut().step();
        }
        let wall_s = t0.elapsed().as_secs_f64();
        // The root's id in this layout (the boxes' bodies come before the robot's).
        let root = stand.body_id(root_name)?;
        anyhow::ensure!(stand.data().subtree_com()[root][2].is_finite(), "the standing simulation diverged");
        Ok(wall_s)
    };
    // The two layouts in turn, each first in every other round.
    let rounds = repeat.max(1);
    let (mut one_each, mut in_world) = (Vec::with_capacity(rounds), Vec::with_capacity(rounds));
    for round in 0..rounds {
        let order = if round % 2 == 0 {
            [BoxBodies::OneEach, BoxBodies::InWorldBody]
        } else {
            [BoxBodies::InWorldBody, BoxBodies::OneEach]
        };
        for layout in order {
            let wall_s = stand_s(layout)?;
            match layout {
                BoxBodies::OneEach => one_each.push(wall_s),
                BoxBodies::InWorldBody => in_world.push(wall_s),
            }
        }
    }
    let median = |v: Vec<f64>| stairbench::stats::median(v).unwrap_or(f64::NAN);
    let (wall_s, baseline_s) = (median(one_each), median(in_world));

    let mut t = format!(
        "HRP-4-class model ({} joints, nq = {}, nv = {nv}), {CONFIGS} random configurations within the joint limits, median of {repeat}; single-threaded; machine: {}.\n\n",
        model.joints().len(),
        model.nq(),
        machine()
    );
    t += "| per configuration | ours (nalgebra, allocation-free) | MuJoCo 3.17 (mj_kinematics + mj_comPos + mj_jacSite + mj_jacSubtreeCom) | ratio MuJoCo / ours |\n|---|---|---|---|\n";
    t += &format!(
        "| FK + {} frame Jacobians (6 x {nv}) + CoM + CoM Jacobian (3 x {nv}) | {:.2} us | {:.2} us | {:.2} |\n",
        frames.len(),
        ours_s * 1e6,
        mj_s * 1e6,
        mj_s / ours_s
    );
    t += &format!(
        "\nSimulation: the standing robot (half-sitting, 34 position servos, feet in contact) in Exp. 1's world ({} boxes) at {:.0} Hz, median of {}: {STAND_S:.0} simulated s in {:.2} wall s = **{:.1} x real time** (goal: at least 20 x), each box in a static body of its own; every box in the world body (MuJoCo walks its tree of boxes for each robot body): {:.2} wall s, {:.1} x real time; **ratio {:.2}**.\n",
        scene.boxes().len(),
        1.0 / timestep_s,
        rounds,
        wall_s,
        STAND_S / wall_s,
        baseline_s,
        STAND_S / baseline_s,
        baseline_s / wall_s
    );
    Ok(t)
}
