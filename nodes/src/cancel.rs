//! Cooperative cancellation for long kernels.
//!
//! A run is cancelled by Ctrl-C, SIGTERM or the editor; the engine raises one flag. Nodes
//! check it between steps, but one kernel call can work for minutes (clustering with a
//! tiny radius is quadratic in frames), so such a kernel takes a [`Cancel`] and polls it
//! after each bounded piece of work (well under 100 ms on this project's machines), then
//! returns [`Cancelled`]. Polling is one relaxed atomic load.

use std::sync::atomic::{AtomicBool, Ordering};

/// A run's stop request as a kernel sees it.
#[derive(Debug, Clone, Copy)]
pub struct Cancel<'a>(Option<&'a AtomicBool>);

/// The kernel stopped early because its run was cancelled; its partial work is dropped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("cancelled")]
pub struct Cancelled;

impl Cancel<'static> {
    /// Never cancelled: for tests, benchmarks and callers outside a run.
    pub const NEVER: Cancel<'static> = Cancel(None);
}

impl<'a> Cancel<'a> {
    /// Cancelled once `flag` is set.
    pub fn on(flag: &'a AtomicBool) -> Self {
        Cancel(Some(flag))
    }

    /// `Err(Cancelled)` once the run has been cancelled.
    pub fn check(self) -> Result<(), Cancelled> {
        match self.0 {
            Some(flag) if flag.load(Ordering::Relaxed) => Err(Cancelled),
            _ => Ok(()),
        }
    }
}
