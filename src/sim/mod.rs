//! MuJoCo side of the bench: the compiled world and what is asked of it (ray casts, frames).

pub mod climb;
pub mod execute;
pub mod observe;
pub mod speed_margin;
pub mod stop;
pub mod world;

pub use world::{RayHit, SimError, World};
