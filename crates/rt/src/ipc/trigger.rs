//! Triggers: what an event task (or a task waiting with a timeout) waits for.

use std::fmt;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use crate::sys::{PiLock, monotonic_ns};

/// How long a waiting thread sleeps at most before looking at its stop flag again.
const STOP_POLL_NS: u64 = 20_000_000;

/// Outcome of a wait.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum WaitResult {
    Ready,
    TimedOut,
    Stopped,
}

/// Waits under `lock` until `ready` (called with the state locked; it may also take what it
/// waited for) returns true, the absolute monotonic deadline passes, or `stop` is raised.
pub(crate) fn wait_on<S>(
    lock: &PiLock<S>,
    deadline_mono_ns: Option<u64>,
    stop: Option<&AtomicBool>,
    mut ready: impl FnMut(&mut S) -> bool,
) -> WaitResult {
    let mut guard = lock.lock();
    loop {
        if ready(&mut guard) {
            return WaitResult::Ready;
        }
        if stop.is_some_and(|s| s.load(Ordering::Acquire)) {
            return WaitResult::Stopped;
        }
        let now = monotonic_ns();
        if deadline_mono_ns.is_some_and(|d| now >= d) {
            return WaitResult::TimedOut;
        }
        let mut until = deadline_mono_ns.unwrap_or(u64::MAX);
        if stop.is_some() {
            until = until.min(now + STOP_POLL_NS);
        }
        // Far-future deadlines are capped so the timespec stays in range.
        until = until.min(now + 3_600_000_000_000);
        guard.wait_until(until);
    }
}

/// The executive's view of something a task can wait for.
pub(crate) trait TriggerSource: Send + Sync {
    fn name(&self) -> &str;
    /// A token for "now": edge-triggered sources (event semaphores) fire only after it.
    fn arm(&self) -> u64;
    /// Whether the trigger has fired since `token`.
    fn is_ready(&self, token: u64) -> bool;
    /// Takes the trigger (a binary or counting semaphore's count) if it is still ready.
    fn try_take(&self, token: u64) -> bool;
    /// Blocks until ready (without taking), the deadline or the stop flag.
    fn wait_ready(
        &self,
        token: u64,
        deadline_mono_ns: Option<u64>,
        stop: &AtomicBool,
    ) -> WaitResult;
}

/// Something a task can wait for: a mailbox receiving data or getting room, or a semaphore
/// being signalled. Cheap to clone (one reference count).
///
/// Semantics when used as a trigger: a mailbox fires while it holds data ([`crate::Mailbox::data_trigger`])
/// or has room ([`crate::Mailbox::space_trigger`]) and is not consumed by the wake-up (the task
/// takes the message); a binary semaphore fires while signalled and the wake-up takes it; a
/// counting semaphore fires while its count is above zero and the wake-up takes one; an event
/// semaphore fires on each `set` or `pulse` after the task started waiting (edge-triggered, so
/// a set that stays set does not re-run the task).
#[derive(Clone)]
pub struct Trigger {
    pub(crate) source: Arc<dyn TriggerSource>,
}

impl Trigger {
    pub(crate) fn new(source: Arc<dyn TriggerSource>) -> Self {
        Trigger { source }
    }

    /// The name of the channel or semaphore behind the trigger.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn name(&self) -> &str {
        self.source.name()
    }
}

impl fmt::Debug for Trigger {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Trigger({})", self.name())
    }
}
