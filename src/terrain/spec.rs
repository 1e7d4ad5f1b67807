//! What a scene's `[terrain]` table says: the map (a file or a procedural
//! one), its cell size and placement, and the levels synthesised below it.
//! The scene composes it into its schema; the terrain, pyramid and pack
//! stages read it.

use super::procedural::Procedural;
use serde::Deserialize;
use std::path::PathBuf;

/// A cell size: one value for square cells, or `[x, y]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(untagged)]
pub enum CellSize {
    /// Square cells, metres per side.
    Square(f64),
    /// Metres across (x) and down (y).
    Xy([f64; 2]),
}

/// A scene's `[terrain]`: a heightmap file or a procedural map, and its placement.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Spec {
    /// Heightmap file, relative to the scene file.
    pub file: Option<PathBuf>,
    /// A seeded procedural map instead of a file.
    pub procedural: Option<Procedural>,
    /// Overrides the file's cell size (metres).
    pub cell_size: Option<CellSize>,
    /// The CRS of a map whose file names none, as `EPSG:<code>`: a
    /// geographic one (4326, 4269, 4258, 4283, 4617) converts its degrees
    /// to metres (`terrain::crs`).
    pub crs: Option<String>,
    /// The variable of a netCDF file that holds the map, where its CF
    /// `standard_name`s do not single one out (`terrain::netcdf`).
    pub variable: Option<String>,
    /// Metres per height unit of the map (default 1).
    #[serde(default = "one")]
    pub vertical_scale: f64,
    /// World (x, y) of the map's north-west corner (metres); cameras are
    /// given in the same world coordinates.
    #[serde(default)]
    pub origin: [f64; 2],
    /// Levels finer than the map, synthesised (LH04; docs/explanation/synthesis.md).
    #[serde(default)]
    pub synthesis: Option<SynthesisSpec>,
}

fn one() -> f64 {
    1.0
}

impl CellSize {
    /// The (x, y) cell size, metres.
    pub fn pair(&self) -> [f64; 2] {
        match *self {
            CellSize::Square(s) => [s, s],
            CellSize::Xy(xy) => xy,
        }
    }
}

/// What `[terrain] synthesis = { levels, roughness, seed }` asks for; the
/// synthesis stage checks it (`synthesis::source::validate`) and makes the
/// levels. It is data here so that the terrain's spec needs nothing above
/// this stage.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SynthesisSpec {
    /// Levels added, 1..=`synthesis::source::MAX_LEVELS`.
    pub levels: usize,
    /// The roughness exponent H; measured from the map when `None`.
    #[serde(default)]
    pub roughness: Option<f64>,
    /// The noise table's seed (default 0).
    #[serde(default)]
    pub seed: u64,
}
