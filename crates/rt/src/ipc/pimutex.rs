//! A mutex with priority inheritance, for data shared between tasks of different priority.

use std::ops::{Deref, DerefMut};

use crate::sys::{PiGuard, PiLock};

/// A mutex using `PTHREAD_PRIO_INHERIT`: while a low-priority thread holds it, a
/// higher-priority thread waiting for it lends its priority to the holder, so a
/// middle-priority thread cannot starve both (priority inversion).
///
/// It is the one lock real-time task bodies may take; keep critical sections short and
/// bounded. Under the virtual-time scheduler everything runs on one thread, so it is only
/// contended by threads outside the task set.
pub struct PiMutex<T> {
    lock: PiLock<T>,
}

/// Access to the data while the mutex is held; unlocks when dropped.
pub struct PiMutexGuard<'a, T> {
    guard: PiGuard<'a, T>,
}

impl<T: Send> PiMutex<T> {
    /// A mutex around `value`.
    pub fn new(value: T) -> Self {
        PiMutex {
            lock: PiLock::new(value),
        }
    }

    /// Locks, waiting (with priority inheritance) while another thread holds it.
    pub fn lock(&self) -> PiMutexGuard<'_, T> {
        PiMutexGuard {
            guard: self.lock.lock(),
        }
    }

    /// Locks if free.
    pub fn try_lock(&self) -> Option<PiMutexGuard<'_, T>> {
        self.lock.try_lock().map(|guard| PiMutexGuard { guard })
    }
}

impl<T> Deref for PiMutexGuard<'_, T> {
    type Target = T;
    fn deref(&self) -> &T {
        &self.guard
    }
}

impl<T> DerefMut for PiMutexGuard<'_, T> {
    fn deref_mut(&mut self) -> &mut T {
        &mut self.guard
    }
}
