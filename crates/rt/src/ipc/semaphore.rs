//! Binary, counting and event semaphores.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering};
use std::time::Duration;

use super::trigger::{TriggerSource, WaitResult, wait_on};
use super::{IpcError, Trigger};
use crate::error::ConfigError;
use crate::sys::{PiLock, in_task_body, monotonic_ns};
use crate::time::duration_ns;

fn deadline_after(timeout: Duration) -> u64 {
    monotonic_ns().saturating_add(duration_ns(timeout))
}

fn outcome(result: WaitResult) -> Result<(), IpcError> {
    match result {
        WaitResult::Ready => Ok(()),
        WaitResult::TimedOut | WaitResult::Stopped => Err(IpcError::Timeout),
    }
}

// ---------------------------------------------------------------------------------------

struct CountShared {
    name: String,
    max: u32,
    count: PiLock<u32>,
    /// Copy of the count, written under the lock, so triggers poll without locking.
    mirror: AtomicU32,
}

impl CountShared {
    fn try_wait(&self) -> bool {
        if self.mirror.load(Ordering::Acquire) == 0 {
            return false;
        }
        let mut c = self.count.lock();
        if *c > 0 {
            *c -= 1;
            self.mirror.store(*c, Ordering::Release);
            true
        } else {
            false
        }
    }

    fn store(&self, value: u32) {
        let mut c = self.count.lock();
        *c = value;
        self.mirror.store(value, Ordering::Release);
    }

    fn wait_until(&self, deadline: Option<u64>) -> Result<(), IpcError> {
        if in_task_body() {
            return Err(IpcError::BlockingInTask);
        }
        let mirror = &self.mirror;
        outcome(wait_on(&self.count, deadline, None, |c| {
            if *c > 0 {
                *c -= 1;
                mirror.store(*c, Ordering::Release);
                true
            } else {
                false
            }
        }))
    }
}

impl TriggerSource for CountShared {
    fn name(&self) -> &str {
        &self.name
    }
    fn arm(&self) -> u64 {
        0
    }
    fn is_ready(&self, _token: u64) -> bool {
        self.mirror.load(Ordering::Acquire) > 0
    }
    fn try_take(&self, _token: u64) -> bool {
        self.try_wait()
    }
    fn wait_ready(&self, _token: u64, deadline: Option<u64>, stop: &AtomicBool) -> WaitResult {
        wait_on(&self.count, deadline, Some(stop), |c| *c > 0)
    }
}

/// A binary semaphore: `signal` makes it available (signalling twice is the same as once);
/// a successful wait takes it (auto-reset).
#[derive(Clone)]
pub struct BinarySemaphore {
    shared: Arc<CountShared>,
}

impl BinarySemaphore {
    /// A binary semaphore called `name`, initially not signalled.
    ///
    /// Real-time: no (set-up: allocates).
    pub fn new(name: &str) -> Self {
        BinarySemaphore {
            shared: Arc::new(CountShared {
                name: name.to_string(),
                max: 1,
                count: PiLock::new(0),
                mirror: AtomicU32::new(0),
            }),
        }
    }

    /// The semaphore's name.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn name(&self) -> &str {
        &self.shared.name
    }

    /// Makes the semaphore available and wakes a waiter.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn signal(&self) {
        self.shared.store(1);
        self.shared.count.notify_all();
    }

    /// True when signalled and not yet taken.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn is_signalled(&self) -> bool {
        self.shared.mirror.load(Ordering::Acquire) > 0
    }

    /// Takes the semaphore if signalled.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn try_wait(&self) -> bool {
        self.shared.try_wait()
    }

    /// Blocks until signalled, then takes it (outside threads only).
    ///
    /// Real-time: no (blocks; refused inside a task body).
    pub fn wait(&self) -> Result<(), IpcError> {
        self.shared.wait_until(None)
    }

    /// Like [`wait`](Self::wait) with a timeout on the OS monotonic clock.
    ///
    /// Real-time: no (blocks; refused inside a task body).
    pub fn wait_timeout(&self, timeout: Duration) -> Result<(), IpcError> {
        self.shared.wait_until(Some(deadline_after(timeout)))
    }

    /// A trigger that fires while signalled; the wake-up takes the semaphore.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn trigger(&self) -> Trigger {
        Trigger::new(Arc::clone(&self.shared) as Arc<dyn TriggerSource>)
    }
}

/// A counting semaphore with a maximum count.
#[derive(Clone)]
pub struct CountingSemaphore {
    shared: Arc<CountShared>,
}

impl CountingSemaphore {
    /// A counting semaphore called `name` with `initial` units and at most `max`.
    ///
    /// Real-time: no (set-up: allocates).
    pub fn new(name: &str, initial: u32, max: u32) -> Result<Self, ConfigError> {
        if max == 0 {
            return Err(ConfigError::ZeroCapacity {
                channel: name.to_string(),
            });
        }
        if initial > max {
            return Err(ConfigError::InitialAboveMax {
                channel: name.to_string(),
                initial,
                max,
            });
        }
        Ok(CountingSemaphore {
            shared: Arc::new(CountShared {
                name: name.to_string(),
                max,
                count: PiLock::new(initial),
                mirror: AtomicU32::new(initial),
            }),
        })
    }

    /// The semaphore's name.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn name(&self) -> &str {
        &self.shared.name
    }

    /// Adds one unit; refused with [`IpcError::AtMaximum`] when at the maximum.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn signal(&self) -> Result<(), IpcError> {
        {
            let mut c = self.shared.count.lock();
            if *c >= self.shared.max {
                return Err(IpcError::AtMaximum);
            }
            *c += 1;
            self.shared.mirror.store(*c, Ordering::Release);
        }
        self.shared.count.notify_all();
        Ok(())
    }

    /// Units available now.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn count(&self) -> u32 {
        self.shared.mirror.load(Ordering::Acquire)
    }

    /// Takes one unit if there is one.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn try_wait(&self) -> bool {
        self.shared.try_wait()
    }

    /// Blocks until a unit is available and takes it (outside threads only).
    ///
    /// Real-time: no (blocks; refused inside a task body).
    pub fn wait(&self) -> Result<(), IpcError> {
        self.shared.wait_until(None)
    }

    /// Like [`wait`](Self::wait) with a timeout on the OS monotonic clock.
    ///
    /// Real-time: no (blocks; refused inside a task body).
    pub fn wait_timeout(&self, timeout: Duration) -> Result<(), IpcError> {
        self.shared.wait_until(Some(deadline_after(timeout)))
    }

    /// A trigger that fires while the count is above zero; the wake-up takes one unit.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn trigger(&self) -> Trigger {
        Trigger::new(Arc::clone(&self.shared) as Arc<dyn TriggerSource>)
    }
}

// ---------------------------------------------------------------------------------------

#[derive(Default)]
struct EventState {
    set: bool,
    /// Bumped by every set (from reset) and every pulse: what edge-triggered waiters see.
    generation: u64,
}

struct EventShared {
    name: String,
    state: PiLock<EventState>,
    /// Copy of the generation, written under the lock, so triggers poll without locking.
    generation: AtomicU64,
}

impl TriggerSource for EventShared {
    fn name(&self) -> &str {
        &self.name
    }
    fn arm(&self) -> u64 {
        self.generation.load(Ordering::Acquire)
    }
    fn is_ready(&self, token: u64) -> bool {
        self.generation.load(Ordering::Acquire) != token
    }
    fn try_take(&self, token: u64) -> bool {
        self.is_ready(token)
    }
    fn wait_ready(&self, token: u64, deadline: Option<u64>, stop: &AtomicBool) -> WaitResult {
        wait_on(&self.state, deadline, Some(stop), |s| s.generation != token)
    }
}

/// An event semaphore: stays set until reset; waiting does not consume it; `pulse` releases
/// every current waiter and leaves it reset.
#[derive(Clone)]
pub struct EventSemaphore {
    shared: Arc<EventShared>,
}

impl EventSemaphore {
    /// An event called `name`, initially reset.
    ///
    /// Real-time: no (set-up: allocates).
    pub fn new(name: &str) -> Self {
        Self::with_state(name, false)
    }

    /// An event called `name`, initially set when `set` is true.
    ///
    /// Real-time: no (set-up: allocates).
    pub fn with_state(name: &str, set: bool) -> Self {
        EventSemaphore {
            shared: Arc::new(EventShared {
                name: name.to_string(),
                state: PiLock::new(EventState { set, generation: 0 }),
                generation: AtomicU64::new(0),
            }),
        }
    }

    /// The event's name.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn name(&self) -> &str {
        &self.shared.name
    }

    /// Sets the event, releasing every waiter; it stays set.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn set(&self) {
        {
            let mut s = self.shared.state.lock();
            if !s.set {
                s.set = true;
                s.generation += 1;
                self.shared
                    .generation
                    .store(s.generation, Ordering::Release);
            }
        }
        self.shared.state.notify_all();
    }

    /// Resets the event.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn reset(&self) {
        self.shared.state.lock().set = false;
    }

    /// Releases every current waiter and leaves the event reset.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn pulse(&self) {
        {
            let mut s = self.shared.state.lock();
            s.set = false;
            s.generation += 1;
            self.shared
                .generation
                .store(s.generation, Ordering::Release);
        }
        self.shared.state.notify_all();
    }

    /// True while set.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn is_set(&self) -> bool {
        self.shared.state.lock().set
    }

    fn wait_until(&self, deadline: Option<u64>) -> Result<(), IpcError> {
        if in_task_body() {
            return Err(IpcError::BlockingInTask);
        }
        let start = self.shared.state.lock().generation;
        outcome(wait_on(&self.shared.state, deadline, None, |s| {
            s.set || s.generation != start
        }))
    }

    /// Blocks until the event is set or pulsed (returns at once when set; outside threads only).
    ///
    /// Real-time: no (blocks; refused inside a task body).
    pub fn wait(&self) -> Result<(), IpcError> {
        self.wait_until(None)
    }

    /// Like [`wait`](Self::wait) with a timeout on the OS monotonic clock.
    ///
    /// Real-time: no (blocks; refused inside a task body).
    pub fn wait_timeout(&self, timeout: Duration) -> Result<(), IpcError> {
        self.wait_until(Some(deadline_after(timeout)))
    }

    /// A trigger that fires on each set or pulse after the task began waiting.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn trigger(&self) -> Trigger {
        Trigger::new(Arc::clone(&self.shared) as Arc<dyn TriggerSource>)
    }

    /// Blocks (without the in-task check) until set, the deadline or `stop`; used by the
    /// real-time runner for task start requests.
    pub(crate) fn wait_set_or_stop(&self, stop: &AtomicBool) -> bool {
        wait_on(&self.shared.state, None, Some(stop), |s| s.set) == WaitResult::Ready
    }
}
