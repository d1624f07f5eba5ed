//! A request to end a run early (Ctrl-C in `stairbench run`): the execution ends at the next
//! physics step and the loop after it, so the report is printed and recordings are closed
//! with their summary instead of being cut off.

use std::sync::atomic::{AtomicBool, Ordering};

static STOP: AtomicBool = AtomicBool::new(false);

/// Asks the running climb to stop.
pub fn request() {
    STOP.store(true, Ordering::Relaxed);
}

/// Whether a stop was asked for.
pub fn requested() -> bool {
    STOP.load(Ordering::Relaxed)
}
