//! Bounded mailbox with the RTOS operations of SEEDS.md.

use std::collections::VecDeque;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::Duration;

use super::trigger::{TriggerSource, WaitResult, wait_on};
use super::{IpcError, Rejected, Trigger};
use crate::error::ConfigError;
use crate::sys::{PiLock, in_task_body, monotonic_ns};
use crate::time::duration_ns;

struct Shared<T> {
    name: String,
    capacity: usize,
    queue: PiLock<VecDeque<T>>,
    /// Copy of the queue length, written under the lock, so triggers poll without locking.
    len: AtomicUsize,
}

/// A bounded FIFO of messages between tasks (and between tasks and outside threads).
///
/// Storage for `capacity` messages is allocated when the mailbox is created; no operation
/// allocates afterwards. Clones share the same mailbox.
pub struct Mailbox<T> {
    shared: Arc<Shared<T>>,
}

impl<T> Clone for Mailbox<T> {
    fn clone(&self) -> Self {
        Mailbox {
            shared: Arc::clone(&self.shared),
        }
    }
}

impl<T: Send + 'static> Mailbox<T> {
    /// A mailbox called `name` holding at most `capacity` messages.
    ///
    /// Real-time: no (set-up: allocates).
    pub fn new(name: &str, capacity: usize) -> Result<Self, ConfigError> {
        if capacity == 0 {
            return Err(ConfigError::ZeroCapacity {
                channel: name.to_string(),
            });
        }
        Ok(Mailbox {
            shared: Arc::new(Shared {
                name: name.to_string(),
                capacity,
                queue: PiLock::new(VecDeque::with_capacity(capacity)),
                len: AtomicUsize::new(0),
            }),
        })
    }

    /// The mailbox's name.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn name(&self) -> &str {
        &self.shared.name
    }

    /// The most messages it holds.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn capacity(&self) -> usize {
        self.shared.capacity
    }

    /// Messages waiting now.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn len(&self) -> usize {
        self.shared.len.load(Ordering::Acquire)
    }

    /// True when no message waits.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// True when there is no room.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn is_full(&self) -> bool {
        self.len() >= self.shared.capacity
    }

    fn changed(&self) {
        self.shared.queue.notify_all();
    }

    /// Conditional put: appends `value` or hands it back with [`IpcError::Full`].
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn try_put(&self, value: T) -> Result<(), Rejected<T>> {
        {
            let mut q = self.shared.queue.lock();
            if q.len() >= self.shared.capacity {
                return Err(Rejected::new(IpcError::Full, value));
            }
            q.push_back(value);
            self.shared.len.store(q.len(), Ordering::Release);
        }
        self.changed();
        Ok(())
    }

    /// Urgent put: places `value` at the head, ahead of every waiting message; fails with
    /// [`IpcError::Full`] when there is no room (it never displaces a message).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn put_front(&self, value: T) -> Result<(), Rejected<T>> {
        {
            let mut q = self.shared.queue.lock();
            if q.len() >= self.shared.capacity {
                return Err(Rejected::new(IpcError::Full, value));
            }
            q.push_front(value);
            self.shared.len.store(q.len(), Ordering::Release);
        }
        self.changed();
        Ok(())
    }

    fn put_until(&self, value: T, deadline: Option<u64>) -> Result<(), Rejected<T>> {
        if in_task_body() {
            return Err(Rejected::new(IpcError::BlockingInTask, value));
        }
        let capacity = self.shared.capacity;
        let len = &self.shared.len;
        let mut slot = Some(value);
        let result = wait_on(&self.shared.queue, deadline, None, |q| {
            if q.len() < capacity {
                if let Some(v) = slot.take() {
                    q.push_back(v);
                    len.store(q.len(), Ordering::Release);
                }
                true
            } else {
                false
            }
        });
        match (result, slot) {
            (WaitResult::Ready, _) => {
                self.changed();
                Ok(())
            }
            (_, Some(v)) => Err(Rejected::new(IpcError::Timeout, v)),
            // The value was queued exactly as the wait ended.
            (_, None) => {
                self.changed();
                Ok(())
            }
        }
    }

    /// Blocking put (outside threads only): waits for room.
    ///
    /// Real-time: no (blocks; refused inside a task body).
    pub fn put(&self, value: T) -> Result<(), Rejected<T>> {
        self.put_until(value, None)
    }

    /// Timed put (outside threads only): waits at most `timeout` of OS monotonic time.
    ///
    /// Real-time: no (blocks; refused inside a task body).
    pub fn put_timeout(&self, value: T, timeout: Duration) -> Result<(), Rejected<T>> {
        self.put_until(
            value,
            Some(monotonic_ns().saturating_add(duration_ns(timeout))),
        )
    }

    /// Conditional get: the oldest message, or `None` when empty.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn try_get(&self) -> Option<T> {
        // Most polls find the mailbox empty: answer those without taking the lock. A put
        // racing with this load is seen by the next poll, exactly as if it came after it.
        if self.is_empty() {
            return None;
        }
        let v = {
            let mut q = self.shared.queue.lock();
            let v = q.pop_front();
            self.shared.len.store(q.len(), Ordering::Release);
            v
        };
        if v.is_some() {
            self.changed();
        }
        v
    }

    fn get_until(&self, deadline: Option<u64>) -> Result<T, IpcError> {
        if in_task_body() {
            return Err(IpcError::BlockingInTask);
        }
        let mut out = None;
        let len = &self.shared.len;
        wait_on(&self.shared.queue, deadline, None, |q| {
            out = q.pop_front();
            len.store(q.len(), Ordering::Release);
            out.is_some()
        });
        match out {
            Some(v) => {
                self.changed();
                Ok(v)
            }
            None => Err(IpcError::Timeout),
        }
    }

    /// Blocking get (outside threads only): waits for a message.
    ///
    /// Real-time: no (blocks; refused inside a task body).
    pub fn get(&self) -> Result<T, IpcError> {
        self.get_until(None)
    }

    /// Timed get (outside threads only): waits at most `timeout` of OS monotonic time.
    ///
    /// Real-time: no (blocks; refused inside a task body).
    pub fn get_timeout(&self, timeout: Duration) -> Result<T, IpcError> {
        self.get_until(Some(monotonic_ns().saturating_add(duration_ns(timeout))))
    }

    /// A copy of the oldest message without removing it.
    ///
    /// Real-time: yes (no allocation when `T`'s clone allocates nothing, no blocking).
    pub fn peek(&self) -> Option<T>
    where
        T: Clone,
    {
        if self.is_empty() {
            return None;
        }
        self.shared.queue.lock().front().cloned()
    }

    /// Looks at the oldest message without removing or copying it.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn peek_with<R>(&self, f: impl FnOnce(Option<&T>) -> R) -> R {
        f(self.shared.queue.lock().front())
    }

    /// Removes every message; returns how many there were.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn clear(&self) -> usize {
        let n = {
            let mut q = self.shared.queue.lock();
            let n = q.len();
            q.clear();
            self.shared.len.store(0, Ordering::Release);
            n
        };
        if n > 0 {
            self.changed();
        }
        n
    }

    /// A trigger that fires while the mailbox holds a message (the task then takes it).
    ///
    /// Real-time: no (set-up: allocates).
    pub fn data_trigger(&self) -> Trigger {
        Trigger::new(Arc::new(DataTrigger(Arc::clone(&self.shared))))
    }

    /// A trigger that fires while the mailbox has room.
    ///
    /// Real-time: no (set-up: allocates).
    pub fn space_trigger(&self) -> Trigger {
        Trigger::new(Arc::new(SpaceTrigger(Arc::clone(&self.shared))))
    }
}

struct DataTrigger<T>(Arc<Shared<T>>);
struct SpaceTrigger<T>(Arc<Shared<T>>);

impl<T: Send> TriggerSource for DataTrigger<T> {
    fn name(&self) -> &str {
        &self.0.name
    }
    fn arm(&self) -> u64 {
        0
    }
    fn is_ready(&self, _token: u64) -> bool {
        self.0.len.load(Ordering::Acquire) > 0
    }
    fn try_take(&self, token: u64) -> bool {
        self.is_ready(token)
    }
    fn wait_ready(&self, _token: u64, deadline: Option<u64>, stop: &AtomicBool) -> WaitResult {
        wait_on(&self.0.queue, deadline, Some(stop), |q| !q.is_empty())
    }
}

impl<T: Send> TriggerSource for SpaceTrigger<T> {
    fn name(&self) -> &str {
        &self.0.name
    }
    fn arm(&self) -> u64 {
        0
    }
    fn is_ready(&self, _token: u64) -> bool {
        self.0.len.load(Ordering::Acquire) < self.0.capacity
    }
    fn try_take(&self, token: u64) -> bool {
        self.is_ready(token)
    }
    fn wait_ready(&self, _token: u64, deadline: Option<u64>, stop: &AtomicBool) -> WaitResult {
        let capacity = self.0.capacity;
        wait_on(&self.0.queue, deadline, Some(stop), |q| q.len() < capacity)
    }
}
