//! The master's time base: the monotonic clock on a real bus, or a virtual clock that a
//! test (or a simulation) advances, so that a whole bus runs deterministically.

use std::sync::atomic::{AtomicU64, Ordering};

/// A time base in nanoseconds.
#[derive(Debug, Clone, Copy)]
pub enum Clock {
    /// `CLOCK_MONOTONIC`.
    Monotonic,
    /// A clock that moves only when told to.
    Virtual(&'static AtomicU64),
}

impl Clock {
    /// A virtual clock standing at `start_ns`. It lives as long as the process: a master
    /// and its simulated devices keep a reference to it.
    pub fn new_virtual(start_ns: u64) -> Self {
        Self::Virtual(Box::leak(Box::new(AtomicU64::new(start_ns))))
    }

    /// The time now (ns).
    pub fn now_ns(self) -> u64 {
        match self {
            Self::Monotonic => monotonic_ns(),
            Self::Virtual(time) => time.load(Ordering::Acquire),
        }
    }

    /// Waits until `t_ns` (monotonic: sleeps; virtual: moves the clock there if it is
    /// behind).
    pub fn sleep_until(self, t_ns: u64) {
        match self {
            Self::Monotonic => {
                let spec = libc::timespec {
                    tv_sec: (t_ns / 1_000_000_000) as libc::time_t,
                    tv_nsec: (t_ns % 1_000_000_000) as libc::c_long,
                };
                // EINTR only shortens the wait; the caller's deadline logic copes.
                // SAFETY: the timespec is valid for the call.
                unsafe {
                    libc::clock_nanosleep(
                        libc::CLOCK_MONOTONIC,
                        libc::TIMER_ABSTIME,
                        &raw const spec,
                        std::ptr::null_mut(),
                    );
                }
            }
            Self::Virtual(time) => {
                time.fetch_max(t_ns, Ordering::AcqRel);
            }
        }
    }

    /// Moves a virtual clock forward by `ns`; a monotonic clock moves by itself.
    pub fn advance(self, ns: u64) {
        if let Self::Virtual(time) = self {
            time.fetch_add(ns, Ordering::AcqRel);
        }
    }

    /// Whether this clock is virtual.
    pub fn is_virtual(self) -> bool {
        matches!(self, Self::Virtual(_))
    }
}

/// `CLOCK_MONOTONIC` in nanoseconds.
pub fn monotonic_ns() -> u64 {
    let mut spec = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: the timespec is valid for the call.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &raw mut spec) };
    (spec.tv_sec as u64)
        .saturating_mul(1_000_000_000)
        .saturating_add(spec.tv_nsec as u64)
}
