//! Contact wrench cones and static-stability polygons (issue 5, §6.2): the double-description
//! polygon against Bretl and Lall's projection (an independent method), against the convex
//! hull of coplanar soles, and the CWC's span against its 16 face inequalities.

// Test helpers unwrap: a panic there is the test failing.
#![allow(clippy::unwrap_used)]

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector6};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use stairbench::geom2d::{self, P2};
use stairbench::planning::dd::{extreme_rays, DdParams};
use stairbench::planning::polygon::{by_bretl, by_double_description, hausdorff, PolygonError};
use stairbench::planning::Contact;

fn sole(x: f64, y: f64, z: f64, roll: f64, pitch: f64, yaw: f64, mu: f64) -> Contact {
    let pose = Isometry3::from_parts(
        Translation3::new(x, y, z),
        UnitQuaternion::from_euler_angles(roll, pitch, yaw),
    );
    Contact::new(pose, 0.12, 0.065, mu).unwrap()
}

#[test]
fn double_description_of_a_span_gives_the_16_face_inequalities() {
    let c = sole(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.7);
    let faces = extreme_rays(&c.span(), &DdParams::default()).unwrap();
    let want = c.local_faces();
    assert_eq!(faces.len(), 16, "{} faces", faces.len());
    for r in 0..16 {
        let w: Vector6<f64> = want.row(r).transpose().normalize();
        let best = faces.iter().map(|f| (f - w).norm()).fold(f64::INFINITY, f64::min);
        assert!(best < 1e-9, "Caron et al.'s row {r} not found by DD (off by {best})");
    }
    // And every generator satisfies every face (the world form of a moved contact too).
    let moved = sole(0.4, -0.2, 0.3, 0.2, -0.1, 0.7, 0.5);
    for g in moved.span() {
        let v = moved.faces() * g;
        assert!(v.max() <= 1e-12, "a generator violates a face by {}", v.max());
    }
}

#[test]
fn coplanar_horizontal_soles_give_their_convex_hull() {
    let stance = [sole(0.0, 0.09, 0.0, 0.0, 0.0, 0.0, 1.0), sole(0.15, -0.09, 0.0, 0.0, 0.0, 0.2, 1.0)];
    let dd = by_double_description(&stance, &DdParams::default()).unwrap();
    let corners: Vec<P2> = stance.iter().flat_map(|c| c.corners()).map(|p| P2::new(p.x, p.y)).collect();
    let hull = geom2d::convex_hull(&corners);
    let d = hausdorff(&dd, &hull);
    assert!(d < 1e-6, "DD polygon is {d} m from the soles' hull");
    assert!((geom2d::area(&dd) - geom2d::area(&hull)).abs() < 1e-6);
}

#[test]
fn double_description_matches_bretl_on_random_stances() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let max_tilt = 20f64.to_radians();
    let mut worst = 0.0f64;
    let mut compared = 0;
    for case in 0..60 {
        let n = 1 + case % 2;
        let stance: Vec<Contact> = (0..n)
            .map(|i| {
                sole(
                    rng.random_range(-0.2..0.2) + 0.3 * i as f64,
                    rng.random_range(-0.15..0.15) + 0.2 * i as f64,
                    rng.random_range(0.0..0.3),
                    rng.random_range(-max_tilt..max_tilt),
                    rng.random_range(-max_tilt..max_tilt),
                    rng.random_range(-std::f64::consts::PI..std::f64::consts::PI),
                    0.7,
                )
            })
            .collect();
        let dd = by_double_description(&stance, &DdParams::default());
        let bretl = by_bretl(&stance, 1e-5);
        match (dd, bretl) {
            (Ok(a), Ok(b)) => {
                let d = hausdorff(&a, &b);
                worst = worst.max(d);
                compared += 1;
                assert!(d <= 1e-3, "case {case}: DD and Bretl differ by {d} m\n{a:?}\n{b:?}");
            }
            (Err(PolygonError::Empty), Err(PolygonError::Empty)) => {}
            (a, b) => panic!("case {case}: DD {a:?} vs Bretl {b:?}"),
        }
    }
    println!("{compared} stances compared, worst Hausdorff distance {worst:.2e} m");
    assert!(compared >= 50);
}

#[test]
fn a_wall_alone_cannot_hold_the_robot() {
    let wall = [sole(0.5, 0.0, 1.0, 0.0, -std::f64::consts::FRAC_PI_2, 0.0, 0.7)];
    assert_eq!(by_double_description(&wall, &DdParams::default()), Err(PolygonError::Empty));
    assert_eq!(by_bretl(&wall, 1e-4), Err(PolygonError::Empty));
    assert_eq!(by_double_description(&[], &DdParams::default()), Err(PolygonError::NoContact));
}
