//! Single-writer, many-reader snapshot of plain data (a seqlock over a few slots): one task
//! publishes a state image every cycle (the feedback image, the status), any number of
//! tasks and outside threads read the newest one. Neither side takes a lock or makes a
//! system call.
//!
//! The value lives in [`SLOTS`] slots used in turn. The writer fills the slot after the
//! newest one and only then makes it the newest, so a reader always finds a complete
//! newest slot, even when it preempted the writer in the middle of a write (a reader of
//! higher priority on the writer's processor must never wait for it, or it would wait
//! forever). A read fails only when the writer, running at the same time on another
//! processor, started `SLOTS` new values during the reader's copy; [`SeqlockReader::try_read`]
//! gives up after a few such attempts, so a real-time reader keeps its previous value
//! rather than looping.

use std::cell::UnsafeCell;
use std::mem::MaybeUninit;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering, fence};

/// Slots the writer cycles through: a read fails only when the writer laps them during it.
pub const SLOTS: usize = 4;
/// Attempts of one [`SeqlockReader::try_read`].
const ATTEMPTS: usize = 4;
/// The version of a slot being written (never a publication number).
const WRITING: u64 = u64::MAX;

#[repr(C)]
struct Slot<T> {
    /// The publication number the slot holds, or `WRITING`.
    version: AtomicU64,
    value: UnsafeCell<MaybeUninit<T>>,
}

/// The seqlock itself, in place: a publication counter and [`SLOTS`] slots, `#[repr(C)]`
/// and free of pointers, so it can live in memory shared between processes (a mapping at a
/// different address in each) as well as behind the [`SeqlockWriter`] / [`SeqlockReader`]
/// pair. The single-writer rule is the caller's: [`SeqlockCell::publish`] is `unsafe`.
///
/// In memory another process writes, `T` must be plain data for which every bit pattern is
/// a value (integers, floats, arrays of them): a reader keeps only copies the protocol
/// proves whole, but it cannot prove that the other side wrote a valid `T`.
#[repr(C)]
pub struct SeqlockCell<T> {
    /// Number of the newest publication; it lives in slot `published % SLOTS`.
    published: AtomicU64,
    slots: [Slot<T>; SLOTS],
}

// SAFETY: only the single writer stores into a slot, and only into one no reader may use
// (its version is `WRITING` meanwhile). Readers copy a slot optimistically and keep the copy
// only when the slot's version was the same, published number before and after the copy,
// i.e. when no store overlapped it (the protocol of a seqlock, as crossbeam's `AtomicCell`
// uses for values without a native atomic). `T: Copy` makes the copies plain bytes.
unsafe impl<T: Copy + Send> Sync for SeqlockCell<T> {}

impl<T: Copy> SeqlockCell<T> {
    /// A cell holding `initial` as publication 0.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn new(initial: T) -> Self {
        let slot = |version| Slot {
            version: AtomicU64::new(version),
            value: UnsafeCell::new(MaybeUninit::new(initial)),
        };
        SeqlockCell {
            published: AtomicU64::new(0),
            slots: [slot(0), slot(WRITING), slot(WRITING), slot(WRITING)],
        }
    }

    /// Writes a cell holding `initial` at `cell`, whatever the memory held before (a fresh
    /// shared mapping).
    ///
    /// # Safety
    /// `cell` is valid for writes and aligned, and nobody else uses the memory meanwhile.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub unsafe fn init_at(cell: *mut Self, initial: T) {
        // SAFETY: the caller's promise; `write` does not read the old bytes.
        unsafe { cell.write(SeqlockCell::new(initial)) };
    }

    /// Makes `value` the newest (wait-free: a few stores and one copy of `T`).
    ///
    /// # Safety
    /// Only one thread, in one process, publishes into a cell.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub unsafe fn publish(&self, value: T) {
        let next = self.begin();
        // SAFETY: the slot is marked `WRITING`, no reader keeps what it copies from it.
        unsafe { std::ptr::write_volatile(self.slot_value(next), MaybeUninit::new(value)) };
        self.commit(next);
    }

    /// Makes a copy of `*value` the newest, copied once, straight into its slot (a
    /// large value the writer keeps between publications is not copied twice).
    ///
    /// # Safety
    /// Only one thread, in one process, publishes into a cell.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub unsafe fn publish_ref(&self, value: &T) {
        let next = self.begin();
        // SAFETY: the slot is marked `WRITING`, no reader keeps what it copies from it;
        // `value` is a whole `T` and no part of the cell. The release in `commit` orders
        // the copy before the publication, as for `publish`.
        unsafe {
            std::ptr::copy_nonoverlapping(value as *const T, self.slot_value(next).cast::<T>(), 1)
        };
        self.commit(next);
    }

    /// The newest value as its writer sees it (no retry).
    ///
    /// # Safety
    /// Called by the cell's one writer (nobody stores meanwhile).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub unsafe fn writer_value(&self) -> T {
        let n = self.published.load(Ordering::Relaxed);
        // SAFETY: only the writer stores into slots, and not while this reads; the newest
        // slot is always initialised.
        unsafe { (*self.slot_value(n)).assume_init() }
    }

    /// The newest value, or `None` when the writer, running on another processor, replaced
    /// every slot during each of a few attempts (a real-time reader then keeps its previous
    /// value). Never waits.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn try_read(&self) -> Option<T> {
        let mut copy = MaybeUninit::uninit();
        // SAFETY: `try_read_into` returned true: `copy` holds a whole publication.
        self.try_read_into(&mut copy)
            .then(|| unsafe { copy.assume_init() })
    }

    /// [`try_read`](Self::try_read) straight into `dst`, in one copy: true when `dst` then
    /// holds the newest value whole; after false it holds bytes of no value.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn try_read_into(&self, dst: &mut MaybeUninit<T>) -> bool {
        for _ in 0..ATTEMPTS {
            let n = self.published.load(Ordering::Acquire);
            let slot = &self.slots[(n % SLOTS as u64) as usize];
            if slot.version.load(Ordering::Acquire) != n {
                continue;
            }
            // SAFETY: a possibly torn copy of plain bytes into a `MaybeUninit`, which may
            // hold any bytes; it counts only if the check below proves that no store
            // overlapped it.
            unsafe { super::volatile_copy(slot.value.get(), dst) };
            fence(Ordering::Acquire);
            if slot.version.load(Ordering::Relaxed) == n {
                return true;
            }
        }
        false
    }

    /// The newest value, trying until a read succeeds (for threads that may wait).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn read(&self) -> T {
        loop {
            if let Some(v) = self.try_read() {
                return v;
            }
            std::hint::spin_loop();
        }
    }

    /// Publications so far.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn version(&self) -> u64 {
        self.published.load(Ordering::Acquire)
    }

    fn slot_value(&self, n: u64) -> *mut MaybeUninit<T> {
        self.slots[(n % SLOTS as u64) as usize].value.get()
    }

    /// Marks the slot of the next publication as being written; returns its number.
    fn begin(&self) -> u64 {
        let next = self.published.load(Ordering::Relaxed) + 1;
        let slot = &self.slots[(next % SLOTS as u64) as usize];
        slot.version.store(WRITING, Ordering::Relaxed);
        // The mark is visible before any byte of the new value.
        fence(Ordering::Release);
        next
    }

    /// Makes publication `next` (written into its slot) the newest.
    fn commit(&self, next: u64) {
        let slot = &self.slots[(next % SLOTS as u64) as usize];
        slot.version.store(next, Ordering::Release);
        self.published.store(next, Ordering::Release);
    }
}

struct Shared<T> {
    name: String,
    cell: SeqlockCell<T>,
}

/// The publishing end (one per value; not `Clone`).
pub struct SeqlockWriter<T> {
    shared: Arc<Shared<T>>,
}

/// A reading end; clone it for every reader.
pub struct SeqlockReader<T> {
    shared: Arc<Shared<T>>,
}

impl<T> Clone for SeqlockReader<T> {
    fn clone(&self) -> Self {
        SeqlockReader {
            shared: Arc::clone(&self.shared),
        }
    }
}

/// A snapshot channel called `name`, holding `initial` until the first publication.
///
/// Real-time: no (set-up: allocates).
pub fn seqlock<T: Copy + Send>(name: &str, initial: T) -> (SeqlockWriter<T>, SeqlockReader<T>) {
    let shared = Arc::new(Shared {
        name: name.to_string(),
        cell: SeqlockCell::new(initial),
    });
    (
        SeqlockWriter {
            shared: Arc::clone(&shared),
        },
        SeqlockReader { shared },
    )
}

impl<T: Copy + Send> SeqlockWriter<T> {
    /// Makes `value` the newest (wait-free: a few stores and one copy of `T`).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn publish(&mut self, value: T) {
        // SAFETY: this writer is the cell's only one (not `Clone`, `&mut self`).
        unsafe { self.shared.cell.publish(value) }
    }

    /// Makes a copy of `*value` the newest, in one copy (see [`SeqlockCell::publish_ref`]).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn publish_ref(&mut self, value: &T) {
        // SAFETY: this writer is the cell's only one (not `Clone`, `&mut self`).
        unsafe { self.shared.cell.publish_ref(value) }
    }

    /// Publishes the newest value changed by `update` (the closure edits a copy of it).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn publish_with(&mut self, update: impl FnOnce(&mut T)) {
        let mut value = self.value();
        update(&mut value);
        self.publish(value);
    }

    /// The newest value (the writer's own, read without a retry).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn value(&self) -> T {
        // SAFETY: this is the cell's only writer.
        unsafe { self.shared.cell.writer_value() }
    }

    /// Publications so far.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn version(&self) -> u64 {
        self.shared.cell.published.load(Ordering::Relaxed)
    }

    /// The channel's name.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn name(&self) -> &str {
        &self.shared.name
    }

    /// A reader of this channel.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn reader(&self) -> SeqlockReader<T> {
        SeqlockReader {
            shared: Arc::clone(&self.shared),
        }
    }

    #[cfg(test)]
    fn slot_value(&self, n: u64) -> *mut MaybeUninit<T> {
        self.shared.cell.slot_value(n)
    }

    #[cfg(test)]
    fn begin(&mut self) -> u64 {
        self.shared.cell.begin()
    }

    #[cfg(test)]
    fn commit(&mut self, next: u64) {
        self.shared.cell.commit(next)
    }
}

impl<T: Copy + Send> SeqlockReader<T> {
    /// The newest value, or `None` when the writer, running on another processor, replaced
    /// every slot during each of a few attempts (a real-time reader then keeps its previous
    /// value). Never waits.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn try_read(&self) -> Option<T> {
        self.shared.cell.try_read()
    }

    /// Reads into `value` and returns true, or leaves it alone and returns false (see
    /// [`try_read`](Self::try_read)).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn read_into(&self, value: &mut T) -> bool {
        match self.try_read() {
            Some(v) => {
                *value = v;
                true
            }
            None => false,
        }
    }

    /// The newest value, trying until a read succeeds: for threads outside the task set
    /// (an HMI, a test), which may wait. A real-time task uses [`try_read`](Self::try_read).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn read(&self) -> T {
        self.shared.cell.read()
    }

    /// Publications so far (a cheap test for news).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn version(&self) -> u64 {
        self.shared.cell.version()
    }

    /// The channel's name.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn name(&self) -> &str {
        &self.shared.name
    }
}

/// A reader that keeps its own copy of the newest value (the feedback image a task reads
/// every period): [`get`](Self::get) copies from the seqlock only when there is a newer
/// publication, once, into the spare of two buffers, which becomes the copy when the read
/// succeeded (when it failed, the copy before stays, as with
/// [`SeqlockReader::read_into`]).
pub struct SeqlockCopy<T> {
    reader: SeqlockReader<T>,
    buffers: [MaybeUninit<T>; 2],
    /// The buffer that holds the copy (always a whole value).
    current: usize,
    /// The publication the copy is (at least).
    version: u64,
}

impl<T: Copy + Send> SeqlockCopy<T> {
    /// The copy of the newest value now.
    ///
    /// Real-time: no (set-up: waits for a first read).
    pub fn new(reader: SeqlockReader<T>) -> Self {
        let version = reader.version();
        let first = reader.read();
        SeqlockCopy {
            reader,
            buffers: [MaybeUninit::new(first), MaybeUninit::uninit()],
            current: 0,
            version,
        }
    }

    /// The newest value (never waits).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn get(&mut self) -> &T {
        let version = self.reader.version();
        if version != self.version {
            let spare = 1 - self.current;
            if self
                .reader
                .shared
                .cell
                .try_read_into(&mut self.buffers[spare])
            {
                self.current = spare;
                self.version = version;
            }
        }
        // SAFETY: `current` always names a buffer that holds a whole value: the first
        // read, or a read `try_read_into` proved whole.
        unsafe { self.buffers[self.current].assume_init_ref() }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_copy_follows_the_newest_value() {
        let (mut w, r) = seqlock("feedback", [1u64; 80]);
        let mut copy = SeqlockCopy::new(r);
        assert_eq!(*copy.get(), [1; 80]);
        for i in 2..=5u64 {
            w.publish([i; 80]);
            assert_eq!(*copy.get(), [i; 80]);
            assert_eq!(*copy.get(), [i; 80], "read again without a publication");
        }
    }

    #[test]
    fn a_value_published_by_reference_is_read_whole_through_every_slot() {
        let (mut w, r) = seqlock("status", [0u64; 120]);
        // More publications than slots, each value distinct in every element.
        for i in 1..=(3 * SLOTS as u64) {
            let value: [u64; 120] = std::array::from_fn(|k| i * 1000 + k as u64);
            w.publish_ref(&value);
            assert_eq!(r.read(), value);
            assert_eq!(w.value(), value);
            assert_eq!(r.version(), i);
        }
    }

    #[test]
    fn every_reader_sees_the_newest_value() {
        let (mut w, r) = seqlock("feedback", 7u32);
        let r2 = r.clone();
        assert_eq!(r.read(), 7);
        assert_eq!(w.version(), 0);
        for i in 1..=10 {
            w.publish(i);
        }
        assert_eq!((r.read(), r2.read()), (10, 10));
        assert_eq!(r.version(), 10);
        w.publish_with(|v| *v += 5);
        assert_eq!(w.value(), 15);
        assert_eq!(r2.try_read(), Some(15));
    }

    #[test]
    fn a_reader_that_preempts_the_writer_mid_write_gets_the_previous_value_at_once() {
        let (mut w, r) = seqlock("status", (1u64, 1u64));
        w.publish((2, 2));
        // The writer is interrupted between marking its slot and publishing it.
        let next = w.begin();
        // SAFETY: test of the protocol: half a value in the slot being written.
        unsafe { (*w.slot_value(next)).as_mut_ptr().cast::<u64>().write(3) };
        assert_eq!(
            r.try_read(),
            Some((2, 2)),
            "the newest complete value, first try"
        );
        // SAFETY: as above, the rest of the value.
        unsafe {
            (*w.slot_value(next))
                .as_mut_ptr()
                .cast::<u64>()
                .add(1)
                .write(3)
        };
        w.commit(next);
        assert_eq!(r.try_read(), Some((3, 3)));
    }

    #[test]
    fn values_are_never_torn_across_threads() {
        let (mut w, r) = seqlock("pair", [0u64; 8]);
        let readers: Vec<_> = (0..2)
            .map(|_| {
                let r = r.clone();
                std::thread::spawn(move || {
                    let mut last = 0;
                    while last < 200_000 {
                        let v = r.read();
                        assert!(v.iter().all(|&x| x == v[0]), "torn value {v:?}");
                        assert!(v[0] >= last, "went back in time");
                        last = v[0];
                    }
                })
            })
            .collect();
        for i in 1..=200_000u64 {
            w.publish([i; 8]);
        }
        for t in readers {
            t.join().unwrap();
        }
    }
}
