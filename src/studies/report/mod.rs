//! Reports: charts (SVG and PNG) of measured series, and the text they and
//! the diagrams are labelled with.

pub mod chart;
pub mod text;
