//! rtcnc motion: motion planning and interpolation for CNC machines.
//!
//! This crate is a layer-2 library of rtcnc: no threads, no I/O, no dependency on the other
//! rtcnc crates.
//!
//! - [`Planner`]: look-ahead path planning (corner blends and smoothing of dense polylines
//!   within the G64 tolerance, exact stops), jerk-limited path speed under every axis's
//!   velocity, acceleration and jerk limit, and interpolation: feed it [`Move`]s (mm and
//!   seconds), call [`Planner::next`] once per servo period to get joint set-points. No
//!   allocation in [`Planner::next`].
//! - [`otg`]: the time-optimal jerk-limited state-to-state trajectory generator (jog,
//!   point-to-point moves).
//!
//! See `docs/motion.md` for the methods and their guarantees.
//!
//! # Real-time use
//!
//! These may run on a real-time path (no allocation, no blocking call, bounded time; the
//! planner's are counted by `tests/no_alloc.rs`): [`Planner::push`], [`Planner::push_all`],
//! [`Planner::flush`], [`Planner::next`], the overrides, [`Planner::hold`],
//! [`Planner::resume`], [`Planner::abort`], [`Planner::quick_stop`], [`Planner::unemit`],
//! [`Planner::reset_at`] and the planner's read-only accessors; the [`Move`] constructors;
//! the [`otg`] functions and their profiles' evaluation. The rest is set-up and may
//! allocate: [`Planner::new`] and [`Planner::with_history`] (memory is fixed there),
//! [`TrivialKinematics`]' constructors, [`MachineLimits::validate`] (its error names the
//! limit), and formatting an error's message. Each public function's doc says it in a line
//! of its own, `Real-time: yes (...)` or `Real-time: no (why)`;
//! `crates/kernel/tests/real_time_docs.rs` checks that every one has it.
#![forbid(unsafe_code)]
// Numeric code over fixed 9-axis arrays reads best with index loops; negated comparisons are
// how NaN is refused (`!(x > 0.0)` is true for NaN).
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]

/// The planner's diagnostic lines on stderr, for debugging the generator: compiled in only
/// with the crate's `diagnostics` feature, and printed only when the planner's trace is on
/// (`RTCNC_MOTION_TRACE` set when it was built). Without the feature the condition is a
/// constant false and the line is dead code (still type-checked), so the real-time paths
/// neither print nor allocate. `trace!(on, "format", args..)` prints a line;
/// `trace!(on, { statements })` runs a block that prints.
macro_rules! trace {
    ($on:expr, { $($body:tt)* }) => {
        if cfg!(feature = "diagnostics") && $on {
            $($body)*
        }
    };
    ($on:expr, $($arg:tt)+) => {
        if cfg!(feature = "diagnostics") && $on {
            eprintln!($($arg)+);
        }
    };
}

mod axes;
mod builder;
mod error;
mod five_axis;
mod geometry;
mod head_kinematics;
mod input;
mod kinematics;
mod limits;
pub mod nurbs;
pub mod otg;
mod piece;
mod planner;
mod scurve;
mod spline;
mod table_kinematics;

pub use axes::{AXES, Axis, AxisVec};
pub use builder::GeometryStats;
pub use error::MotionError;
pub use five_axis::FiveAxisKinematics;
pub use head_kinematics::HeadKinematics;
pub use input::{Bezier, Feed, Move, MoveKind, PathMode};
pub use kinematics::{JointLimits, Kinematics, TrivialKinematics};
pub use limits::{AxisLimits, MIN_JERK_PHASE_PERIODS, MachineLimits};
pub use planner::{MotionState, Planner, Preparation, PreparedMove, RewindError, RunStats, Status};
pub use spline::CurvePart;
pub use table_kinematics::{Chord, MAX_CHORDS, TableKinematics, TcpMove, TiltAxis, TipPath};
