//! A mutex with priority inheritance, for data shared between tasks of different priority.
//!
//! It is Linux's priority-inheritance futex used directly, as glibc's `PTHREAD_PRIO_INHERIT`
//! mutex uses it underneath: the lock word holds the owner's thread id. Taking a free lock
//! and giving back an uncontended one are one compare-and-swap each in user space; only
//! when another thread holds it does the caller enter the kernel (`FUTEX_LOCK_PI`), which
//! queues it by priority and lends that priority to the owner until it unlocks
//! (`FUTEX_UNLOCK_PI` hands the lock to the highest waiter). Without glibc's generic mutex
//! path around it the uncontended case costs a few nanoseconds instead of some tens, which
//! matters for data every servo cycle locks.

use std::cell::{Cell, UnsafeCell};
use std::ops::{Deref, DerefMut};
use std::sync::atomic::{AtomicU32, Ordering};

/// A mutex with the priority-inheritance protocol: while a low-priority thread holds it, a
/// higher-priority thread waiting for it lends its priority to the holder, so a
/// middle-priority thread cannot starve both (priority inversion).
///
/// It is the one lock real-time task bodies may take; keep critical sections short and
/// bounded. Under the virtual-time scheduler everything runs on one thread, so it is only
/// contended by threads outside the task set. Not recursive: a thread that locks it twice
/// waits for itself (the kernel refuses the second lock, see [`PiMutex::lock`]).
pub struct PiMutex<T> {
    /// 0 when free, else the owner's thread id (with the kernel's waiters bit).
    word: AtomicU32,
    data: UnsafeCell<T>,
}

// SAFETY: `data` is only reached through a guard, and a guard exists only while the lock
// word holds the calling thread's id.
unsafe impl<T: Send> Send for PiMutex<T> {}
// SAFETY: as above.
unsafe impl<T: Send> Sync for PiMutex<T> {}

/// Access to the data while the mutex is held; unlocks when dropped.
pub struct PiMutexGuard<'a, T> {
    mutex: &'a PiMutex<T>,
    tid: u32,
}

thread_local! {
    static TID: Cell<u32> = const { Cell::new(0) };
}

/// This thread's kernel thread id (what a PI futex word holds), asked for once per thread.
fn thread_id() -> u32 {
    TID.with(|t| {
        let mut id = t.get();
        if id == 0 {
            // SAFETY: gettid has no arguments and cannot fail.
            id = unsafe { libc::syscall(libc::SYS_gettid) } as u32;
            t.set(id);
        }
        id
    })
}

fn futex(word: &AtomicU32, op: libc::c_int) -> libc::c_long {
    // SAFETY: the word is a live, aligned u32; the PI operations take no timeout (null:
    // wait without one) and no second address.
    unsafe {
        libc::syscall(
            libc::SYS_futex,
            word.as_ptr(),
            op | libc::FUTEX_PRIVATE_FLAG,
            0,
            std::ptr::null::<libc::timespec>(),
            std::ptr::null::<u32>(),
            0,
        )
    }
}

impl<T: Send> PiMutex<T> {
    /// A mutex around `value`.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn new(value: T) -> Self {
        PiMutex {
            word: AtomicU32::new(0),
            data: UnsafeCell::new(value),
        }
    }

    /// Locks, waiting (with priority inheritance) while another thread holds it.
    ///
    /// Locking a mutex the thread already holds is a programming error; the kernel answers
    /// it with `EDEADLK` and this then goes on without the lock, as `pthread_mutex_lock`'s
    /// ignored error code did before.
    ///
    /// Real-time: yes (waits only for the holder, whose priority it raises; no allocation).
    pub fn lock(&self) -> PiMutexGuard<'_, T> {
        let tid = thread_id();
        if self
            .word
            .compare_exchange(0, tid, Ordering::Acquire, Ordering::Relaxed)
            .is_err()
        {
            loop {
                if futex(&self.word, libc::FUTEX_LOCK_PI) == 0 {
                    break;
                }
                let error = std::io::Error::last_os_error().raw_os_error();
                // EAGAIN: the owner is exiting; EINTR: a signal. Try again.
                if !matches!(error, Some(libc::EAGAIN) | Some(libc::EINTR)) {
                    break;
                }
            }
        }
        PiMutexGuard { mutex: self, tid }
    }

    /// Locks if free.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn try_lock(&self) -> Option<PiMutexGuard<'_, T>> {
        let tid = thread_id();
        self.word
            .compare_exchange(0, tid, Ordering::Acquire, Ordering::Relaxed)
            .ok()
            .map(|_| PiMutexGuard { mutex: self, tid })
    }
}

impl<T> Drop for PiMutexGuard<'_, T> {
    fn drop(&mut self) {
        let word = &self.mutex.word;
        // Uncontended: the word is exactly our id. Otherwise the kernel has queued waiters
        // (the waiters bit is set) and hands the lock to the highest of them.
        if word
            .compare_exchange(self.tid, 0, Ordering::Release, Ordering::Relaxed)
            .is_err()
        {
            futex(word, libc::FUTEX_UNLOCK_PI);
        }
    }
}

impl<T> Deref for PiMutexGuard<'_, T> {
    type Target = T;
    fn deref(&self) -> &T {
        // SAFETY: the guard holds the lock.
        unsafe { &*self.mutex.data.get() }
    }
}

impl<T> DerefMut for PiMutexGuard<'_, T> {
    fn deref_mut(&mut self) -> &mut T {
        // SAFETY: the guard holds the lock, and `&mut self` makes this the only reference.
        unsafe { &mut *self.mutex.data.get() }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    #[test]
    fn threads_take_turns_and_no_increment_is_lost() {
        let m = Arc::new(PiMutex::new(0u64));
        let threads: Vec<_> = (0..4)
            .map(|_| {
                let m = Arc::clone(&m);
                std::thread::spawn(move || {
                    for _ in 0..20_000 {
                        *m.lock() += 1;
                    }
                })
            })
            .collect();
        for t in threads {
            t.join().unwrap();
        }
        assert_eq!(*m.lock(), 80_000);
    }

    #[test]
    fn try_lock_fails_while_held_and_the_word_names_the_owner() {
        let m = PiMutex::new(1u8);
        let g = m.lock();
        assert_eq!(m.word.load(Ordering::Relaxed), thread_id());
        let other = std::thread::scope(|s| s.spawn(|| m.try_lock().is_none()).join().unwrap());
        assert!(other);
        drop(g);
        assert_eq!(m.word.load(Ordering::Relaxed), 0);
        assert!(m.try_lock().is_some());
    }
}
