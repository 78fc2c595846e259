//! Driving ethercrab from a real-time periodic thread, without its async runtime.
//!
//! ethercrab's operations are futures: they put a frame in its PDU storage, wake the TX
//! side through a waker, and wait for the reply. Its usual TX/RX task is another future
//! (or a thread) that sends the frames and feeds the replies back.
//!
//! Here the TX side's waker *is* the TX/RX: when ethercrab wakes it, the frame is sent on
//! the link at once and the calling thread waits (bounded by the exchange's deadline) for
//! the reply, which it hands to ethercrab's receiver. ethercrab wakes the sender just
//! before it first polls the reply, so in the usual case the reply is already there on that
//! first poll: one `poll` of `tx_rx_dc` does the whole cycle on the caller's thread, with
//! no second thread, no cross-thread wake-up, no timer registration and no allocation.
//! A frame that does not come back by the deadline makes the poll return `Pending`; the
//! exchange then drops the future (ethercrab frees the frame) and counts a lost cycle.
//!
//! The TX/RX state sits behind a priority-inheriting mutex taken with `try_lock` only, so
//! the waker never blocks and is sound even if called from elsewhere.
//!
//! Start-up operations (scan, SDOs, state changes) run differently: there the executor
//! sends and receives between polls, so that ethercrab's waiting loops yield and their
//! time-outs count; they register ethercrab's timers, which costs nothing that matters
//! outside the cycle.

use std::future::Future;
use std::pin::pin;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::task::{Context, Poll, Wake, Waker};
use std::time::{Duration, Instant};

use ethercrab::{PduRx, PduTx, ReceiveAction};
use rtcnc_rt::PiMutex;

use crate::link::{Link, MAX_FRAME};

/// Offset of the first datagram's index in an Ethernet frame (14 + 2 + 1).
const FIRST_INDEX: usize = 17;
/// Frames that may be in flight at once (ethercrab's storage holds no more).
pub const FRAMES: usize = 16;

/// Round trips in 1 µs bins up to this many µs (the last bin holds everything longer).
pub const ROUND_TRIP_BINS: usize = 20_000;

/// Counters of the TX/RX.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TxRxCounters {
    /// Frames sent.
    pub sent: u64,
    /// Replies accepted.
    pub received: u64,
    /// Replies that came after their cycle had given up on them (dropped).
    pub late: u64,
    /// Send or receive errors of the link, and replies ethercrab refused.
    pub errors: u64,
    /// Round trip of the last reply (ns): from sending to receiving.
    pub last_round_trip_ns: u64,
}

/// The TX/RX state: ethercrab's two ends, the link, and what is in flight.
pub struct TxRx {
    tx: PduTx<'static>,
    rx: PduRx<'static>,
    link: Box<dyn Link>,
    buffer: Box<[u8; MAX_FRAME]>,
    in_flight: [u8; FRAMES],
    in_flight_count: usize,
    sent_at: Instant,
    deadline: Instant,
    counters: TxRxCounters,
    /// Round trips of accepted replies, 1 µs bins; allocated once.
    round_trips: Box<[u32; ROUND_TRIP_BINS]>,
    longest_round_trip_ns: u64,
}

impl TxRx {
    /// Sends every frame ethercrab has ready, then receives until all of them are back or
    /// the deadline has passed.
    fn pump(&mut self, waker: &Waker) {
        self.tx.replace_waker(waker);
        while let Some(frame) = self.tx.next_sendable_frame() {
            let link = &mut self.link;
            let mut index = None;
            let sent = frame.send_blocking(|bytes| {
                index = bytes.get(FIRST_INDEX).copied();
                link.send(bytes)
                    .map(|()| bytes.len())
                    .map_err(|_| ethercrab::error::Error::SendFrame)
            });
            match (sent, index) {
                (Ok(_), Some(index)) => {
                    self.counters.sent += 1;
                    self.sent_at = Instant::now();
                    if !self.in_flight[..self.in_flight_count].contains(&index)
                        && self.in_flight_count < FRAMES
                    {
                        self.in_flight[self.in_flight_count] = index;
                        self.in_flight_count += 1;
                    }
                }
                _ => self.counters.errors += 1,
            }
        }
        // A simulated segment's replies are there at once: taking them does not depend on
        // how long the simulation took, so a test's outcome does not either.
        let at_once = self.link.replies_at_once();
        while self.in_flight_count > 0 {
            let now = Instant::now();
            if now >= self.deadline && !at_once {
                break;
            }
            let wait = self.deadline.saturating_duration_since(now);
            match self.link.receive(&mut self.buffer[..], wait) {
                Ok(Some(len)) => self.accept(len),
                Ok(None) => break,
                Err(_) => {
                    self.counters.errors += 1;
                    break;
                }
            }
        }
    }

    /// Hands a received frame to ethercrab if it answers a frame in flight.
    fn accept(&mut self, len: usize) {
        let frame = &self.buffer[..len];
        let Some(&index) = frame.get(FIRST_INDEX) else {
            return;
        };
        let Some(at) = self.in_flight[..self.in_flight_count]
            .iter()
            .position(|&i| i == index)
        else {
            // A reply to a frame given up on, or our own frame echoed: never delivered
            // to the cycle that reuses the slot.
            self.counters.late += 1;
            return;
        };
        match self.rx.receive_frame(frame) {
            Ok(ReceiveAction::Processed) => {
                self.in_flight.copy_within(at + 1..self.in_flight_count, at);
                self.in_flight_count -= 1;
                self.counters.received += 1;
                let round_trip = self.sent_at.elapsed().as_nanos() as u64;
                self.counters.last_round_trip_ns = round_trip;
                self.longest_round_trip_ns = self.longest_round_trip_ns.max(round_trip);
                let bin = ((round_trip / 1000) as usize).min(ROUND_TRIP_BINS - 1);
                self.round_trips[bin] = self.round_trips[bin].saturating_add(1);
            }
            Ok(ReceiveAction::Ignored) => {}
            Err(_) => self.counters.errors += 1,
        }
    }
}

/// The shared TX/RX, and the waker ethercrab's sender side calls.
pub struct Pump {
    state: PiMutex<TxRx>,
    /// Whether a wake does the TX/RX at once (cyclic exchanges). At start-up it does not:
    /// ethercrab's waiting loops (state changes, mailboxes) must return `Pending` between
    /// frames for their time-outs to be checked, so the executor pumps between polls.
    at_once: AtomicBool,
}

impl Wake for Pump {
    fn wake(self: Arc<Self>) {
        self.wake_by_ref();
    }

    fn wake_by_ref(self: &Arc<Self>) {
        if !self.at_once.load(Ordering::Relaxed) {
            return;
        }
        if let Some(mut state) = self.state.try_lock() {
            let waker = Waker::from(Arc::clone(self));
            state.pump(&waker);
        }
    }
}

/// Drives ethercrab's futures on the calling thread.
pub struct Driver {
    pump: Arc<Pump>,
    waker: Waker,
}

/// An operation did not finish in time.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Stalled;

impl Driver {
    /// A driver over `link` for ethercrab's `tx` and `rx` ends.
    pub fn new(tx: PduTx<'static>, rx: PduRx<'static>, link: Box<dyn Link>) -> Self {
        let now = Instant::now();
        let pump = Arc::new(Pump {
            state: PiMutex::new(TxRx {
                tx,
                rx,
                link,
                buffer: Box::new([0; MAX_FRAME]),
                in_flight: [0; FRAMES],
                in_flight_count: 0,
                sent_at: now,
                deadline: now,
                counters: TxRxCounters::default(),
                round_trips: Box::new([0; ROUND_TRIP_BINS]),
                longest_round_trip_ns: 0,
            }),
            at_once: AtomicBool::new(false),
        });
        let waker = Waker::from(Arc::clone(&pump));
        if let Some(state) = pump.state.try_lock() {
            state.tx.replace_waker(&waker);
        }
        Self { pump, waker }
    }

    fn set_deadline(&self, deadline: Instant, forget_in_flight: bool) {
        if let Some(mut state) = self.pump.state.try_lock() {
            state.deadline = deadline;
            if forget_in_flight {
                state.in_flight_count = 0;
            }
            state.tx.replace_waker(&self.waker);
        }
    }

    /// Pumps once; returns whether waiting longer could still bring a reply.
    fn pump_now(&self) -> bool {
        match self.pump.state.try_lock() {
            Some(mut state) => {
                state.pump(&self.waker);
                !state.link.replies_at_once()
            }
            None => true,
        }
    }

    /// Runs a start-up operation to completion, waiting at most `reply_timeout` for each
    /// reply and `timeout` in all.
    pub fn block_on<F: Future>(
        &self,
        future: F,
        reply_timeout: Duration,
        timeout: Duration,
    ) -> Result<F::Output, Stalled> {
        self.pump.at_once.store(false, Ordering::Relaxed);
        let mut future = pin!(future);
        let mut context = Context::from_waker(Waker::noop());
        let end = Instant::now() + timeout;
        loop {
            self.set_deadline(Instant::now() + reply_timeout, false);
            if let Poll::Ready(output) = future.as_mut().poll(&mut context) {
                return Ok(output);
            }
            self.pump_now();
            if let Poll::Ready(output) = future.as_mut().poll(&mut context) {
                return Ok(output);
            }
            if Instant::now() >= end {
                return Err(Stalled);
            }
            // Waiting on one of ethercrab's own delays: let time pass.
            std::thread::yield_now();
        }
    }

    /// One cyclic operation with a hard deadline: `None` if it did not complete by then
    /// (the future is dropped and ethercrab frees its frames).
    pub fn cycle<F: Future>(&self, future: F, deadline: Instant) -> Option<F::Output> {
        self.set_deadline(deadline, true);
        self.pump.at_once.store(true, Ordering::Relaxed);
        let mut future = pin!(future);
        let mut context = Context::from_waker(Waker::noop());
        loop {
            if let Poll::Ready(output) = future.as_mut().poll(&mut context) {
                return Some(output);
            }
            // A frame ethercrab made ready without waking, or a reply still coming.
            let may_come = self.pump_now();
            if may_come && Instant::now() >= deadline {
                return None;
            }
            if !may_come {
                if let Poll::Ready(output) = future.as_mut().poll(&mut context) {
                    return Some(output);
                }
                return None;
            }
        }
    }

    /// The TX/RX counters.
    pub fn counters(&self) -> TxRxCounters {
        self.pump
            .state
            .try_lock()
            .map(|s| s.counters)
            .unwrap_or_default()
    }

    /// The round-trip histogram (1 µs bins) and the longest round trip (ns); `None` if
    /// the TX/RX is busy.
    pub fn round_trips(&self) -> Option<(Vec<u32>, u64)> {
        self.pump
            .state
            .try_lock()
            .map(|s| (s.round_trips.to_vec(), s.longest_round_trip_ns))
    }

    /// Whether the link is up.
    pub fn link_up(&self) -> bool {
        self.pump
            .state
            .try_lock()
            .is_some_and(|mut s| s.link.is_up())
    }
}
