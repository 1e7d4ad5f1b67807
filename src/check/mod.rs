//! Checks of rendered images against references: the golden scenes, and the
//! GPU back end against the CPU rasteriser.

pub mod compare;
pub mod golden;
pub mod outside;
#[cfg(feature = "gpu")]
pub mod parity;
