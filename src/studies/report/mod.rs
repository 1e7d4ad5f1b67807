//! Reports: charts (SVG and PNG) of measured series.

pub mod chart;
mod font;
