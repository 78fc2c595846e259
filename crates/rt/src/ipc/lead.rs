//! A lead queue: values computed ahead of the period they are for, so that a producer which
//! stalls for a while does not leave its consumer without one, and which the producer can
//! still replace while the consumer has not taken them (an urgent change then acts at
//! once instead of after the lead).
//!
//! Each value carries the number of the period it is for. One producer writes numbers in
//! increasing order, up to a lead it chooses; one consumer takes, each period, the value of
//! that period's number and no other. [`LeadProducer::rewind`] reclaims every value not yet
//! taken from a given number on, and tells which number the producer must write next: the
//! consumer never takes a value that was reclaimed, and never takes one out of order.
//!
//! Neither side waits or makes a system call; both are wait-free (the producer's rewind
//! visits at most `capacity` slots). A slot's state lives in one atomic stamp, the period
//! number shifted left by two bits with the state in the low bits:
//!
//! - `READY`: written, not taken. The consumer takes it by a compare-and-swap to `TAKEN`;
//!   the producer reclaims it by a compare-and-swap to `WRITING`. Exactly one of the two
//!   wins, so a value is either taken or replaced, never both.
//! - `TAKEN`: the consumer has it; the slot is free for a number `capacity` later.
//! - `WRITING`: the producer is (re)writing it; the consumer finds nothing there this
//!   period.
//!
//! The consumer reads a value before its compare-and-swap and keeps it only when the swap
//! succeeds, i.e. when the stamp was still the same `READY` stamp: no write overlapped the
//! read (the protocol of a seqlock).

use std::cell::UnsafeCell;
use std::mem::MaybeUninit;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering, fence};

use crate::error::ConfigError;

const STATE_BITS: u32 = 2;
const STATE_MASK: u64 = (1 << STATE_BITS) - 1;
const EMPTY: u64 = 0;
const READY: u64 = 1;
const TAKEN: u64 = 2;
const WRITING: u64 = 3;
/// Period numbers must fit the stamp beside the state.
pub const MAX_NUMBER: u64 = u64::MAX >> STATE_BITS;

fn stamp(number: u64, state: u64) -> u64 {
    (number << STATE_BITS) | state
}

fn number_of(stamp: u64) -> u64 {
    stamp >> STATE_BITS
}

fn state_of(stamp: u64) -> u64 {
    stamp & STATE_MASK
}

struct Slot<T> {
    stamp: AtomicU64,
    value: UnsafeCell<MaybeUninit<T>>,
}

struct Shared<T> {
    name: String,
    slots: Box<[Slot<T>]>,
    /// The number the consumer will ask for next (it asks for each number once, in order).
    consumer_next: AtomicU64,
}

// SAFETY: a slot's value is written only by the producer, and only while the slot's stamp
// is `WRITING` (after winning the slot from `READY` or finding it `TAKEN`/`EMPTY`, states in
// which the consumer no longer reads it); the consumer copies a value optimistically and
// keeps the copy only when the stamp was the same `READY` stamp before the copy and at its
// compare-and-swap after it, i.e. when no write overlapped the copy. `T: Copy` makes the
// copies plain bytes.
unsafe impl<T: Copy + Send> Sync for Shared<T> {}

/// The writing end (one producer).
pub struct LeadProducer<T> {
    shared: Arc<Shared<T>>,
    /// The next number this producer writes.
    next: u64,
}

/// The taking end (one consumer).
pub struct LeadConsumer<T> {
    shared: Arc<Shared<T>>,
}

/// What a take found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Missing {
    /// The producer has not written this number yet (it fell behind by the whole lead).
    NotWritten,
    /// The producer is replacing this number right now (a rewind in progress).
    BeingReplaced,
}

/// A lead queue called `name` with room for `capacity` values ahead of the consumer, split
/// into its two ends. Both start at number `first`.
///
/// Real-time: no (set-up: allocates).
pub fn lead_queue<T: Copy + Send>(
    name: &str,
    capacity: usize,
    first: u64,
) -> Result<(LeadProducer<T>, LeadConsumer<T>), ConfigError> {
    if capacity == 0 {
        return Err(ConfigError::ZeroCapacity {
            channel: name.to_string(),
        });
    }
    let slots = (0..capacity)
        .map(|_| Slot {
            stamp: AtomicU64::new(stamp(0, EMPTY)),
            value: UnsafeCell::new(MaybeUninit::uninit()),
        })
        .collect();
    let shared = Arc::new(Shared {
        name: name.to_string(),
        slots,
        consumer_next: AtomicU64::new(first),
    });
    Ok((
        LeadProducer {
            shared: Arc::clone(&shared),
            next: first,
        },
        LeadConsumer { shared },
    ))
}

impl<T> Shared<T> {
    fn slot(&self, number: u64) -> &Slot<T> {
        &self.slots[(number % self.slots.len() as u64) as usize]
    }
}

impl<T: Copy + Send> LeadProducer<T> {
    /// The number the next [`push`](Self::push) writes.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn next_number(&self) -> u64 {
        self.next
    }

    /// The number the consumer asks for next: every number below it is taken or passed.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn consumer_next(&self) -> u64 {
        self.shared.consumer_next.load(Ordering::Acquire)
    }

    /// Values written ahead of the consumer now (0 when it has caught up, or passed numbers
    /// the producer never wrote).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn lead(&self) -> u64 {
        self.next.saturating_sub(self.consumer_next())
    }

    /// Capacity of the queue.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn capacity(&self) -> usize {
        self.shared.slots.len()
    }

    /// The queue's name.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn name(&self) -> &str {
        &self.shared.name
    }

    /// Writes `value` for the next number; returns that number, or hands `value` back when
    /// its slot still holds a value the consumer has not taken (the queue is full: the
    /// producer is a whole capacity ahead).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn push(&mut self, value: T) -> Result<u64, T> {
        let number = self.next;
        if number > MAX_NUMBER {
            return Err(value);
        }
        let slot = self.shared.slot(number);
        let old = slot.stamp.load(Ordering::Acquire);
        // A `READY` value the consumer has not reached yet is one it may still take; one it
        // has passed without taking (the producer was late for it) is garbage. Should the
        // consumer be taking it right now, its compare-and-swap fails on the new stamp.
        if state_of(old) == READY && number_of(old) >= self.consumer_next() {
            return Err(value);
        }
        slot.stamp.store(stamp(number, WRITING), Ordering::Relaxed);
        // The mark is visible before any byte of the new value.
        fence(Ordering::Release);
        // SAFETY: the slot is `WRITING`; the consumer keeps no copy it makes from it. One
        // copy into the slot (a volatile store of a large value goes through a temporary);
        // the release store below orders it before the `READY` mark.
        unsafe { std::ptr::copy_nonoverlapping(&value, slot.value.get().cast::<T>(), 1) };
        slot.stamp.store(stamp(number, READY), Ordering::Release);
        self.next = number + 1;
        Ok(number)
    }

    /// Moves the producer past the numbers the consumer has already passed without a
    /// value (the producer fell a whole lead behind); returns how many it skipped.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn catch_up(&mut self) -> u64 {
        let consumer = self.consumer_next();
        let skipped = consumer.saturating_sub(self.next);
        self.next = self.next.max(consumer);
        skipped
    }

    /// Reclaims every value from number `from` on that the consumer has not taken, and
    /// returns the number to write next (the producer's `next_number` afterwards): `from`
    /// when the consumer has taken nothing from `from` on, else one past the last value it
    /// took. Values below the returned number are the consumer's; the reclaimed ones will
    /// never be taken. Wait-free: one compare-and-swap per value written ahead.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn rewind(&mut self, from: u64) -> u64 {
        let start = from.min(self.next);
        let mut first_free = start;
        for number in start..self.next {
            let slot = self.shared.slot(number);
            let ready = stamp(number, READY);
            let reclaimed = slot
                .stamp
                .compare_exchange(
                    ready,
                    stamp(number, WRITING),
                    Ordering::AcqRel,
                    Ordering::Acquire,
                )
                .is_ok();
            if !reclaimed {
                // Taken by the consumer (it takes in order, so everything before it is its
                // own or passed): the producer goes on after it.
                first_free = number + 1;
            }
        }
        self.next = first_free;
        first_free
    }
}

impl<T: Copy + Send> LeadConsumer<T> {
    /// Takes the value for `number` (the consumer's period now). Asking moves the
    /// consumer on: the numbers below `number` are passed, whether they were taken or not.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn take(&mut self, number: u64) -> Result<T, Missing> {
        let next = self.shared.consumer_next.load(Ordering::Relaxed);
        if number >= next {
            self.shared
                .consumer_next
                .store(number.saturating_add(1), Ordering::Release);
        }
        let slot = self.shared.slot(number);
        let seen = slot.stamp.load(Ordering::Acquire);
        if seen != stamp(number, READY) {
            return Err(if number_of(seen) == number && state_of(seen) == WRITING {
                Missing::BeingReplaced
            } else {
                Missing::NotWritten
            });
        }
        // SAFETY: the value is `READY` for `number`; the copy is kept only when the swap
        // below proves that no write overlapped it.
        let value = unsafe { std::ptr::read_volatile(slot.value.get()) };
        match slot.stamp.compare_exchange(
            seen,
            stamp(number, TAKEN),
            Ordering::AcqRel,
            Ordering::Acquire,
        ) {
            // SAFETY: the producer wrote the value before it published `READY`.
            Ok(_) => Ok(unsafe { value.assume_init() }),
            Err(_) => Err(Missing::BeingReplaced),
        }
    }

    /// The number the consumer asks for next.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn next_number(&self) -> u64 {
        self.shared.consumer_next.load(Ordering::Relaxed)
    }

    /// The queue's name.
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
    fn values_are_taken_by_the_number_they_are_for() {
        let (mut p, mut c) = lead_queue::<u32>("lead", 4, 10).unwrap();
        assert_eq!(p.push(100), Ok(10));
        assert_eq!(p.push(110), Ok(11));
        assert_eq!(p.lead(), 2);
        assert_eq!(c.take(10), Ok(100));
        assert_eq!(c.take(11), Ok(110));
        assert_eq!(c.take(12), Err(Missing::NotWritten));
        // A value is taken once.
        assert_eq!(c.take(11), Err(Missing::NotWritten));
    }

    #[test]
    fn a_full_queue_refuses_until_the_consumer_takes() {
        let (mut p, mut c) = lead_queue::<u32>("lead", 3, 0).unwrap();
        for v in 0..3 {
            assert_eq!(p.push(v), Ok(u64::from(v)));
        }
        assert_eq!(p.push(3), Err(3));
        assert_eq!(c.take(0), Ok(0));
        assert_eq!(p.push(3), Ok(3));
    }

    #[test]
    fn a_passed_value_frees_its_slot_for_a_later_number() {
        // The consumer skipped number 0 (the producer was late); the slot of number 0 is
        // then reused for number 2 although 0's value was never taken.
        let (mut p, mut c) = lead_queue::<u32>("lead", 2, 0).unwrap();
        assert_eq!(c.take(0), Err(Missing::NotWritten));
        assert_eq!(p.consumer_next(), 1);
        assert_eq!(p.lead(), 0);
        assert_eq!(p.catch_up(), 1);
        assert_eq!(p.next_number(), 1);
        assert_eq!(p.push(1), Ok(1));
        assert_eq!(p.push(2), Ok(2));
        assert_eq!(c.take(1), Ok(1));
        assert_eq!(c.take(2), Ok(2));
    }

    #[test]
    fn a_rewind_replaces_exactly_what_was_not_taken() {
        let (mut p, mut c) = lead_queue::<u32>("lead", 8, 0).unwrap();
        for v in 0..6 {
            p.push(v).unwrap();
        }
        assert_eq!(c.take(0), Ok(0));
        assert_eq!(c.take(1), Ok(1));
        // From 1 on: 1 is taken, so the producer goes on at 2.
        assert_eq!(p.rewind(1), 2);
        assert_eq!(p.next_number(), 2);
        // Reclaimed values are never taken...
        assert_eq!(c.take(2), Err(Missing::BeingReplaced));
        // ...their replacements are.
        assert_eq!(p.push(302), Ok(2));
        assert_eq!(p.push(303), Ok(3));
        assert_eq!(c.take(3), Ok(303));
        // A rewind from beyond what was written changes nothing.
        assert_eq!(p.rewind(10), 4);
    }

    #[test]
    fn producer_and_consumer_on_two_threads_never_share_a_value() {
        // Each value encodes its number and the producer's generation (rewinds so far).
        // The consumer asks for every number once, in order (as by a clock), and must get
        // each value for its own number and, after a value of generation g, never one of an
        // older generation: a reclaimed value is never taken.
        const N: u64 = 100_000;
        let (mut p, mut c) = lead_queue::<(u64, u64)>("lead", 16, 0).unwrap();
        let producer = std::thread::spawn(move || {
            let mut generation = 0u64;
            let mut rewinds = 0u64;
            let mut round = 0u64;
            while p.consumer_next() < N {
                round += 1;
                p.catch_up();
                let target = (p.consumer_next() + 12).min(N);
                while p.next_number() < target {
                    let n = p.next_number();
                    if p.push((n, generation)).is_err() {
                        break;
                    }
                }
                if round % 5 == 0 {
                    generation += 1;
                    rewinds += 1;
                    let from = p.consumer_next();
                    p.rewind(from);
                }
                std::thread::yield_now();
            }
            rewinds
        });
        let mut taken = 0u64;
        let mut newest_generation = 0u64;
        for number in 0..N {
            // A period of the consumer's clock: the producer runs meanwhile.
            for _ in 0..4 {
                std::thread::yield_now();
            }
            if let Ok((n, generation)) = c.take(number) {
                assert_eq!(n, number);
                assert!(generation >= newest_generation);
                newest_generation = generation;
                taken += 1;
            }
        }
        let rewinds = producer.join().unwrap();
        // Enough of both for the checks above to mean something, however the two threads
        // were scheduled.
        assert!(rewinds > 10, "{rewinds}");
        assert!(taken > 1000, "{taken}");
    }
}
