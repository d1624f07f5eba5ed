//! Perception against ground truth, the paper's real data, and bad input.

// Test helpers unwrap: a panic there is the test failing.
#![allow(clippy::unwrap_used)]

mod common;

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use proptest::prelude::*;
use stairbench::cloud::io::read_xyz_text;
use stairbench::cloud::{PointCloud, ScanGrid};
use stairbench::geom2d::{self, P2};
use stairbench::perception::{
    filter_slope, metrics, normals, perceive, perceive_voxels, Method, NeighbourSearch, NoStaircase,
    Perception, PerceptionError, PerceptionParams, PerceptionStream,
};
use stairbench::scenario::{Risers, Scenario};
use stairbench::sensor::AssembleParams;
use stairbench::sim::scan_scenario;
use std::path::Path;

fn scan(s: &Scenario) -> PointCloud {
    scan_scenario(s, &mut |_, _| {}).unwrap().sweep.assemble(&AssembleParams::default()).unwrap()
}

fn exp1(noise_m: f64) -> Scenario {
    let mut s = Scenario::default();
    s.lidar.noise_sigma_m = noise_m;
    s
}

#[test]
fn papers_real_exp1_data_gives_the_papers_three_steps() {
    // The paper's own Exp. 1 output, copied into the repository (its README names the source).
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/paper_exp1");
    let cloud = read_xyz_text(&dir.join("voxels.txt")).unwrap();
    let found = perceive_voxels(&cloud, &PerceptionParams::default()).unwrap();
    let paper = read_xyz_text(&dir.join("rectangles.txt")).unwrap();
    let mut rects: Vec<Vec<Point3<f32>>> = paper.points().chunks(4).map(|c| c.to_vec()).collect();
    rects.sort_by(|a, b| a[0].z.total_cmp(&b[0].z));
    assert_eq!(
        found.segments.len(),
        3,
        "{:?}",
        found.segments.iter().map(|s| s.height_m()).collect::<Vec<_>>()
    );
    for (seg, rect) in found.segments.iter().zip(&rects) {
        let h = rect.iter().map(|p| p.z as f64).sum::<f64>() / 4.0;
        assert!((seg.height_m() - h).abs() < 0.02, "height {} vs paper {h}", seg.height_m());
        let theirs: Vec<P2> = rect.iter().map(|p| P2::new(p.x as f64, p.y as f64)).collect();
        let iou = geom2d::iou(&metrics::xy(seg.corners()), &theirs);
        assert!(iou >= 0.6, "IoU {iou:.2} with the paper's step at {h:.3} m");
    }
}

#[test]
fn exp1_scans_find_all_three_steps() {
    for (noise, min_iou) in [(0.0, 0.85), (0.01, 0.85)] {
        let s = exp1(noise);
        let scene = common::scene_of(&s);
        let p = PerceptionParams::default();
        let r = perceive(&scan(&s), &p).unwrap();
        let sc = metrics::score(&r.segments, scene.steps(), p.voxel_resolution_m);
        assert_eq!(sc.found, 3, "noise {noise}: {sc:?}");
        assert_eq!(sc.false_segments, 0, "noise {noise}: {sc:?}");
        for st in &sc.steps {
            assert!(st.iou >= min_iou, "noise {noise}: step {} IoU {:.2}", st.index + 1, st.iou);
            assert!(
                st.height_error_m.abs() < 0.005,
                "noise {noise}: step {} dz {}",
                st.index + 1,
                st.height_error_m
            );
        }
        if noise == 0.0 {
            assert!(sc.steps[0].area_percent >= 90.0, "first step area {:.1} %", sc.steps[0].area_percent);
        }
    }
}

/// Each step's front edge from the start view, along the ascent, against its true nose
/// (metres; a perceived step matched to the true one at its height), perceived with `p`.
fn front_errors(s: &Scenario, p: &PerceptionParams) -> Vec<f64> {
    fronts(s, p).into_iter().map(|(err, _)| err).collect()
}

/// [`front_errors`], each with whether the front was placed on the tread's own face.
fn fronts(s: &Scenario, p: &PerceptionParams) -> Vec<(f64, bool)> {
    let scene = common::scene_of(s);
    let r = perceive(&scan(s), p).unwrap();
    let yaw = scene.ascent_yaw_rad();
    let u = Vector3::new(yaw.cos(), yaw.sin(), 0.0);
    r.segments
        .iter()
        .filter_map(|seg| {
            let step = scene.steps().iter().find(|t| (t.height_m - seg.height_m()).abs() < 0.03)?;
            let front = seg.center().coords.dot(&u) - seg.depth_m() / 2.0;
            Some((front - step.corners[0].coords.dot(&u), seg.front_on_face()))
        })
        .collect()
}

/// Under twice the data sheet's range noise, a step's front edge lies on its true nose
/// within 5 mm from the start view, by either method: placed on the riser below it (the
/// rectangles' own edges, from the tread's voxels or cells, err by up to 2.8 cm there: a
/// 0.269 m tread seen 0.245 m deep, and a foot on a 0.24 m tread put its toe on the next
/// riser). The cells' rectangles run out past the riser, toward the sensor (the nose's
/// returns, scattered along the rays, lie in the tread's plane before it), so their riser
/// is looked for farther inside the edge than outside it (`riser.front_inward_m`).
#[test]
fn a_steps_front_edge_lies_on_its_nose_under_range_noise() {
    for method in [Method::Paper, Method::Cells] {
        let mut p = PerceptionParams { method, ..Default::default() };
        let (mut worst, mut worst_own, mut n) = (0.0f64, 0.0f64, 0);
        for seed in 0..4 {
            let mut s = exp1(0.02);
            s.seed = seed;
            let e = front_errors(&s, &p);
            assert!(e.len() >= 2, "{method:?}, seed {seed}: {} steps matched", e.len());
            for (k, err) in e.iter().enumerate() {
                assert!(
                    err.abs() < 0.005,
                    "{method:?}, seed {seed}, step {}: front {:+.1} mm off the nose",
                    k + 1,
                    err * 1e3
                );
                worst = worst.max(err.abs());
                n += 1;
            }
            p.riser.enabled = false;
            worst_own = front_errors(&s, &p).iter().fold(worst_own, |w, e| w.max(e.abs()));
            p.riser.enabled = true;
        }
        println!(
            "{method:?}: {n} fronts within {:.1} mm of their noses (the rectangles' own edges: within {:.1} mm)",
            worst * 1e3,
            worst_own * 1e3
        );
    }
}

/// On open risers no riser stands under a nose: a step's front goes onto its slab's face,
/// from the returns a little under its top. Under the data sheet's range noise (10 mm) every
/// front is placed so by either method, within 5 mm of its nose (the rectangles' own edges
/// run out past it, toward the sensor). Under twice that, from Exp. 1's start, the face may
/// be lost in the tread's own strays and the front left where the rectangle put it; a face
/// believed is within 1 cm.
#[test]
fn an_open_riser_steps_front_edge_lies_on_its_slab_face_under_range_noise() {
    for method in [Method::Paper, Method::Cells] {
        let p = PerceptionParams { method, ..Default::default() };
        for (noise_m, within_m) in [(0.01, 0.005), (0.02, 0.010)] {
            let (mut worst, mut faces, mut n) = (0.0f64, 0, 0);
            for seed in 0..4 {
                let mut s = exp1(noise_m);
                s.staircase.risers = Risers::Open;
                s.seed = seed;
                let e = fronts(&s, &p);
                assert!(e.len() >= 2, "{method:?}, seed {seed}: {} steps matched", e.len());
                for (k, &(err, on_face)) in e.iter().enumerate() {
                    let what = format!("{method:?}, {noise_m} m of noise, seed {seed}, step {}", k + 1);
                    assert!(on_face || noise_m > 0.01, "{what}: the front not on its face");
                    if on_face {
                        assert!(err.abs() < within_m, "{what}: front {:+.1} mm off the nose", err * 1e3);
                        (worst, faces) = (worst.max(err.abs()), faces + 1);
                    }
                    n += 1;
                }
            }
            assert!(faces > 0, "{method:?}, {noise_m} m of noise: no front on its face");
            println!(
                "{method:?}, {} mm of noise: {faces} of {n} open-riser fronts on their faces, within {:.1} mm of their noses",
                noise_m * 1e3,
                worst * 1e3
            );
        }
    }
}

/// Perception on one scan of `s` (from its start), scored against its true steps (2 cm
/// tolerance).
fn perceive_scored(s: &Scenario) -> (Perception, metrics::Score) {
    let scene = common::scene_of(s);
    let r = perceive(&scan(s), &PerceptionParams::default()).unwrap();
    let sc = metrics::score(&r.segments, scene.steps(), 0.02);
    (r, sc)
}

#[test]
fn a_staircase_yawed_by_30_degrees_comes_out_turned() {
    let mut s =
        Scenario::from_toml_str("[staircase]\nyaw_deg = 30\nstart_m = [0.6, 0.1]\n", "yaw.toml").unwrap();
    s.lidar.noise_sigma_m = 0.005;
    let (r, sc) = perceive_scored(&s);
    assert_eq!(sc.found, 3, "{sc:?}");
    for seg in &r.segments {
        let a = seg.along();
        let yaw = a.y.atan2(a.x).to_degrees();
        assert!((yaw - 30.0).abs() < 3.0, "ascent at {yaw:.1} deg");
        assert!(
            (seg.width_m() - 0.5).abs() < 0.06 && (seg.depth_m() - 0.27).abs() < 0.06,
            "{} x {}",
            seg.depth_m(),
            seg.width_m()
        );
    }
}

/// A top landing is deeper than the steps, so §4.3's shape clustering alone leaves it out
/// (the loop then first saw it from the last step, its nose hidden, and walked into its
/// riser). From the floor, every step and the landing are found, each on its true step.
#[test]
fn a_deep_top_landing_is_found_with_the_flight() {
    for landing_m in [0.3, 1.0] {
        let toml = format!(
            "[staircase]\nsteps = 3\nrise_m = 0.2\ntread_m = 0.27\nwidth_m = 0.5\nlanding_m = {landing_m}\n"
        );
        let mut s = Scenario::from_toml_str(&toml, "landing.toml").unwrap();
        s.lidar.noise_sigma_m = 0.007;
        let scene = common::scene_of(&s);
        let r = perceive(&scan(&s), &PerceptionParams::default()).unwrap();
        let sc = metrics::score(&r.segments, scene.steps(), 0.02);
        assert_eq!(sc.found, 3, "landing {landing_m} m: {sc:?}");
        assert_eq!(sc.false_segments, 0, "landing {landing_m} m: {sc:?}");
        for st in &sc.steps {
            assert!(st.iou >= 0.85, "landing {landing_m} m: step {} IoU {:.2}", st.index + 1, st.iou);
        }
    }
}

/// A stairwell's walls a few centimetres off the flight's sides: the rays that pass the
/// treads' side edges come down through the gap to the walls below, and the walls' returns
/// at a tread's height lie in its plane two or three columns past its edge. Read as the
/// tread's, they widened it by the gap (1.12 m treads read 1.18 m in `regressions-0029` at
/// two noise draws in eight), and the step map's registration, voting on the treads' side
/// edges, moved the robot's estimate 47 mm sideways by them. Each tread comes out as wide
/// as it is, whatever the draw: under 10 mm of noise with the walls 4 and 6 cm off, and
/// under 20 mm with them 5.8 cm off, as in `regressions-0029`. Of these the 4 cm walls
/// widened a tread before (1.039 m at draw 2); on this straight flight the farther walls
/// lie three places off and never touched, as on `regressions-0029`'s turned one they did.
#[test]
fn a_stairwells_gap_beside_the_flight_is_not_read_as_tread() {
    for (gap_m, noise_m) in [(0.04, 0.01), (0.06, 0.01), (0.058, 0.02)] {
        let wall = |side: f64| {
            format!(
                "[[boxes]]\nname = \"wall{side}\"\ncenter_m = [2.2, {y}, 1.3]\nsize_m = [2.0, 0.1, 2.6]\n",
                y = side * (0.5 + gap_m + 0.05)
            )
        };
        let toml = format!(
            "[staircase]\nsteps = 4\nrise_m = 0.16\ntread_m = 0.3\nwidth_m = 1.0\nstart_m = [1.2, 0.0]\n{}{}",
            wall(1.0),
            wall(-1.0)
        );
        for seed in 0..6 {
            let mut s = Scenario::from_toml_str(&toml, "stairwell.toml").unwrap();
            s.seed = seed;
            s.lidar.noise_sigma_m = noise_m;
            let (r, sc) = perceive_scored(&s);
            let what = format!("gap {gap_m} m, noise {noise_m} m, seed {seed}");
            assert!(sc.found >= 3, "{what}: {sc:?}");
            for seg in &r.segments {
                let (z, w) = (seg.height_m(), seg.width_m());
                assert!(
                    (w - 1.0).abs() < 0.025,
                    "{what}: the tread at {z:.3} m read {w:.3} m wide, 1.0 m true"
                );
            }
        }
    }
}

/// A wide, low flight (the ci suite's case 96): the supervoxel clustering cut each 1.3 m
/// tread into strips, and the staircase came back as 15 "steps" at 5 heights (the planner
/// saw rises of 0 and 19 cm treads and refused). Each tread is one segment on its true step.
#[test]
fn a_wide_low_tread_is_one_segment() {
    let toml = "seed = 1473681528205108050\n\
        [staircase]\nsteps = 8\nrise_m = 0.114\ntread_m = 0.364\nwidth_m = 1.30\nyaw_deg = -16.7\n\
        start_m = [0.84, -0.38]\n[robot]\nyaw_deg = -14.1\n\
        [lidar]\nnoise_sigma_m = 0.0075\ndropout_probability = 0.0087\n";
    let s = Scenario::from_toml_str(toml, "wide.toml").unwrap();
    let (r, sc) = perceive_scored(&s);
    assert!(sc.found >= 4, "{sc:?}");
    assert_eq!(sc.false_segments, 0, "{sc:?}");
    assert_eq!(r.segments.len(), sc.found, "one segment per tread: {sc:?}");
    for st in sc.steps.iter().filter(|st| st.found) {
        assert!(st.iou >= 0.85, "step {} IoU {:.2}", st.index + 1, st.iou);
    }
}

/// A low flight under 15 mm of range noise (the ci suite's case 60, boxes behind the robot
/// left out): RANSAC's plane through step 1's supervoxel centres came out tilted 5.5 degrees
/// (the foot, then planned on that tilt, met the tread heel first, 2 cm up). With the cell
/// method, the cells at a tread's back edge, holding the foot of the riser above, passed as
/// level and tilted the region's plane 1.4-2.7 deg toward the sensor, and the treads by
/// 0.9-1.5 deg (`cells.fit_noise_factor`). Treads are level by either method; every
/// segment's normal is within a degree of vertical.
#[test]
fn a_tread_under_range_noise_comes_out_level() {
    let toml = "seed = 8443359241396318136\n\
        [staircase]\nsteps = 7\nrise_m = 0.1434\ntread_m = 0.3206\nwidth_m = 1.404\nyaw_deg = 2.29\n\
        start_m = [1.4838, 0.2580]\nlanding_m = 1.0\n\
        [room]\nsize_m = [8.28, 3.54, 3.10]\ncenter_m = [1.616, 0.318]\n\
        [robot]\nyaw_deg = -2.26\n\
        [lidar]\nnoise_sigma_m = 0.0148\ndropout_probability = 0.0008\n";
    let s = Scenario::from_toml_str(toml, "low-noisy.toml").unwrap();
    let scene = common::scene_of(&s);
    let cloud = scan(&s);
    for method in [Method::Paper, Method::Cells] {
        let r = perceive(&cloud, &PerceptionParams { method, ..Default::default() }).unwrap();
        let sc = metrics::score(&r.segments, scene.steps(), 0.02);
        assert!(sc.found >= 4, "{method}: {sc:?}");
        for seg in &r.segments {
            let tilt_deg = seg.normal().z.clamp(-1.0, 1.0).acos().to_degrees();
            println!("{method}: segment at {:.3} m: tilt {tilt_deg:.2} deg", seg.height_m());
            assert!(
                tilt_deg < 1.0,
                "{method}: the tread at {:.3} m is tilted {tilt_deg:.2} deg",
                seg.height_m()
            );
        }
    }
}

/// `a`'s first `rows` scan rows followed by `b`'s others, seen from `a`'s viewpoint: what
/// a stream has been given of `a` when `b`'s rows arrive instead.
fn spliced(a: &PointCloud, b: &PointCloud, rows: usize) -> PointCloud {
    let (ga, gb) = (a.grid().unwrap(), b.grid().unwrap());
    let (mut points, mut cells) = (Vec::new(), Vec::new());
    for r in 0..ga.rows() {
        let (from, grid) = if r < rows { (a, ga) } else { (b, gb) };
        for beam in 0..grid.beams() {
            cells.push(match grid.point_at(r, beam) {
                Some(i) => {
                    points.push(from.points()[i]);
                    (points.len() - 1) as u32
                }
                None => ScanGrid::EMPTY,
            });
        }
    }
    let grid = ScanGrid::new(ga.rows(), ga.beams(), cells).unwrap();
    PointCloud::new(points, a.viewpoint(), a.gravity(), Some(grid))
}

/// A sweep whose rows are given to the stream as they arrive, one at a time or in uneven
/// bunches, gives exactly the steps and counts of the whole sweep: Exp. 1, and a low flight
/// under 15 mm of noise on cells of 7 rows (240 rows leave a partial row of cells at the
/// end). The streamed work is the same arithmetic in the same order: equal is bit for bit.
/// The rows not yet arrived are not read: up to row 101 the stream is given one noise
/// draw's sweep, and from there another's (spliced on the first), and it gives what the
/// spliced sweep gives.
#[test]
fn a_streamed_sweep_gives_what_the_whole_sweep_gives() {
    let low = "[staircase]\nsteps = 7\nrise_m = 0.1434\ntread_m = 0.3206\nwidth_m = 1.404\n\
        [lidar]\nnoise_sigma_m = 0.0148\n";
    const SPLICE: usize = 101;
    for (s, cell_rows) in [(exp1(0.01), 8), (Scenario::from_toml_str(low, "low.toml").unwrap(), 7)] {
        let early = scan(&s);
        let mut other = s.clone();
        other.seed += 1;
        let cloud = spliced(&early, &scan(&other), SPLICE);
        let rows = cloud.grid().unwrap().rows();
        let mut p = PerceptionParams::default();
        assert_eq!(p.method, Method::Cells);
        p.cells.rows = cell_rows;
        let whole = perceive(&cloud, &p).unwrap();
        assert!(whole.segments.len() >= 3);
        assert_ne!(perceive(&early, &p).unwrap().segments, whole.segments, "the splice changes the steps");
        for bunch in [1, 7, 61] {
            let mut stream = PerceptionStream::new(&cloud, &p).unwrap();
            for r in (bunch..rows + bunch).step_by(bunch) {
                let r = r.min(rows);
                stream.arrived(if r <= SPLICE { &early } else { &cloud }, r);
            }
            let got = stream.finish(&cloud).unwrap();
            assert_eq!(got.segments, whole.segments, "rows in bunches of {bunch}");
            assert_eq!(got.counts, whole.counts, "rows in bunches of {bunch}");
        }
    }
}

/// The same sweep gives the same steps, to the bit, on a machine of any number of cores:
/// the suites' verdicts and figures must not depend on where they run (a 16-core machine
/// running a suite wide, a 2-core CI). Each method, in thread pools of 1 to 16 threads, on
/// Exp. 1 and on Exp. 2's longer flight. With step 3's points binned in a band per thread,
/// 3 and 16 threads summed the columns in another order than 1 and 2 and found steps a few
/// ulps apart, and a climb on them went another way.
#[test]
fn the_steps_are_the_same_on_any_number_of_cores() {
    let exp2 = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/exp2.toml");
    for s in [exp1(0.01), Scenario::load(&exp2).unwrap()] {
        let cloud = scan(&s);
        for method in [Method::Cells, Method::Paper] {
            let p = PerceptionParams { method, ..Default::default() };
            let mut first: Option<(usize, Perception)> = None;
            for threads in [1, 2, 3, 5, 16] {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                let got = pool.install(|| perceive(&cloud, &p)).unwrap();
                assert!(got.segments.len() >= 3, "{}: {method:?} found {}", s.name, got.segments.len());
                match &first {
                    None => first = Some((threads, got)),
                    Some((t, want)) => {
                        assert_eq!(
                            got.segments, want.segments,
                            "{}, {method:?}: {threads} threads against {t}",
                            s.name
                        );
                        assert_eq!(
                            got.counts, want.counts,
                            "{}, {method:?}: {threads} threads against {t}",
                            s.name
                        );
                    }
                }
            }
        }
    }
}

/// Twice the data sheet's range noise (20 mm), the paper's Exp. 1 seen from the start,
/// noise draws 0-9: the sweep's noise is measured within 10 %, k grows to 20, and every
/// draw finds the first step on the true one (IoU at least 0.6, height within 1 cm). On
/// the paper's k = 10 whatever the noise, the normals of the near, steeply seen tread are
/// noise and the first step was lost in 6 of 10 draws (wide suite: 7 flights refused, "a
/// step is missing", for it); the test checks that case is still shown.
#[test]
fn the_first_step_is_found_under_twice_the_data_sheets_noise() {
    // The paper's pipeline: its normals' k grows with the noise (the cells have none).
    let p = PerceptionParams { method: Method::Paper, ..Default::default() };
    let paper_k = PerceptionParams { k_grows_with_noise: false, ..p.clone() };
    let (mut found, mut found_paper_k) = (0, 0);
    for seed in 0..10 {
        let mut s = exp1(0.02);
        s.seed = seed;
        let scene = common::scene_of(&s);
        let cloud = scan(&s);
        let r = perceive(&cloud, &p).unwrap();
        let noise_mm = r.counts.range_noise_mm.expect("a sweep's noise is measured");
        assert!((noise_mm / 20.0 - 1.0).abs() < 0.1, "seed {seed}: {noise_mm:.1} mm measured");
        assert_eq!(r.counts.normal_neighbours, 20, "seed {seed}");
        let first = &metrics::score(&r.segments, scene.steps(), 0.02).steps[0];
        if first.found && first.iou >= 0.6 && first.height_error_m.abs() < 0.01 {
            found += 1;
        }
        if perceive(&cloud, &paper_k)
            .is_ok_and(|r| metrics::score(&r.segments, scene.steps(), 0.02).steps[0].found)
        {
            found_paper_k += 1;
        }
    }
    assert_eq!(found, 10, "the first step found on the true one in {found} of 10 draws");
    assert!(found_paper_k <= 7, "k = 10 found it in {found_paper_k} of 10: the case is not shown");
}

#[test]
fn grid_neighbourhoods_match_the_kd_tree() {
    let cloud = scan(&exp1(0.01));
    let p = PerceptionParams { method: Method::Paper, ..Default::default() };
    let g = cloud.gravity();
    let grid = normals::estimate(&cloud, 10, NeighbourSearch::ScanGrid);
    let tree = normals::estimate(&cloud, 10, NeighbourSearch::KdTree);
    let (a, b) = (
        filter_slope(&grid, &g, p.normal_distance_threshold).len(),
        filter_slope(&tree, &g, p.normal_distance_threshold).len(),
    );
    assert!((a as f64 / b as f64 - 1.0).abs() < 0.05, "Filter 1 keeps {a} (grid) vs {b} (k-d tree)");
    let scene = common::scene_of(&exp1(0.01));
    let mut scores = Vec::new();
    for search in [NeighbourSearch::ScanGrid, NeighbourSearch::KdTree] {
        let q = PerceptionParams { neighbour_search: search, ..p.clone() };
        let r = perceive(&cloud, &q).unwrap();
        scores.push(metrics::score(&r.segments, scene.steps(), 0.02));
    }
    assert_eq!((scores[0].found, scores[1].found), (3, 3));
    for i in 0..3 {
        let (x, y) = (scores[0].steps[i].iou, scores[1].steps[i].iou);
        assert!((x - y).abs() < 0.05, "step {}: IoU {x:.2} (grid) vs {y:.2} (k-d tree)", i + 1);
    }
}

fn no_staircase(cloud: &PointCloud) -> NoStaircase {
    match perceive(cloud, &PerceptionParams::default()) {
        Err(PerceptionError::NoStaircase(why)) => why,
        Err(e) => panic!("unexpected error {e}"),
        Ok(r) => panic!("found {} steps", r.segments.len()),
    }
}

fn grid_points(f: impl Fn(f32, f32) -> Point3<f32>, n: usize, step: f32) -> Vec<Point3<f32>> {
    (0..n * n).map(|i| f((i % n) as f32 * step, (i / n) as f32 * step)).collect()
}

#[test]
fn bad_clouds_give_a_clear_no_staircase() {
    let vp = Point3::new(0.0, 0.0, 1.4);
    assert_eq!(no_staircase(&PointCloud::unorganized(vec![], vp)), NoStaircase::EmptyCloud);
    no_staircase(&PointCloud::unorganized(vec![Point3::new(1.0, 0.0, 0.0)], vp));
    let nan = vec![
        Point3::new(f32::NAN, 0.0, 0.0),
        Point3::new(f32::INFINITY, 1.0, 0.0),
        Point3::new(0.0, f32::NEG_INFINITY, 2.0),
    ];
    no_staircase(&PointCloud::unorganized(nan, vp));
    // Walls only: every normal is horizontal.
    let wall = grid_points(|a, b| Point3::new(2.0, a - 1.0, b), 100, 0.01);
    let why = no_staircase(&PointCloud::unorganized(wall, vp));
    assert!(
        matches!(why, NoStaircase::NoHorizontalSurface { points: 10000, after_filter1: 0, .. }),
        "{why:?}"
    );
    // A flat floor only: found, but it is the ground.
    let floor = grid_points(|a, b| Point3::new(a - 0.5, b - 0.5, 0.0), 150, 0.01);
    let why = no_staircase(&PointCloud::unorganized(floor, vp));
    assert!(
        matches!(why, NoStaircase::OnlyGround { segments: 1, ground_m } if ground_m.abs() < 1e-3),
        "{why:?}"
    );
}

#[test]
fn nan_points_in_a_real_scan_change_nothing() {
    let mut cloud = scan(&exp1(0.0));
    let mut pts = cloud.points().to_vec();
    pts.extend((0..1000).map(|i| Point3::new(f32::NAN, i as f32, 0.0)));
    cloud = PointCloud::unorganized(pts, cloud.viewpoint());
    let scene = common::scene_of(&exp1(0.0));
    let r = perceive(&cloud, &PerceptionParams::default()).unwrap();
    assert_eq!(metrics::score(&r.segments, scene.steps(), 0.02).found, 3);
}

#[test]
fn ten_million_points_are_handled() {
    // A flat floor of 10 million points (unorganized: k-d tree path): a result, no panic.
    let n = 3163; // n^2 > 10^7
    let pts = grid_points(|a, b| Point3::new(a - 5.0, b - 5.0, 0.0), n, 0.003);
    assert!(pts.len() >= 10_000_000);
    let why = no_staircase(&PointCloud::unorganized(pts, Point3::new(0.0, 0.0, 1.4)));
    assert!(matches!(why, NoStaircase::OnlyGround { .. }), "{why:?}");
}

#[test]
fn invalid_parameters_name_the_field() {
    let cloud = PointCloud::unorganized(vec![Point3::origin(); 10], Point3::new(0.0, 0.0, 1.0));
    let p = PerceptionParams { normal_neighbours: 1, ..Default::default() };
    let e = perceive(&cloud, &p).unwrap_err().to_string();
    assert!(e.contains("normal_neighbours"), "{e}");
    let p = PerceptionParams { voxel_resolution_m: f64::NAN, ..Default::default() };
    assert!(perceive(&cloud, &p).unwrap_err().to_string().contains("voxel_resolution_m"));
    let mut p = PerceptionParams { method: Method::Cells, ..Default::default() };
    p.cells.merge_distance_m = -1.0;
    assert!(perceive(&cloud, &p).unwrap_err().to_string().contains("cells.merge_distance_m"));
}

/// A synthetic staircase: points on the treads, risers and floor, 1 cm apart (unorganized).
fn synthetic_stairs() -> Vec<Point3<f32>> {
    let mut pts = Vec::new();
    let step = 0.01;
    for i in 0..300 {
        for j in 0..150 {
            let (x, y) = (-1.0 + i as f32 * step, -0.75 + j as f32 * step);
            let k = ((x - 0.6) / 0.27).floor();
            let z = if x < 0.6 { 0.0 } else { 0.2 * (k + 1.0).min(3.0) };
            pts.push(Point3::new(x, y, z));
        }
    }
    for k in 0..3 {
        for j in 0..150 {
            for h in 0..20 {
                pts.push(Point3::new(
                    0.6 + 0.27 * k as f32,
                    -0.75 + j as f32 * step,
                    0.2 * k as f32 + h as f32 * step,
                ));
            }
        }
    }
    pts
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(8))]

    /// A turned and moved staircase gives the same rectangles, turned and moved.
    #[test]
    fn rigid_motions_move_the_rectangles(yaw in -3.1f64..3.1, tx in -3.0f64..3.0, ty in -3.0f64..3.0) {
        let base = synthetic_stairs();
        let vp = Point3::new(-1.5f32, 0.0, 1.4);
        let p = PerceptionParams::default();
        let r0 = perceive(&PointCloud::unorganized(base.clone(), vp.cast()), &p).unwrap();
        let m = Isometry3::from_parts(Translation3::new(tx, ty, 0.0), UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw));
        let mf = m.cast::<f32>();
        let moved: Vec<Point3<f32>> = base.iter().map(|q| mf * q).collect();
        let r1 = perceive(&PointCloud::unorganized(moved, (mf * vp).cast()), &p).unwrap();
        prop_assert_eq!(r0.segments.len(), r1.segments.len());
        for (a, b) in r0.segments.iter().zip(&r1.segments) {
            let back: Vec<Point3<f64>> = b.corners().iter().map(|c| m.inverse_transform_point(c)).collect();
            for c in a.corners() {
                let d = back.iter().map(|q| (q - c).norm()).fold(f64::INFINITY, f64::min);
                prop_assert!(d < 0.03, "corner {c} moved by {d}");
            }
            prop_assert!((a.height_m() - b.height_m()).abs() < 0.005);
        }
    }
}

/// Two like clutter boxes beside a three-step flight, nearer the sensor than its steps (the
/// ci suite's case 127): the boxes' tops, two segments of one shape, tied the flight's two
/// like steps and won as nearer, a "staircase" of two steps at one height, and the flight
/// was refused as a 0.378 m first rise. A flight rises: the steps found are the true ones.
#[test]
fn like_boxes_side_by_side_are_not_a_staircase() {
    let toml = "seed = 4293448516482489633\n\
        [staircase]\nsteps = 3\nrise_m = 0.1769\ntread_m = 0.2699\nwidth_m = 1.2608\nyaw_deg = 9.02\n\
        start_m = [1.1190, 0.1861]\nlanding_m = 0.3\n\
        [room]\nsize_m = [4.51, 4.15, 3.0]\ncenter_m = [1.057, 0.086]\n\
        [[boxes]]\nname = \"clutter_1\"\ncenter_m = [0.3819, 0.9163, 0.1879]\nsize_m = [0.4697, 0.3758, 0.3758]\nyaw_deg = 16.1\n\
        [[boxes]]\nname = \"clutter_2\"\ncenter_m = [1.1259, -0.7134, 0.1879]\nsize_m = [0.4697, 0.3758, 0.3758]\nyaw_deg = 28.1\n\
        [robot]\nyaw_deg = 12.7\n\
        [lidar]\nnoise_sigma_m = 0.0063\ndropout_probability = 0.0004\n";
    let s = Scenario::from_toml_str(toml, "boxes-beside.toml").unwrap();
    let (r, sc) = perceive_scored(&s);
    assert!(sc.found >= 2, "{sc:?}");
    assert_eq!(sc.false_segments, 0, "{sc:?}");
    assert_eq!(r.segments.len(), sc.found, "{sc:?}");
}

/// A level tread under 14.5 mm of range noise (the ci suite's case 42's staircase, noise seed 9):
/// its 94 supervoxel centres spanned 3.2 cm from lowest to highest, more than epsilon, and
/// §4.3's filter dropped it; the planner then refused the flight for a step missing below
/// the next one. The height a segment spans is its surface's: every true step in view is
/// found, each once.
#[test]
fn a_level_tread_under_range_noise_is_not_dropped_for_its_height_extent() {
    let toml = r#"
seed = 9
boxes = []

[staircase]
steps = 6
rise_m = 0.14842055837278834
tread_m = 0.3027085871334755
width_m = 1.367663284147501
yaw_deg = 24.54125544768781
start_m = [0.644248249112154, 0.3658928380180529]
landing_m = 0.3
friction = 0.95815682173457
missing_steps = []

[room]
size_m = [5.053351110470658, 4.1230934884596735, 3.0]
center_m = [1.3266755552353284, 0.805383623618916]
walls = true
ceiling = true
floor_friction = 0.8

[robot]
position_m = [0.0, 0.0]
yaw_deg = 23.06158704084143

[lidar]
mount_xyz_m = [0.0, 0.0, 0.07]
mount_rpy_deg = [0.0, 0.0, 0.0]
axis_to_optical_m = [0.0, 0.0, 0.035]
tilt_start_deg = 10.0
tilt_end_deg = 70.0
tilt_speed_dps = 10.0
servo_ticks_per_rev = 4096
fov_deg = 270.0
resolution_deg = 0.25
row_period_s = 0.025
range_min_m = 0.1
range_max_m = 30.0
noise_sigma_m = 0.014534422756826829
dropout_probability = 0.003469116074115104
"#;
    let s = Scenario::from_toml_str(toml, "noisy-tread.toml").unwrap();
    let (r, sc) = perceive_scored(&s);
    for st in &sc.steps {
        println!("step {}: found {} IoU {:.2}", st.index + 1, st.found, st.iou);
    }
    assert!(sc.steps[..5].iter().all(|st| st.found), "{sc:?}");
    assert_eq!(sc.false_segments, 0, "{sc:?}");
    assert_eq!(r.segments.len(), sc.found, "{sc:?}");
}

/// The cell method ([`Method::Cells`]) against the paper's pipeline and the ground truth on
/// the same sweeps: the paper's Exp. 1 and Exp. 2 and the 24 cm step, noise-free, at the
/// data sheet's 10 mm and at twice it, two noise draws each. It finds every step the paper's
/// pipeline finds, no false segment, each on its true height within 5 mm and with an IoU
/// at least the lower of the paper's less 0.05 and 0.9.
#[test]
fn the_cell_method_finds_what_the_papers_pipeline_finds() {
    let paper = PerceptionParams { method: Method::Paper, ..Default::default() };
    let cells = PerceptionParams { method: Method::Cells, ..Default::default() };
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios");
    for name in ["exp1", "exp2", "hrp4_step"] {
        for (noise_m, seed) in [(0.0, 0), (0.01, 1), (0.01, 2), (0.02, 1), (0.02, 2)] {
            let mut s = Scenario::load(&dir.join(format!("{name}.toml"))).unwrap();
            s.lidar.noise_sigma_m = noise_m;
            s.seed = seed;
            let scene = common::scene_of(&s);
            let cloud = scan(&s);
            let theirs = perceive(&cloud, &paper).unwrap();
            let ours = perceive(&cloud, &cells).unwrap();
            assert_eq!(ours.method, Method::Cells);
            let (a, b) = (
                metrics::score(&theirs.segments, scene.steps(), 0.02),
                metrics::score(&ours.segments, scene.steps(), 0.02),
            );
            let case = format!("{name}, noise {:.0} mm, seed {seed}", noise_m * 1e3);
            println!(
                "{case}: paper {} found, IoU {:?}; cells {} found, IoU {:?}, {:.1} ms",
                a.found,
                a.steps.iter().map(|s| (s.iou * 100.0).round() / 100.0).collect::<Vec<_>>(),
                b.found,
                b.steps.iter().map(|s| (s.iou * 100.0).round() / 100.0).collect::<Vec<_>>(),
                ours.timings.total_ms
            );
            assert_eq!(b.false_segments, 0, "{case}: {b:?}");
            for (t, o) in a.steps.iter().zip(&b.steps).filter(|(t, _)| t.found) {
                assert!(o.found, "{case}: step {} found by the paper's pipeline only", t.index + 1);
                assert!(
                    o.iou >= (t.iou - 0.05).min(0.9),
                    "{case}: step {} IoU {:.2} against the paper's {:.2}",
                    t.index + 1,
                    o.iou,
                    t.iou
                );
                assert!(
                    o.height_error_m.abs() < 0.005,
                    "{case}: step {} dz {}",
                    t.index + 1,
                    o.height_error_m
                );
            }
        }
    }
}

/// Exp. 1 seen from farther back (the robot 1.0 to 1.2 m behind its start, as a head on a
/// tripod there sees it): the top tread, 0.8 m below the head and over 2 m ahead, spans
/// about 8 scan rows. The cells find every step the paper's pipeline finds, on its height.
/// Without cutting a mixed cell in halves (`cells.split_rows`) the tread's rows
/// fall across two rows of cells, each mixed with the riser below or the wall behind, and
/// it is lost in some of these views (checked here, so that the views keep showing it).
#[test]
fn a_tread_seen_over_few_rows_is_found_by_the_cells() {
    let paper = PerceptionParams { method: Method::Paper, ..Default::default() };
    let cells = PerceptionParams { method: Method::Cells, ..Default::default() };
    let mut unsplit = cells.clone();
    unsplit.cells.split_rows = false;
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios");
    let (mut compared, mut lost_whole) = (0, 0);
    for (start_m, seed) in [(1.6, 1), (1.7, 2), (1.8, 1), (1.8, 2)] {
        let mut s = Scenario::load(&dir.join("exp1.toml")).unwrap();
        s.staircase.start_m[0] = start_m;
        s.seed = seed;
        let scene = common::scene_of(&s);
        let cloud = scan(&s);
        let a = metrics::score(&perceive(&cloud, &paper).unwrap().segments, scene.steps(), 0.02);
        let b = metrics::score(&perceive(&cloud, &cells).unwrap().segments, scene.steps(), 0.02);
        let whole = metrics::score(&perceive(&cloud, &unsplit).unwrap().segments, scene.steps(), 0.02);
        let case = format!("start {start_m} m, seed {seed}");
        println!(
            "{case}: paper {} found, cells {} found ({} with whole cells only)",
            a.found, b.found, whole.found
        );
        lost_whole += usize::from(whole.found < a.found);
        assert_eq!(b.false_segments, 0, "{case}: {b:?}");
        for (t, o) in a.steps.iter().zip(&b.steps).filter(|(t, _)| t.found) {
            assert!(o.found, "{case}: step {} found by the paper's pipeline only", t.index + 1);
            assert!(o.height_error_m.abs() < 0.005, "{case}: step {} dz {}", t.index + 1, o.height_error_m);
            compared += 1;
        }
    }
    assert!(compared >= 10, "{compared} steps compared");
    assert!(lost_whole > 0, "whole cells lose no step in these views: they no longer show the case");
}

/// Exp. 2 under 22 mm of range noise (the `wide` suite's upper end), by either method: every
/// tread's back edge lies within 10 mm of the riser above it, the highest tread seen too
/// (whose riser above is seen only in part, the tread above it not at all). The foot of a
/// riser seen through that noise lands on the plane of the tread below it past the riser;
/// given to the tread, it draws it centimetres too deep, and a foot put in its middle
/// stands against the riser (`wide-0003` with cells: refused, the riser in the sole's way).
#[test]
fn a_treads_back_lies_on_the_riser_above_it_under_range_noise() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios");
    let (mut checked, mut worst) = (0, 0.0f64);
    for method in [Method::Paper, Method::Cells] {
        let p = PerceptionParams { method, ..Default::default() };
        for seed in 0..4 {
            let mut s = Scenario::load(&dir.join("exp2.toml")).unwrap();
            s.lidar.noise_sigma_m = 0.022;
            s.seed = seed;
            let scene = common::scene_of(&s);
            let r = perceive(&scan(&s), &p).unwrap();
            let score = metrics::score(&r.segments, scene.steps(), p.voxel_resolution_m);
            let found: Vec<_> = score.steps.iter().filter(|t| t.found).collect();
            assert!(found.len() >= 4, "{method:?}, seed {seed}: {} steps found", found.len());
            // The flight's last tread ends at the landing's edge, not a riser.
            for t in found.iter().filter(|t| t.index + 1 < scene.steps().len()) {
                assert!(
                    t.back_error_m.abs() < 0.010,
                    "{method:?}, seed {seed}, step {}: back {:+.1} mm off the riser above it",
                    t.index + 1,
                    t.back_error_m * 1e3
                );
                worst = worst.max(t.back_error_m.abs());
                checked += 1;
            }
        }
    }
    println!("{checked} backs within {:.1} mm of their risers", worst * 1e3);
}

/// Exp. 2 under twice the data sheet's noise, with the cell method and the backs left where
/// the cells put them: no tread's back runs past the riser behind it by more than 15 mm. The
/// foot of a riser seen through 20 mm of noise lands on the plane of the tread below it past
/// the tread's end; such points lie behind the riser's plane as their ray meets it, and the
/// cells leave them to it. Nor does the rule eat the tread: its back stops short of the
/// riser by at most 25 mm (a voxel and a quarter).
#[test]
fn a_risers_foot_seen_through_noise_stays_off_the_tread_below() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios");
    let mut p = PerceptionParams { method: Method::Cells, ..Default::default() };
    p.riser.backs = false;
    for seed in [1, 2] {
        let mut s = Scenario::load(&dir.join("exp2.toml")).unwrap();
        s.lidar.noise_sigma_m = 0.02;
        s.seed = seed;
        let scene = common::scene_of(&s);
        let r = perceive(&scan(&s), &p).unwrap();
        let u = Vector3::new(scene.ascent_yaw_rad().cos(), scene.ascent_yaw_rad().sin(), 0.0);
        let steps = scene.steps();
        let mut checked = 0;
        for seg in &r.segments {
            assert!(!seg.back_on_riser(), "backs off, yet one was placed");
            let Some(k) = steps.iter().position(|t| (t.height_m - seg.height_m()).abs() < 0.03) else {
                continue;
            };
            if k + 1 >= steps.len()
                || !r.segments.iter().any(|o| (o.height_m() - steps[k + 1].height_m).abs() < 0.03)
            {
                continue; // its back is the edge of the view, not a riser
            }
            let back = seg.center().coords.dot(&u) + seg.depth_m() / 2.0;
            let riser = steps[k + 1].corners[0].coords.dot(&u);
            assert!(
                (-0.025..0.015).contains(&(back - riser)),
                "seed {seed}, step {}: back {:+.1} mm off the riser",
                k + 1,
                (back - riser) * 1e3
            );
            checked += 1;
        }
        assert!(checked >= 3, "seed {seed}: {checked} backs checked");
    }
}

/// A cloud with no scan grid (a file) asked for the cell method runs the paper's pipeline
/// and says so.
#[test]
fn the_cell_method_on_a_cloud_without_a_grid_runs_the_papers() {
    let cloud = scan(&exp1(0.01));
    let file = PointCloud::unorganized(cloud.points().to_vec(), cloud.viewpoint());
    let p = PerceptionParams { method: Method::Cells, ..Default::default() };
    let r = perceive(&file, &p).unwrap();
    assert_eq!(r.method, Method::Paper);
    assert_eq!(r.segments.len(), 3);
}

/// `perceive -k` or `--search` with the cell method on a sweep is refused with what to do:
/// those options set the paper's normals, which the cells never compute, and a run that
/// took them silently would report the cells' steps as if the normals had been chosen.
#[test]
fn the_papers_normal_options_with_the_cell_method_are_refused() {
    for extra in [&["-k", "15"][..], &["--search", "kd-tree"][..]] {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_stairbench"))
            .args(["perceive", "exp1", "--method", "cells"])
            .args(extra)
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{extra:?} accepted");
        assert!(err.contains("--method paper"), "{extra:?}: {err}");
    }
}
