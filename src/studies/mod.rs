//! Studies that run the pipeline to measure it: accuracy against time
//! (`tradeoff`), growth with terrain size (`scaling`), crack surveys
//! (`cracks`), flights (`fly`), the GPU back end as a second renderer
//! (`gpu_side`), the view sets they share (`views`), their
//! image metrics (`metrics`), the clipmap diagram and the charts (`report`),
//! and the joining of a sharded sweep's parts (`merge`).

pub mod cracks;
pub mod diagram;
pub mod fly;
pub mod gpu_side;
pub mod merge;
pub mod metrics;
pub(crate) mod report;
/// Scatter charts with a Pareto front, which the benches draw too.
pub use report::chart;
pub mod scaling;
/// A sweep's parts: the studies take a [`shard::Shard`]; the type sits below
/// every stage that is sharded.
pub use crate::shard;
pub mod synthesis;
pub mod tradeoff;
pub mod views;
