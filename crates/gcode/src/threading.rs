//! Spindle-synchronised motion: G33 (one threading move) and the G76 lathe threading cycle,
//! expanded into passes the way LinuxCNC's interpreter expands them.

use crate::block::{Block, gg};
use crate::canon::{CanonCommand as C, Pose};
use crate::error::{ErrorKind, GcodeError};
use crate::interp::Interpreter;

/// Most passes (depth and spring passes together) one G76 block may expand to.
const MAX_PASSES: u32 = 10_000;

type Res<T> = Result<T, GcodeError>;

/// The geometry of one G76 job, in the active length units.
struct Thread {
    boring: bool,
    safe_x: f64,
    start_y: f64,
    start_z: f64,
    end_depth: f64,
    taper_dist: f64,
    entry_taper: bool,
    exit_taper: bool,
    taper_pitch: f64,
    pitch: f64,
    full_threadheight: f64,
    target_z: f64,
}

impl Interpreter {
    fn sync_err(&self, b: &Block, kind: ErrorKind, msg: impl Into<String>) -> GcodeError {
        self.error_at(kind, usize::from(b.g_col[gg::MOTION]) + 1, msg)
    }

    fn spindle_turning(&self) -> bool {
        self.state.spindle.is_some()
    }

    /// G33: a straight move at K length units per spindle revolution.
    pub(crate) fn g33(&mut self, b: &Block) -> Res<()> {
        if !self.spindle_turning() {
            return Err(self.sync_err(b, ErrorKind::State, "spindle not turning in G33"));
        }
        self.state.motion = 330;
        let end = self.find_ends(b);
        let pitch = b.get(b'k').unwrap_or(0.0);
        self.emit(C::StartSpeedFeedSync {
            spindle: 0,
            feed_per_revolution: pitch,
            velocity_mode: false,
        });
        self.emit(C::StraightFeed(end));
        self.emit(C::StopSpeedFeedSync);
        self.state.position = end;
        Ok(())
    }

    /// G33.1: rigid tapping at K per revolution; the tool comes back to where it started.
    pub(crate) fn g33_1(&mut self, b: &Block) -> Res<()> {
        if !self.spindle_turning() {
            return Err(self.sync_err(b, ErrorKind::State, "spindle not turning in G33.1"));
        }
        self.state.motion = 331;
        let end = self.find_ends(b);
        self.emit(C::StartSpeedFeedSync {
            spindle: 0,
            feed_per_revolution: b.get(b'k').unwrap_or(0.0),
            velocity_mode: false,
        });
        self.emit(C::RigidTap {
            end,
            scale: b.get(b'i').map_or(1.0, |i| i.max(1.0)),
        });
        self.emit(C::StopSpeedFeedSync);
        Ok(())
    }

    /// G76: multi-pass threading on a lathe (X radial, Z along the spindle).
    pub(crate) fn g76(&mut self, b: &Block) -> Res<()> {
        if !self.spindle_turning() {
            return Err(self.sync_err(b, ErrorKind::State, "spindle 0 not turning in G76"));
        }
        let end = self.find_ends(b);
        let cur = self.state.position;
        if (cur.a, cur.b, cur.c, cur.u, cur.v, cur.w) != (end.a, end.b, end.c, end.u, end.v, end.w)
        {
            return Err(self.sync_err(b, ErrorKind::BadValue, "cannot move rotary axes with G76"));
        }
        if self.state.cutter.is_some() {
            return Err(self.sync_err(
                b,
                ErrorKind::State,
                "cannot use G76 with cutter radius compensation on",
            ));
        }
        let (mut i, mut j, mut k) = (
            b.get(b'i').unwrap_or(0.0),
            b.get(b'j').unwrap_or(0.0),
            b.get(b'k').unwrap_or(0.0),
        );
        if i == 0.0 {
            return Err(self.err_word(b, b'i', "in G76, I must not be 0"));
        }
        if j <= 0.0 {
            return Err(self.err_word(b, b'j', "in G76, J must be greater than 0"));
        }
        if k <= j {
            return Err(self.err_word(b, b'k', "in G76, K must be greater than J"));
        }
        if self.state.lathe_diameter {
            i /= 2.0;
            j /= 2.0;
            k /= 2.0;
        }
        self.state.motion = 760;
        let full_dia_depth = i.abs();
        let start_depth = i.abs() + j.abs();
        let cut_increment = j.abs();
        let full_threadheight = k.abs();
        let end_depth = k.abs() + i.abs();
        let pitch = b.get(b'p').unwrap_or(0.0);
        let mut compound = b.get(b'q').unwrap_or(0.0).to_radians();
        if end.z > cur.z {
            compound = -compound;
        }
        let spring_cuts = b.get(b'h').map_or(0, |h| h.round().max(0.0) as u32);
        // The passes are expanded at once: their number is bounded like the depth passes'.
        if spring_cuts > MAX_PASSES {
            return Err(self.sync_err(
                b,
                ErrorKind::BadValue,
                "G76 H: more than 10000 spring passes",
            ));
        }
        let degression = b.get(b'r').filter(|r| *r >= 1.0).unwrap_or(1.0);
        let mut taper_dist = b.get(b'e').unwrap_or(0.0).max(0.0);
        let taper_pitch = if taper_dist > 0.0 {
            pitch * taper_dist.hypot(full_threadheight) / taper_dist
        } else {
            pitch
        };
        if end.z > cur.z {
            taper_dist = -taper_dist;
        }
        let flags = b.get(b'l').map_or(0, |l| l.round().max(0.0) as u32);
        let t = Thread {
            boring: i > 0.0,
            safe_x: cur.x,
            start_y: cur.y,
            start_z: cur.z,
            end_depth,
            taper_dist,
            entry_taper: flags & 1 != 0,
            exit_taper: flags & 2 != 0,
            taper_pitch,
            pitch,
            full_threadheight,
            target_z: end.z + k.abs() * compound.tan(),
        };
        let mut pass = 1u32;
        let mut depth = start_depth;
        while depth < end_depth {
            let zoff = (depth - full_dia_depth) * compound.tan();
            self.threading_pass(&t, depth, zoff);
            pass += 1;
            depth = full_dia_depth + cut_increment * f64::from(pass).powf(1.0 / degression);
            if pass > MAX_PASSES {
                return Err(self.sync_err(
                    b,
                    ErrorKind::BadValue,
                    "G76 would need more than 10000 passes",
                ));
            }
        }
        if pass.saturating_add(spring_cuts) > MAX_PASSES {
            return Err(self.sync_err(
                b,
                ErrorKind::BadValue,
                "G76 would need more than 10000 passes",
            ));
        }
        let zoff = (end_depth - full_dia_depth) * compound.tan();
        for _ in 0..=spring_cuts {
            self.threading_pass(&t, end_depth, zoff);
        }
        self.emit(C::StraightTraverse(end));
        self.state.position = end;
        Ok(())
    }

    fn err_word(&self, b: &Block, letter: u8, msg: &str) -> GcodeError {
        let col = if b.has(letter) {
            b.column(letter) + 1
        } else {
            0
        };
        self.error_at(ErrorKind::BadValue, col, msg)
    }

    fn thread_move(&mut self, t: &Thread, feed: bool, x: f64, z: f64) {
        let p = Pose {
            x,
            y: t.start_y,
            z,
            ..self.state.position
        };
        self.emit(if feed {
            C::StraightFeed(p)
        } else {
            C::StraightTraverse(p)
        });
        self.state.position = p;
    }

    fn sync(&mut self, pitch: f64) {
        self.emit(C::StartSpeedFeedSync {
            spindle: 0,
            feed_per_revolution: pitch,
            velocity_mode: false,
        });
    }

    fn threading_pass(&mut self, t: &Thread, depth: f64, zoff: f64) {
        let x_at = |d: f64| if t.boring { t.safe_x + d } else { t.safe_x - d };
        let back = if t.boring {
            t.safe_x + depth - t.end_depth
        } else {
            t.safe_x - depth + t.end_depth
        };
        let shallow = if t.boring {
            t.safe_x + depth - t.full_threadheight
        } else {
            t.safe_x - depth + t.full_threadheight
        };
        self.thread_move(t, false, back, t.start_z - zoff);
        if t.taper_dist != 0.0 && t.entry_taper {
            self.emit(C::FeedOverride(false));
            self.sync(t.taper_pitch);
            self.thread_move(t, true, shallow, t.start_z - zoff);
            self.thread_move(t, true, x_at(depth), t.start_z - zoff - t.taper_dist);
            self.sync(t.pitch);
        } else {
            self.thread_move(t, false, x_at(depth), t.start_z - zoff);
            self.emit(C::FeedOverride(false));
            self.sync(t.pitch);
        }
        if t.taper_dist != 0.0 && t.exit_taper {
            self.thread_move(t, true, x_at(depth), t.target_z - zoff + t.taper_dist);
            self.sync(t.taper_pitch);
            self.thread_move(t, true, shallow, t.target_z - zoff);
        } else {
            self.thread_move(t, true, x_at(depth), t.target_z - zoff);
        }
        self.emit(C::StopSpeedFeedSync);
        self.thread_move(t, false, back, t.target_z - zoff);
        self.emit(C::FeedOverride(true));
    }
}
