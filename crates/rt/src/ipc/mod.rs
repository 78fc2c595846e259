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

use std::mem::MaybeUninit;

use thiserror::Error;

/// The optimistic copy of a slot another thread may be writing (a seqlock's reader):
/// volatile reads, kept only when the caller's check proves no store overlapped them. A
/// value made of whole 8-byte words is read word by word straight into `dst`; one
/// volatile read of the whole value would go through a temporary and copy it twice.
///
/// # Safety
/// `src` is valid for reads and `dst` for writes of a `T`, both aligned, not overlapping.
///
/// Real-time: yes (no allocation, no blocking).
#[inline]
pub(crate) unsafe fn volatile_copy<T>(src: *const MaybeUninit<T>, dst: *mut MaybeUninit<T>) {
    const WORD: usize = std::mem::size_of::<u64>();
    if std::mem::size_of::<T>() % WORD == 0 && std::mem::align_of::<T>() >= WORD {
        // Words of `MaybeUninit`: padding bytes are copied as they are, never read as
        // integers.
        let (src, dst) = (
            src.cast::<MaybeUninit<u64>>(),
            dst.cast::<MaybeUninit<u64>>(),
        );
        for i in 0..std::mem::size_of::<T>() / WORD {
            // SAFETY: word `i` lies inside both values (the size is a whole number of
            // words), and both are aligned for `u64` (their alignment is at least 8).
            unsafe { dst.add(i).write(std::ptr::read_volatile(src.add(i))) };
        }
    } else {
        // SAFETY: the caller's promise.
        unsafe { dst.write(std::ptr::read_volatile(src)) };
    }
}

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

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, Clone, Copy, PartialEq)]
    struct Words {
        position: [f64; 5],
        count: u64,
        flags: u32,
        on: bool,
    }

    #[test]
    fn a_volatile_copy_gives_the_value_whole() {
        // 53 bytes padded to 56, aligned to 8: word by word.
        let words = Words {
            position: [1.5, -2.0, 3.25, f64::MAX, -0.0],
            count: u64::MAX - 7,
            flags: 0xDEAD_BEEF,
            on: true,
        };
        let src = MaybeUninit::new(words);
        let mut dst = MaybeUninit::<Words>::uninit();
        // SAFETY: two distinct, aligned values of the type.
        unsafe { volatile_copy(&src, &mut dst) };
        // SAFETY: the copy above wrote a whole value.
        assert_eq!(unsafe { dst.assume_init() }, words);
        // Neither a whole number of words nor 8-aligned: one volatile read.
        let bytes: [u8; 13] = std::array::from_fn(|i| i as u8 * 19);
        let src = MaybeUninit::new(bytes);
        let mut dst = MaybeUninit::<[u8; 13]>::uninit();
        // SAFETY: as above.
        unsafe { volatile_copy(&src, &mut dst) };
        // SAFETY: as above.
        assert_eq!(unsafe { dst.assume_init() }, bytes);
    }
}
