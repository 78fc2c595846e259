//! The compensation stage: a bounded look-ahead of one move, as LinuxCNC's interpreter keeps.

use std::collections::VecDeque;
use std::f64::consts::{FRAC_PI_2, PI, TAU};

use super::error::{CompError, CompErrorKind as K};
use super::geometry::{
    CORNER_TOLERANCE, EQUAL_TOLERANCE, P2, concave_retreat, direction, distance, from_plane,
    lathe_origin_shift, line_offset_end, polar, side_angle, sweep, to_plane, tool_inside_arc,
};
use crate::arc_tolerance::ArcRadiusTolerance;
use crate::canon::{Arc, Canon, CanonCommand, CompensationSide, Plane, Pose, Source, Units};

/// How many commands may wait in the stage by default (see [`Compensator::with_capacity`]).
pub const DEFAULT_CAPACITY: usize = 256;

/// Largest allowed change of an arc's radius when its end point is moved (a consistency
/// check: it never changes for a correct corner).
const MOVED_ARC_RADIUS_TOLERANCE: f64 = 0.01;

/// Allowed growth of an arc's sweep (radians) when its end point moves back at a concave
/// corner before it counts as gouging: LinuxCNC 2.9 allows 0.001 in inch programs and
/// 0.0254 in millimetre programs (the inch figure scaled as if it were a length).
fn sweep_growth_tolerance(units: Units) -> f64 {
    match units {
        Units::Inches => 0.001,
        Units::Mm => 0.0254,
    }
}

/// What compensation refuses while it is on.
fn refused_with_compensation(command: &CanonCommand) -> Option<K> {
    use CanonCommand as C;
    match command {
        C::SetG92Offset(_) | C::SetXyRotation(_) => Some(K::AxisOffsetChange),
        C::SetMotionControlMode(_) | C::SetNaivecamTolerance(_) => Some(K::ControlModeChange),
        C::SetDigitalOutput { .. } | C::SetAnalogOutput { .. } => Some(K::OutputChange),
        C::WaitInput { .. } => Some(K::WaitInput),
        C::FeedOverride(_) | C::SpeedOverride { .. } | C::AdaptiveFeed(_) | C::FeedHold(_) => {
            Some(K::OverrideChange)
        }
        C::TurnProbeOn | C::TurnProbeOff | C::StraightProbe { .. } => Some(K::Probe),
        C::SplineFeed(_) | C::NurbsFeed(_) => Some(K::Spline),
        _ => None,
    }
}

/// The commands that keep their place behind a held move (as in LinuxCNC); the others take
/// effect at once, ahead of it.
fn follows_held_moves(command: &CanonCommand) -> bool {
    use CanonCommand as C;
    matches!(
        command,
        C::Comment(_)
            | C::Dwell(_)
            | C::SetFeedMode { .. }
            | C::SetFeedRate(_)
            | C::StartSpindle { .. }
            | C::StopSpindle { .. }
            | C::OrientSpindle { .. }
            | C::WaitOrientComplete { .. }
            | C::MistOn
            | C::MistOff
            | C::FloodOn
            | C::FloodOff
            | C::UserMCode { .. }
            | C::SetSpindleSpeed { .. }
            | C::SetSpindleMode { .. }
    )
}

/// A compensated move waiting for the next move, which may still shorten it.
#[derive(Clone, Debug)]
enum Pending {
    Line {
        source: Source,
        traverse: bool,
        /// Direction of the programmed motion: a move whose new direction opposes it would
        /// run backwards, i.e. gouge.
        dir: P2,
        /// End in plane coordinates (u, v, w).
        end: [f64; 3],
        /// The other axes of the end pose.
        pose: Pose,
        /// A positioning move whose end a concave corner must not move.
        fixed: bool,
    },
    Arc {
        source: Source,
        /// Sweep of the programmed arc (0: the end point is never moved).
        original_turns: f64,
        end: P2,
        centre: P2,
        turn: i32,
        /// End on the axis normal to the plane.
        w: f64,
        /// Rotary and UVW ends.
        rest: Arc,
    },
    Other(Canon),
}

#[derive(Clone, Copy, Debug, Default)]
struct Offsets {
    g5x: Pose,
    g92: Pose,
    rotation: f64,
    tool: Pose,
}

/// Cutter radius compensation as a stage between the interpreter and the motion planner.
///
/// Push the interpreter's canonical commands in order with [`push`](Self::push), and after
/// every push take the compensated commands out with [`pop`](Self::pop) until it returns
/// `None`. A compensated move leaves the stage only when the next move has decided its end
/// point (a concave corner shortens it), so the stage holds one move plus the commands
/// queued behind it; [`finish`](Self::finish) releases what is held at the end of input.
///
/// The output is LinuxCNC 2.9's: the same moves, corner arcs, entry and exit moves, the same
/// order of commands (feed rate, spindle, coolant, dwell, comment and user M codes queue
/// behind a held move; everything else passes it), and the same errors.
///
/// Memory is fixed at construction; `push` and `pop` do not allocate (the buffers hold at
/// most `capacity` waiting commands and `2 × capacity + 8` ready ones).
#[derive(Debug)]
pub struct Compensator {
    capacity: usize,
    ready: VecDeque<Canon>,
    pending: VecDeque<Pending>,
    plane: Plane,
    units: Units,
    side: Option<CompensationSide>,
    radius: f64,
    orientation: i32,
    first_move: bool,
    arc_not_allowed: bool,
    /// Programmed (uncompensated) position: where the interpreter thinks the tool is.
    programmed: Pose,
    /// Compensated tool position in plane coordinates, while compensating.
    current: [f64; 3],
    endpoint: P2,
    endpoint_valid: bool,
    offsets: Offsets,
}

impl Default for Compensator {
    fn default() -> Self {
        Compensator::new()
    }
}

impl Compensator {
    /// A stage holding at most [`DEFAULT_CAPACITY`] waiting commands.
    pub fn new() -> Compensator {
        Compensator::with_capacity(DEFAULT_CAPACITY)
    }

    /// A stage holding at most `capacity` (at least 4) commands behind a held move: feed
    /// rates, comments, spindle commands and moves with no motion in the plane between
    /// two moves of the plane. More is an error ([`CompErrorKind::BufferFull`](K::BufferFull)).
    pub fn with_capacity(capacity: usize) -> Compensator {
        let capacity = capacity.max(4);
        Compensator {
            capacity,
            ready: VecDeque::with_capacity(2 * capacity + 8),
            pending: VecDeque::with_capacity(capacity),
            plane: Plane::XY,
            units: Units::Mm,
            side: None,
            radius: 0.0,
            orientation: 0,
            first_move: true,
            arc_not_allowed: false,
            programmed: Pose::ZERO,
            current: [0.0; 3],
            endpoint: [0.0; 2],
            endpoint_valid: false,
            offsets: Offsets::default(),
        }
    }

    /// Tells the stage where the tool is, in program coordinates, when that is not the end
    /// of the last move it saw: at start-up, or after the machine moved outside the program
    /// (jog, MDI, a probe's actual trip point). The next compensation entry starts there.
    /// Ignored while a compensated path is under way.
    pub fn set_position(&mut self, programmed: Pose) {
        if !self.compensating() || self.first_move {
            self.programmed = programmed;
        }
    }

    /// True while G41/G42 is in force.
    pub fn is_active(&self) -> bool {
        self.side.is_some()
    }

    /// How many commands wait for the next move.
    pub fn held(&self) -> usize {
        self.pending.len()
    }

    /// The next compensated command, if one is ready.
    pub fn pop(&mut self) -> Option<Canon> {
        self.ready.pop_front()
    }

    /// Takes one command of the interpreter. On an error the held commands are dropped
    /// (LinuxCNC stops there too), compensation is off and the stage can take a new program;
    /// what was ready before the error is still returned by `pop`.
    pub fn push(&mut self, canon: Canon) -> Result<(), CompError> {
        if self.ready.len() > self.capacity {
            return Err(CompError::new(K::BufferFull, canon.source));
        }
        let result = self.process(canon);
        if result.is_err() {
            self.pending.clear();
            self.side = None;
            self.first_move = true;
            self.endpoint_valid = false;
        }
        result
    }

    /// End of input: releases the held commands.
    pub fn finish(&mut self) {
        self.dequeue();
    }

    fn process(&mut self, canon: Canon) -> Result<(), CompError> {
        use CanonCommand as C;
        let src = canon.source;
        let active = self.side.is_some();
        if active {
            if let Some(kind) = refused_with_compensation(&canon.command) {
                return Err(CompError::new(kind, src));
            }
        }
        if follows_held_moves(&canon.command) {
            return self.enqueue(canon);
        }
        match &canon.command {
            C::StraightTraverse(p) | C::StraightFeed(p) => {
                let traverse = matches!(canon.command, C::StraightTraverse(_));
                let p = *p;
                self.arc_not_allowed = false;
                if self.compensating() {
                    self.straight(src, traverse, p)?;
                    self.programmed = p;
                    return Ok(());
                }
                self.programmed = p;
            }
            C::ArcFeed(arc) => {
                let arc = *arc;
                if self.arc_not_allowed {
                    return Err(CompError::new(K::ArcAfterCompensationOff, src));
                }
                let end = self.arc_end_pose(&arc);
                if self.compensating() {
                    self.arc(src, &arc)?;
                    self.programmed = end;
                    return Ok(());
                }
                self.programmed = end;
            }
            C::StartCutterRadiusCompensation {
                side,
                radius,
                orientation,
            } => {
                if active {
                    return Err(CompError::new(K::AlreadyOn, src));
                }
                let (side, radius, orientation) = (*side, *radius, *orientation);
                return self.start_compensation(canon, side, radius, orientation);
            }
            C::StopCutterRadiusCompensation => return self.stop_compensation(canon),
            C::SelectPlane(plane) => {
                if active && *plane != self.plane {
                    return Err(CompError::new(K::PlaneChange, src));
                }
                self.plane = *plane;
            }
            C::UseLengthUnits(units) if *units != self.units => {
                self.scale(self.units.mm_per_unit() / units.mm_per_unit());
                self.units = *units;
            }
            C::SetG5xOffset { offset, .. } => {
                // With compensation on this is the first reset of M2 / M30 (G54..G59 and
                // G10 L2 of the active system are refused with compensation on): LinuxCNC
                // finishes the compensated path, then turns compensation off.
                self.end_compensation(src)?;
                let offset = *offset;
                self.change_offsets(|o| o.g5x = offset);
            }
            C::SetG92Offset(offset) => {
                let offset = *offset;
                self.change_offsets(|o| o.g92 = offset);
            }
            C::SetXyRotation(r) => {
                let r = *r;
                self.change_offsets(|o| o.rotation = r);
            }
            C::UseToolLengthOffset(offset) => {
                let offset = *offset;
                self.change_offsets(|o| o.tool = offset);
            }
            C::StraightProbe { end, .. } => self.programmed = *end,
            C::NurbsFeed(n) => {
                if let Some(last) = n.points.last() {
                    self.programmed.x = last.x;
                    self.programmed.y = last.y;
                }
            }
            C::SplineFeed(s) => {
                self.programmed.x = s.end[0];
                self.programmed.y = s.end[1];
            }
            C::ProgramStop | C::OptionalProgramStop | C::PalletShuttle => {
                self.flush_at_current(src)?;
            }
            C::ProgramEnd | C::OnReset | C::Finish => {
                self.end_compensation(src)?;
                self.arc_not_allowed = false;
            }
            _ => {}
        }
        // Everything else takes effect at once, ahead of a held move (as in LinuxCNC).
        self.ready.push_back(canon);
        Ok(())
    }

    /// G41/G42 (G41.1/G42.1: `orientation`), compensation being off.
    fn start_compensation(
        &mut self,
        canon: Canon,
        side: CompensationSide,
        radius: f64,
        orientation: i32,
    ) -> Result<(), CompError> {
        let src = canon.source;
        if !matches!(self.plane, Plane::XY | Plane::XZ)
            || (self.plane != Plane::XZ && orientation != 0 && orientation != 9)
        {
            return Err(CompError::new(K::WrongPlane, src));
        }
        if !radius.is_finite() {
            return Err(CompError::new(K::BadRadius, src));
        }
        let mut side = side;
        if radius < 0.0 {
            side = match side {
                CompensationSide::Left => CompensationSide::Right,
                CompensationSide::Right => CompensationSide::Left,
            };
        }
        self.side = Some(side);
        self.radius = radius.abs();
        self.orientation = orientation;
        self.first_move = true;
        self.enqueue(canon)
    }

    /// G40.
    fn stop_compensation(&mut self, canon: Canon) -> Result<(), CompError> {
        let src = canon.source;
        self.enqueue(canon)?;
        if self.compensating() && !self.first_move {
            self.move_endpoint_and_flush(src, [self.current[0], self.current[1]])?;
            self.dequeue();
            self.arc_not_allowed = true;
        }
        self.side = None;
        self.first_move = true;
        Ok(())
    }

    /// True when moves are to be offset: compensation on with a non-zero radius.
    fn compensating(&self) -> bool {
        self.side.is_some() && self.radius > 0.0
    }

    /// Finishes the compensated path at the current point and turns compensation off
    /// (M2 / M30, reset, end of program).
    fn end_compensation(&mut self, src: Source) -> Result<(), CompError> {
        self.flush_at_current(src)?;
        self.dequeue();
        self.side = None;
        self.first_move = true;
        Ok(())
    }

    fn flush_at_current(&mut self, src: Source) -> Result<(), CompError> {
        if self.compensating() && !self.first_move {
            self.move_endpoint_and_flush(src, [self.current[0], self.current[1]])?;
        }
        self.dequeue();
        Ok(())
    }

    /// Queues a command behind a held move, or passes it on when nothing is held.
    fn enqueue(&mut self, canon: Canon) -> Result<(), CompError> {
        if self.pending.is_empty() {
            self.ready.push_back(canon);
            Ok(())
        } else {
            self.hold(Pending::Other(canon))
        }
    }

    fn hold(&mut self, p: Pending) -> Result<(), CompError> {
        if self.pending.len() >= self.capacity {
            let source = match &p {
                Pending::Line { source, .. } | Pending::Arc { source, .. } => *source,
                Pending::Other(c) => c.source,
            };
            return Err(CompError::new(K::BufferFull, source));
        }
        self.pending.push_back(p);
        Ok(())
    }

    fn set_endpoint(&mut self, p: P2) {
        self.endpoint = p;
        self.endpoint_valid = true;
    }

    /// Releases every held command, in order, converting held moves to canonical commands.
    fn dequeue(&mut self) {
        self.endpoint_valid = false;
        let shift = if self.plane == Plane::XZ {
            lathe_origin_shift(self.orientation, self.radius)
        } else {
            [0.0, 0.0]
        };
        while let Some(p) = self.pending.pop_front() {
            let canon = match p {
                Pending::Other(c) => c,
                Pending::Line {
                    source,
                    traverse,
                    end,
                    mut pose,
                    ..
                } => {
                    from_plane(
                        self.plane,
                        [end[0] + shift[0], end[1] + shift[1], end[2]],
                        &mut pose,
                    );
                    Canon {
                        source,
                        command: if traverse {
                            CanonCommand::StraightTraverse(pose)
                        } else {
                            CanonCommand::StraightFeed(pose)
                        },
                    }
                }
                Pending::Arc {
                    source,
                    end,
                    centre,
                    turn,
                    w,
                    rest,
                    ..
                } => Canon {
                    source,
                    command: CanonCommand::ArcFeed(Arc {
                        first_end: end[0] + shift[0],
                        second_end: end[1] + shift[1],
                        first_axis: centre[0] + shift[0],
                        second_axis: centre[1] + shift[1],
                        rotation: turn,
                        axis_end_point: w,
                        ..rest
                    }),
                },
            };
            self.ready.push_back(canon);
        }
    }

    /// Moves the end of every held move to `to` (a concave corner), checking that none of
    /// them runs backwards, and releases them.
    fn move_endpoint_and_flush(&mut self, src: Source, to: P2) -> Result<(), CompError> {
        if self.pending.is_empty() {
            return Ok(());
        }
        let endpoint = self.endpoint;
        let check = self.endpoint_valid;
        let sweep_tolerance = sweep_growth_tolerance(self.units);
        for p in self.pending.iter_mut() {
            match p {
                Pending::Arc {
                    original_turns,
                    end,
                    centre,
                    turn,
                    ..
                } => {
                    let r1 = distance(*end, *centre);
                    let r2 = distance(to, *centre);
                    let l2 = sweep(endpoint, *centre, *turn, to);
                    if (r1 - r2).abs() > MOVED_ARC_RADIUS_TOLERANCE {
                        return Err(CompError::new(K::Internal, src));
                    }
                    if *original_turns != 0.0
                        && check
                        && l2.abs() > original_turns.abs() + sweep_tolerance
                    {
                        return Err(CompError::new(K::ArcGouge, src));
                    }
                    *end = to;
                }
                // LinuxCNC moves this one too, so that the tool goes straight to the corner
                // and the entry arc becomes a full circle: keep it where it is.
                Pending::Line { fixed: true, .. } => {}
                Pending::Line {
                    traverse, dir, end, ..
                } => {
                    let dot = dir[0] * (to[0] - endpoint[0]) + dir[1] * (to[1] - endpoint[1]);
                    if check && dot < 0.0 {
                        let kind = if *traverse {
                            K::StraightTraverseGouge
                        } else {
                            K::StraightFeedGouge
                        };
                        return Err(CompError::new(kind, src));
                    }
                    end[0] = to[0];
                    end[1] = to[1];
                }
                Pending::Other(_) => {}
            }
        }
        self.dequeue();
        self.set_endpoint(to);
        Ok(())
    }

    /// The first held move, if it is an arc: its compensated centre, end and turn. A lathe
    /// entry's positioning move is not the move that makes the corner: LinuxCNC looks at it
    /// and takes the entry arc for a line (an arc end moved off its circle, or a full
    /// circle); the stage looks past it.
    fn held_arc(&self) -> Option<(P2, P2, i32)> {
        let first = self
            .pending
            .iter()
            .find(|p| !matches!(p, Pending::Line { fixed: true, .. }));
        match first {
            Some(Pending::Arc {
                centre, end, turn, ..
            }) => Some((*centre, *end, *turn)),
            _ => None,
        }
    }

    fn straight(&mut self, src: Source, traverse: bool, p: Pose) -> Result<(), CompError> {
        let side = self.side.unwrap_or(CompensationSide::Left);
        let radius = self.radius;
        let [px, py, pz] = to_plane(self.plane, &p);
        if self.first_move {
            return self.straight_entry(src, traverse, p);
        }

        let c = self.current;
        let c2 = [c[0], c[1]];
        let op = to_plane(self.plane, &self.programmed);
        if px == op[0] && py == op[1] {
            // No motion in the plane: stay at the compensated point; held with the move
            // before it, which may still move.
            self.hold(Pending::Line {
                source: src,
                traverse,
                dir: [0.0, 0.0],
                end: [c[0], c[1], pz],
                pose: p,
                fixed: false,
            })?;
            self.current[2] = pz;
            return Ok(());
        }
        let op2 = [op[0], op[1]];
        let mut theta = direction(op2, c2);
        let mut alpha = direction(op2, [px, py]);
        let (beta, gamma) = match side {
            CompensationSide::Left => {
                if theta < alpha {
                    theta += TAU;
                }
                (theta - alpha - FRAC_PI_2, FRAC_PI_2)
            }
            CompensationSide::Right => {
                if alpha < theta {
                    alpha += TAU;
                }
                (alpha - theta - FRAC_PI_2, -FRAC_PI_2)
            }
        };
        let end = polar([px, py], radius, alpha + gamma);
        let mid = polar(op2, radius, alpha + gamma);
        let small = CORNER_TOLERANCE;
        // Tool outside a held arc, reversing onto a line: LinuxCNC keeps the tool on the
        // same side of the joint (the top of an "h"), which makes the corner concave.
        let h_shape = beta > PI - small
            && self
                .held_arc()
                .is_some_and(|(_, _, turn)| !tool_inside_arc(side, turn));
        let concave = beta < -small || beta > PI + small || h_shape;

        if !concave && beta > small {
            // Convex corner: an arc around the programmed corner point (a traverse to the
            // arc's end for G0: there is no arc traverse).
            self.move_endpoint_and_flush(src, c2)?;
            if traverse {
                self.hold(Pending::Line {
                    source: src,
                    traverse: true,
                    dir: [0.0, 0.0],
                    end: [mid[0], mid[1], c[2]],
                    pose: p,
                    fixed: false,
                })?;
            } else {
                self.hold(Pending::Arc {
                    source: src,
                    original_turns: 0.0,
                    end: mid,
                    centre: op2,
                    turn: corner_turn(side),
                    w: c[2],
                    rest: rest_of_pose(&p),
                })?;
            }
            self.dequeue();
            self.set_endpoint(mid);
        } else if concave {
            if self.pending.is_empty() {
                return Err(CompError::new(K::ConcaveAfterStop, src));
            }
            let to = match self.held_arc() {
                None => {
                    // Line to line: the intersection of the two offset lines.
                    let halfcorner = (beta + PI) / 2.0;
                    if halfcorner == 0.0 {
                        return Err(CompError::new(K::ZeroDegreeCorner, src));
                    }
                    polar(c2, concave_retreat(radius, beta), theta + gamma)
                }
                Some(held) => self.arc_to_line_meeting(src, held, op2, [px, py])?,
            };
            self.move_endpoint_and_flush(src, to)?;
        } else {
            // Straight on, or a tangent arc into a line: nothing to add.
            self.dequeue();
            self.set_endpoint(c2);
        }
        self.hold(Pending::Line {
            source: src,
            traverse,
            dir: [px - op[0], py - op[1]],
            end: [end[0], end[1], pz],
            pose: p,
            fixed: false,
        })?;
        self.current = [end[0], end[1], pz];
        Ok(())
    }

    /// The first move with compensation on, a line: from the current point to the point
    /// one radius to the side of the programmed end, perpendicular to the programmed move.
    fn straight_entry(&mut self, src: Source, traverse: bool, p: Pose) -> Result<(), CompError> {
        let side = self.side.unwrap_or(CompensationSide::Left);
        let radius = self.radius;
        let [px, py, pz] = to_plane(self.plane, &p);
        let c = to_plane(self.plane, &self.programmed);
        let c2 = [c[0], c[1]];
        if distance(c2, [px, py]) <= radius {
            return Err(CompError::new(K::EntryMoveTooShort, src));
        }
        let alpha = direction(c2, [px, py]) + side_angle(side);
        let end = line_offset_end(c2, [px, py], radius, side);
        self.set_endpoint(c2);
        self.hold(Pending::Line {
            source: src,
            traverse,
            dir: [alpha.cos(), alpha.sin()],
            end: [end[0], end[1], pz],
            pose: p,
            fixed: false,
        })?;
        self.first_move = false;
        self.current = [end[0], end[1], pz];
        Ok(())
    }

    /// A concave corner from the held arc (centre, end, turn) into a line from `op2` to
    /// `to`: where the offset line meets the compensated arc.
    fn arc_to_line_meeting(
        &self,
        src: Source,
        (centre, prev_end, prev_turn): (P2, P2, i32),
        op2: P2,
        [px, py]: P2,
    ) -> Result<P2, CompError> {
        let side = self.side.unwrap_or(CompensationSide::Left);
        let radius = self.radius;
        let oldrad = distance(centre, prev_end);
        let base_dir = direction(op2, [px, py]);
        let theta = if prev_turn > 0 {
            base_dir + FRAC_PI_2
        } else {
            base_dir - FRAC_PI_2
        };
        let phi = direction(op2, centre);
        let inside = tool_inside_arc(side, prev_turn);
        let oldrad_uncomp = if inside {
            oldrad + radius
        } else {
            oldrad - radius
        };
        let d = oldrad_uncomp * (theta - phi).cos();
        let l = (if inside { d - radius } else { d + radius }) / oldrad;
        if !(-1.0..=1.0).contains(&l) {
            return Err(CompError::new(K::ArcToStraightGouge, src));
        }
        let angle = if inside == (prev_turn > 0) {
            -l.acos() + theta + PI
        } else {
            l.acos() + theta + PI
        };
        Ok(polar(centre, oldrad, angle))
    }

    fn arc(&mut self, src: Source, arc: &Arc) -> Result<(), CompError> {
        let side = self.side.unwrap_or(CompensationSide::Left);
        let radius = self.radius;
        let turn = arc.rotation;
        if turn == 0 {
            return Err(CompError::new(K::Internal, src));
        }
        let end = [arc.first_end, arc.second_end];
        let centre = [arc.first_axis, arc.second_axis];
        let end_w = arc.axis_end_point;
        let inside = tool_inside_arc(side, turn);

        if self.first_move {
            return self.arc_entry(src, arc);
        }

        let op = to_plane(self.plane, &self.programmed);
        let op2 = [op[0], op[1]];
        let c = self.current;
        let c2 = [c[0], c[1]];
        let arc_radius = distance(centre, end);
        let theta = direction(op2, c2) - side_angle(side);
        let mut delta = direction(op2, centre);
        let alpha = if turn > 0 {
            delta - FRAC_PI_2
        } else {
            delta + FRAC_PI_2
        };
        let mut beta = match side {
            CompensationSide::Left => theta - alpha,
            CompensationSide::Right => alpha - theta,
        };
        if beta > 1.5 * PI {
            beta -= TAU;
        } else if beta < -FRAC_PI_2 {
            beta += TAU;
        }
        let gamma = if inside {
            if arc_radius <= radius {
                return Err(CompError::new(K::ToolRadiusNotLessThanArcRadius, src));
            }
            direction(end, centre)
        } else {
            delta += PI;
            direction(centre, end)
        };
        let new_end = polar(end, radius, gamma);
        let small = CORNER_TOLERANCE;
        let main = Pending::Arc {
            source: src,
            original_turns: sweep(op2, centre, turn, end),
            end: new_end,
            centre,
            turn,
            w: end_w,
            rest: *arc,
        };

        if beta < -small || beta > PI + small || ((beta - PI).abs() < small && !inside) {
            // Concave corner: move the end of the held move to where the compensated arc
            // starts.
            if self.pending.is_empty() {
                return Err(CompError::new(K::ConcaveAfterStop, src));
            }
            let to = match self.held_arc() {
                None => self.line_to_arc_meeting(src, arc, beta, theta)?,
                Some(held) => self.arc_to_arc_meeting(src, held, arc)?,
            };
            self.move_endpoint_and_flush(src, to)?;
            self.hold(main)?;
        } else if beta > small {
            // Convex corner: an arc around the programmed corner point first.
            let mid = polar(op2, radius, delta);
            self.dequeue();
            self.hold(Pending::Arc {
                source: src,
                original_turns: 0.0,
                end: mid,
                centre: op2,
                turn: corner_turn(side),
                w: c[2],
                rest: *arc,
            })?;
            self.dequeue();
            self.set_endpoint(mid);
            self.hold(main)?;
        } else {
            // Tangent.
            self.dequeue();
            self.set_endpoint(c2);
            self.hold(main)?;
        }
        self.current = [new_end[0], new_end[1], end_w];
        Ok(())
    }

    /// The first move with compensation on, an arc: an arc from the current point to the
    /// compensated end point, tangent to the cutter at that end.
    fn arc_entry(&mut self, src: Source, arc: &Arc) -> Result<(), CompError> {
        let side = self.side.unwrap_or(CompensationSide::Left);
        let radius = self.radius;
        let turn = arc.rotation;
        let end = [arc.first_end, arc.second_end];
        let centre = [arc.first_axis, arc.second_axis];
        let end_w = arc.axis_end_point;
        let inside = tool_inside_arc(side, turn);
        let c = to_plane(self.plane, &self.programmed);
        let c2 = [c[0], c[1]];
        if distance(end, c2) <= radius {
            return Err(CompError::new(K::EntryArcTooShort, src));
        }
        if inside && distance(centre, c2) <= radius {
            return Err(CompError::new(K::ToolRadiusNotLessThanArcRadius, src));
        }
        let gamma = if inside {
            direction(end, centre)
        } else {
            direction(centre, end)
        };
        self.first_move = false;
        let new_end = polar(end, radius, gamma);
        let b_len = distance(c2, new_end) / 2.0;
        let ab_ang = direction(new_end, centre);
        let a_ang = direction(new_end, c2) - ab_ang;
        if a_ang.cos().abs() < EQUAL_TOLERANCE {
            return Err(CompError::new(K::ToolRadiusNotLessThanArcRadius, src));
        }
        let new_centre = polar(new_end, b_len / a_ang.cos(), ab_ang);
        // A consistency check of the construction, with LinuxCNC's absolute tolerance of
        // the arc's radius difference in the program's units.
        let spiral = ArcRadiusTolerance::default_for(self.units).absolute;
        if (distance(new_centre, new_end) - distance(new_centre, c2)).abs() > spiral {
            return Err(CompError::new(K::Internal, src));
        }
        let rest = *arc;
        if self.orientation != 0 && self.orientation != 9 {
            // A lathe tool's origin is not the centre of its nose: move the origin to
            // the compensated start first, or the arc is not an arc.
            let mut pose = self.programmed;
            set_rest_of_pose(&mut pose, &rest);
            self.hold(Pending::Line {
                source: src,
                traverse: false,
                dir: [0.0, 0.0],
                end: c,
                pose,
                fixed: true,
            })?;
            self.set_endpoint(c2);
        }
        self.hold(Pending::Arc {
            source: src,
            original_turns: sweep(c2, new_centre, turn, new_end),
            end: new_end,
            centre: new_centre,
            turn,
            w: end_w,
            rest,
        })?;
        self.current = [new_end[0], new_end[1], end_w];
        Ok(())
    }

    /// The circle the tool's centre follows along `arc`: the arc's radius less the tool's
    /// where the tool is inside the arc, plus it where outside.
    fn offset_circle(&self, arc: &Arc) -> OffsetCircle {
        let side = self.side.unwrap_or(CompensationSide::Left);
        let centre = [arc.first_axis, arc.second_axis];
        let arc_radius = distance(centre, [arc.first_end, arc.second_end]);
        let inside = tool_inside_arc(side, arc.rotation);
        let radius = if inside {
            arc_radius - self.radius
        } else {
            arc_radius + self.radius
        };
        OffsetCircle {
            centre,
            arc_radius,
            radius,
            inside,
        }
    }

    /// A concave corner from the held line into `arc`, the corner's angle `beta` and the
    /// held line's offset direction `theta`: where the offset line meets the compensated
    /// arc.
    fn line_to_arc_meeting(
        &self,
        src: Source,
        arc: &Arc,
        beta: f64,
        theta: f64,
    ) -> Result<P2, CompError> {
        let radius = self.radius;
        let turn = arc.rotation;
        let OffsetCircle {
            centre,
            arc_radius,
            radius: dist,
            inside,
        } = self.offset_circle(arc);
        let cy = arc_radius * (beta - FRAC_PI_2).sin();
        let l = if inside {
            (cy + radius) / dist
        } else {
            (cy - radius) / dist
        };
        if !(-1.0..=1.0).contains(&l) {
            return Err(CompError::new(K::ArcGouge, src));
        }
        let angle = match (inside, turn > 0) {
            (true, true) => theta + l.asin(),
            (true, false) => theta - l.asin(),
            (false, true) => theta + PI - l.asin(),
            (false, false) => theta + PI + l.asin(),
        };
        Ok(polar(centre, dist, angle))
    }

    /// A concave corner from the held arc (centre, end, turn) into `arc`: where the two
    /// compensated circles meet.
    fn arc_to_arc_meeting(
        &self,
        src: Source,
        (prev_centre, prev_end, prev_turn): (P2, P2, i32),
        arc: &Arc,
    ) -> Result<P2, CompError> {
        let side = self.side.unwrap_or(CompensationSide::Left);
        let turn = arc.rotation;
        let OffsetCircle {
            centre,
            radius: newrad,
            ..
        } = self.offset_circle(arc);
        let oldrad = distance(prev_centre, prev_end);
        let arc_cc = distance(prev_centre, centre);
        if oldrad == 0.0 || arc_cc == 0.0 {
            return Err(CompError::new(K::ArcsSameCentre, src));
        }
        let a = (oldrad * oldrad + arc_cc * arc_cc - newrad * newrad) / (2.0 * oldrad * arc_cc);
        if !(-1.0..=1.0).contains(&a) {
            return Err(CompError::new(K::ArcToArcGouge, src));
        }
        let pullback = a.acos();
        let cc_dir = direction(prev_centre, centre);
        let dir = if tool_inside_arc(side, prev_turn) == (turn > 0) {
            cc_dir + pullback
        } else {
            cc_dir - pullback
        };
        Ok(polar(prev_centre, oldrad, dir))
    }

    /// The end pose of an arc in the current plane (axes not in the arc keep their value).
    fn arc_end_pose(&self, arc: &Arc) -> Pose {
        let mut pose = self.programmed;
        set_rest_of_pose(&mut pose, arc);
        let uvw = [arc.first_end, arc.second_end, arc.axis_end_point];
        match self.plane {
            Plane::XY | Plane::XZ => from_plane(self.plane, uvw, &mut pose),
            Plane::YZ => {
                pose.y = uvw[0];
                pose.z = uvw[1];
                pose.x = uvw[2];
            }
            // LinuxCNC has no arcs in the UVW planes; nothing to follow.
            Plane::UV | Plane::WU | Plane::VW => {}
        }
        pose
    }

    /// Applies a change of work offsets: the programmed position keeps its place on the
    /// machine, so its program coordinates change.
    fn change_offsets(&mut self, change: impl FnOnce(&mut Offsets)) {
        let machine = to_machine(&self.offsets, &self.programmed);
        change(&mut self.offsets);
        let programmed = from_machine(&self.offsets, &machine);
        let before = to_plane(self.plane, &self.programmed);
        let after = to_plane(self.plane, &programmed);
        for (c, (a, b)) in self.current.iter_mut().zip(after.iter().zip(before.iter())) {
            *c += a - b;
        }
        self.programmed = programmed;
    }

    /// A change of length units: everything held converts (as LinuxCNC's `qc_scale`).
    fn scale(&mut self, f: f64) {
        scale_pose(&mut self.programmed, f);
        for c in self.current.iter_mut() {
            *c *= f;
        }
        self.endpoint = [self.endpoint[0] * f, self.endpoint[1] * f];
        self.radius *= f;
        scale_pose(&mut self.offsets.g5x, f);
        scale_pose(&mut self.offsets.g92, f);
        scale_pose(&mut self.offsets.tool, f);
        for p in self.pending.iter_mut() {
            match p {
                Pending::Line { end, pose, .. } => {
                    for e in end.iter_mut() {
                        *e *= f;
                    }
                    scale_pose(pose, f);
                }
                Pending::Arc {
                    end,
                    centre,
                    w,
                    rest,
                    ..
                } => {
                    *end = [end[0] * f, end[1] * f];
                    *centre = [centre[0] * f, centre[1] * f];
                    *w *= f;
                    rest.u *= f;
                    rest.v *= f;
                    rest.w *= f;
                }
                Pending::Other(_) => {}
            }
        }
    }
}

/// Direction of the arc that rounds a convex corner: clockwise with the tool on the left.
fn corner_turn(side: CompensationSide) -> i32 {
    match side {
        CompensationSide::Left => -1,
        CompensationSide::Right => 1,
    }
}

/// An arc carrying the rotary and UVW ends of a pose (for a corner arc: they move on it).
fn rest_of_pose(p: &Pose) -> Arc {
    Arc {
        first_end: 0.0,
        second_end: 0.0,
        first_axis: 0.0,
        second_axis: 0.0,
        rotation: 0,
        axis_end_point: 0.0,
        a: p.a,
        b: p.b,
        c: p.c,
        u: p.u,
        v: p.v,
        w: p.w,
    }
}

fn set_rest_of_pose(pose: &mut Pose, arc: &Arc) {
    pose.a = arc.a;
    pose.b = arc.b;
    pose.c = arc.c;
    pose.u = arc.u;
    pose.v = arc.v;
    pose.w = arc.w;
}

fn scale_pose(p: &mut Pose, f: f64) {
    p.x *= f;
    p.y *= f;
    p.z *= f;
    p.u *= f;
    p.v *= f;
    p.w *= f;
}

fn rotate(x: f64, y: f64, degrees: f64) -> (f64, f64) {
    if degrees == 0.0 {
        return (x, y);
    }
    let (s, c) = degrees.to_radians().sin_cos();
    (x * c - y * s, x * s + y * c)
}

/// `machine = rotate(program + g92, rotation) + g5x + tool` (the convention of `canon`).
fn to_machine(o: &Offsets, p: &Pose) -> Pose {
    let mut v = p.to_array();
    let g92 = o.g92.to_array();
    let g5x = o.g5x.to_array();
    let tool = o.tool.to_array();
    for (i, x) in v.iter_mut().enumerate() {
        *x += g92[i];
    }
    let (x, y) = rotate(v[0], v[1], o.rotation);
    v[0] = x;
    v[1] = y;
    for (i, x) in v.iter_mut().enumerate() {
        *x += g5x[i] + tool[i];
    }
    Pose::from_array(v)
}

fn from_machine(o: &Offsets, m: &Pose) -> Pose {
    let mut v = m.to_array();
    let g92 = o.g92.to_array();
    let g5x = o.g5x.to_array();
    let tool = o.tool.to_array();
    for (i, x) in v.iter_mut().enumerate() {
        *x -= g5x[i] + tool[i];
    }
    let (x, y) = rotate(v[0], v[1], -o.rotation);
    v[0] = x;
    v[1] = y;
    for (i, x) in v.iter_mut().enumerate() {
        *x -= g92[i];
    }
    Pose::from_array(v)
}

/// The circle a compensated tool's centre follows along an arc.
struct OffsetCircle {
    centre: P2,
    /// The programmed arc's radius.
    arc_radius: f64,
    /// The tool centre's.
    radius: f64,
    /// The tool is on the arc's inside.
    inside: bool,
}
