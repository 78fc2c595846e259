//! Plain-data input of the planner: moves in mm (degrees for rotary axes) and seconds.

use crate::axes::AxisVec;

/// How fast a feed move goes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Feed {
    /// Path speed in mm/s (G94; the interpreter's mm/min divided by 60).
    UnitsPerSecond(f64),
    /// Inverse time (G93): the move takes this many seconds (at 100 % override).
    InverseTime {
        /// Duration of the move.
        seconds: f64,
    },
    /// Per revolution (G95): mm per spindle revolution, with the spindle speed the move runs at.
    PerRevolution {
        /// Feed per revolution, mm.
        mm_per_rev: f64,
        /// Spindle speed, revolutions per second.
        spindle_rev_per_s: f64,
    },
}

/// Path control mode of a move (applies to the junction at its end).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PathMode {
    /// G61.1: stop at the end of every move.
    ExactStop,
    /// G61: follow the programmed path exactly; stop only where the path has a corner.
    ExactPath,
    /// G64 P Q: round corners within `tolerance` (P, mm); merge nearly collinear lines within
    /// `merge_tolerance` (Q, mm; 0 disables merging).
    Blend {
        /// Maximal distance of the rounded path from the programmed corner.
        tolerance: f64,
        /// Collinear-merge tolerance.
        merge_tolerance: f64,
    },
}

/// The geometry of one move; the start is the end of the previous move.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MoveKind {
    /// Straight line to `end` (all nine axes move linearly).
    Line {
        /// End point.
        end: AxisVec,
        /// Rapid traverse (G0): speed set by the axis limits and the rapid override.
        rapid: bool,
    },
    /// Arc or helix: around `centre` counter-clockwise seen from the tip of `normal`
    /// (right-hand rule; a G2 in G17 has normal (0,0,-1)), `turns` extra full turns, ending
    /// at `end`. The component along the normal and the axes A..W move linearly (helix).
    /// When the end point's distance from the centre (in the plane) differs from the start
    /// point's, the radius changes linearly with the angle (a spiral, as LinuxCNC runs
    /// such an arc), provided the difference is within `radius_tolerance`.
    Arc {
        /// End point.
        end: AxisVec,
        /// Centre (X Y Z); its component along the normal is irrelevant.
        centre: [f64; 3],
        /// Plane normal (need not be unit length).
        normal: [f64; 3],
        /// Additional full turns (0 for an arc of less than one turn).
        turns: u32,
        /// Largest difference between the end and the start radius the caller accepts, mm
        /// (the interpreter's tolerance, e.g. `rtcnc_gcode::ArcRadiusTolerance`); a larger
        /// one is refused with [`crate::MotionError::ArcRadiusMismatch`]. 0 for an exact
        /// circle (the rounding of the coordinates is always allowed).
        radius_tolerance: f64,
    },
    /// Polynomial spline (G5 cubic, G5.1 quadratic) in Bézier form, from the start point
    /// through the control points to `end`, evaluated exactly as the polynomial. Every axis
    /// follows the polynomial: an axis whose control values lie evenly spaced between its
    /// start and end value moves linearly (the axes outside a G5 plane).
    Spline {
        /// End point.
        end: AxisVec,
        /// Inner control points.
        control: Bezier,
    },
    /// Dwell at rest.
    Dwell {
        /// Seconds.
        seconds: f64,
    },
}

/// Inner control points of a [`MoveKind::Spline`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Bezier {
    /// Quadratic Bézier (G5.1): one control point.
    Quadratic(AxisVec),
    /// Cubic Bézier (G5): two control points, the first after the start point.
    Cubic([AxisVec; 2]),
}

/// One move as the planner receives it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Move {
    /// Geometry.
    pub kind: MoveKind,
    /// Feed (ignored by rapids and dwells).
    pub feed: Feed,
    /// Path control mode.
    pub mode: PathMode,
    /// Source line number, carried into errors and status.
    pub line: u32,
}

impl Move {
    /// A feed line at `feed` mm/s.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn line(end: AxisVec, feed: f64, mode: PathMode, line: u32) -> Self {
        Move {
            kind: MoveKind::Line { end, rapid: false },
            feed: Feed::UnitsPerSecond(feed),
            mode,
            line,
        }
    }

    /// A rapid line.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn rapid(end: AxisVec, mode: PathMode, line: u32) -> Self {
        Move {
            kind: MoveKind::Line { end, rapid: true },
            feed: Feed::UnitsPerSecond(f64::INFINITY),
            mode,
            line,
        }
    }

    /// An arc or helix at `feed` mm/s, an exact circle (see [`Move::with_radius_tolerance`]).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn arc(
        end: AxisVec,
        centre: [f64; 3],
        normal: [f64; 3],
        turns: u32,
        feed: f64,
        mode: PathMode,
        line: u32,
    ) -> Self {
        Move {
            kind: MoveKind::Arc {
                end,
                centre,
                normal,
                turns,
                radius_tolerance: 0.0,
            },
            feed: Feed::UnitsPerSecond(feed),
            mode,
            line,
        }
    }

    /// The same move, an arc whose end radius may differ from its start radius by up to
    /// `tolerance` mm (run as a spiral); other moves are returned unchanged.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn with_radius_tolerance(mut self, tolerance: f64) -> Self {
        if let MoveKind::Arc {
            radius_tolerance, ..
        } = &mut self.kind
        {
            *radius_tolerance = tolerance;
        }
        self
    }

    /// A spline (G5, G5.1) at `feed` mm/s.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn spline(end: AxisVec, control: Bezier, feed: f64, mode: PathMode, line: u32) -> Self {
        Move {
            kind: MoveKind::Spline { end, control },
            feed: Feed::UnitsPerSecond(feed),
            mode,
            line,
        }
    }

    /// A dwell.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn dwell(seconds: f64, line: u32) -> Self {
        Move {
            kind: MoveKind::Dwell { seconds },
            feed: Feed::UnitsPerSecond(1.0),
            mode: PathMode::ExactStop,
            line,
        }
    }
}
