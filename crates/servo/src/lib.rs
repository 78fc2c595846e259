//! Position control for one joint of a machine, run once per servo cycle.
//!
//! Two loops share one vocabulary ([`SetPoint`] in, a command out, a [`ServoFault`] when the
//! joint cannot follow):
//!
//! - [`PidController`]: the controller closes the position loop and outputs a velocity
//!   command (an analogue drive behind a DAC, or a drive in cyclic synchronous velocity
//!   mode). PID on the position error with velocity and acceleration feed-forward, bias,
//!   deadband, output limit and integrator clamping (anti-windup), after LinuxCNC's `pid`
//!   component.
//! - [`CspLoop`]: the drive closes its own loop (CiA 402 cyclic synchronous position); the
//!   controller passes the set-point on with optional velocity and torque feed-forward
//!   offsets and still watches the following error.
//!
//! [`ServoLoop`] holds either, chosen by the configuration (`loop = "pid"` or `"csp"`).
//! Both check the following error against [`FollowingErrorLimits`]: a static limit at
//! standstill and a limit that grows with the commanded speed (LinuxCNC's `MIN_FERROR` and
//! `FERROR`).
//!
//! Every per-cycle call is allocation-free and never panics on data: a non-finite input or
//! period is a [`ServoFault`], never a NaN output. On a real-time path: the loops' `update`
//! and `reset`, [`FollowingErrorMonitor::check`], [`SetPointDifferentiator::next`] and the
//! accessors. Set-up only (they validate, and an error names the field): the constructors,
//! the configurations' `validate` and [`PidController::set_gains`]. The caller passes the
//! period each cycle. Each public function's doc says it in a line of its own,
//! `Real-time: yes (...)` or `Real-time: no (why)`; `crates/kernel/tests/real_time_docs.rs`
//! checks that every one has it. Configuration structs deserialize with serde (the machine
//! TOML) and validate with errors that name the field.
//!
//! ```
//! use rtcnc_servo::{FollowingErrorLimits, PidConfig, PidController, PidGains, SetPoint};
//!
//! let limits = FollowingErrorLimits { min_ferror: 0.01, ferror: 0.1, max_velocity: 100.0 };
//! let config = PidConfig { gains: PidGains::default(), following_error: limits };
//! let mut pid = PidController::new(0, &config)?;
//! // Each cycle: the interpolator's set-point, the measured position, the period.
//! let setpoint = SetPoint { position: 1.0, velocity: 10.0, acceleration: 0.0 };
//! let velocity_command = pid.update(setpoint, 0.999, 0.001)?;
//! assert!((velocity_command - (200.0 * 0.001 + 10.0)).abs() < 1e-9);
//! // Too far behind: a fault naming the joint.
//! let fault = pid.update(setpoint, 0.5, 0.001).unwrap_err();
//! assert_eq!(fault.code(), "servo.following_error");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

#![forbid(unsafe_code)]

mod config;
mod csp;
mod fault;
mod following_error;
mod joint_loop;
mod pid;
mod setpoint;

pub use config::{
    ConfigError, CspConfig, FollowingErrorLimits, MAX_FEEDBACK_DELAY, PidConfig, PidGains,
};
pub use csp::{CspCommand, CspLoop};
pub use fault::ServoFault;
pub use following_error::FollowingErrorMonitor;
pub use joint_loop::{ServoCommand, ServoLoop, ServoLoopConfig};
pub use pid::PidController;
pub use setpoint::{SetPoint, SetPointDifferentiator};
