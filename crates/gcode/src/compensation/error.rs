//! Errors of the compensation stage: LinuxCNC's messages, a stable code, the source line.

use std::fmt;
use std::sync::Arc;

use crate::canon::Source;
use crate::error::{ErrorKind, GcodeError};

/// What went wrong. The messages are LinuxCNC 2.9's, word for word, where it has one.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum CompErrorKind {
    /// The first straight move after G41/G42 is not longer than the tool radius.
    EntryMoveTooShort,
    /// The first move after G41/G42 is an arc whose chord is not longer than the tool radius.
    EntryArcTooShort,
    /// The tool runs inside an arc whose radius is not larger than the tool's.
    ToolRadiusNotLessThanArcRadius,
    /// At a concave corner the tool would have to back up beyond the start of a straight
    /// feed.
    StraightFeedGouge,
    /// The same for a straight traverse.
    StraightTraverseGouge,
    /// The same for an arc.
    ArcGouge,
    /// Two arcs meet at a concave corner the tool cannot fit in.
    ArcToArcGouge,
    /// An arc then a straight line meet at a concave corner the tool cannot fit in.
    ArcToStraightGouge,
    /// Two consecutive arcs have the same centre and meet at a corner.
    ArcsSameCentre,
    /// A straight line turns back on itself (a zero degree inside corner).
    ZeroDegreeCorner,
    /// The move right after G40 is an arc.
    ArcAfterCompensationOff,
    /// G41/G42 while compensation is already on.
    AlreadyOn,
    /// Compensation in a plane other than XY (G17) or XZ (G18), or a lathe tool
    /// orientation outside G18.
    WrongPlane,
    /// A plane change while compensation is on.
    PlaneChange,
    /// G92 / G52 offsets change while compensation is on.
    AxisOffsetChange,
    /// G61 / G61.1 / G64 while compensation is on.
    ControlModeChange,
    /// Motion-synchronized or immediate I/O (M62-M68) while compensation is on.
    OutputChange,
    /// M66 while compensation is on.
    WaitInput,
    /// M48-M53 while compensation is on.
    OverrideChange,
    /// G38.x while compensation is on.
    Probe,
    /// G5 / G5.1 while compensation is on.
    Spline,
    /// A concave corner right after a program stop, whose move can no longer be shortened.
    ConcaveAfterStop,
    /// The radius is not a finite number.
    BadRadius,
    /// More commands wait between two moves than the stage's buffer holds, or the caller
    /// did not take the stage's output.
    BufferFull,
    /// An internal consistency check failed (LinuxCNC reports these as bugs too).
    Internal,
}

impl CompErrorKind {
    /// Stable machine-readable code, e.g. `C-GOUGE`.
    pub fn code(self) -> &'static str {
        use CompErrorKind as K;
        match self {
            K::EntryMoveTooShort | K::EntryArcTooShort => "C-ENTRY",
            K::ToolRadiusNotLessThanArcRadius => "C-ARC-RADIUS",
            K::StraightFeedGouge
            | K::StraightTraverseGouge
            | K::ArcGouge
            | K::ArcToArcGouge
            | K::ArcToStraightGouge
            | K::ZeroDegreeCorner
            | K::ConcaveAfterStop => "C-GOUGE",
            K::ArcsSameCentre => "C-ARC-CENTRE",
            K::ArcAfterCompensationOff => "C-EXIT",
            K::AlreadyOn => "C-ON",
            K::WrongPlane | K::PlaneChange => "C-PLANE",
            K::AxisOffsetChange
            | K::ControlModeChange
            | K::OutputChange
            | K::WaitInput
            | K::OverrideChange
            | K::Probe
            | K::Spline => "C-STATE",
            K::BadRadius => "C-RADIUS",
            K::BufferFull => "C-BUFFER",
            K::Internal => "C-BUG",
        }
    }

    /// The plain message (LinuxCNC's text where it has one).
    pub fn message(self) -> &'static str {
        use CompErrorKind as K;
        match self {
            K::EntryMoveTooShort => {
                "Length of cutter compensation entry move is not greater than the tool radius"
            }
            K::EntryArcTooShort => {
                "Radius of cutter compensation entry arc is not greater than the tool radius"
            }
            K::ToolRadiusNotLessThanArcRadius => "Tool radius not less than arc radius with comp",
            K::StraightFeedGouge => {
                "Straight feed in concave corner cannot be reached by the tool without gouging"
            }
            K::StraightTraverseGouge => {
                "Straight traverse in concave corner cannot be reached by the tool without gouging"
            }
            K::ArcGouge => {
                "Arc move in concave corner cannot be reached by the tool without gouging"
            }
            K::ArcToArcGouge => {
                "Arc to arc motion makes a corner the compensated tool can't fit in without gouging"
            }
            K::ArcToStraightGouge => {
                "Arc to straight motion makes a corner the compensated tool can't fit in without gouging"
            }
            K::ArcsSameCentre => {
                "Arc to arc motion is invalid because the arcs have the same center"
            }
            K::ZeroDegreeCorner => "Zero degree inside corner is invalid for cutter compensation",
            K::ArcAfterCompensationOff => {
                "The move just after exiting cutter compensation mode must be straight, not an arc"
            }
            K::AlreadyOn => "Cannot turn cutter radius comp on when on",
            K::WrongPlane => "Cutter radius compensation allowed only in XY, XZ planes",
            K::PlaneChange => "Cannot change planes with cutter radius compensation on",
            K::AxisOffsetChange => "Cannot change axis offsets with cutter radius comp",
            K::ControlModeChange => "Cannot change control mode with cutter radius compensation on",
            K::OutputChange => "Cannot set outputs with cutter radius compensation on",
            K::WaitInput => "Cannot wait for an input with cutter radius compensation on",
            K::OverrideChange => {
                "Cannot enable or disable overrides with cutter radius compensation on"
            }
            K::Probe => "Cannot probe with cutter radius comp on",
            K::Spline => "Cannot convert spline with cutter radius compensation",
            K::ConcaveAfterStop => {
                "Concave corner right after a program stop with cutter radius compensation: \
                 the move before the stop can no longer be shortened"
            }
            K::BadRadius => "Cutter compensation radius is not a finite number",
            K::BufferFull => {
                "Too many commands between two moves with cutter radius compensation on \
                 (the compensation buffer is full)"
            }
            K::Internal => "Bug in tool radius comp",
        }
    }
}

/// An error of the compensation stage, at the block that caused it.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub struct CompError {
    /// What went wrong.
    pub kind: CompErrorKind,
    /// The block whose command could not be compensated.
    pub at: Source,
}

impl CompError {
    pub(crate) fn new(kind: CompErrorKind, source: Source) -> CompError {
        CompError { kind, at: source }
    }

    /// Stable machine-readable code.
    pub fn code(&self) -> &'static str {
        self.kind.code()
    }

    /// The plain message.
    pub fn message(&self) -> &'static str {
        self.kind.message()
    }

    /// The same error as an interpreter error, so that one error type reports both stages;
    /// `file` is the name of the file `self.at.file` designates (see
    /// `Interpreter::file_name`).
    pub fn into_gcode_error(self, file: Arc<str>) -> GcodeError {
        let kind = match self.kind {
            CompErrorKind::ToolRadiusNotLessThanArcRadius | CompErrorKind::ArcsSameCentre => {
                ErrorKind::Arc
            }
            CompErrorKind::BadRadius => ErrorKind::BadValue,
            _ => ErrorKind::State,
        };
        GcodeError {
            kind,
            file,
            line: self.at.line,
            column: 0,
            message: self.kind.message().to_string(),
        }
    }
}

impl fmt::Display for CompError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "line {}: {}", self.at.line, self.kind.message())
    }
}
