//! The simulated world MuJoCo is given: where the scene's boxes sit in its body tree, and that
//! the layout changes the work of MuJoCo's collision detection only, not the physics. Here the
//! robot stands on the floor; climbs, stairs and all, are compared by running a suite with
//! either layout.

// Test helpers unwrap: a panic there is the test failing.
#![allow(clippy::unwrap_used)]

mod common;

use stairbench::scenario::Scenario;
use stairbench::scene::mjcf::{BoxBodies, WorldOptions, WORLD_GEOM_GROUP};
use stairbench::sim::plant::Plant;
use stairbench::sim::World;

#[test]
fn each_box_in_a_body_of_its_own_gives_the_same_contacts_as_all_in_the_world_body() {
    let scene = common::scene_of(&Scenario::default());
    let plant = Plant::nominal(&stairbench::robot::hrp4::model().unwrap());
    let mut worlds = [BoxBodies::OneEach, BoxBodies::InWorldBody].map(|layout| {
        World::with_plant_options(&scene, &plant, &WorldOptions { layout, ..Default::default() }).unwrap()
    });
    // Where the boxes are: each in a static body of its own under the world body, or all in it.
    for (world, own_bodies) in worlds.iter().zip([true, false]) {
        let m = world.model();
        let boxes: Vec<usize> =
            (0..m.ffi().ngeom as usize).filter(|&g| world.geom_group(g) == WORLD_GEOM_GROUP).collect();
        assert_eq!(boxes.len(), scene.boxes().len());
        let bodies: Vec<usize> = boxes.iter().map(|&g| m.geom_bodyid()[g] as usize).collect();
        let distinct: std::collections::BTreeSet<usize> = bodies.iter().copied().collect();
        if own_bodies {
            assert_eq!(distinct.len(), boxes.len(), "one body per box");
            for &b in &bodies {
                assert_eq!(
                    (m.body_parentid()[b], m.body_weldid()[b]),
                    (0, 0),
                    "static, under the world body"
                );
            }
        } else {
            assert_eq!(distinct.into_iter().collect::<Vec<_>>(), vec![0], "all in the world body");
        }
    }
    // The same contacts, step by step, and the same motion: the layout only changes the work.
    let pairs = |w: &World| {
        let mut v: Vec<(String, String)> = w
            .data()
            .contact()
            .iter()
            .map(|c| (w.geom_name(c.geom1 as usize).to_string(), w.geom_name(c.geom2 as usize).to_string()))
            .collect();
        v.sort();
        v
    };
    for step in 0..1500 {
        for w in worlds.iter_mut() {
            w.data_mut().step();
        }
        if step % 100 == 99 {
            let [a, b] = &worlds;
            assert!(!pairs(a).is_empty(), "the feet stand on the floor");
            assert_eq!(pairs(a), pairs(b), "step {step}");
            let gap =
                a.data().qpos().iter().zip(b.data().qpos()).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max);
            assert!(gap < 1e-9, "step {step}: configurations differ by {gap}");
        }
    }
}
