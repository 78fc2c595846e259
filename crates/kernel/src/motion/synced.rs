//! Spindle-synchronised moves (G33, a G76 pass): once the path stands, the line waits for
//! the spindle's index, then its progress follows pitch × the spindle's revolutions since
//! the index, read every period from the drive (position synchronisation, as LinuxCNC).
//! The gap from rest is closed time-optimally within the axes' limits, planned in the
//! frame that moves with the spindle; near the end the line goes to rest on its end point.
//!
//! A rigid tap (G33.1) follows the spindle the same way, both ways, as LinuxCNC's: at the
//! bottom it commands the spindle reversed and follows it through its deceleration (the
//! overrun past the bottom) and back up; at the start point it commands the spindle's first
//! direction again, follows it through that reversal (the overrun above the start), and
//! goes back to the start point unsynchronised.
//!
//! Consecutive synchronised lines (chained G33 blocks, a G76 pass with tapers) run as one
//! chain on one index: the position is a function of the spindle's revolutions, each line
//! at its own pitch, the corners blended over a span of revolutions sized so that at the
//! spindle's speed the axes keep half their acceleration and jerk limits. The tool
//! locks on with a constant lag (it accelerates to the spindle's speed and stays behind by
//! what that cost, the same for every pass at that speed, as LinuxCNC's), so that it never
//! runs faster than the spindle through a corner.

use rtcnc_motion::AXES;
use rtcnc_motion::otg::{self, Limits, OnlineAxis};

use super::MotionCore;
use super::state::Event;
use crate::fault::FaultCode;
use crate::messages::{JointSetpoints, MAX_SYNCED_CHAIN};
use crate::shared::Feedback;

/// The share of the chain's limits each axis can take, of the chains' limits kept in a
/// corner blend and along a chain (the rest for the lock-on's acceleration meanwhile).
const CHAIN_LIMIT_SHARE: f64 = 0.5;

/// G33 / a G76 pass: a line whose progress follows the spindle's angle. A chain's progress
/// is the first line's pitch × revolutions, mapped onto the chain.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct SyncedMove {
    start: [f64; AXES],
    /// Unit direction.
    dir: [f64; AXES],
    /// Per axis, the most it moves per mm of progress (the largest over a chain's lines).
    shares: [f64; AXES],
    length: f64,
    /// mm per revolution.
    pitch: f64,
    /// The geometry is `MotionCore::synced_chain`'s.
    chain: bool,
    /// While tracking: the progress's offset from pitch × revolutions, jerk-limited from
    /// where it was at the index to 0 (planned in the frame that moves with the spindle,
    /// so it catches up time-optimally and then stays on it).
    offset: Option<OnlineAxis>,
    /// Progress along the line (mm): at rest before the index, to the end after tracking.
    otg: OnlineAxis,
    /// Path limits along the line (velocity, acceleration, jerk).
    limits: (f64, f64, f64),
    /// Unwrapped spindle angle (degrees), the last reading (0..360) and the change over
    /// the period before it (set-points computed ahead go on with it).
    angle: f64,
    reading: f64,
    delta: f64,
    /// The unwrapped angle of the index the move started at; `None` while waiting for it.
    index: Option<f64>,
    /// Going to the end at rest (or stopping): no longer tracking.
    finishing: bool,
    /// +1 when the spindle turned towards increasing angles at the index, else -1: the
    /// progress is pitch × the revolutions in that direction.
    direction: f64,
    /// The change of the angle over the period before the last measured one (for the
    /// acceleration the final placement of a tap starts with).
    delta_before: f64,
    /// G33.1.
    tap: Option<RigidTap>,
    line: u32,
}

impl SyncedMove {
    /// The spindle's turn over this period (degrees), measured from `reading` when
    /// `decide`, else as if it turned on as in the period before; the angle moves on by it.
    #[inline]
    fn turn(&mut self, reading: f64, decide: bool) -> f64 {
        let delta = if decide {
            let mut delta = reading - self.reading;
            if delta > 180.0 {
                delta -= 360.0;
            } else if delta <= -180.0 {
                delta += 360.0;
            }
            self.reading = reading;
            delta
        } else {
            self.reading = (self.reading + self.delta).rem_euclid(360.0);
            self.delta
        };
        if decide {
            // Predicted periods go on with the acceleration last measured.
            self.delta_before = self.delta;
        }
        self.delta = delta;
        self.angle += delta;
        delta
    }

    /// Waiting for the index (at angle 0): the first crossing of a whole turn, over this
    /// period's turn `delta`.
    #[inline]
    fn find_index(&mut self, delta: f64) {
        if self.index.is_none() {
            let (now, before) = (
                (self.angle / 360.0).floor(),
                ((self.angle - delta) / 360.0).floor(),
            );
            if now != before {
                self.index = Some(360.0 * now.max(before));
                self.direction = if delta < 0.0 { -1.0 } else { 1.0 };
            }
        }
    }

    /// Past the index and not finishing: the progress and its speed on the spindle this
    /// period (`None` once it finishes: the progress is then `otg`'s).
    #[inline]
    fn follow_spindle(&mut self, delta: f64, dt: f64) -> Option<(f64, f64)> {
        let (Some(index), false) = (self.index, self.finishing) else {
            return None;
        };
        let (vmax, a, j) = self.limits;
        // Signed: a tap's spindle reverses.
        let speed = self.pitch * self.direction * delta / 360.0 / dt;
        let here = self.pitch * self.direction * (self.angle - index) / 360.0;
        if self.offset.is_none() {
            self.lock_on(speed, here);
        }
        let offset = self.offset.as_mut()?;
        // The set-point is applied in the next period: where the spindle will be.
        let e = offset.step(dt);
        let p = here + speed * dt + e.p;
        let v = speed + e.v;
        let stopping = 0.5 * v * (v / a + a / j) + v * dt;
        let length = self.length;
        let placing = self.tap.as_mut().is_some_and(|t| {
            t.phase = match t.phase {
                TapPhase::In if p >= length => TapPhase::Reversing,
                TapPhase::Reversing if speed < 0.0 => TapPhase::Out,
                TapPhase::Out if p <= 0.0 => TapPhase::Restoring,
                other => other,
            };
            t.phase == TapPhase::Restoring && speed > 0.0
        });
        if placing {
            // This set-point is still the spindle's; the placement starts from it.
            self.place_back(p, delta, e.a, dt);
            Some((p, v))
        } else if self.tap.is_none() && p + stopping >= self.length {
            // The end: at most this speed, then to rest on the end point.
            // (From the last set-point, which `otg` holds.)
            self.finishing = true;
            let limits = Limits::symmetric(v.abs().max(speed).max(1e-6), a, j);
            let _ = self.otg.set_limits(limits);
            let _ = self.otg.set_target(otg::State::at_rest(self.length));
            None
        } else {
            // Where a stop would start from (abort, fault).
            if let Ok(o) = OnlineAxis::new(
                otg::State::new(p, v, e.a),
                Limits::symmetric(vmax.max(v.abs()), a, j),
            ) {
                self.otg = o;
            }
            Some((p, v))
        }
    }

    /// At the index: the offset from the spindle's progress `here` (its speed `speed`), to
    /// be closed; without one the move finishes.
    #[inline]
    fn lock_on(&mut self, speed: f64, here: f64) {
        let (vmax, a, j) = self.limits;
        let relative = Limits {
            max_velocity: vmax - speed,
            min_velocity: -vmax - speed,
            max_acceleration: a,
            min_acceleration: -a,
            max_jerk: j,
        };
        let at = self.otg.sample();
        // A chain locks on with the lag its acceleration costs (it never runs ahead of the
        // spindle into a corner), planned from the index's instant (the spindle has turned
        // on since) so that the lag is the same every pass; a line catches up with the
        // index.
        self.offset = if self.chain {
            let since = if speed > 0.0 { here / speed } else { 0.0 };
            let start = otg::State::new(at.p, at.v - speed, at.a);
            OnlineAxis::new(start, relative)
                .and_then(|mut o| {
                    o.stop()?;
                    o.step(since);
                    Ok(o)
                })
                .ok()
        } else {
            let start = otg::State::new(at.p - here, at.v - speed, at.a);
            OnlineAxis::new(start, relative)
                .and_then(|mut o| o.set_target(otg::State::at_rest(0.0)).map(|()| o))
                .ok()
        };
        if self.offset.is_none() {
            self.finishing = true;
            let _ = self.otg.stop();
        }
    }

    /// A tap's spindle turns in again: back to the start unsynchronised, from the motion
    /// it followed to `p` (its acceleration too, `offset_acceleration` being the offset's,
    /// so that it goes on smoothly).
    #[inline]
    fn place_back(&mut self, p: f64, delta: f64, offset_acceleration: f64, dt: f64) {
        let (vmax, a, j) = self.limits;
        self.finishing = true;
        // The set-points' own velocity and acceleration (the spindle's speed measured is
        // that of the period before).
        let turning = self.pitch * self.direction * (delta - self.delta_before) / 360.0;
        let acceleration = (turning / (dt * dt) + offset_acceleration).clamp(-a, a);
        let before = self.otg.sample().p;
        let velocity = (p - before) / dt + 0.5 * acceleration * dt;
        if let Ok(mut o) = OnlineAxis::new(
            otg::State::new(p, velocity, acceleration),
            Limits::symmetric(vmax.max(velocity.abs()), a, j),
        ) {
            let _ = o.set_target(otg::State::at_rest(0.0));
            self.otg = o;
        } else {
            let _ = self.otg.set_target(otg::State::at_rest(0.0));
        }
    }
}

/// Where a rigid tap is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum TapPhase {
    /// Into the hole.
    In,
    /// Past the bottom: the spindle is commanded reversed and still turns in.
    Reversing,
    /// Out of the hole with the reversed spindle.
    Out,
    /// Past the start: the spindle is commanded in its first direction again and still
    /// turns out; once it turns in, the tool goes back to the start unsynchronised.
    Restoring,
}

/// G33.1: the spindle's command during the tap (the overrides do not change it).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct RigidTap {
    /// The spindle speed on the way in (rpm, the programmed one, without the override).
    rpm: f64,
    /// The speed factor on the way out (the I word, at least 1).
    scale: f64,
    /// The spindle's commanded direction on the way in.
    reverse: bool,
    phase: TapPhase,
}

impl RigidTap {
    /// The spindle's command in this phase: (reversed, rpm).
    fn spindle(&self) -> (bool, f64) {
        match self.phase {
            TapPhase::In | TapPhase::Restoring => (self.reverse, self.rpm),
            TapPhase::Reversing | TapPhase::Out => (!self.reverse, self.rpm * self.scale),
        }
    }
}

/// One line of a chain, placed on the chain's revolutions.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct ChainLine {
    /// Where it starts (the chain's start for the first line).
    from: [f64; AXES],
    /// mm per revolution of every axis.
    per_rev: [f64; AXES],
    /// Revolutions from the chain's start at its start and its end.
    r0: f64,
    r1: f64,
    /// Half the revolutions the blend into the next line takes (0: none).
    blend: f64,
    /// Program line.
    line: u32,
}

impl ChainLine {
    /// On the line (extended beyond its ends) at `r` revolutions.
    fn at(&self, r: f64) -> [f64; AXES] {
        let mut x = self.from;
        for (x, v) in x.iter_mut().zip(self.per_rev) {
            *x += v * (r - self.r0);
        }
        x
    }
}

/// The lines of a chain of synchronised moves: collected from the look-ahead until its last
/// one comes, then placed on the revolutions of the spindle for the chain in progress.
#[derive(Debug, Clone, Copy)]
pub(super) struct SyncedChain {
    /// (end, pitch, program line) of the chained lines waiting for the last one.
    pending: [([f64; AXES], f64, u32); MAX_SYNCED_CHAIN],
    pending_count: usize,
    lines: [ChainLine; MAX_SYNCED_CHAIN],
    count: usize,
}

impl SyncedChain {
    pub(super) fn new() -> Self {
        SyncedChain {
            pending: [([0.0; AXES], 0.0, 0); MAX_SYNCED_CHAIN],
            pending_count: 0,
            lines: [ChainLine::default(); MAX_SYNCED_CHAIN],
            count: 0,
        }
    }

    /// Forgets the lines collected (the program stopped before its chain started).
    pub(super) fn clear(&mut self) {
        self.pending_count = 0;
    }

    /// The position `r` revolutions from the chain's start: on its lines, blended
    /// through the corners (the velocity per revolution changes as a smoothstep over the
    /// blend, so the acceleration is continuous).
    fn position(&self, r: f64) -> [f64; AXES] {
        let lines = &self.lines[..self.count.min(MAX_SYNCED_CHAIN)];
        let Some(last) = lines.last() else {
            return [0.0; AXES];
        };
        let r = r.clamp(0.0, last.r1);
        let k = lines
            .iter()
            .position(|l| r < l.r1)
            .unwrap_or(lines.len() - 1);
        let blended = |a: &ChainLine, b: &ChainLine| {
            let h = a.blend;
            let t = ((r - a.r1 + h) / (2.0 * h)).clamp(0.0, 1.0);
            let integral = t * t * t - 0.5 * t * t * t * t;
            let mut x = a.at(r);
            for i in 0..AXES {
                x[i] += (b.per_rev[i] - a.per_rev[i]) * 2.0 * h * integral;
            }
            x
        };
        if k > 0 && r < lines[k].r0 + lines[k - 1].blend {
            return blended(&lines[k - 1], &lines[k]);
        }
        if k + 1 < lines.len() && r > lines[k].r1 - lines[k].blend {
            return blended(&lines[k], &lines[k + 1]);
        }
        lines[k].at(r)
    }

    /// The program line of the chain's line at `r` revolutions (a corner's blend belongs
    /// to the line before it).
    fn line(&self, r: f64) -> Option<u32> {
        let lines = &self.lines[..self.count.min(MAX_SYNCED_CHAIN)];
        lines
            .iter()
            .find(|l| r < l.r1 - l.blend)
            .or(lines.last())
            .map(|l| l.line)
    }

    /// The chain's end.
    fn end(&self) -> [f64; AXES] {
        match self.lines[..self.count.min(MAX_SYNCED_CHAIN)].last() {
            Some(l) => l.at(l.r1),
            None => [0.0; AXES],
        }
    }
}

impl MotionCore {
    /// A chained synchronised line (more follow): kept until the last one comes. False
    /// when the chain is too long.
    pub(super) fn chain_synced(&mut self, end: [f64; AXES], pitch: f64, line: u32) -> bool {
        let c = &mut self.synced_chain;
        // Room for the last line too.
        if c.pending_count + 1 >= MAX_SYNCED_CHAIN {
            c.pending_count = 0;
            return false;
        }
        c.pending[c.pending_count] = (end, pitch, line);
        c.pending_count += 1;
        true
    }

    /// Starts a chain of synchronised lines from where the machine stands: the chained
    /// lines collected and the last one (`end`, `pitch`). Refused as a single line is, and
    /// when a corner cannot be blended within the limits at the spindle's speed in the
    /// revolutions its lines leave for it.
    fn start_synced_chain(&mut self, end: [f64; AXES], pitch: f64, line: u32) {
        let feedback = *self.interface.feedback.get();
        let fail = |code| Event::Fail {
            code,
            line,
            value: 0.0,
        };
        let start = self.out.last.axes;
        let pending = self.synced_chain.pending_count.min(MAX_SYNCED_CHAIN - 1);
        self.synced_chain.pending_count = 0;
        let mut ends = self.synced_chain.pending;
        ends[pending] = (end, pitch, line);
        let mut lines = [ChainLine::default(); MAX_SYNCED_CHAIN];
        let mut count = 0;
        let (mut from, mut r) = (start, 0.0);
        for &(end, pitch, line) in &ends[..=pending] {
            let mut length2 = 0.0;
            for i in 0..AXES {
                length2 += (end[i] - from[i]) * (end[i] - from[i]);
            }
            let length = length2.sqrt();
            if !length.is_finite() || !pitch.is_finite() {
                self.fire(fail(FaultCode::MotionError));
                return;
            }
            if length == 0.0 {
                continue;
            }
            if pitch <= 0.0 {
                self.fire(fail(FaultCode::SyncFailed));
                return;
            }
            let mut per_rev = [0.0; AXES];
            for i in 0..AXES {
                per_rev[i] = (end[i] - from[i]) / length * pitch;
                if per_rev[i].abs() > 1e-12
                    && (!self.machine.axis_present[i]
                        || end[i] < self.machine.axis_min[i]
                        || end[i] > self.machine.axis_max[i])
                {
                    self.fire(fail(FaultCode::MotionError));
                    return;
                }
            }
            let r1 = r + length / pitch;
            lines[count] = ChainLine {
                from,
                per_rev,
                r0: r,
                r1,
                blend: 0.0,
                line,
            };
            count += 1;
            (from, r) = (end, r1);
        }
        if count == 0 {
            self.fire(Event::Proceed);
            return;
        }
        // The corners' blends, at the spindle's speed (commanded, or measured if faster).
        let rps = self.spindle_command().max(feedback.spindle_rpm.abs()) / 60.0;
        for c in 0..count - 1 {
            let (a, b) = (&lines[c], &lines[c + 1]);
            let mut h: f64 = 0.0;
            for i in 0..AXES {
                let change = (b.per_rev[i] - a.per_rev[i]).abs();
                if change < 1e-12 {
                    continue;
                }
                let l = self.machine.axis_limits[i];
                let acceleration = CHAIN_LIMIT_SHARE * l.max_acceleration;
                let jerk = CHAIN_LIMIT_SHARE * l.max_jerk;
                h = h
                    .max(0.75 * change * rps * rps / acceleration)
                    .max((1.5 * change * rps * rps * rps / jerk).sqrt());
            }
            // The first line may give all its revolutions to its one corner, the others
            // half to each.
            let before = if c == 0 {
                a.r1 - a.r0
            } else {
                0.5 * (a.r1 - a.r0)
            };
            let after = 0.5 * (b.r1 - b.r0);
            if !h.is_finite() || h > before.min(after) {
                self.fire(fail(FaultCode::SyncFailed));
                return;
            }
            lines[c].blend = h;
        }
        // Progress is the first line's pitch × revolutions; each axis's share of it.
        let pitch = (0..AXES)
            .map(|i| lines[0].per_rev[i] * lines[0].per_rev[i])
            .sum::<f64>()
            .sqrt();
        let mut shares = [0.0f64; AXES];
        for l in &lines[..count] {
            for i in 0..AXES {
                shares[i] = shares[i].max(l.per_rev[i].abs() / pitch);
            }
        }
        let (mut v, mut a, mut j) = (f64::INFINITY, f64::INFINITY, f64::INFINITY);
        for i in 0..AXES {
            if shares[i] < 1e-12 {
                continue;
            }
            let l = self.machine.axis_limits[i];
            v = v.min(l.max_velocity / shares[i]);
            a = a.min(CHAIN_LIMIT_SHARE * l.max_acceleration / shares[i]);
            j = j.min(CHAIN_LIMIT_SHARE * l.max_jerk / shares[i]);
        }
        let mut dir = [0.0; AXES];
        for i in 0..AXES {
            dir[i] = lines[0].per_rev[i] / pitch;
        }
        self.synced_chain.lines = lines;
        self.synced_chain.count = count;
        let length = pitch * r;
        let speed = pitch * feedback.spindle_rpm.abs() / 60.0;
        let progress = OnlineAxis::new(otg::State::at_rest(0.0), Limits::symmetric(v, a, j));
        match progress {
            Ok(otg) if self.spindle.on && speed > 0.0 && speed <= 0.9 * v => {
                self.synced = Some(SyncedMove {
                    start,
                    dir,
                    shares,
                    length,
                    pitch,
                    chain: true,
                    offset: None,
                    otg,
                    limits: (v, a, j),
                    angle: feedback.spindle_angle_deg,
                    reading: feedback.spindle_angle_deg,
                    delta: 0.0,
                    index: None,
                    finishing: false,
                    direction: 1.0,
                    delta_before: 0.0,
                    tap: None,
                    line,
                });
                self.fire(Event::Synced);
            }
            _ => {
                self.fire(fail(FaultCode::SyncFailed));
            }
        }
    }

    /// Where a synchronised move is at `progress`.
    fn synced_position(&self, m: &SyncedMove, progress: f64) -> [f64; AXES] {
        if m.chain {
            return self.synced_chain.position(progress / m.pitch);
        }
        let mut x = m.start;
        for i in 0..AXES {
            x[i] += m.dir[i] * progress;
        }
        x
    }

    /// Starts a spindle-synchronised line (G33) from where the machine stands: it waits for
    /// the spindle's index, then its progress follows pitch × revolutions. Refused when the
    /// spindle stands, when the line leaves the soft limits, or when the spindle turns too
    /// fast for the pitch and the axes (the axes could not keep up). `tap`: a rigid tap
    /// (G33.1) with its speed factor on the way out.
    pub(super) fn start_synced(
        &mut self,
        end: [f64; AXES],
        pitch: f64,
        tap: Option<f64>,
        line: u32,
    ) {
        let feedback = *self.interface.feedback.get();
        let fail = |code| Event::Fail {
            code,
            line,
            value: 0.0,
        };
        // From where the machine stands, not after the set-points produced ahead there.
        self.discard_ahead();
        if self.synced_chain.pending_count > 0 && tap.is_none() {
            self.start_synced_chain(end, pitch, line);
            return;
        }
        self.synced_chain.pending_count = 0;
        let start = self.out.last.axes;
        let mut dir = [0.0; AXES];
        let mut length2 = 0.0;
        for i in 0..AXES {
            dir[i] = end[i] - start[i];
            length2 += dir[i] * dir[i];
        }
        let length = length2.sqrt();
        if !length.is_finite() {
            self.fire(fail(FaultCode::MotionError));
            return;
        }
        if length == 0.0 {
            self.fire(Event::Proceed);
            return;
        }
        let (mut v, mut a, mut j) = (f64::INFINITY, f64::INFINITY, f64::INFINITY);
        for i in 0..AXES {
            dir[i] /= length;
            let share = dir[i].abs();
            if share < 1e-12 {
                continue;
            }
            if !self.machine.axis_present[i]
                || end[i] < self.machine.axis_min[i]
                || end[i] > self.machine.axis_max[i]
            {
                self.fire(fail(FaultCode::MotionError));
                return;
            }
            let l = self.machine.axis_limits[i];
            v = v.min(l.max_velocity / share);
            a = a.min(l.max_acceleration / share);
            j = j.min(l.max_jerk / share);
        }
        // A tap runs at the programmed speed (the override does not apply) and comes out
        // at `scale` times it.
        let tap = tap.map(|scale| RigidTap {
            rpm: self.spindle_command_without_override(),
            scale: if scale.is_finite() {
                scale.max(1.0)
            } else {
                1.0
            },
            reverse: self.interface.requests.spindle_reverse,
            phase: TapPhase::In,
        });
        let fastest_rpm = match tap {
            Some(t) => feedback.spindle_rpm.abs().max(t.rpm) * t.scale,
            None => feedback.spindle_rpm.abs(),
        };
        let speed = pitch * fastest_rpm / 60.0;
        let progress = OnlineAxis::new(otg::State::at_rest(0.0), Limits::symmetric(v, a, j));
        match progress {
            Ok(otg)
                if self.spindle.on
                    && feedback.spindle_rpm != 0.0
                    && speed > 0.0
                    && speed <= 0.9 * v
                    && pitch > 0.0 =>
            {
                let mut shares = [0.0; AXES];
                for i in 0..AXES {
                    shares[i] = dir[i].abs();
                }
                self.synced = Some(SyncedMove {
                    start,
                    dir,
                    shares,
                    length,
                    pitch,
                    chain: false,
                    offset: None,
                    otg,
                    limits: (v, a, j),
                    angle: feedback.spindle_angle_deg,
                    reading: feedback.spindle_angle_deg,
                    delta: 0.0,
                    index: None,
                    finishing: false,
                    direction: 1.0,
                    delta_before: 0.0,
                    tap,
                    line,
                });
                self.command_tap_spindle();
                self.fire(Event::Synced);
            }
            _ => {
                self.fire(fail(FaultCode::SyncFailed));
            }
        }
    }

    /// One period of the synchronised move: follows the spindle's angle (from the last
    /// exchange when `decide`, else as if the spindle turned on as in the period before)
    /// and gives the axis position; a finished move hands the path back to the planner
    /// where it ended (when `decide`; until then it stands there).
    pub(super) fn synced_step(
        &mut self,
        feedback: &Feedback,
        sp: &mut JointSetpoints,
        decide: bool,
    ) {
        let Some(mut m) = self.synced else {
            return;
        };
        let dt = self.machine.period_s;
        let delta = m.turn(feedback.spindle_angle_deg, decide);
        m.find_index(delta);
        let progress = m.follow_spindle(delta, dt);
        let s = match progress {
            Some((p, v)) => otg::Sample {
                p,
                v,
                a: 0.0,
                j: 0.0,
            },
            None if m.finishing || m.offset.is_none() => m.otg.step(dt),
            None => m.otg.sample(),
        };
        sp.axes = self.synced_position(&m, s.p);
        sp.move_end = if m.chain {
            self.synced_chain.end()
        } else {
            self.synced_position(&m, m.length)
        };
        for jn in 0..self.machine.joint_count {
            if let Some(i) = self.machine.joints[jn].axis {
                sp.joints[jn] = sp.axes[i];
            }
        }
        sp.line = if m.chain {
            self.synced_chain.line(s.p / m.pitch).unwrap_or(m.line)
        } else {
            m.line
        };
        sp.path_speed = s.v.abs();
        if decide && m.finishing && m.otg.is_finished() {
            self.synced = None;
            if m.tap.is_some() {
                // The spindle's own command again (with the override in force).
                let rpm = self.spindle_command();
                if self.interface.requests.spindle_rpm != rpm {
                    self.requests_mut().spindle_rpm = rpm;
                }
            }
            let _ = self.path.planner.reset_at(sp.axes);
            if std::mem::take(&mut self.hold.after_sync) {
                // Standing between moves now: the next one waits for a resume.
                self.hold.held = true;
            }
        } else {
            self.synced = Some(m);
            if decide {
                self.command_tap_spindle();
            }
        }
    }

    /// A rigid tap's spindle command, during the tap (`None` otherwise): (reversed, rpm).
    pub(super) fn tap_spindle(&self) -> Option<(bool, f64)> {
        self.synced.and_then(|m| m.tap).map(|t| t.spindle())
    }

    /// Gives the machine logic the rigid tap's spindle command of its phase, if it changed.
    fn command_tap_spindle(&mut self) {
        let Some((reverse, rpm)) = self.tap_spindle() else {
            return;
        };
        let r = &self.interface.requests;
        if r.spindle_reverse != reverse || r.spindle_rpm != rpm {
            let r = self.requests_mut();
            r.spindle_reverse = reverse;
            r.spindle_rpm = rpm;
        }
    }

    /// Stops a synchronised move along its line (abort, fault): it no longer tracks. A tap
    /// in the hole stops with the spindle, as LinuxCNC's abort stops it.
    pub(super) fn stop_synced(&mut self, quick: bool) {
        if let Some(t) = self.synced.and_then(|m| m.tap) {
            self.spindle.on = false;
            let r = self.requests_mut();
            r.spindle_on = false;
            r.spindle_reverse = t.reverse;
        }
        if let Some(m) = self.synced.as_mut() {
            m.tap = None;
            m.finishing = true;
            if quick {
                let (v, _, _) = m.limits;
                let (mut a, mut j) = (f64::INFINITY, f64::INFINITY);
                for i in 0..AXES {
                    let share = m.shares[i];
                    if share > 1e-12 {
                        a = a.min(self.machine.axis_quick[i].max_acceleration / share);
                        j = j.min(self.machine.axis_quick[i].max_jerk / share);
                    }
                }
                let _ = m.otg.set_limits(Limits::symmetric(v, a, j));
            }
            let _ = m.otg.stop();
        }
    }

    /// Look-ahead, while the program is in a synchronised move: it goes on once the move
    /// has handed the path back.
    pub(super) fn synced_done(&mut self) -> bool {
        if self.synced.is_some() {
            return false;
        }
        self.fire(Event::Proceed)
    }
}
