//! A request to stop long work early (Ctrl-C in `stairbench run`, a regress timeout), owned
//! by whoever started the work and passed in: the sensor ends its sweep, the execution its
//! physics loop and the closed loop its cycle at the next point where stopping is clean, so
//! reports are printed and recordings closed with their summary instead of being cut off.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// A shared stop flag. Clones share the flag; [`Cancel::never`] is a token nobody cancels.
#[derive(Debug, Clone, Default)]
pub struct Cancel(Arc<AtomicBool>);

impl Cancel {
    /// A new token, not cancelled.
    pub fn new() -> Self {
        Self::default()
    }

    /// A token for work nobody will stop (tests, benches).
    pub fn never() -> Self {
        Self::default()
    }

    /// Asks the work holding a clone of this token to stop.
    pub fn cancel(&self) {
        self.0.store(true, Ordering::Relaxed);
    }

    /// Whether a stop was asked for.
    pub fn is_cancelled(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clones_share_the_flag_and_separate_tokens_do_not() {
        let a = Cancel::new();
        let b = a.clone();
        let other = Cancel::new();
        assert!(!b.is_cancelled());
        a.cancel();
        assert!(b.is_cancelled());
        assert!(!other.is_cancelled());
    }
}
