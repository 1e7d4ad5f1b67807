//! # terraclip
//!
//! A CPU reference implementation of geometry-clipmap terrain rendering
//! (Losasso & Hoppe 2004; GPU Gems 2 ch. 2; Holkner; Brettell).
//!
//! ## Usage
//! Parse or build a [`Scene`], open a [`Session`] on it (the terrain and its
//! pyramid are built once, the LOD scheme is kept across frames) and call
//! [`Session::render`] with a camera for each frame; it returns the
//! [`Image`] (RGBA8 and Depth32Float) and its [`RenderStats`]. The README's
//! example runs as a doctest.
//!
//! ## Implementation
//! Data flows one way: scene → heightmap → pyramid → LOD scheme → frame →
//! raster → shade. `docs/architecture.md` describes the stages.

pub mod camera;
pub mod clipmap;
pub mod cracks;
pub mod diagram;
pub mod error;
pub mod fly;
pub mod frame;
pub mod golden;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod heightmap;
pub mod huge;
pub mod lod;
pub mod metrics;
pub mod pyramid;
pub mod raster;
pub mod render;
pub mod report;
pub mod scaling;
pub mod scene;
pub mod shade;
pub mod stats;
pub mod surface;
pub mod tradeoff;
pub mod vertex;
pub mod views;
pub mod world;

pub use camera::Camera;
pub use error::{Error, Result};
pub use render::{Image, RenderOptions, RenderStats, Session};
pub use scene::Scene;
pub use stats::Passes;

/// The README's code blocks, compiled and run by `cargo test --doc`.
#[doc = include_str!("../README.md")]
#[cfg(doctest)]
pub struct ReadmeDoctests;
