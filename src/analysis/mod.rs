//! What lancer measures about images and renders: the per-pixel z-test,
//! the error figures and FLIP, the compare command, convergence studies and
//! their plots, and the benchmark suite.

pub mod bench;
pub mod compare;
pub mod converge;
pub mod metrics;
pub mod plot;
pub mod study;
pub mod ztest;

#[cfg(test)]
mod test_images;
