//! Wait-free "latest value" (triple buffer): a real-time task publishes a state snapshot
//! every cycle, a reader (HMI, status task) takes the newest one whenever it looks. Neither
//! side ever waits for the other, and no value is torn.

use std::cell::UnsafeCell;
use std::sync::Arc;
use std::sync::atomic::{AtomicU8, Ordering};

/// Set in `Shared::middle` when the middle slot holds a value the reader has not taken.
const FRESH: u8 = 0b100;
const INDEX: u8 = 0b011;

struct Shared<T> {
    name: String,
    slots: [UnsafeCell<T>; 3],
    /// Index of the slot between writer and reader, plus the FRESH bit.
    middle: AtomicU8,
}

// SAFETY: each slot is used by one side at a time: the writer owns `back`, the reader owns
// `front`, and the middle slot changes hands only through the atomic swap (AcqRel), which
// also orders the data written into it.
unsafe impl<T: Send> Sync for Shared<T> {}

/// The publishing end (one per value).
pub struct LatestWriter<T> {
    shared: Arc<Shared<T>>,
    back: u8,
}

/// The reading end (one per value).
pub struct LatestReader<T> {
    shared: Arc<Shared<T>>,
    front: u8,
}

/// A latest-value channel called `name`, starting with `initial` on both ends.
///
/// Real-time: no (set-up: allocates).
pub fn latest<T: Clone + Send>(name: &str, initial: T) -> (LatestWriter<T>, LatestReader<T>) {
    let shared = Arc::new(Shared {
        name: name.to_string(),
        slots: [
            UnsafeCell::new(initial.clone()),
            UnsafeCell::new(initial.clone()),
            UnsafeCell::new(initial),
        ],
        middle: AtomicU8::new(1),
    });
    (
        LatestWriter {
            shared: Arc::clone(&shared),
            back: 0,
        },
        LatestReader { shared, front: 2 },
    )
}

impl<T: Send> LatestWriter<T> {
    /// Makes `value` the newest (wait-free; the value it replaces is dropped here, so give
    /// `T` no heap parts when publishing from a real-time task).
    ///
    /// Real-time: yes (wait-free; the value replaced is dropped here, so give `T` no heap parts).
    pub fn publish(&mut self, value: T) {
        if let Some(slot) = self.shared.slots.get(usize::from(self.back)) {
            // SAFETY: the writer owns the back slot.
            unsafe { *slot.get() = value };
        }
        let previous = self.shared.middle.swap(self.back | FRESH, Ordering::AcqRel);
        self.back = previous & INDEX;
    }

    /// Lets the writer update the value in place, then publishes it (wait-free).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn publish_with(&mut self, update: impl FnOnce(&mut T)) {
        if let Some(slot) = self.shared.slots.get(usize::from(self.back)) {
            // SAFETY: the writer owns the back slot.
            update(unsafe { &mut *slot.get() });
        }
        let previous = self.shared.middle.swap(self.back | FRESH, Ordering::AcqRel);
        self.back = previous & INDEX;
    }

    /// The channel's name.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn name(&self) -> &str {
        &self.shared.name
    }
}

impl<T: Send> LatestReader<T> {
    /// The newest published value (wait-free).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn read(&mut self) -> &T {
        self.refresh();
        self.current()
    }

    /// True when a value newer than the last read is waiting.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn has_news(&self) -> bool {
        self.shared.middle.load(Ordering::Acquire) & FRESH != 0
    }

    fn refresh(&mut self) {
        if self.has_news() {
            let previous = self.shared.middle.swap(self.front, Ordering::AcqRel);
            self.front = previous & INDEX;
        }
    }

    fn current(&self) -> &T {
        let slot = &self.shared.slots[usize::from(self.front & INDEX) % 3];
        // SAFETY: the reader owns the front slot until its next swap, which needs `&mut self`.
        unsafe { &*slot.get() }
    }

    /// The channel's name.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn name(&self) -> &str {
        &self.shared.name
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_reader_sees_the_newest_value_and_keeps_it_until_a_newer_one() {
        let (mut w, mut r) = latest("status", 0u32);
        assert_eq!(*r.read(), 0);
        assert!(!r.has_news());
        w.publish(1);
        w.publish(2);
        assert!(r.has_news());
        assert_eq!(*r.read(), 2, "older values are skipped");
        assert_eq!(*r.read(), 2, "no news: the same value");
        w.publish_with(|v| *v += 40); // updates the writer's slot, which held 1
        assert_eq!(*r.read(), 41);
    }

    #[test]
    fn values_are_never_torn_across_threads() {
        let (mut w, mut r) = latest("pair", (0u64, 0u64));
        let writer = std::thread::spawn(move || {
            for i in 1..=200_000u64 {
                w.publish((i, i.wrapping_mul(31)));
            }
        });
        let mut last = 0;
        while last < 200_000 {
            let (a, b) = *r.read();
            assert_eq!(b, a.wrapping_mul(31), "torn value");
            assert!(a >= last, "went back in time");
            last = a;
        }
        writer.join().unwrap();
    }
}
