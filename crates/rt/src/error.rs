//! Errors of building a task set or creating an IPC object: each names the task, thread or
//! channel at fault and has a stable code.

use thiserror::Error;

/// A task set or a channel was described wrongly. Found at start-up, never while running.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum ConfigError {
    /// A periodic thread with a zero period.
    #[error("thread '{thread}': period must be greater than zero")]
    ZeroPeriod {
        /// The thread.
        thread: String,
    },
    /// A priority outside 0..=127.
    #[error("{kind} '{name}': priority {priority} is outside 0..=127")]
    PriorityOutOfRange {
        /// "thread" or "task".
        kind: &'static str,
        /// Its name.
        name: String,
        /// The priority given.
        priority: i32,
    },
    /// Two threads or two tasks with one name.
    #[error("{kind} name '{name}' is used twice")]
    DuplicateName {
        /// "thread" or "task".
        kind: &'static str,
        /// The name.
        name: String,
    },
    /// An empty name.
    #[error("a {kind} has an empty name")]
    EmptyName {
        /// "thread" or "task".
        kind: &'static str,
    },
    /// A periodic task that runs zero times per activation.
    #[error("task '{task}': runs per activation must be at least 1")]
    ZeroRuns {
        /// The task.
        task: String,
    },
    /// A deadline of zero.
    #[error("task '{task}': deadline must be greater than zero")]
    ZeroDeadline {
        /// The task.
        task: String,
    },
    /// A deadline given to a background task.
    #[error("task '{task}': background tasks have no deadline")]
    DeadlineOnBackground {
        /// The task.
        task: String,
    },
    /// A periodic thread without tasks.
    #[error("thread '{thread}' has no tasks")]
    EmptyThread {
        /// The thread.
        thread: String,
    },
    /// A task added to a thread id that this builder did not create.
    #[error("task '{task}': unknown thread")]
    UnknownThread {
        /// The task.
        task: String,
    },
    /// A mailbox, ring or semaphore with no room.
    #[error("channel '{channel}': capacity must be at least 1")]
    ZeroCapacity {
        /// The channel.
        channel: String,
    },
    /// A counting semaphore whose initial count exceeds its maximum.
    #[error("semaphore '{channel}': initial count {initial} exceeds the maximum {max}")]
    InitialAboveMax {
        /// The semaphore.
        channel: String,
        /// Initial count.
        initial: u32,
        /// Maximum count.
        max: u32,
    },
}

impl ConfigError {
    /// Stable error code.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn code(&self) -> &'static str {
        match self {
            ConfigError::ZeroPeriod { .. } => "zero_period",
            ConfigError::PriorityOutOfRange { .. } => "priority_out_of_range",
            ConfigError::DuplicateName { .. } => "duplicate_name",
            ConfigError::EmptyName { .. } => "empty_name",
            ConfigError::ZeroRuns { .. } => "zero_runs",
            ConfigError::EmptyThread { .. } => "empty_thread",
            ConfigError::ZeroDeadline { .. } => "zero_deadline",
            ConfigError::DeadlineOnBackground { .. } => "deadline_on_background",
            ConfigError::UnknownThread { .. } => "unknown_thread",
            ConfigError::ZeroCapacity { .. } => "zero_capacity",
            ConfigError::InitialAboveMax { .. } => "initial_above_max",
        }
    }
}
