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
