//! Errors of the motion library: values with a stable code, never panics.

use thiserror::Error;

/// Everything the planner can refuse. `line` is the program line of the offending move
/// (0 when the error is about the machine configuration rather than a move).
#[derive(Debug, Clone, PartialEq, Error)]
pub enum MotionError {
    /// A machine limit is zero, negative, NaN or infinite where a finite positive value is needed.
    #[error("invalid limit {what}: {value} (must be finite and > 0)")]
    InvalidLimit {
        /// Which limit (for example `"axis X jerk"`).
        what: String,
        /// The value given.
        value: f64,
    },
    /// A move contains NaN or an infinite coordinate, feed or time.
    #[error("line {line}: {what} is not a finite number")]
    NotFinite {
        /// Program line.
        line: u32,
        /// Which field.
        what: &'static str,
    },
    /// A move whose path has zero length (it would carry no motion).
    #[error("line {line}: zero-length move")]
    ZeroLength {
        /// Program line.
        line: u32,
    },
    /// Feed rate zero or negative on a feed move.
    #[error("line {line}: feed rate {feed} must be > 0")]
    InvalidFeed {
        /// Program line.
        line: u32,
        /// Resolved feed in mm/s.
        feed: f64,
    },
    /// Arc start and end are at distances from the centre that differ by more than the
    /// move's `radius_tolerance`.
    #[error(
        "line {line}: arc radius mismatch: start radius {start_radius} mm, end radius {end_radius} mm (tolerance {tolerance} mm)"
    )]
    ArcRadiusMismatch {
        /// Program line.
        line: u32,
        /// Distance of the start point from the centre.
        start_radius: f64,
        /// Distance of the end point from the centre.
        end_radius: f64,
        /// The move's tolerance.
        tolerance: f64,
    },
    /// Arc geometry that defines no arc (zero radius, zero normal).
    #[error("line {line}: invalid arc: {why}")]
    InvalidArc {
        /// Program line.
        line: u32,
        /// Reason.
        why: &'static str,
    },
    /// Spline control points that define no followable curve: the curve stops or turns back
    /// inside (a cusp), or a control point lies on its end point (no direction there).
    #[error("line {line}: invalid spline: {why}")]
    InvalidSpline {
        /// Program line.
        line: u32,
        /// Reason.
        why: &'static str,
    },
    /// Invalid path-control tolerance (negative or NaN P or Q).
    #[error("line {line}: invalid blend tolerance {value}")]
    InvalidTolerance {
        /// Program line.
        line: u32,
        /// The value.
        value: f64,
    },
    /// The move's path leaves the machine envelope.
    #[error(
        "line {line}: soft limit: axis {axis} would reach {position:.6} mm, outside [{min}, {max}]"
    )]
    SoftLimit {
        /// Program line.
        line: u32,
        /// Axis letter.
        axis: char,
        /// Extreme position the path reaches.
        position: f64,
        /// Lower limit.
        min: f64,
        /// Upper limit.
        max: f64,
    },
    /// A tool-centre-point move cannot be cut into joint-space chords within its
    /// tolerance.
    #[error("line {line}: tool-centre-point move: {why}")]
    ToolCentrePoint {
        /// Program line.
        line: u32,
        /// Reason.
        why: &'static str,
    },
    /// Kinematics configuration error.
    #[error("kinematics: {0}")]
    Kinematics(String),
    /// Moves were pushed while the planner queue is full; push again after some periods.
    #[error("planner queue full")]
    QueueFull,
    /// A command that needs the machine at rest was given while moving.
    #[error("planner busy: {0}")]
    Busy(&'static str),
}

impl MotionError {
    /// Stable machine-readable code (`MOTION-xxx`).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn code(&self) -> &'static str {
        match self {
            MotionError::InvalidLimit { .. } => "MOTION-001",
            MotionError::NotFinite { .. } => "MOTION-002",
            MotionError::ZeroLength { .. } => "MOTION-003",
            MotionError::InvalidFeed { .. } => "MOTION-004",
            MotionError::ArcRadiusMismatch { .. } => "MOTION-005",
            MotionError::InvalidArc { .. } => "MOTION-006",
            MotionError::InvalidTolerance { .. } => "MOTION-007",
            MotionError::SoftLimit { .. } => "MOTION-008",
            MotionError::Kinematics(_) => "MOTION-009",
            MotionError::QueueFull => "MOTION-010",
            MotionError::Busy(_) => "MOTION-011",
            MotionError::InvalidSpline { .. } => "MOTION-012",
            MotionError::ToolCentrePoint { .. } => "MOTION-013",
        }
    }

    /// Program line the error refers to, when it refers to a move.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn line(&self) -> Option<u32> {
        match self {
            MotionError::NotFinite { line, .. }
            | MotionError::ZeroLength { line }
            | MotionError::InvalidFeed { line, .. }
            | MotionError::ArcRadiusMismatch { line, .. }
            | MotionError::InvalidArc { line, .. }
            | MotionError::InvalidSpline { line, .. }
            | MotionError::ToolCentrePoint { line, .. }
            | MotionError::InvalidTolerance { line, .. }
            | MotionError::SoftLimit { line, .. } => Some(*line),
            _ => None,
        }
    }
}
