//! Checks of rendered images against references: the golden scenes, and the
//! GPU back end against the CPU rasteriser.

pub mod compare;
pub mod golden;
#[cfg(feature = "gpu")]
pub mod parity;
