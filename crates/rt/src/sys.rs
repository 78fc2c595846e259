//! Thin wrappers over the POSIX calls the executive needs: the monotonic clock, absolute
//! sleeps, a priority-inheritance mutex with a monotonic condition variable, scheduling
//! policy, CPU affinity and memory locking.

use std::cell::UnsafeCell;
use std::ops::{Deref, DerefMut};
use std::sync::atomic::{AtomicBool, Ordering};

/// Nanoseconds on `CLOCK_MONOTONIC`.
pub(crate) fn monotonic_ns() -> u64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid out-pointer; CLOCK_MONOTONIC always exists on Linux.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    (ts.tv_sec as u64) * 1_000_000_000 + ts.tv_nsec as u64
}

fn timespec_from_ns(ns: u64) -> libc::timespec {
    libc::timespec {
        tv_sec: (ns / 1_000_000_000) as libc::time_t,
        tv_nsec: (ns % 1_000_000_000) as libc::c_long,
    }
}

/// Sleeps until the absolute `CLOCK_MONOTONIC` time `ns` (TIMER_ABSTIME, restarted on EINTR).
pub(crate) fn sleep_until_monotonic(ns: u64) {
    let ts = timespec_from_ns(ns);
    loop {
        // SAFETY: valid timespec pointer; a null remainder is allowed with TIMER_ABSTIME.
        let rc = unsafe {
            libc::clock_nanosleep(
                libc::CLOCK_MONOTONIC,
                libc::TIMER_ABSTIME,
                &ts,
                std::ptr::null_mut(),
            )
        };
        if rc != libc::EINTR {
            return;
        }
    }
}

/// A mutex with the priority-inheritance protocol (`PTHREAD_PRIO_INHERIT`) and a condition
/// variable on `CLOCK_MONOTONIC`. The blocking IPC objects (mailboxes, semaphores) are built
/// on it; `PiMutex` uses the same kernel mechanism (a PI futex) without the condition
/// variable. So the only lock a real-time task ever takes is a PI mutex.
pub(crate) struct PiLock<T> {
    // Boxed: pthread objects must not move after initialisation.
    mutex: Box<UnsafeCell<libc::pthread_mutex_t>>,
    cond: Box<UnsafeCell<libc::pthread_cond_t>>,
    data: UnsafeCell<T>,
}

// SAFETY: access to `data` is serialised by the pthread mutex.
unsafe impl<T: Send> Send for PiLock<T> {}
// SAFETY: as above; `&PiLock<T>` only hands out `&mut T` under the lock.
unsafe impl<T: Send> Sync for PiLock<T> {}

impl<T> PiLock<T> {
    pub(crate) fn new(value: T) -> Self {
        // SAFETY: zeroed pthread objects are immediately initialised by the *_init calls,
        // which are given valid attribute objects.
        unsafe {
            let mutex: Box<UnsafeCell<libc::pthread_mutex_t>> =
                Box::new(UnsafeCell::new(std::mem::zeroed()));
            let mut mattr: libc::pthread_mutexattr_t = std::mem::zeroed();
            libc::pthread_mutexattr_init(&mut mattr);
            libc::pthread_mutexattr_setprotocol(&mut mattr, libc::PTHREAD_PRIO_INHERIT);
            libc::pthread_mutex_init(mutex.get(), &mattr);
            libc::pthread_mutexattr_destroy(&mut mattr);

            let cond: Box<UnsafeCell<libc::pthread_cond_t>> =
                Box::new(UnsafeCell::new(std::mem::zeroed()));
            let mut cattr: libc::pthread_condattr_t = std::mem::zeroed();
            libc::pthread_condattr_init(&mut cattr);
            libc::pthread_condattr_setclock(&mut cattr, libc::CLOCK_MONOTONIC);
            libc::pthread_cond_init(cond.get(), &cattr);
            libc::pthread_condattr_destroy(&mut cattr);

            PiLock {
                mutex,
                cond,
                data: UnsafeCell::new(value),
            }
        }
    }

    pub(crate) fn lock(&self) -> PiGuard<'_, T> {
        // SAFETY: the mutex was initialised in `new` and lives as long as `self`.
        unsafe { libc::pthread_mutex_lock(self.mutex.get()) };
        IPC_TOUCHED.with(|t| t.set(true));
        PiGuard { lock: self }
    }

    /// Wakes every thread waiting on the condition variable.
    pub(crate) fn notify_all(&self) {
        // SAFETY: the condition variable was initialised in `new`.
        unsafe { libc::pthread_cond_broadcast(self.cond.get()) };
    }
}

impl<T> Drop for PiLock<T> {
    fn drop(&mut self) {
        // SAFETY: nobody can hold the lock or wait on it while we have `&mut self`.
        unsafe {
            libc::pthread_cond_destroy(self.cond.get());
            libc::pthread_mutex_destroy(self.mutex.get());
        }
    }
}

pub(crate) struct PiGuard<'a, T> {
    lock: &'a PiLock<T>,
}

impl<T> PiGuard<'_, T> {
    /// Waits on the condition variable until woken or until the absolute monotonic time
    /// `deadline_ns`. Returns false when the deadline passed.
    pub(crate) fn wait_until(&mut self, deadline_ns: u64) -> bool {
        let ts = timespec_from_ns(deadline_ns);
        // SAFETY: we hold the mutex (guard exists); both objects are initialised.
        let rc = unsafe {
            libc::pthread_cond_timedwait(self.lock.cond.get(), self.lock.mutex.get(), &ts)
        };
        rc != libc::ETIMEDOUT
    }
}

impl<T> Deref for PiGuard<'_, T> {
    type Target = T;
    fn deref(&self) -> &T {
        // SAFETY: the guard proves we hold the mutex.
        unsafe { &*self.lock.data.get() }
    }
}

impl<T> DerefMut for PiGuard<'_, T> {
    fn deref_mut(&mut self) -> &mut T {
        // SAFETY: the guard proves we hold the mutex.
        unsafe { &mut *self.lock.data.get() }
    }
}

impl<T> Drop for PiGuard<'_, T> {
    fn drop(&mut self) {
        // SAFETY: we locked it when creating the guard.
        unsafe { libc::pthread_mutex_unlock(self.lock.mutex.get()) };
    }
}

/// Lowest and highest SCHED_FIFO priority of this OS (1 and 99 on Linux).
///
/// Real-time: yes (no allocation, no blocking).
pub fn os_fifo_range() -> (i32, i32) {
    // SAFETY: plain queries.
    unsafe {
        (
            libc::sched_get_priority_min(libc::SCHED_FIFO),
            libc::sched_get_priority_max(libc::SCHED_FIFO),
        )
    }
}

/// Maps an executive priority (0..=127, the RTX64 range) onto the OS SCHED_FIFO range,
/// keeping order: 0 -> lowest, 127 -> highest.
///
/// Real-time: yes (no allocation, no blocking).
pub fn os_priority(priority: i32) -> i32 {
    let (lo, hi) = os_fifo_range();
    let p = priority.clamp(0, 127);
    lo + (p * (hi - lo) + 63) / 127
}

/// The smallest executive priority that [`os_priority`] maps onto the OS priority `os`.
///
/// Real-time: yes (no allocation, no blocking).
pub fn executive_priority_for_os(os: i32) -> i32 {
    (0..=127).find(|&p| os_priority(p) >= os).unwrap_or(127)
}

/// Outcome of asking the OS for SCHED_FIFO.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum SchedOutcome {
    Fifo,
    NotPermitted,
}

pub(crate) fn set_current_thread_fifo(os_priority: i32) -> SchedOutcome {
    let param = libc::sched_param {
        sched_priority: os_priority,
    };
    // SAFETY: valid param for the calling thread.
    let rc = unsafe { libc::pthread_setschedparam(libc::pthread_self(), libc::SCHED_FIFO, &param) };
    if rc == 0 {
        SchedOutcome::Fifo
    } else {
        SchedOutcome::NotPermitted
    }
}

/// The CPUs this process may run on (its affinity mask), in increasing order.
///
/// Real-time: no (allocates).
pub fn allowed_cpus() -> Vec<usize> {
    // SAFETY: cpu_set_t is plain data; sched_getaffinity fills at most its size.
    unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        if libc::sched_getaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &mut set) != 0 {
            return (0..std::thread::available_parallelism().map_or(1, |n| n.get())).collect();
        }
        (0..libc::CPU_SETSIZE as usize)
            .filter(|&cpu| libc::CPU_ISSET(cpu, &set))
            .collect()
    }
}

pub(crate) fn set_current_thread_affinity(cpus: &[usize]) -> bool {
    // SAFETY: cpu_set_t is plain data; CPU_SET bounds-checks against its size.
    unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        libc::CPU_ZERO(&mut set);
        for &cpu in cpus {
            libc::CPU_SET(cpu, &mut set);
        }
        libc::pthread_setaffinity_np(
            libc::pthread_self(),
            std::mem::size_of::<libc::cpu_set_t>(),
            &set,
        ) == 0
    }
}

/// True when locking all current and future memory cannot make later allocations fail: the
/// memlock limit is infinite or the process has CAP_IPC_LOCK.
pub(crate) fn may_lock_all_memory() -> bool {
    let mut limit = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: valid out-pointer.
    let unlimited = unsafe { libc::getrlimit(libc::RLIMIT_MEMLOCK, &mut limit) } == 0
        && limit.rlim_cur == libc::RLIM_INFINITY;
    unlimited || has_effective_capability(CAP_IPC_LOCK)
}

/// Capability number of CAP_IPC_LOCK (linux/capability.h).
const CAP_IPC_LOCK: u32 = 14;

/// Reads an effective capability bit from /proc/self/status (start-up only).
fn has_effective_capability(bit: u32) -> bool {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|status| {
            let hex = status
                .lines()
                .find_map(|l| l.strip_prefix("CapEff:"))?
                .trim()
                .to_string();
            u64::from_str_radix(&hex, 16).ok()
        })
        .is_some_and(|caps| caps & (1u64 << bit) != 0)
}

pub(crate) fn lock_all_memory() -> bool {
    // SAFETY: plain syscall.
    unsafe { libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE) == 0 }
}

/// Touches `bytes` of stack so that page faults happen now, not in the first cycles.
pub(crate) fn prefault_stack(bytes: usize) {
    let mut probe = [0u8; 64 * 1024];
    let n = bytes.min(probe.len());
    for i in (0..n).step_by(4096) {
        // volatile so the compiler keeps the writes
        // SAFETY: `i < probe.len()`.
        unsafe { std::ptr::write_volatile(probe.as_mut_ptr().add(i), 1) };
    }
    std::hint::black_box(&probe);
}

thread_local! {
    static IN_TASK_BODY: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
    static IN_PERIODIC_BODY: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
    /// Set whenever this thread took the lock of a blocking IPC object (every change of a
    /// mailbox, semaphore or start event happens under it): the virtual-time runner polls
    /// its triggers only after that.
    static IPC_TOUCHED: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Whether this thread took an IPC object's lock since the last call (and clears it).
pub(crate) fn take_ipc_touched() -> bool {
    IPC_TOUCHED.with(|t| t.replace(false))
}

/// True while the calling thread is executing a task body (blocking IPC calls are refused).
pub(crate) fn in_task_body() -> bool {
    IN_TASK_BODY.with(|f| f.get())
}

pub(crate) fn set_in_task_body(on: bool) {
    IN_TASK_BODY.with(|f| f.set(on));
}

/// True while the calling thread is executing the body of a periodic task, under either
/// scheduler: the code that must not allocate, block or take a lock other than a PI mutex.
/// An allocation-counting test reads it from its global allocator (a plain thread-local
/// read: it neither allocates nor blocks). May run on a real-time path.
///
/// Real-time: yes (no allocation, no blocking).
pub fn in_periodic_body() -> bool {
    IN_PERIODIC_BODY.with(|f| f.get())
}

pub(crate) fn set_in_periodic_body(on: bool) {
    IN_PERIODIC_BODY.with(|f| f.set(on));
}

/// Prints a message once per process for a given flag.
pub(crate) fn warn_once(flag: &AtomicBool, message: &str) {
    if !flag.swap(true, Ordering::Relaxed) {
        eprintln!("rtcnc-rt: warning: {message}");
    }
}

/// Asks the kernel to keep CPUs out of power-saving states deeper than `us` microseconds of
/// exit latency (PM QoS, as cyclictest does); the request holds while the file stays open.
pub(crate) fn hold_cpu_dma_latency(us: u32) -> Option<std::fs::File> {
    use std::io::Write;
    let mut file = std::fs::OpenOptions::new()
        .write(true)
        .open("/dev/cpu_dma_latency")
        .ok()?;
    file.write_all(&(us as i32).to_ne_bytes()).ok()?;
    Some(file)
}
