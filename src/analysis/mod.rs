//! What lancer measures about images and renders: metrics and the per-pixel
//! z-test, FLIP, the compare report, convergence studies and their plots,
//! and the benchmark suite.

pub mod bench;
pub mod compare;
pub mod converge;
pub mod plot;
pub mod study;
