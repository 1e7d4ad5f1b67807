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
//! raster → shade. `docs/explanation/architecture.md` describes the stages.

#![warn(missing_docs)]

pub mod camera;
pub mod check;
pub mod clipmap;
pub mod cpu;
pub mod error;
pub mod export;
pub mod frame;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod lod;
pub(crate) mod names;
pub mod pack;
pub mod pyramid;
pub mod raster;
pub mod render;
pub mod scene;
pub(crate) mod shade;
pub mod shard;
pub mod studies;
pub mod synthesis;
pub mod terrain;

pub use camera::Camera;
pub use error::{Error, Result};
pub use frame::stats::Passes;
pub use render::{Image, RenderOptions, RenderStats, Session};
pub use scene::Scene;

/// The README's code blocks, compiled and run by `cargo test --doc`.
#[doc = include_str!("../README.md")]
#[cfg(doctest)]
pub struct ReadmeDoctests;
