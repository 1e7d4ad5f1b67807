//! Terrain packs: LH04's compressed residual pyramid, tiled so a clipmap
//! update can decode only what it uncovers. [`codec`] predicts, quantises
//! and entropy-codes (`predict` and `fitted` make its predictions, `fast`
//! is the fast coder's tile); [`model`] is the family of entropy models it
//! codes with; [`file`](mod@file) is the `.tcz` file.

pub mod codec;
mod fast;
pub mod file;
mod fitted;
pub mod model;
mod predict;
pub mod reader;
pub mod stream;

pub use codec::{Coder, Lattice, Packed, PackedLevel, Predictor, Quant, Tile, TileError};
