//! rtcnc motion library: look-ahead path planning, jerk-limited path speed and interpolation.
//! [`otg`] holds the time-optimal jerk-limited state-to-state trajectory generator (jog,
//! homing, independent axes).
//!
//! Feed [`Planner::push`] with [`Move`]s (mm and seconds), call [`Planner::next`] once per
//! servo period to get joint set-points. No threads, no allocation in [`Planner::next`].
//! See `docs/motion.md` for the method and its guarantees.
#![warn(missing_docs)]
// Numeric code over fixed 9-axis arrays reads best with index loops; negated comparisons are
// how NaN is refused (`!(x > 0.0)` is true for NaN).
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]

mod axes;
mod builder;
mod error;
mod geometry;
mod input;
mod kinematics;
mod limits;
pub mod otg;
mod piece;
mod planner;
mod scurve;

pub use axes::{AXES, Axis, AxisVec};
pub use builder::GeometryStats;
pub use error::MotionError;
pub use input::{Feed, Move, MoveKind, PathMode};
pub use kinematics::{JointLimits, Kinematics, TrivialKinematics};
pub use limits::{AxisLimits, MachineLimits};
pub use planner::{MotionState, Planner, RunStats, Status};
