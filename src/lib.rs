//! # terraclip
//!
//! A CPU reference implementation of geometry-clipmap terrain rendering
//! (Losasso & Hoppe 2004; GPU Gems 2 ch. 2; Holkner; Brettell).
//!
//! ## Usage
//! Load a [`heightmap::Heightmap`], build a [`pyramid::Pyramid`], create a
//! [`clipmap::Clipmap`], call [`clipmap::Clipmap::update`] with the viewer and
//! [`clipmap::Clipmap::meshes`] for the frame's geometry.
//!
//! ## Implementation
//! Data flows one way: scene → heightmap → pyramid → LOD scheme → frame.
//! See `README.md` for the pipeline and the CLI.

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

pub use error::{Error, Result};
