//! Ctrl-C: a request to stop that long-running loops check between waves,
//! so that a render stops cleanly (no output, no temporary file) instead of
//! dying wherever the signal lands.

use std::sync::atomic::{AtomicBool, Ordering};

/// Set once an interrupt was asked for.
static REQUESTED: AtomicBool = AtomicBool::new(false);

/// The error a loop returns when it stopped because of an interrupt.
#[derive(Debug, thiserror::Error)]
#[error("interrupted; nothing was written")]
pub struct Interrupted;

/// Asks every loop that checks [`check`] to stop. Returns whether an
/// interrupt had already been asked for.
pub fn request() -> bool {
    REQUESTED.swap(true, Ordering::SeqCst)
}

/// `Err(Interrupted)` once an interrupt was asked for.
pub fn check() -> Result<(), Interrupted> {
    if REQUESTED.load(Ordering::SeqCst) {
        Err(Interrupted)
    } else {
        Ok(())
    }
}
