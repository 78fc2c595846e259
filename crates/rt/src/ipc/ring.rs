//! Wait-free single-producer single-consumer ring for data between real-time tasks.
//!
//! A ring is not a trigger: it never makes a system call, so it cannot wake anybody. The
//! consumer polls it every period (the pipeline rule of SEEDS.md: a stage gives up its turn
//! when its input is empty or its output has no room).

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
    pub fn push(&mut self, value: T) -> Result<(), T> {
        self.inner.push(value).map_err(|rtrb::PushError::Full(v)| v)
    }

    /// Free slots now.
    pub fn slots(&self) -> usize {
        self.inner.slots()
    }

    /// True when there is no room.
    pub fn is_full(&self) -> bool {
        self.inner.is_full()
    }

    /// The ring's name.
    pub fn name(&self) -> &str {
        &self.name
    }
}

impl<T> RingConsumer<T> {
    /// The oldest item, or `None` when empty.
    pub fn pop(&mut self) -> Option<T> {
        self.inner.pop().ok()
    }

    /// Hands every item waiting now to `f`, oldest first, by reference, then removes them
    /// (no copy out of the ring, which counts for large items); returns how many.
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
    pub fn peek(&self) -> Option<&T> {
        self.inner.peek().ok()
    }

    /// Items waiting now.
    pub fn len(&self) -> usize {
        self.inner.slots()
    }

    /// True when nothing waits.
    pub fn is_empty(&self) -> bool {
        self.inner.is_empty()
    }

    /// The ring's name.
    pub fn name(&self) -> &str {
        &self.name
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
}
