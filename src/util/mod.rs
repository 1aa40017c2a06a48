//! Small leaf modules that every layer may use: they import nothing else of
//! the crate.

pub mod color;
pub mod dirs;
pub mod exr_file;
pub mod interrupt;
pub mod metrics;
pub mod text;

/// The version and the git commit lancer was built from, e.g.
/// `0.1.0 (commit 1a2b3c4d5e6f)`; the commit reads `unknown commit` when the
/// build was not made in a git checkout (`build.rs` asks git).
pub const VERSION: &str = concat!(
    env!("CARGO_PKG_VERSION"),
    " (",
    env!("LANCER_GIT_COMMIT"),
    ")"
);
