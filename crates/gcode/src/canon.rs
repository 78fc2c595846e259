//! Canonical machining commands: what the interpreter emits, what tool compensation consumes
//! and produces, and what the motion kernel executes.
//!
//! The vocabulary and argument order are those of LinuxCNC's canonical interface as its
//! stand-alone interpreter `rs274` prints them, so that [`Canon::write_rs274`] output can be
//! diffed line by line with `rs274`'s. Lengths are in the program's current length units
//! (the last [`CanonCommand::UseLengthUnits`] says which), angles in degrees, feed rates in
//! length units per minute (or per revolution in [`FeedMode::UnitsPerRevolution`]), times in
//! seconds. Coordinates are in the current work coordinate system; the consumer applies the
//! offsets it was told about: `machine = rotate(program + g92, rotation) + g5x`, and the tool
//! length offset on top.

use std::borrow::Cow;

/// Identifies a source file of one interpreter run (0 is the main program; subroutine files
/// get the next numbers, see `Interpreter::file_name`).
pub type FileId = u16;

/// Where a canonical command came from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Source {
    /// File the block was read from.
    pub file: FileId,
    /// 1-based line number in that file (0 for commands that belong to no block, like the
    /// start-up preamble).
    pub line: u32,
    /// The block's N word, if it had one.
    pub n: Option<u32>,
}

/// A position of all nine axes (X Y Z linear, A B C rotary, U V W linear).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Pose {
    /// X axis.
    pub x: f64,
    /// Y axis.
    pub y: f64,
    /// Z axis.
    pub z: f64,
    /// A axis (degrees).
    pub a: f64,
    /// B axis (degrees).
    pub b: f64,
    /// C axis (degrees).
    pub c: f64,
    /// U axis.
    pub u: f64,
    /// V axis.
    pub v: f64,
    /// W axis.
    pub w: f64,
}

impl Pose {
    /// All axes at zero.
    pub const ZERO: Pose = Pose {
        x: 0.0,
        y: 0.0,
        z: 0.0,
        a: 0.0,
        b: 0.0,
        c: 0.0,
        u: 0.0,
        v: 0.0,
        w: 0.0,
    };

    /// The nine coordinates in the order X Y Z A B C U V W.
    pub fn to_array(&self) -> [f64; 9] {
        [
            self.x, self.y, self.z, self.a, self.b, self.c, self.u, self.v, self.w,
        ]
    }

    /// Builds a pose from coordinates in the order X Y Z A B C U V W.
    pub fn from_array(v: [f64; 9]) -> Pose {
        Pose {
            x: v[0],
            y: v[1],
            z: v[2],
            a: v[3],
            b: v[4],
            c: v[5],
            u: v[6],
            v: v[7],
            w: v[8],
        }
    }
}

/// Length units.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Units {
    /// Millimetres (G21).
    Mm,
    /// Inches (G20).
    Inches,
}

impl Units {
    /// How many millimetres one unit is.
    pub fn mm_per_unit(self) -> f64 {
        match self {
            Units::Mm => 1.0,
            Units::Inches => 25.4,
        }
    }
}

/// The plane of arcs, canned cycles and cutter compensation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Plane {
    /// G17.
    XY,
    /// G18 (arcs use Z as first and X as second axis).
    XZ,
    /// G19.
    YZ,
    /// G17.1.
    UV,
    /// G18.1.
    WU,
    /// G19.1.
    VW,
}

/// Path control mode (G61, G61.1, G64).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PathMode {
    /// G61.1: stop at the end of every move.
    ExactStop,
    /// G61: follow the path exactly, may keep speed through tangent corners.
    ExactPath,
    /// G64 P: blend corners within `tolerance` (0 = as fast as possible).
    Continuous {
        /// Maximum deviation from the programmed path.
        tolerance: f64,
    },
}

/// How F is to be read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FeedMode {
    /// G94: units per minute.
    UnitsPerMinute,
    /// G93: the interpreter already turned each move's inverse time into units per minute.
    InverseTime,
    /// G95: units per spindle revolution.
    UnitsPerRevolution,
}

/// Spindle rotation direction.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpindleDirection {
    /// M3.
    Clockwise,
    /// M4.
    CounterClockwise,
}

/// Side of the path the cutter keeps to under radius compensation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CompensationSide {
    /// G41 / G41.1.
    Left,
    /// G42 / G42.1.
    Right,
}

/// Which G38 probing move.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ProbeKind {
    /// G38.2: towards the workpiece, error if the probe does not trip.
    TowardError,
    /// G38.3: towards the workpiece, no error.
    Toward,
    /// G38.4: away from the workpiece, error if the probe does not release.
    AwayError,
    /// G38.5: away from the workpiece, no error.
    Away,
}

/// Condition of an M66 wait.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WaitMode {
    /// L0: read the input now, no waiting.
    Immediate,
    /// L1: wait for a rising edge.
    Rise,
    /// L2: wait for a falling edge.
    Fall,
    /// L3: wait for the input to be high (analog: above 0... see M66 docs).
    High,
    /// L4: wait for the input to be low.
    Low,
}

/// An arc (or helix) in the selected plane, in the argument order of LinuxCNC's `ARC_FEED`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Arc {
    /// End point on the plane's first axis (X in G17, Z in G18, Y in G19).
    pub first_end: f64,
    /// End point on the plane's second axis (Y in G17, X in G18, Z in G19).
    pub second_end: f64,
    /// Centre on the first axis.
    pub first_axis: f64,
    /// Centre on the second axis.
    pub second_axis: f64,
    /// Turns: +n counter-clockwise, -n clockwise, |n| - 1 extra full turns.
    pub rotation: i32,
    /// End point on the axis normal to the plane (helix).
    pub axis_end_point: f64,
    /// A axis end.
    pub a: f64,
    /// B axis end.
    pub b: f64,
    /// C axis end.
    pub c: f64,
    /// U axis end.
    pub u: f64,
    /// V axis end.
    pub v: f64,
    /// W axis end.
    pub w: f64,
}

/// A G5 (cubic) or G5.1 (quadratic) spline in the XY plane, as Bézier control points.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spline {
    /// 4 for a cubic (G5), 3 for a quadratic (G5.1) spline.
    pub order: u8,
    /// First control point after the start point (X, Y).
    pub p1: [f64; 2],
    /// Second control point (cubic only; equal to `p1` for a quadratic spline).
    pub p2: [f64; 2],
    /// End point (X, Y).
    pub end: [f64; 2],
}

/// A control point of a NURBS curve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NurbsPoint {
    /// X.
    pub x: f64,
    /// Y.
    pub y: f64,
    /// Weight (positive).
    pub weight: f64,
}

/// A G5.2/G5.3 NURBS curve in the XY plane: the rational B-spline of order `order` (degree
/// `order - 1`) with these control points (the first is the start point, the last the end
/// point) on LinuxCNC's clamped uniform knot vector, for `n = points.len() - 1` and
/// `k = order`: `k` knots 0, then `1, 2, ..., n - k + 1`, then `k` knots `n - k + 2`; the
/// parameter runs from 0 to `n - k + 2`.
#[derive(Clone, Debug, PartialEq)]
pub struct Nurbs {
    /// Order k (at least 3 as LinuxCNC reads L; at most the number of points).
    pub order: u32,
    /// Control points, start point first.
    pub points: Vec<NurbsPoint>,
}

/// A tool table entry as G10 L1/L10/L11 sets it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ToolEntry {
    /// Pocket number.
    pub pocket: i32,
    /// Tool number.
    pub tool: i32,
    /// Offsets of all nine axes, in the tool table's (user) units.
    pub offset: Pose,
    /// Diameter, in user units.
    pub diameter: f64,
    /// Lathe front angle.
    pub front_angle: f64,
    /// Lathe back angle.
    pub back_angle: f64,
    /// Lathe orientation (0-9).
    pub orientation: i32,
}

/// Text carried by a command: most are fixed strings of the interpreter.
pub type Text = Cow<'static, str>;

/// One canonical machining command.
#[derive(Clone, Debug, PartialEq)]
pub enum CanonCommand {
    /// The following lengths are in these units.
    UseLengthUnits(Units),
    /// Offset of work coordinate system `index` (1 = G54 ... 9 = G59.3), now active.
    SetG5xOffset {
        /// 1..=9.
        index: u8,
        /// The offset, in the current length units.
        offset: Pose,
    },
    /// G92 offset now in force.
    SetG92Offset(Pose),
    /// Rotation of the XY plane of the active work coordinate system, degrees.
    SetXyRotation(f64),
    /// Feed rates refer to the XYZ path (the only reference LinuxCNC uses).
    SetFeedReference,
    /// The interpreter was reset: all transient machine state returns to its default.
    OnReset,
    /// A program comment or an interpreter note.
    Comment(Text),
    /// An operator message: `(MSG,...)` or `(DEBUG,...)`.
    Message(Text),
    /// `(PRINT,...)` text: for a log, not for the operator (rs274 prints it outside its
    /// canonical stream).
    Print(Text),
    /// `(LOGOPEN,file)` / `(LOGAPPEND,file)`: start writing `(LOG,...)` lines to a file.
    LogOpen {
        /// File name as written.
        path: Text,
        /// Append instead of truncating.
        append: bool,
    },
    /// `(LOG,text)` with parameters substituted.
    Log(Text),
    /// `(LOGCLOSE)`.
    LogClose,
    /// Arc / canned cycle / compensation plane.
    SelectPlane(Plane),
    /// G61 / G61.1 / G64.
    SetMotionControlMode(PathMode),
    /// G64 Q: co-linear segments may be merged within this tolerance.
    SetNaivecamTolerance(f64),
    /// G93 / G94 / G95.
    SetFeedMode {
        /// Spindle the per-revolution mode refers to.
        spindle: u8,
        /// The mode.
        mode: FeedMode,
    },
    /// Feed rate for the following feed moves.
    SetFeedRate(f64),
    /// Spindle speed (rpm, or surface speed in constant surface speed mode).
    SetSpindleSpeed {
        /// Spindle number.
        spindle: u8,
        /// Speed.
        speed: f64,
    },
    /// M3 / M4.
    StartSpindle {
        /// Spindle number.
        spindle: u8,
        /// Direction.
        direction: SpindleDirection,
    },
    /// M5 (also before a tool change).
    StopSpindle {
        /// Spindle number.
        spindle: u8,
    },
    /// G96 (constant surface speed with a maximum rpm) or G97 (`max_rpm` 0: plain rpm).
    SetSpindleMode {
        /// Spindle number.
        spindle: u8,
        /// 0 for G97; the D word of G96 (0 = no limit) otherwise.
        max_rpm: f64,
        /// True in G96.
        constant_surface_speed: bool,
    },
    /// M19: orient the spindle.
    OrientSpindle {
        /// Spindle number.
        spindle: u8,
        /// Angle, degrees.
        angle: f64,
        /// P: 0 shortest way, 1 clockwise, 2 counter-clockwise.
        mode: i32,
    },
    /// M19 Q: wait (at most `timeout` seconds) for the orientation to finish.
    WaitOrientComplete {
        /// Spindle number.
        spindle: u8,
        /// Seconds.
        timeout: f64,
    },
    /// T word: prepare this tool.
    SelectTool(i32),
    /// M6 begins.
    StartChange,
    /// M6: change to the tool of this pocket (0 = no tool).
    ChangeTool(i32),
    /// M61: the spindle now holds this tool (no motion).
    ChangeToolNumber(i32),
    /// G43 / G43.1 / G43.2 / G49: tool length offset now in force.
    UseToolLengthOffset(Pose),
    /// G10 L1 / L10 / L11: a tool table entry was changed.
    SetToolTableEntry(Box<ToolEntry>),
    /// G4.
    Dwell(f64),
    /// G0 and the rapid parts of cycles.
    StraightTraverse(Pose),
    /// G1 and the feed parts of cycles.
    StraightFeed(Pose),
    /// G2 / G3.
    ArcFeed(Arc),
    /// G5 / G5.1.
    SplineFeed(Spline),
    /// G5.2 ... G5.3.
    NurbsFeed(Nurbs),
    /// Before a G38 move.
    TurnProbeOn,
    /// After a G38 move.
    TurnProbeOff,
    /// The following feed moves advance `feed_per_revolution` per spindle revolution
    /// (G33, G76 threading).
    StartSpeedFeedSync {
        /// Spindle number.
        spindle: u8,
        /// Length units per revolution.
        feed_per_revolution: f64,
        /// True: velocity mode (G33.1 style), false: position synchronised.
        velocity_mode: bool,
    },
    /// End of spindle-synchronised motion.
    StopSpeedFeedSync,
    /// G33.1: rigid tapping to `end` and back out (the spindle reverses), synchronised.
    RigidTap {
        /// Bottom of the hole.
        end: Pose,
        /// Spindle speed factor on the way out (I word, at least 1).
        scale: f64,
    },
    /// G38.2 - G38.5 straight probing move.
    StraightProbe {
        /// End point.
        end: Pose,
        /// Which probe move.
        kind: ProbeKind,
    },
    /// M62 / M63 (`synchronized`, with the next move) or M64 / M65 (at once).
    SetDigitalOutput {
        /// Output number.
        index: u32,
        /// On (M62/M64) or off (M63/M65).
        on: bool,
        /// True for M62/M63.
        synchronized: bool,
    },
    /// M67 (`synchronized`) / M68 analog output.
    SetAnalogOutput {
        /// Output number.
        index: u32,
        /// Value.
        value: f64,
        /// True for M67.
        synchronized: bool,
    },
    /// M66: wait for an input.
    WaitInput {
        /// Digital (P) or analog (E) input.
        digital: bool,
        /// Input number.
        index: u32,
        /// Condition.
        mode: WaitMode,
        /// Seconds (0 = do not wait).
        timeout: f64,
    },
    /// M7.
    MistOn,
    /// M9.
    MistOff,
    /// M8.
    FloodOn,
    /// M9.
    FloodOff,
    /// M48 / M49 / M50.
    FeedOverride(bool),
    /// M48 / M49 / M51.
    SpeedOverride {
        /// Spindle number.
        spindle: u8,
        /// Enabled.
        enable: bool,
    },
    /// M52.
    AdaptiveFeed(bool),
    /// M53.
    FeedHold(bool),
    /// G41 / G42 / G41.1 / G42.1: start cutter radius compensation.
    StartCutterRadiusCompensation {
        /// Side of the path.
        side: CompensationSide,
        /// Tool radius in the current length units (from the tool table or the D word).
        radius: f64,
        /// Lathe tool orientation (L word of G41.1/G42.1, or the tool table's).
        orientation: i32,
    },
    /// G40.
    StopCutterRadiusCompensation,
    /// M428 (true) / M429: tool-centre-point control on or off. The interpreter goes on
    /// from the same program position; a machine with five-axis kinematics gives it the
    /// position the joints stand for under the new kinematics
    /// ([`crate::Interpreter::kinematics_switched`]).
    SetToolCentrePoint(bool),
    /// M100 - M199: passed on to the machine logic.
    UserMCode {
        /// 100..=199.
        code: u16,
        /// P word.
        p: Option<f64>,
        /// Q word.
        q: Option<f64>,
    },
    /// M0 / M60 (after the shuttle).
    ProgramStop,
    /// M1.
    OptionalProgramStop,
    /// M60.
    PalletShuttle,
    /// M2 / M30.
    ProgramEnd,
    /// The program ended at its closing `%` (no M2 resets): finish queued motion.
    Finish,
}

impl Pose {
    /// The linear axes (X Y Z U V W) multiplied by `f`, the rotary ones (A B C) unchanged.
    pub fn scale_linear(&self, f: f64) -> Pose {
        Pose {
            x: self.x * f,
            y: self.y * f,
            z: self.z * f,
            u: self.u * f,
            v: self.v * f,
            w: self.w * f,
            ..*self
        }
    }
}

impl CanonCommand {
    /// The same command with its lengths in millimetres, given the length units it was
    /// issued in (the last [`CanonCommand::UseLengthUnits`]): positions, centres, offsets,
    /// feed rates, tolerances, radii. Angles, times, speeds and spindle surface speeds are
    /// left as they are; `UseLengthUnits` itself becomes millimetres.
    pub fn to_mm(&self, units: Units) -> CanonCommand {
        let f = units.mm_per_unit();
        if f == 1.0 {
            return self.clone();
        }
        use CanonCommand as C;
        match self {
            C::UseLengthUnits(_) => C::UseLengthUnits(Units::Mm),
            C::SetG5xOffset { index, offset } => C::SetG5xOffset {
                index: *index,
                offset: offset.scale_linear(f),
            },
            C::SetG92Offset(p) => C::SetG92Offset(p.scale_linear(f)),
            C::SetMotionControlMode(PathMode::Continuous { tolerance }) => {
                C::SetMotionControlMode(PathMode::Continuous {
                    tolerance: tolerance * f,
                })
            }
            C::SetNaivecamTolerance(t) => C::SetNaivecamTolerance(t * f),
            C::SetFeedRate(r) => C::SetFeedRate(r * f),
            C::UseToolLengthOffset(p) => C::UseToolLengthOffset(p.scale_linear(f)),
            C::StraightTraverse(p) => C::StraightTraverse(p.scale_linear(f)),
            C::StraightFeed(p) => C::StraightFeed(p.scale_linear(f)),
            C::ArcFeed(a) => C::ArcFeed(Arc {
                first_end: a.first_end * f,
                second_end: a.second_end * f,
                first_axis: a.first_axis * f,
                second_axis: a.second_axis * f,
                axis_end_point: a.axis_end_point * f,
                u: a.u * f,
                v: a.v * f,
                w: a.w * f,
                ..*a
            }),
            C::SplineFeed(sp) => {
                let m = |p: [f64; 2]| [p[0] * f, p[1] * f];
                C::SplineFeed(Spline {
                    p1: m(sp.p1),
                    p2: m(sp.p2),
                    end: m(sp.end),
                    ..*sp
                })
            }
            C::NurbsFeed(n) => C::NurbsFeed(Nurbs {
                order: n.order,
                points: n
                    .points
                    .iter()
                    .map(|p| NurbsPoint {
                        x: p.x * f,
                        y: p.y * f,
                        weight: p.weight,
                    })
                    .collect(),
            }),
            C::StartSpeedFeedSync {
                spindle,
                feed_per_revolution,
                velocity_mode,
            } => C::StartSpeedFeedSync {
                spindle: *spindle,
                feed_per_revolution: feed_per_revolution * f,
                velocity_mode: *velocity_mode,
            },
            C::RigidTap { end, scale } => C::RigidTap {
                end: end.scale_linear(f),
                scale: *scale,
            },
            C::StraightProbe { end, kind } => C::StraightProbe {
                end: end.scale_linear(f),
                kind: *kind,
            },
            C::StartCutterRadiusCompensation {
                side,
                radius,
                orientation,
            } => C::StartCutterRadiusCompensation {
                side: *side,
                radius: radius * f,
                orientation: *orientation,
            },
            other => other.clone(),
        }
    }
}

/// A canonical command with the place in the program it came from.
#[derive(Clone, Debug, PartialEq)]
pub struct Canon {
    /// Where it came from.
    pub source: Source,
    /// What to do.
    pub command: CanonCommand,
}

impl Canon {
    /// Appends this command as `rs274` prints it (one line, with newline) to `out`, and
    /// returns false (appending nothing) for commands `rs274` does not print: `(PRINT,...)`
    /// text and M66 waits. `with_n` prefixes the `N.....` column of `rs274`.
    ///
    /// Differences: U/V/W coordinates are printed as three more numbers when any of them is
    /// non-zero (rs274 has no U/V/W), M100-M199 print as `USER_M_CODE(code, p, q)` (-1 for a
    /// missing word).
    pub fn write_rs274(&self, out: &mut Vec<u8>, with_n: bool) -> bool {
        use CanonCommand as C;
        if matches!(self.command, C::Print(_) | C::WaitInput { .. }) {
            return false;
        }
        if with_n {
            push_n_column(out, self.source.n);
        }
        write_call(out, &self.command);
        out.push(b'\n');
        true
    }
}

/// The call itself, as rs274 prints it. One arm per canonical call, grouped by kind; a call
/// whose printed form takes more than one step has a function of its own.
fn write_call(o: &mut Vec<u8>, command: &CanonCommand) {
    use CanonCommand as C;
    match command {
        // Units, offsets, planes and modes.
        C::UseLengthUnits(u) => o.extend_from_slice(length_units_call(*u)),
        C::SetG5xOffset { index, offset } => write_g5x_offset(o, *index, offset),
        C::SetG92Offset(p) => call_pose(o, b"SET_G92_OFFSET(", p),
        C::SetXyRotation(r) => call_f4(o, b"SET_XY_ROTATION(", *r),
        C::SetFeedReference => o.extend_from_slice(b"SET_FEED_REFERENCE(CANON_XYZ)"),
        C::OnReset => o.extend_from_slice(b"ON_RESET()"),
        C::SelectPlane(p) => write_select_plane(o, *p),
        C::SetMotionControlMode(m) => write_motion_control_mode(o, m),
        C::SetNaivecamTolerance(t) => call_f4(o, b"SET_NAIVECAM_TOLERANCE(", *t),
        C::SetFeedMode { spindle, mode } => write_feed_mode(o, *spindle, *mode),
        C::SetFeedRate(f) => call_f4(o, b"SET_FEED_RATE(", *f),

        // Text: comments, messages, the log file.
        C::Comment(t) => call_text(o, b"COMMENT(\"", t),
        C::Message(t) => call_text(o, b"MESSAGE(\"", t),
        // rs274 prints neither: write_rs274 returns before the call.
        C::Print(_) | C::WaitInput { .. } => {}
        C::LogOpen { path, append } => call_text(o, log_open_call(*append), path),
        C::Log(t) => call_text(o, b"LOG(\"", t),
        C::LogClose => o.extend_from_slice(b"LOGCLOSE()"),

        // Spindle.
        C::SetSpindleSpeed { spindle, speed } => write_spindle_speed(o, *spindle, *speed),
        C::StartSpindle { spindle, direction } => write_start_spindle(o, *spindle, *direction),
        C::StopSpindle { spindle } => call_int(o, b"STOP_SPINDLE_TURNING(", i64::from(*spindle)),
        C::SetSpindleMode {
            spindle, max_rpm, ..
        } => write_spindle_mode(o, *spindle, *max_rpm),
        C::OrientSpindle {
            spindle,
            angle,
            mode,
        } => write_orient_spindle(o, *spindle, *angle, *mode),
        C::WaitOrientComplete { spindle, timeout } => {
            write_wait_orient_complete(o, *spindle, *timeout)
        }

        // Tools.
        C::SelectTool(t) => call_int(o, b"SELECT_TOOL(", i64::from(*t)),
        C::StartChange => o.extend_from_slice(b"START_CHANGE()"),
        C::ChangeTool(p) => call_int(o, b"CHANGE_TOOL(", i64::from(*p)),
        C::ChangeToolNumber(t) => call_int(o, b"CHANGE_TOOL_NUMBER(", i64::from(*t)),
        C::UseToolLengthOffset(p) => write_tool_length_offset(o, p),
        C::SetToolTableEntry(e) => write_tool_table_entry(o, e),

        // Motion and probing.
        C::Dwell(t) => call_f4(o, b"DWELL(", *t),
        C::StraightTraverse(p) => call_pose(o, b"STRAIGHT_TRAVERSE(", p),
        C::StraightFeed(p) => call_pose(o, b"STRAIGHT_FEED(", p),
        C::ArcFeed(a) => write_arc_feed(o, a),
        // rs274 prints only the order of the NURBS it builds.
        C::SplineFeed(s) => write_nurbs_feed(o, i64::from(s.order)),
        // rs274 prints the number of control points.
        C::NurbsFeed(n) => write_nurbs_feed(o, n.points.len() as i64),
        C::StartSpeedFeedSync {
            feed_per_revolution,
            velocity_mode,
            ..
        } => write_speed_feed_sync(o, *feed_per_revolution, *velocity_mode),
        C::StopSpeedFeedSync => o.extend_from_slice(b"STOP_SPEED_FEED_SYNCH()"),
        C::RigidTap { end, .. } => write_rigid_tap(o, end),
        C::TurnProbeOn => o.extend_from_slice(b"TURN_PROBE_ON()"),
        C::TurnProbeOff => o.extend_from_slice(b"TURN_PROBE_OFF()"),
        C::StraightProbe { end, .. } => call_pose(o, b"STRAIGHT_PROBE(", end),

        // Outputs, coolant and overrides.
        C::SetDigitalOutput {
            index,
            on,
            synchronized,
        } => call_int(
            o,
            digital_output_call(*on, *synchronized),
            i64::from(*index),
        ),
        C::SetAnalogOutput {
            index,
            value,
            synchronized,
        } => write_analog_output(o, *index, *value, *synchronized),
        C::MistOn => o.extend_from_slice(b"MIST_ON()"),
        C::MistOff => o.extend_from_slice(b"MIST_OFF()"),
        C::FloodOn => o.extend_from_slice(b"FLOOD_ON()"),
        C::FloodOff => o.extend_from_slice(b"FLOOD_OFF()"),
        C::FeedOverride(on) => write_switch(o, *on, b"FEED_OVERRIDE()"),
        C::SpeedOverride { spindle, enable } => {
            write_switch(o, *enable, b"SPEED_OVERRIDE(");
            push_int(o, i64::from(*spindle));
            o.push(b')');
        }
        C::AdaptiveFeed(on) => write_switch(o, *on, b"ADAPTIVE_FEED()"),
        C::FeedHold(on) => write_switch(o, *on, b"FEED_HOLD()"),

        // Compensation, user M-codes and program flow.
        C::StartCutterRadiusCompensation { side, .. } => {
            o.extend_from_slice(cutter_compensation_comment(*side))
        }
        C::StopCutterRadiusCompensation => o.extend_from_slice(
            b"COMMENT(\"interpreter: cutter radius compensation off\")".as_slice(),
        ),
        C::UserMCode { code, p, q } => write_user_m_code(o, *code, *p, *q),
        C::SetToolCentrePoint(on) => o.extend_from_slice(if *on {
            b"SET_TOOL_CENTRE_POINT(ON)".as_slice()
        } else {
            b"SET_TOOL_CENTRE_POINT(OFF)".as_slice()
        }),
        C::ProgramStop => o.extend_from_slice(b"PROGRAM_STOP()"),
        C::OptionalProgramStop => o.extend_from_slice(b"OPTIONAL_PROGRAM_STOP()"),
        C::PalletShuttle => o.extend_from_slice(b"PALLET_SHUTTLE()"),
        C::ProgramEnd => o.extend_from_slice(b"PROGRAM_END()"),
        C::Finish => o.extend_from_slice(b"FINISH()"),
    }
}

fn length_units_call(u: Units) -> &'static [u8] {
    match u {
        Units::Mm => b"USE_LENGTH_UNITS(CANON_UNITS_MM)",
        Units::Inches => b"USE_LENGTH_UNITS(CANON_UNITS_INCHES)",
    }
}

fn log_open_call(append: bool) -> &'static [u8] {
    if append {
        b"LOGAPPEND(\""
    } else {
        b"LOGOPEN(\""
    }
}

/// `ENABLE_` or `DISABLE_` then the rest of the call's name.
fn write_switch(o: &mut Vec<u8>, on: bool, name: &[u8]) {
    o.extend_from_slice(if on {
        b"ENABLE_".as_slice()
    } else {
        b"DISABLE_"
    });
    o.extend_from_slice(name);
}

/// The `N.....` column of `rs274`: the line number left-aligned in six characters, or
/// dots for a command no numbered line produced.
fn push_n_column(out: &mut Vec<u8>, n: Option<u32>) {
    match n {
        Some(n) => {
            out.push(b'N');
            let start = out.len();
            push_int(out, i64::from(n));
            let width = out.len() - start;
            for _ in width..6 {
                out.push(b' ');
            }
        }
        None => out.extend_from_slice(b"N..... "),
    }
}

fn write_g5x_offset(o: &mut Vec<u8>, index: u8, offset: &Pose) {
    o.extend_from_slice(b"SET_G5X_OFFSET(");
    push_int(o, i64::from(index));
    o.extend_from_slice(b", ");
    push_pose(o, offset);
    o.push(b')');
}

fn write_select_plane(o: &mut Vec<u8>, p: Plane) {
    o.extend_from_slice(b"SELECT_PLANE(");
    o.extend_from_slice(match p {
        Plane::XY => b"CANON_PLANE_XY".as_slice(),
        Plane::XZ => b"CANON_PLANE_XZ",
        Plane::YZ => b"CANON_PLANE_YZ",
        // rs274's printer knows only the three XYZ planes.
        Plane::UV | Plane::WU | Plane::VW => b"CANON_PLANE_UNKNOWN",
    });
    o.push(b')');
}

fn write_motion_control_mode(o: &mut Vec<u8>, m: &PathMode) {
    match m {
        PathMode::ExactStop => o.extend_from_slice(b"SET_MOTION_CONTROL_MODE(CANON_EXACT_STOP)"),
        PathMode::ExactPath => o.extend_from_slice(b"SET_MOTION_CONTROL_MODE(CANON_EXACT_PATH)"),
        PathMode::Continuous { tolerance } => {
            o.extend_from_slice(b"SET_MOTION_CONTROL_MODE(CANON_CONTINUOUS, ");
            push_fixed(o, *tolerance, 6);
            o.push(b')');
        }
    }
}

fn write_feed_mode(o: &mut Vec<u8>, spindle: u8, mode: FeedMode) {
    o.extend_from_slice(b"SET_FEED_MODE(");
    push_int(o, i64::from(spindle));
    o.extend_from_slice(match mode {
        FeedMode::UnitsPerRevolution => b", 1)",
        FeedMode::UnitsPerMinute | FeedMode::InverseTime => b", 0)",
    });
}

fn write_spindle_speed(o: &mut Vec<u8>, spindle: u8, speed: f64) {
    o.extend_from_slice(b"SET_SPINDLE_SPEED(");
    push_int(o, i64::from(spindle));
    o.extend_from_slice(b", ");
    push_fixed(o, speed, 4);
    o.push(b')');
}

fn write_start_spindle(o: &mut Vec<u8>, spindle: u8, direction: SpindleDirection) {
    o.extend_from_slice(match direction {
        SpindleDirection::Clockwise => b"START_SPINDLE_CLOCKWISE(".as_slice(),
        SpindleDirection::CounterClockwise => b"START_SPINDLE_COUNTERCLOCKWISE(",
    });
    push_int(o, i64::from(spindle));
    o.push(b')');
}

fn write_spindle_mode(o: &mut Vec<u8>, spindle: u8, max_rpm: f64) {
    // rs274 prints no comma here.
    o.extend_from_slice(b"SET_SPINDLE_MODE(");
    push_int(o, i64::from(spindle));
    o.push(b' ');
    push_fixed(o, max_rpm, 4);
    o.push(b')');
}

fn write_orient_spindle(o: &mut Vec<u8>, spindle: u8, angle: f64, mode: i32) {
    o.extend_from_slice(b"ORIENT_SPINDLE(");
    push_int(o, i64::from(spindle));
    o.extend_from_slice(b", ");
    push_fixed(o, angle, 4);
    o.extend_from_slice(b", ");
    push_int(o, i64::from(mode));
    o.push(b')');
}

fn write_wait_orient_complete(o: &mut Vec<u8>, spindle: u8, timeout: f64) {
    o.extend_from_slice(b"SPINDLE.");
    push_int(o, i64::from(spindle));
    call_f4(o, b".WAIT_ORIENT_COMPLETE(", timeout);
}

/// The nine offsets, grouped by three: `x y z, a b c, u v w`.
fn write_tool_length_offset(o: &mut Vec<u8>, p: &Pose) {
    o.extend_from_slice(b"USE_TOOL_LENGTH_OFFSET(");
    let v = p.to_array();
    for (i, x) in v.iter().enumerate() {
        if i > 0 {
            o.extend_from_slice(if i % 3 == 0 { b", " } else { b" " });
        }
        push_fixed(o, *x, 4);
    }
    o.push(b')');
}

fn write_tool_table_entry(o: &mut Vec<u8>, e: &ToolEntry) {
    o.extend_from_slice(b"SET_TOOL_TABLE_ENTRY(");
    push_int(o, i64::from(e.pocket));
    o.extend_from_slice(b", ");
    push_int(o, i64::from(e.tool));
    o.extend_from_slice(b", ");
    for (i, x) in e.offset.to_array().iter().enumerate() {
        if i > 0 {
            o.push(b' ');
        }
        push_fixed(o, *x, 4);
    }
    o.extend_from_slice(b", ");
    push_fixed(o, e.front_angle, 4);
    o.extend_from_slice(b", ");
    push_fixed(o, e.back_angle, 4);
    o.extend_from_slice(b", ");
    push_int(o, i64::from(e.orientation));
    o.push(b')');
}

/// U, V and W follow only when one of them is non-zero, as in [`push_pose`].
fn write_arc_feed(o: &mut Vec<u8>, a: &Arc) {
    o.extend_from_slice(b"ARC_FEED(");
    for x in [a.first_end, a.second_end, a.first_axis, a.second_axis] {
        push_fixed(o, x, 4);
        o.extend_from_slice(b", ");
    }
    push_int(o, i64::from(a.rotation));
    for x in [a.axis_end_point, a.a, a.b, a.c] {
        o.extend_from_slice(b", ");
        push_fixed(o, x, 4);
    }
    if a.u != 0.0 || a.v != 0.0 || a.w != 0.0 {
        for x in [a.u, a.v, a.w] {
            o.extend_from_slice(b", ");
            push_fixed(o, x, 4);
        }
    }
    o.push(b')');
}

fn write_nurbs_feed(o: &mut Vec<u8>, n: i64) {
    o.extend_from_slice(b"NURBS_FEED(");
    push_int(o, n);
    o.extend_from_slice(b", ...)");
}

fn write_speed_feed_sync(o: &mut Vec<u8>, feed_per_revolution: f64, velocity_mode: bool) {
    o.extend_from_slice(b"START_SPEED_FEED_SYNC(");
    push_fixed(o, feed_per_revolution, 6);
    o.push(b',');
    o.push(if velocity_mode { b'1' } else { b'0' });
    o.push(b')');
}

fn write_rigid_tap(o: &mut Vec<u8>, end: &Pose) {
    o.extend_from_slice(b"RIGID_TAP(");
    push_fixed(o, end.x, 4);
    o.extend_from_slice(b", ");
    push_fixed(o, end.y, 4);
    o.extend_from_slice(b", ");
    push_fixed(o, end.z, 4);
    o.push(b')');
}

/// LinuxCNC names a synchronized output (M62/M63) a motion output and an immediate one
/// (M64/M65) an auxiliary output.
fn digital_output_call(on: bool, synchronized: bool) -> &'static [u8] {
    match (on, synchronized) {
        (true, true) => b"SET_MOTION_OUTPUT_BIT(",
        (false, true) => b"CLEAR_MOTION_OUTPUT_BIT(",
        (true, false) => b"SET_AUX_OUTPUT_BIT(",
        (false, false) => b"CLEAR_AUX_OUTPUT_BIT(",
    }
}

fn write_analog_output(o: &mut Vec<u8>, index: u32, value: f64, synchronized: bool) {
    o.extend_from_slice(if synchronized {
        b"SET_MOTION_OUTPUT_VALUE(".as_slice()
    } else {
        b"SET_AUX_OUTPUT_VALUE("
    });
    push_int(o, i64::from(index));
    o.push(b',');
    push_fixed(o, value, 6);
    o.push(b')');
}

/// LinuxCNC compensates inside its interpreter and only notes the change.
fn cutter_compensation_comment(side: CompensationSide) -> &'static [u8] {
    match side {
        CompensationSide::Left => b"COMMENT(\"interpreter: cutter radius compensation on left\")",
        CompensationSide::Right => b"COMMENT(\"interpreter: cutter radius compensation on right\")",
    }
}

fn write_user_m_code(o: &mut Vec<u8>, code: u16, p: Option<f64>, q: Option<f64>) {
    o.extend_from_slice(b"USER_M_CODE(");
    push_int(o, i64::from(code));
    // A missing word prints as -1, LinuxCNC's value for "not given".
    for w in [p, q] {
        o.extend_from_slice(b", ");
        push_fixed(o, w.unwrap_or(-1.0), 4);
    }
    o.push(b')');
}

fn call_pose(o: &mut Vec<u8>, name: &[u8], p: &Pose) {
    o.extend_from_slice(name);
    push_pose(o, p);
    o.push(b')');
}

fn call_f4(o: &mut Vec<u8>, name: &[u8], v: f64) {
    o.extend_from_slice(name);
    push_fixed(o, v, 4);
    o.push(b')');
}

fn call_int(o: &mut Vec<u8>, name: &[u8], v: i64) {
    o.extend_from_slice(name);
    push_int(o, v);
    o.push(b')');
}

fn call_text(o: &mut Vec<u8>, name: &[u8], t: &str) {
    o.extend_from_slice(name);
    o.extend_from_slice(t.as_bytes());
    o.extend_from_slice(b"\")");
}

/// X, Y, Z, A, B, C (and U, V, W when any is non-zero), comma separated.
fn push_pose(o: &mut Vec<u8>, p: &Pose) {
    let n = if p.u != 0.0 || p.v != 0.0 || p.w != 0.0 {
        9
    } else {
        6
    };
    for (i, x) in p.to_array()[..n].iter().enumerate() {
        if i > 0 {
            o.extend_from_slice(b", ");
        }
        push_fixed(o, *x, 4);
    }
}

/// Appends a decimal integer.
pub(crate) fn push_int(o: &mut Vec<u8>, v: i64) {
    let mut digits = [0u8; 20];
    let mut n = v.unsigned_abs();
    let mut i = digits.len();
    loop {
        i -= 1;
        digits[i] = b'0' + (n % 10) as u8;
        n /= 10;
        if n == 0 {
            break;
        }
    }
    if v < 0 {
        o.push(b'-');
    }
    push_small(o, &digits[i..]);
}

/// Appends a few bytes one by one: for the short pieces of a number this is faster than
/// a call to `memcpy`.
#[inline]
fn push_small(o: &mut Vec<u8>, bytes: &[u8]) {
    o.reserve(bytes.len());
    for &b in bytes {
        o.push(b);
    }
}

/// Appends `v` with `decimals` digits after the point, like C's `%.Nf`, except that a value
/// that rounds to zero is printed without a minus sign.
pub(crate) fn push_fixed(o: &mut Vec<u8>, v: f64, decimals: u32) {
    const SCALE: [f64; 7] = [1.0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6];
    const POW: [u64; 7] = [1, 10, 100, 1_000, 10_000, 100_000, 1_000_000];
    const ZEROS: [&[u8]; 7] = [
        b"0",
        b"0.0",
        b"0.00",
        b"0.000",
        b"0.0000",
        b"0.00000",
        b"0.000000",
    ];
    let d = decimals.min(6) as usize;
    let scaled = v * SCALE[d];
    // Values near a rounding tie (x.xxxx5) are decided on their exact binary value, as C's
    // printf does; those, huge and non-finite values take the exact (slower) path.
    // (The fraction through an integer cast: `f64::fract` is a libm call on x86-64.)
    let tie = ((scaled - (scaled as i64) as f64).abs() - 0.5).abs() < 1e-6;
    if tie || !scaled.is_finite() || scaled.abs() >= 1.0e15 {
        use std::io::Write;
        let start = o.len();
        let _ = write!(o, "{:.*}", d, v);
        // No minus sign on a value that prints as zero.
        if o[start] == b'-' && o[start + 1..].iter().all(|c| *c == b'0' || *c == b'.') {
            o.remove(start);
        }
        return;
    }
    // Round half away from zero (the cast truncates).
    let n = if scaled >= 0.0 {
        (scaled + 0.5) as i64
    } else {
        (scaled - 0.5) as i64
    };
    if n == 0 {
        o.extend_from_slice(ZEROS[d]);
        return;
    }
    let m = n.unsigned_abs();
    let int = m / POW[d];
    let mut frac = m % POW[d];
    let mut int_digits = 1;
    let mut t = int;
    while t >= 10 {
        t /= 10;
        int_digits += 1;
    }
    let len = usize::from(n < 0) + int_digits + usize::from(d > 0) + d;
    // The digits are laid out in a fixed-size buffer that is appended whole and then cut to
    // length: a constant-size copy is cheaper than a call to memcpy.
    let mut buf = [0u8; 24];
    let mut pos = len.min(buf.len());
    for _ in 0..d {
        pos = pos.saturating_sub(1);
        buf[pos] = b'0' + (frac % 10) as u8;
        frac /= 10;
    }
    if d > 0 {
        pos = pos.saturating_sub(1);
        buf[pos] = b'.';
    }
    let mut t = int;
    loop {
        pos = pos.saturating_sub(1);
        buf[pos] = b'0' + (t % 10) as u8;
        t /= 10;
        if t == 0 {
            break;
        }
    }
    if n < 0 {
        buf[0] = b'-';
    }
    let start = o.len();
    o.extend_from_slice(&buf);
    o.truncate(start + len);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(c: CanonCommand) -> String {
        let mut v = Vec::new();
        Canon {
            source: Source::default(),
            command: c,
        }
        .write_rs274(&mut v, false);
        String::from_utf8(v).unwrap()
    }

    #[test]
    fn fixed_point_matches_printf() {
        let mut v = Vec::new();
        for (x, s) in [
            (0.0, "0.0000"),
            (-0.0, "0.0000"),
            (-0.00001, "0.0000"),
            (12.97940, "12.9794"),
            (-1.5, "-1.5000"),
            (0.123456, "0.1235"),
            (1e17, "100000000000000000.0000"),
            // Ties go by the exact binary value, like printf.
            (1.76975, "1.7697"),
            (22.32435, "22.3243"),
            (-0.00005, "-0.0001"),
        ] {
            v.clear();
            push_fixed(&mut v, x, 4);
            assert_eq!(std::str::from_utf8(&v).unwrap(), s);
        }
    }

    #[test]
    fn inch_commands_convert_to_mm() {
        let inch = CanonCommand::ArcFeed(Arc {
            first_end: 1.0,
            second_end: 2.0,
            first_axis: 0.5,
            second_axis: 0.25,
            rotation: -1,
            axis_end_point: -0.1,
            a: 90.0,
            b: 0.0,
            c: 0.0,
            u: 0.0,
            v: 0.0,
            w: 1.0,
        });
        let CanonCommand::ArcFeed(a) = inch.to_mm(Units::Inches) else {
            panic!("not an arc");
        };
        assert_eq!(
            (a.first_end, a.second_end, a.first_axis, a.second_axis),
            (25.4, 50.8, 12.7, 6.35)
        );
        assert_eq!(
            (a.axis_end_point, a.a, a.w, a.rotation),
            (-2.54, 90.0, 25.4, -1)
        );
        assert_eq!(
            CanonCommand::SetFeedRate(10.0).to_mm(Units::Inches),
            CanonCommand::SetFeedRate(254.0)
        );
        assert_eq!(
            CanonCommand::Dwell(2.0).to_mm(Units::Inches),
            CanonCommand::Dwell(2.0)
        );
        assert_eq!(
            CanonCommand::SetFeedRate(10.0).to_mm(Units::Mm),
            CanonCommand::SetFeedRate(10.0)
        );
    }

    #[test]
    fn lines_as_rs274_prints_them() {
        // Expected texts are rs274 output lines (LinuxCNC 2.9).
        assert_eq!(
            line(CanonCommand::SetSpindleMode {
                spindle: 0,
                max_rpm: 2000.0,
                constant_surface_speed: true
            }),
            "SET_SPINDLE_MODE(0 2000.0000)\n"
        );
        assert_eq!(
            line(CanonCommand::UseToolLengthOffset(Pose {
                z: 12.9794,
                ..Pose::ZERO
            })),
            "USE_TOOL_LENGTH_OFFSET(0.0000 0.0000 12.9794, 0.0000 0.0000 0.0000, 0.0000 0.0000 0.0000)\n"
        );
        assert_eq!(
            line(CanonCommand::SetMotionControlMode(PathMode::Continuous {
                tolerance: 0.01
            })),
            "SET_MOTION_CONTROL_MODE(CANON_CONTINUOUS, 0.010000)\n"
        );
        assert_eq!(
            line(CanonCommand::SetAnalogOutput {
                index: 1,
                value: 2.5,
                synchronized: true
            }),
            "SET_MOTION_OUTPUT_VALUE(1,2.500000)\n"
        );
        assert_eq!(
            line(CanonCommand::ArcFeed(Arc {
                first_end: 2.0,
                second_end: 1.0,
                first_axis: 1.5,
                second_axis: 0.5,
                rotation: -1,
                axis_end_point: 1.0,
                a: 0.0,
                b: 0.0,
                c: 0.0,
                u: 0.0,
                v: 0.0,
                w: 0.0
            })),
            "ARC_FEED(2.0000, 1.0000, 1.5000, 0.5000, -1, 1.0000, 0.0000, 0.0000, 0.0000)\n"
        );
    }
}
