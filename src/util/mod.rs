//! Small leaf modules that every layer may use: they import nothing else of
//! the crate.

pub mod color;
pub mod dirs;
pub mod interrupt;
pub mod metrics;
pub mod text;
