//! `bench polygon`: the static-stability polygon of one stance by double description, against
//! Bretl and Lall's projection with LPs (the baseline) in the same process, single-threaded.

use super::{machine, median_s};
use anyhow::Result;
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use stairbench::planning::dd::DdParams;
use stairbench::planning::polygon::{by_bretl, by_double_description};
use stairbench::planning::Contact;
use std::hint::black_box;

/// Stances per timing run.
const STANCES: usize = 100;

fn stances(contacts: usize, rng: &mut ChaCha8Rng) -> Vec<Vec<Contact>> {
    let tilt = 20f64.to_radians();
    (0..STANCES)
        .map(|_| {
            (0..contacts)
                .map(|i| {
                    let pose = Isometry3::from_parts(
                        Translation3::new(
                            0.3 * i as f64 + rng.random_range(-0.1..0.1),
                            0.18 * (i % 2) as f64 + rng.random_range(-0.05..0.05),
                            rng.random_range(0.0..0.3),
                        ),
                        UnitQuaternion::from_euler_angles(
                            rng.random_range(-tilt..tilt),
                            rng.random_range(-tilt..tilt),
                            rng.random_range(-0.5..0.5),
                        ),
                    );
                    Contact::new(pose, 0.12, 0.065, 0.7).expect("valid contact")
                })
                .collect()
        })
        .collect()
}

/// Returns the Markdown table.
pub fn run(repeat: usize) -> Result<String> {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let mut t = format!(
        "{STANCES} random stances per row (soles 24 x 13 cm, friction 0.7, heights up to 30 cm apart, tilted up to 20 deg), median of {repeat}; single-threaded; machine: {}.\n\n",
        machine()
    );
    t += "| contacts | double description | baseline: Bretl projection (clarabel LPs, 10 um) | ratio | failures (DD / Bretl) |\n|---|---|---|---|---|\n";
    for n in [1, 2, 3] {
        let set = stances(n, &mut rng);
        let p = DdParams::default();
        let (mut dd_fail, mut bretl_fail) = (0, 0);
        for s in &set {
            dd_fail += usize::from(by_double_description(s, &p).is_err());
            bretl_fail += usize::from(by_bretl(s, 1e-5).is_err());
        }
        let dd_s = one.install(|| {
            median_s(repeat, || {
                for s in &set {
                    let _ = black_box(by_double_description(s, &p));
                }
            })
        }) / STANCES as f64;
        let bretl_s = one.install(|| {
            median_s(repeat, || {
                for s in &set {
                    let _ = black_box(by_bretl(s, 1e-5));
                }
            })
        }) / STANCES as f64;
        t += &format!(
            "| {n} | {:.3} ms | {:.3} ms | {:.1} | {dd_fail} / {bretl_fail} |\n",
            dd_s * 1e3,
            bretl_s * 1e3,
            bretl_s / dd_s
        );
    }
    t += "\nA failure is a stance with no polygon (an error); with tilts this small every stance holds, so any failure here is a bug.\n";
    Ok(t)
}
