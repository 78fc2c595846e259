//! Wait-free single-producer single-consumer ring for data between real-time tasks.
//!
//! A ring is not a trigger: it never makes a system call, so it cannot wake anybody. The
//! consumer polls it every period (the pipeline rule of SEEDS.md: a stage gives up its turn
//! when its input is empty or its output has no room).

use std::cell::UnsafeCell;
use std::mem::MaybeUninit;
use std::sync::atomic::{AtomicU64, Ordering};

use crate::error::ConfigError;

/// The writing end of a ring.
pub struct RingProducer<T> {
    inner: rtrb::Producer<T>,
    name: std::sync::Arc<str>,
}

/// The reading end of a ring.
pub struct RingConsumer<T> {
    inner: rtrb::Consumer<T>,
    name: std::sync::Arc<str>,
}

/// A ring called `name` with room for `capacity` items, split into its two ends.
///
/// Real-time: no (set-up: allocates).
pub fn ring<T>(
    name: &str,
    capacity: usize,
) -> Result<(RingProducer<T>, RingConsumer<T>), ConfigError> {
    if capacity == 0 {
        return Err(ConfigError::ZeroCapacity {
            channel: name.to_string(),
        });
    }
    let (p, c) = rtrb::RingBuffer::new(capacity);
    let name: std::sync::Arc<str> = name.into();
    Ok((
        RingProducer {
            inner: p,
            name: name.clone(),
        },
        RingConsumer { inner: c, name },
    ))
}

impl<T> RingProducer<T> {
    /// Appends `value`, or hands it back when the ring is full.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn push(&mut self, value: T) -> Result<(), T> {
        self.inner.push(value).map_err(|rtrb::PushError::Full(v)| v)
    }

    /// Free slots now.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn slots(&self) -> usize {
        self.inner.slots()
    }

    /// True when there is no room.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn is_full(&self) -> bool {
        self.inner.is_full()
    }

    /// The ring's name.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn name(&self) -> &str {
        &self.name
    }
}

impl<T> RingConsumer<T> {
    /// The oldest item, or `None` when empty.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn pop(&mut self) -> Option<T> {
        self.inner.pop().ok()
    }

    /// Hands every item waiting now to `f`, oldest first, by reference, then removes them
    /// (no copy out of the ring, which counts for large items); returns how many.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn drain_with(&mut self, mut f: impl FnMut(&T)) -> usize {
        let n = self.inner.slots();
        let Ok(chunk) = self.inner.read_chunk(n) else {
            return 0;
        };
        let (first, second) = chunk.as_slices();
        first.iter().chain(second).for_each(&mut f);
        chunk.commit_all();
        n
    }

    /// The oldest item without removing it.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn peek(&self) -> Option<&T> {
        self.inner.peek().ok()
    }

    /// Items waiting now.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn len(&self) -> usize {
        self.inner.slots()
    }

    /// True when nothing waits.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn is_empty(&self) -> bool {
        self.inner.is_empty()
    }

    /// The ring's name.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn name(&self) -> &str {
        &self.name
    }
}

/// The same single-producer single-consumer ring, in place: `#[repr(C)]`, a fixed capacity
/// `N` and no pointers, so it can live in memory shared between processes (mapped at a
/// different address in each). Positions are free-running 64-bit counters (slot = position
/// mod `N`), so both sides can check each other: a consumer never reads past what the
/// producer published, and a producer treats counters that make no sense (left by a
/// process that died or by a corrupted mapping) as a full ring rather than overwriting.
///
/// The one-producer, one-consumer rule is the caller's: [`push`](Self::push) and
/// [`pop`](Self::pop) are `unsafe`. In memory another process writes, `T` must be plain data
/// for which every bit pattern is a value.
#[repr(C)]
pub struct SpscCell<T, const N: usize> {
    /// Next position to write (written by the producer only).
    head: AtomicU64,
    _pad0: [u64; 7],
    /// Next position to read (written by the consumer only).
    tail: AtomicU64,
    _pad1: [u64; 7],
    slots: [UnsafeCell<MaybeUninit<T>>; N],
}

// SAFETY: a slot is written by the producer only while it is outside [tail, head) and read by
// the consumer only while inside, the counters published with release/acquire ordering.
unsafe impl<T: Copy + Send, const N: usize> Sync for SpscCell<T, N> {}

impl<T: Copy, const N: usize> SpscCell<T, N> {
    /// Capacity in items.
    pub const CAPACITY: usize = N;

    /// Makes an empty ring at `cell`, whatever the memory held before (a fresh shared
    /// mapping). The slots are left as they are.
    ///
    /// # Safety
    /// `cell` is valid for writes and aligned, and nobody else uses the memory meanwhile.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub unsafe fn init_at(cell: *mut Self) {
        // SAFETY: the caller's promise; only the counters are written.
        unsafe {
            std::ptr::addr_of_mut!((*cell).head).write(AtomicU64::new(0));
            std::ptr::addr_of_mut!((*cell).tail).write(AtomicU64::new(0));
        }
    }

    /// Appends `value`, or hands it back when the ring is full.
    ///
    /// # Safety
    /// Only one thread, in one process, pushes into a ring.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub unsafe fn push(&self, value: T) -> Result<(), T> {
        let head = self.head.load(Ordering::Relaxed);
        let tail = self.tail.load(Ordering::Acquire);
        // A tail ahead of the head, or lagging by more than N, cannot come from a sound
        // consumer: refuse rather than overwrite what a reader may be copying.
        if N == 0 || head.wrapping_sub(tail) >= N as u64 {
            return Err(value);
        }
        let slot = self.slots[(head % N as u64) as usize].get();
        // SAFETY: the slot is outside [tail, head): the consumer does not read it.
        unsafe { std::ptr::write_volatile(slot, MaybeUninit::new(value)) };
        self.head.store(head.wrapping_add(1), Ordering::Release);
        Ok(())
    }

    /// The oldest item, or `None` when empty.
    ///
    /// # Safety
    /// Only one thread, in one process, pops from a ring.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub unsafe fn pop(&self) -> Option<T> {
        let tail = self.tail.load(Ordering::Relaxed);
        let head = self.head.load(Ordering::Acquire);
        let waiting = head.wrapping_sub(tail);
        if waiting == 0 || waiting > N as u64 {
            return None;
        }
        let slot = self.slots[(tail % N as u64) as usize].get();
        // SAFETY: the slot is inside [tail, head): written and published by the producer,
        // which does not touch it until the tail moves past it.
        let value = unsafe { std::ptr::read_volatile(slot).assume_init() };
        self.tail.store(tail.wrapping_add(1), Ordering::Release);
        Some(value)
    }

    /// Items waiting now (as either side sees it; 0 for counters that make no sense).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn len(&self) -> usize {
        let waiting = self
            .head
            .load(Ordering::Acquire)
            .wrapping_sub(self.tail.load(Ordering::Acquire));
        if waiting > N as u64 {
            0
        } else {
            waiting as usize
        }
    }

    /// True when nothing waits.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Items pushed so far (the producer's position).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn pushed(&self) -> u64 {
        self.head.load(Ordering::Acquire)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn drain_with_hands_over_every_waiting_item_in_order_across_the_wrap() {
        let (mut tx, mut rx) = ring::<u32>("samples", 4).unwrap();
        for v in [1, 2, 3] {
            tx.push(v).unwrap();
        }
        assert_eq!(rx.pop(), Some(1));
        for v in [4, 5] {
            tx.push(v).unwrap(); // 5 lands in the slot after the end: the items wrap
        }
        let mut seen = Vec::new();
        assert_eq!(rx.drain_with(|&v| seen.push(v)), 4);
        assert_eq!(seen, [2, 3, 4, 5]);
        assert!(rx.is_empty());
        assert_eq!(rx.drain_with(|_| panic!("nothing waits")), 0);
    }

    #[test]
    fn the_in_place_ring_works_in_foreign_memory_across_threads_and_wraps() {
        type Cell = SpscCell<[u64; 4], 8>;
        // A zeroed buffer standing in for a fresh shared mapping.
        let layout = std::alloc::Layout::new::<Cell>();
        // SAFETY: a non-zero-sized layout.
        let raw = unsafe { std::alloc::alloc_zeroed(layout) }.cast::<Cell>();
        assert!(!raw.is_null());
        // SAFETY: fresh, aligned, ours alone.
        unsafe { Cell::init_at(raw) };
        // SAFETY: initialised above and freed only after both threads ended.
        let cell: &'static Cell = unsafe { &*raw };
        const ITEMS: u64 = 100_000;
        let producer = std::thread::spawn(move || {
            let mut i = 0;
            while i < ITEMS {
                // SAFETY: the only producer.
                if unsafe { cell.push([i; 4]) }.is_ok() {
                    i += 1;
                }
            }
        });
        let mut next = 0;
        while next < ITEMS {
            // SAFETY: the only consumer.
            if let Some(v) = unsafe { cell.pop() } {
                assert_eq!(v, [next; 4], "items arrive whole and in order");
                next += 1;
            }
        }
        producer.join().unwrap();
        assert!(cell.is_empty());
        assert_eq!(cell.pushed(), ITEMS);
        // SAFETY: allocated above with this layout; no reference is used after this.
        unsafe { std::alloc::dealloc(raw.cast(), layout) };
    }

    #[test]
    fn the_in_place_ring_refuses_when_full_and_distrusts_impossible_counters() {
        let cell = Box::new(SpscCell::<u32, 2> {
            head: AtomicU64::new(0),
            _pad0: [0; 7],
            tail: AtomicU64::new(0),
            _pad1: [0; 7],
            slots: [const { UnsafeCell::new(MaybeUninit::uninit()) }; 2],
        });
        // SAFETY: single-threaded test: one producer, one consumer.
        unsafe {
            assert_eq!(cell.push(1), Ok(()));
            assert_eq!(cell.push(2), Ok(()));
            assert_eq!(cell.push(3), Err(3), "full at its capacity");
            assert_eq!(cell.pop(), Some(1));
            assert_eq!(cell.push(3), Ok(()));
            assert_eq!(
                (cell.pop(), cell.pop(), cell.pop()),
                (Some(2), Some(3), None)
            );
            // A consumer that died with a corrupted tail ahead of the head.
            cell.tail.store(10, Ordering::Relaxed);
            assert_eq!(cell.push(4), Err(4));
            assert_eq!(cell.pop(), None);
            assert_eq!(cell.len(), 0);
        }
    }
}
