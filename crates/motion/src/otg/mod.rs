//! Time-optimal, jerk-limited online trajectory generation (OTG) for single axes and
//! synchronised groups of axes, in the manner of ruckig.
//!
//! * [`position_profile`]: from any state `(p, v, a)` to a target state, time-optimal under
//!   velocity, acceleration and jerk limits.
//! * [`velocity_profile`]: reach a target velocity and acceleration (jog, override, stop).
//!
//! A [`Profile`] is a short list of constant-jerk phases evaluated in closed form by
//! [`Profile::at`], cheap enough for every servo period.

mod brake;
mod check;
mod error;
mod limits;
mod online;
mod position;
mod profile;
mod roots;
mod sync;
mod velocity;

pub use error::OtgError;
pub use limits::{Limits, State};
pub use online::{OnlineAxis, OnlineGroup};
pub use position::{Block, along_path, position_block, position_profile};
pub use profile::{MAX_PHASES, Phase, Profile, Sample};
pub use sync::{Synchronized, position_profile_with_duration, synchronize, synchronize_on_period};
pub use velocity::velocity_profile;
