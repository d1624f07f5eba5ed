//! Planning (§6): contacts and their wrench cones, the static-stability polygon (double
//! description, checked by Bretl and Lall's projection).

pub mod contact;
pub mod dd;
pub mod polygon;

pub use contact::{Contact, ContactSpec};
