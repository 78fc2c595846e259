//! Tool compensation: a stage of its own between the interpreter and the motion planner.
//!
//! The interpreter emits the programmed (uncompensated) path with
//! [`StartCutterRadiusCompensation`](crate::canon::CanonCommand::StartCutterRadiusCompensation)
//! (side, radius in program units, lathe orientation) and
//! [`StopCutterRadiusCompensation`](crate::canon::CanonCommand::StopCutterRadiusCompensation)
//! where G41/G42/G41.1/G42.1 and G40 take effect. [`Compensator`] turns that stream into the
//! path of the tool's centre, the way LinuxCNC 2.9 does inside its interpreter, so its output
//! is what LinuxCNC's `rs274` prints for the same program:
//!
//! - entry: the first move after G41/G42 goes from the current point to a point one radius
//!   to the side of the programmed end (a line, or an arc through the current point);
//! - convex corners get an arc around the programmed corner point (a traverse for G0),
//!   concave corners the intersection of the two offset paths, for line-line, line-arc,
//!   arc-line and arc-arc joints, in the XY plane (G17) and the XZ plane (G18, lathes, with
//!   the tool orientation's origin shift);
//! - exit: after G40 the next move (which must be straight) goes from the compensated point
//!   to the programmed end;
//! - the errors LinuxCNC raises (gouging at a concave corner, a tool that does not fit
//!   inside an arc, an entry move shorter than the radius, an arc after G40, ...) as
//!   [`CompError`] with the block's line.
//!
//! Tool length offsets (G43/G43.1/G49) are applied by the interpreter's
//! `USE_TOOL_LENGTH_OFFSET` downstream: this stage only passes them on.
//!
//! ```
//! use rtcnc_gcode::canon::{Canon, CanonCommand, CompensationSide, Pose, Source};
//! use rtcnc_gcode::compensation::Compensator;
//!
//! let at = |x: f64, y: f64| Pose { x, y, ..Pose::ZERO };
//! let mut comp = Compensator::new();
//! let mut out = Vec::new();
//! for command in [
//!     CanonCommand::StartCutterRadiusCompensation {
//!         side: CompensationSide::Left,
//!         radius: 1.0,
//!         orientation: 0,
//!     },
//!     CanonCommand::StraightFeed(at(10.0, 0.0)),
//!     CanonCommand::StopCutterRadiusCompensation,
//!     CanonCommand::StraightFeed(at(20.0, 0.0)),
//! ] {
//!     comp.push(Canon { source: Source::default(), command })?;
//!     while let Some(c) = comp.pop() {
//!         out.push(c.command);
//!     }
//! }
//! comp.finish();
//! out.extend(std::iter::from_fn(|| comp.pop()).map(|c| c.command));
//! // The entry move ends one radius to the left of X10.
//! assert_eq!(out[1], CanonCommand::StraightFeed(at(10.0, 1.0)));
//! # Ok::<(), rtcnc_gcode::compensation::CompError>(())
//! ```

mod compensator;
mod error;
mod geometry;

pub use compensator::{Compensator, DEFAULT_CAPACITY};
pub use error::{CompError, CompErrorKind};

use crate::canon::Canon;

/// An iterator adapter: compensates a stream of canonical commands (the interpreter's, for
/// instance), turning compensation errors into the stream's error type with `map_err`.
///
/// It yields what the stage releases, in order; an error of the stream or of the stage is
/// yielded after everything released before it. Iteration may go on after an error (the
/// stage has dropped what it held and turned compensation off).
pub struct Compensate<I, F> {
    inner: I,
    map_err: F,
    stage: Compensator,
    error: Option<CompError>,
    finished: bool,
}

impl<I, F> Compensate<I, F> {
    /// Wraps `inner` with a stage of the default capacity.
    pub fn new(inner: I, map_err: F) -> Self {
        Compensate::with_stage(inner, map_err, Compensator::new())
    }

    /// Wraps `inner` with the given stage.
    pub fn with_stage(inner: I, map_err: F, stage: Compensator) -> Self {
        Compensate {
            inner,
            map_err,
            stage,
            error: None,
            finished: false,
        }
    }

    /// The wrapped stream (for instance to ask the interpreter for a file name).
    pub fn inner(&self) -> &I {
        &self.inner
    }

    /// The wrapped stream, mutably.
    pub fn inner_mut(&mut self) -> &mut I {
        &mut self.inner
    }
}

impl<I, E, F> Iterator for Compensate<I, F>
where
    I: Iterator<Item = Result<Canon, E>>,
    F: FnMut(CompError) -> E,
{
    type Item = Result<Canon, E>;

    fn next(&mut self) -> Option<Self::Item> {
        loop {
            if let Some(c) = self.stage.pop() {
                return Some(Ok(c));
            }
            if let Some(e) = self.error.take() {
                return Some(Err((self.map_err)(e)));
            }
            if self.finished {
                return None;
            }
            match self.inner.next() {
                Some(Ok(c)) => {
                    if let Err(e) = self.stage.push(c) {
                        self.error = Some(e);
                    }
                }
                Some(Err(e)) => return Some(Err(e)),
                None => {
                    self.stage.finish();
                    self.finished = true;
                }
            }
        }
    }
}
