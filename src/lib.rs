//! stairbench: a simulation-in-the-loop test bench for humanoid stair climbing, after
//! "Supervoxel Plane Segmentation and Multi-Contact Motion Generation for Humanoid Stair
//! Climbing" (HRP-4 with a tilting Hokuyo lidar).
//!
//! Data flows one way (see DESIGN.md): [`scenario`] → [`scene`] → [`sim`] world → [`sensor`]
//! rows → [`cloud`] → perception → planning → execution. Each stage is a function of its inputs
//! and a parameter struct, so any stage can be fed from a file, a log or a test.
#![warn(missing_docs)]

pub mod cloud;
pub mod geom2d;
pub mod perception;
pub mod planning;
pub mod record;
pub mod robot;
pub mod scenario;
pub mod scene;
pub mod sensor;
pub mod sim;
