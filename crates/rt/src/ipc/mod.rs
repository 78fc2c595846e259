//! Communication between tasks, with the semantics of SEEDS.md: bounded mailboxes,
//! binary / counting / event semaphores, a priority-inheritance mutex, a wait-free
//! single-producer single-consumer ring, a wait-free latest-value cell (triple buffer), a
//! single-writer many-reader snapshot (seqlock) and a lead queue (values computed ahead of
//! the period they are for, replaceable until taken).
//!
//! Every object works the same under both schedulers. Non-blocking calls (`try_*`, `put_front`,
//! `peek`, `clear`, `signal`, `set`, `pulse`) are what task bodies use; a task that must wait
//! returns [`crate::Next::WaitFor`] with the object's [`Trigger`]. Blocking calls (`put`,
//! `get`, `*_timeout`, `wait`) are for threads outside the task set (an HMI, a test) and time
//! out on the OS monotonic clock; called from inside a task body they are refused with
//! [`IpcError::BlockingInTask`] under either scheduler, so the mistake shows the same way in
//! simulation and on the machine.

mod latest;
mod lead;
mod mailbox;
mod pimutex;
mod ring;
mod semaphore;
mod seqlock;
mod trigger;

pub use latest::{LatestReader, LatestWriter, latest};
pub use lead::{LeadConsumer, LeadProducer, Missing, lead_queue};
pub use mailbox::Mailbox;
pub use pimutex::{PiMutex, PiMutexGuard};
pub use ring::{RingConsumer, RingProducer, SpscCell, ring};
pub use semaphore::{BinarySemaphore, CountingSemaphore, EventSemaphore};
pub use seqlock::{
    SLOTS as SEQLOCK_SLOTS, SeqlockCell, SeqlockCopy, SeqlockReader, SeqlockWriter, seqlock,
};
pub use trigger::Trigger;
pub(crate) use trigger::WaitResult;

use thiserror::Error;

/// Why an IPC call did not do what it was asked.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Error)]
pub enum IpcError {
    /// No room (mailbox full, ring full).
    #[error("channel is full")]
    Full,
    /// Nothing to take.
    #[error("channel is empty")]
    Empty,
    /// The timeout passed first.
    #[error("timed out")]
    Timeout,
    /// A blocking call from inside a task body; tasks wait by returning `Next::WaitFor`.
    #[error("blocking call from inside a task body; return Next::WaitFor instead")]
    BlockingInTask,
    /// A counting semaphore is already at its maximum count.
    #[error("semaphore is at its maximum count")]
    AtMaximum,
}

impl IpcError {
    /// Stable error code.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn code(&self) -> &'static str {
        match self {
            IpcError::Full => "full",
            IpcError::Empty => "empty",
            IpcError::Timeout => "timeout",
            IpcError::BlockingInTask => "blocking_in_task",
            IpcError::AtMaximum => "at_maximum",
        }
    }
}

/// A put that did not happen: the reason and the message, handed back to the caller.
#[derive(Debug, PartialEq, Eq)]
pub struct Rejected<T> {
    /// Why.
    pub reason: IpcError,
    /// The message that was not delivered.
    pub value: T,
}

impl<T> Rejected<T> {
    pub(crate) fn new(reason: IpcError, value: T) -> Self {
        Rejected { reason, value }
    }
}
