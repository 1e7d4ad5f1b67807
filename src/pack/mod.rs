//! Terrain packs: LH04's compressed residual pyramid, tiled so a clipmap
//! update can decode only what it uncovers. [`codec`] predicts, quantises
//! and entropy-codes; [`model`] is the family of entropy models it codes
//! with; [`file`](mod@file) is the `.tcz` file.

pub mod codec;
pub mod file;
pub mod model;
mod predict;
pub mod reader;
pub mod stream;

pub use codec::{Lattice, Packed, PackedLevel, Predictor, Quant, Tile, TileError};
