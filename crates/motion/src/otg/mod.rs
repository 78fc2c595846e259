//! Time-optimal, jerk-limited online trajectory generation (OTG) for single axes and
//! synchronised groups of axes, in the manner of ruckig.
//!
//! * [`position_profile`]: from any state `(p, v, a)` to a target state, time-optimal under
//!   velocity, acceleration and jerk limits (a start outside the limits brakes first).
//! * [`velocity_profile`]: reach a target velocity and acceleration (jog, override, stop);
//!   [`synchronize_velocity`]: several axes reaching theirs together.
//! * [`synchronize`] / [`synchronize_on_period`]: several axes arriving together;
//!   [`synchronize_straight`]: several axes along the straight line between the positions;
//!   [`position_profile_with_duration`]: one axis, a prescribed duration.
//! * [`along_path`]: the path planner's 1-D problem `(0, v0, a0) -> (L, v1, 0)`.
//! * [`OnlineAxis`] / [`OnlineGroup`]: one servo period at a time, targets replaceable at
//!   any moment (planned from the current set-point).
//!
//! A [`Profile`] is at most [`MAX_PHASES`] constant-jerk phases evaluated in closed form by
//! [`Profile::at`], cheap enough for every servo period. Errors are [`OtgError`] values with
//! a stable [`OtgError::code`]; nothing here panics on data or returns NaN.
//!
//! ```
//! use rtcnc_motion::otg::{Limits, State, position_profile};
//!
//! // The seeds' experiment: 6000 pulses, 50 pulse/ms, 1 pulse/ms², 0.01 pulse/ms³.
//! let limits = Limits::symmetric(50.0, 1.0, 0.01);
//! let profile = position_profile(State::at_rest(0.0), State::at_rest(6000.0), &limits)?;
//! assert!((profile.duration() - 267.773).abs() < 1e-3);
//! let mut t = 0.0;
//! while t < profile.duration() {
//!     let set_point = profile.at(t); // p, v, a, j for this servo period
//!     assert!(set_point.v <= 50.0);
//!     t += 1.0;
//! }
//! assert_eq!(profile.at(profile.duration()).p, 6000.0);
//! # Ok::<(), rtcnc_motion::otg::OtgError>(())
//! ```

mod brake;
mod check;
mod error;
mod limits;
mod online;
mod position;
mod profile;
mod roots;
mod straight;
mod sync;
mod velocity;

pub use error::OtgError;
pub use limits::{Limits, State};
pub use online::{OnlineAxis, OnlineGroup};
pub use position::{Block, along_path, position_block, position_profile};
pub use profile::{MAX_PHASES, Phase, Profile, Sample};
pub use straight::synchronize_straight;
pub use sync::{Synchronized, position_profile_with_duration, synchronize, synchronize_on_period};
pub use velocity::{synchronize_velocity, velocity_profile};
