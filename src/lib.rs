//! stairbench: a simulation-in-the-loop test bench for humanoid stair climbing, after
//! "Supervoxel Plane Segmentation and Multi-Contact Motion Generation for Humanoid Stair
//! Climbing" (HRP-4 with a tilting Hokuyo lidar).
//!
//! Data flows one way (see DESIGN.md): [`scenario`] → [`scene`] → [`sim`] world → a
//! [`sensor::Source`]'s rows → [`cloud`] → [`perception`] (with its step map) → [`planning`] →
//! an execution ([`climb::Executor`], the simulated robot in [`sim`]). [`climb`] is the closed
//! loop over those traits, emitting [`climb::Event`]s to observers such as [`record`]'s MCAP
//! recorder and Rerun logger. Each stage is a function of its inputs and a parameter struct,
//! so any stage can be fed from a file, a log or a test.
#![warn(missing_docs)]

pub mod cancel;
pub mod climb;
pub mod cloud;
pub mod control;
pub mod estimate;
pub mod geom2d;
pub mod geom3d;
pub mod params;
pub mod perception;
pub mod planning;
pub mod plot_font;
pub mod record;
pub mod regress;
pub mod robot;
pub mod scenario;
pub mod scene;
pub mod sensor;
pub mod sim;
pub mod stats;
