//! `stairbench regress`: CI regression across many generated staircases. A suite file
//! ([`suite`]) says how to draw cases; the generator ([`generate`]) turns each into a scenario
//! with its expected outcome from the ground truth and the planner's declared limits
//! ([`expect`]); the runner ([`runner`]) climbs them in parallel, one JSON line per run
//! ([`results`]); each run gets a verdict ([`verdict`]); the results become a terminal
//! summary and a baseline comparison ([`summary`]), JUnit ([`junit`]) and capability maps
//! ([`maps`]); shards of a suite run on many machines and merge ([`shard`]).

pub mod expect;
pub mod generate;
pub mod junit;
pub mod maps;
pub mod results;
pub mod runner;
pub mod shard;
pub mod suite;
pub mod summary;
pub mod verdict;

pub use generate::{Case, Robot};
pub use results::CaseResult;
pub use verdict::Verdict;

/// The robot of the bench, for the expectations: the planner's limits `gait`, and where the
/// HRP-4-class model's feet stand in half-sitting.
pub fn bench_robot(gait: &crate::planning::footholds::GaitParams) -> Result<Robot, crate::robot::RobotError> {
    let model = crate::robot::hrp4::model()?;
    let q = crate::robot::hrp4::half_sitting_at(&model, &nalgebra::Isometry3::identity())?;
    let stance = crate::planning::plan::stance_at(&model, &q)
        .map_err(|e| crate::robot::RobotError::Invalid(e.to_string()))?;
    let spacing = (stance.left.translation.vector - stance.right.translation.vector).norm() / 2.0;
    Ok(Robot { gait: gait.clone(), feet_half_spacing_m: spacing })
}
