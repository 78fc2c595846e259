//! Canned cycles G73, G74, G81..G89, expanded into straight moves, dwells and spindle
//! commands the way LinuxCNC's interpreter expands them, in the XY, XZ and YZ planes and in
//! the UV, UW and VW planes of the U V W axes.

use crate::block::{Block, gg};
use crate::canon::{CanonCommand as C, FeedMode, PathMode, Plane, Pose, SpindleDirection, Units};
use crate::error::{ErrorKind, GcodeError};
use crate::interp::Interpreter;
use crate::motion::polar_end;

type Res<T> = Result<T, GcodeError>;

/// Most repeats (L) of one canned cycle block: its moves are queued at once.
const MAX_REPEATS: u64 = 10_000;

/// Most pecks (over all repeats) of one G73/G83 block: they are queued at once.
const MAX_PECKS: f64 = 100_000.0;

/// The plane's axes as pose indices: (first, second, normal) and the letters of the words.
struct Axes {
    a: usize,
    b: usize,
    c: usize,
    la: u8,
    lb: u8,
    lc: u8,
}

fn axes(plane: Plane) -> Axes {
    match plane {
        Plane::XY => Axes {
            a: 0,
            b: 1,
            c: 2,
            la: b'x',
            lb: b'y',
            lc: b'z',
        },
        Plane::XZ => Axes {
            a: 2,
            b: 0,
            c: 1,
            la: b'z',
            lb: b'x',
            lc: b'y',
        },
        Plane::YZ => Axes {
            a: 1,
            b: 2,
            c: 0,
            la: b'y',
            lb: b'z',
            lc: b'x',
        },
        Plane::UV => Axes {
            a: 6,
            b: 7,
            c: 8,
            la: b'u',
            lb: b'v',
            lc: b'w',
        },
        Plane::WU => Axes {
            a: 8,
            b: 6,
            c: 7,
            la: b'w',
            lb: b'u',
            lc: b'v',
        },
        Plane::VW => Axes {
            a: 7,
            b: 8,
            c: 6,
            la: b'v',
            lb: b'w',
            lc: b'u',
        },
    }
}

/// True for the planes of the U V W axes (G17.1, G18.1, G19.1).
fn uvw_plane(plane: Plane) -> bool {
    matches!(plane, Plane::UV | Plane::WU | Plane::VW)
}

impl Interpreter {
    fn cycle_err(&self, b: &Block, kind: ErrorKind, msg: impl Into<String>) -> GcodeError {
        self.error_at(kind, usize::from(b.g_col[gg::MOTION]) + 1, msg)
    }

    fn cycle_move(&mut self, ax: &Axes, feed: bool, a: f64, b: f64, c: f64) {
        let mut p = self.state.position.to_array();
        p[ax.a] = a;
        p[ax.b] = b;
        p[ax.c] = c;
        let p = Pose::from_array(p);
        self.emit(if feed {
            C::StraightFeed(p)
        } else {
            C::StraightTraverse(p)
        });
        self.state.position = p;
    }

    pub(crate) fn canned_cycle(&mut self, b: &Block, motion: i32) -> Res<()> {
        let s = &self.state;
        if s.feed_rate == 0.0 {
            return Err(self.cycle_err(b, ErrorKind::State, "cannot feed with zero feed rate"));
        }
        if s.feed_mode == FeedMode::InverseTime {
            return Err(self.cycle_err(
                b,
                ErrorKind::State,
                "cannot use inverse time feed (G93) with canned cycles",
            ));
        }
        if s.cutter.is_some() {
            return Err(self.cycle_err(
                b,
                ErrorKind::State,
                "cannot use canned cycles with cutter radius compensation on",
            ));
        }
        let ax = axes(s.plane);
        // The other triple of linear axes cannot move in a cycle.
        let others = if uvw_plane(s.plane) {
            [b'x', b'y', b'z']
        } else {
            [b'u', b'v', b'w']
        };
        for l in others {
            if b.has(l) {
                return Err(self.cycle_err(
                    b,
                    ErrorKind::UnusedWord,
                    format!(
                        "a {} word cannot be used in a canned cycle in this plane",
                        l.to_ascii_uppercase() as char
                    ),
                ));
            }
        }
        let same = s.motion == motion;
        let r_word = match b.get(b'r') {
            Some(r) => r,
            None if same => self.cycle.r,
            None => {
                return Err(self.cycle_err(
                    b,
                    ErrorKind::MissingWord,
                    "R clearance plane unspecified in canned cycle",
                ));
            }
        };
        let repeats = match b.get(b'l') {
            Some(l) => {
                let l = l.round();
                if l == 0.0 {
                    return Err(self.cycle_err(
                        b,
                        ErrorKind::BadValue,
                        "cannot do zero repeats of a canned cycle",
                    ));
                }
                if l < 0.0 {
                    return Err(self.cycle_err(b, ErrorKind::BadValue, "negative L word"));
                }
                // One block's moves are queued together: keep that bounded.
                if l > MAX_REPEATS as f64 {
                    return Err(self.cycle_err(
                        b,
                        ErrorKind::BadValue,
                        format!("more than {MAX_REPEATS} repeats of a canned cycle in one block"),
                    ));
                }
                l as u64
            }
            None => 1,
        };
        if !same && !b.has(ax.lc) {
            return Err(self.cycle_err(
                b,
                ErrorKind::MissingWord,
                format!(
                    "{} value unspecified in canned cycle",
                    ax.lc.to_ascii_uppercase() as char
                ),
            ));
        }
        let c_word = b.get(ax.lc).unwrap_or(self.cycle.cc);
        let pos = self.state.position.to_array();
        let mut current_cc = pos[ax.c];
        let mut old_cc = match self.cycle.initial_level {
            Some(l) => l,
            None => {
                self.cycle.initial_level = Some(current_cc);
                current_cc
            }
        };
        let (mut aa, mut bb, r, cc, da, db);
        // Polar words (G17 only) step the hole position in radius and angle.
        let (mut dr, mut dt) = (None, None);
        if self.state.absolute {
            r = r_word;
            cc = c_word;
            aa = b.get(ax.la).unwrap_or(pos[ax.a]);
            bb = b.get(ax.lb).unwrap_or(pos[ax.b]);
            if b.has_polar() {
                (aa, bb) = polar_end(pos[0], pos[1], b.polar_radius, b.polar_angle, true);
            }
            da = 0.0;
            db = 0.0;
        } else {
            (dr, dt) = (b.polar_radius, b.polar_angle);
            da = b.get(ax.la).unwrap_or(0.0);
            db = b.get(ax.lb).unwrap_or(0.0);
            r = r_word + old_cc;
            cc = r + c_word;
            aa = pos[ax.a];
            bb = pos[ax.b];
        }
        if r < cc {
            return Err(self.cycle_err(
                b,
                ErrorKind::BadValue,
                format!(
                    "R less than {} in canned cycle",
                    ax.lc.to_ascii_uppercase() as char
                ),
            ));
        }
        if old_cc < r {
            let mut p = self.state.position.to_array();
            p[ax.c] = r;
            let p = Pose::from_array(p);
            self.emit(C::StraightTraverse(p));
            self.state.position = p;
            old_cc = r;
            current_cc = old_cc;
        }
        let clear_cc = if self.state.retract_old_z { old_cc } else { r };
        let saved_mode = self.state.path_mode;
        let saved_naive = self.state.naivecam_tolerance;
        if saved_mode != PathMode::ExactPath {
            self.emit(C::SetMotionControlMode(PathMode::ExactPath));
        }
        // Per-cycle words, checked where LinuxCNC checks them (after the move to R).
        let p_word = b.get(b'p');
        let q_word = b.get(b'q');
        let needs_p = matches!(motion, 820 | 860 | 880 | 890);
        if needs_p && !same && p_word.is_none() {
            return Err(self.cycle_err(
                b,
                ErrorKind::MissingWord,
                format!("dwell time P word missing with G{}", motion / 10),
            ));
        }
        let dwell = p_word.unwrap_or(self.cycle.p);
        let needs_q = matches!(motion, 730 | 830);
        if needs_q && !same && q_word.is_none() {
            return Err(self.cycle_err(
                b,
                ErrorKind::MissingWord,
                format!("Q word missing with G{}", motion / 10),
            ));
        }
        let delta = q_word.unwrap_or(self.cycle.q);
        if needs_q && delta <= 0.0 {
            return Err(self.cycle_err(
                b,
                ErrorKind::BadValue,
                "negative or zero Q value in peck cycle",
            ));
        }
        // The pecks of every repeat are queued at once: their number is bounded.
        let pecks = ((r - cc) / delta).ceil() * repeats as f64;
        if needs_q && (pecks.is_nan() || pecks > MAX_PECKS) {
            return Err(self.cycle_err(
                b,
                ErrorKind::BadValue,
                format!("Q too small: more than {MAX_PECKS} pecks in one peck-cycle block"),
            ));
        }
        let (ci, cj, ck) = if motion == 870 {
            let i = b.get(b'i').or(same.then_some(self.cycle.i));
            let j = b.get(b'j').or(same.then_some(self.cycle.j));
            let k = b.get(b'k').or(same.then_some(self.cycle.k));
            match (i, j, k) {
                (Some(i), Some(j), Some(k)) => (i, j, k),
                _ => {
                    return Err(self.cycle_err(
                        b,
                        ErrorKind::MissingWord,
                        "G87 needs I, J and K words",
                    ));
                }
            }
        } else {
            (0.0, 0.0, 0.0)
        };
        let direction = self.state.spindle;
        let rapid_delta = if self.state.units == Units::Mm {
            0.254
        } else {
            0.01
        };
        for repeat in (1..=repeats).rev() {
            aa += da;
            bb += db;
            if dr.is_some() || dt.is_some() {
                if aa == 0.0 && bb == 0.0 {
                    return Err(self.cycle_err(
                        b,
                        ErrorKind::BadValue,
                        "incremental motion with polar coordinates is indeterminate at the origin",
                    ));
                }
                (aa, bb) = polar_end(aa, bb, dr, None, false);
                (aa, bb) = polar_end(aa, bb, None, dt, false);
            }
            if repeat == repeats && current_cc > r {
                self.cycle_move(&ax, false, aa, bb, current_cc);
                self.cycle_move(&ax, false, aa, bb, r);
            } else {
                self.cycle_move(&ax, false, aa, bb, clear_cc);
                if clear_cc > r {
                    self.cycle_move(&ax, false, aa, bb, r);
                }
            }
            if repeat == repeats {
                match motion {
                    740 if direction != Some(SpindleDirection::CounterClockwise) => {
                        return Err(self.cycle_err(
                            b,
                            ErrorKind::State,
                            match direction {
                                None => "spindle not turning in G74",
                                _ => "spindle turning clockwise in G74",
                            },
                        ));
                    }
                    840 if direction != Some(SpindleDirection::Clockwise) => {
                        return Err(self.cycle_err(
                            b,
                            ErrorKind::State,
                            match direction {
                                None => "spindle not turning in G84",
                                _ => "spindle turning counter-clockwise in G84",
                            },
                        ));
                    }
                    860 | 870 | 880 if direction.is_none() => {
                        return Err(self.cycle_err(
                            b,
                            ErrorKind::State,
                            format!("spindle not turning in G{}", motion / 10),
                        ));
                    }
                    _ => {}
                }
            }
            match motion {
                810 => {
                    self.cycle_move(&ax, true, aa, bb, cc);
                    self.cycle_move(&ax, false, aa, bb, clear_cc);
                }
                820 => {
                    self.cycle_move(&ax, true, aa, bb, cc);
                    self.emit(C::Dwell(dwell));
                    self.cycle_move(&ax, false, aa, bb, clear_cc);
                }
                730 | 830 => {
                    let mut depth = r - delta;
                    while depth > cc {
                        self.cycle_move(&ax, true, aa, bb, depth);
                        if motion == 830 {
                            self.cycle_move(&ax, false, aa, bb, r);
                        }
                        self.cycle_move(&ax, false, aa, bb, depth + rapid_delta);
                        depth -= delta;
                    }
                    self.cycle_move(&ax, true, aa, bb, cc);
                    self.cycle_move(&ax, false, aa, bb, clear_cc);
                }
                740 | 840 => {
                    // Tapping: in at feed, reverse the spindle, dwell, out at feed, restore.
                    let (down, up) = if motion == 840 {
                        (
                            SpindleDirection::Clockwise,
                            SpindleDirection::CounterClockwise,
                        )
                    } else {
                        (
                            SpindleDirection::CounterClockwise,
                            SpindleDirection::Clockwise,
                        )
                    };
                    let fo = self.state.feed_override;
                    let so = self.state.speed_override;
                    self.emit(C::FeedOverride(false));
                    self.emit(C::SpeedOverride {
                        spindle: 0,
                        enable: false,
                    });
                    self.cycle_move(&ax, true, aa, bb, cc);
                    self.emit(C::StopSpindle { spindle: 0 });
                    self.emit(C::StartSpindle {
                        spindle: 0,
                        direction: up,
                    });
                    self.emit(C::Dwell(dwell));
                    self.cycle_move(&ax, true, aa, bb, clear_cc);
                    self.emit(C::StopSpindle { spindle: 0 });
                    self.emit(C::StartSpindle {
                        spindle: 0,
                        direction: down,
                    });
                    if fo {
                        self.emit(C::FeedOverride(true));
                    }
                    if so {
                        self.emit(C::SpeedOverride {
                            spindle: 0,
                            enable: true,
                        });
                    }
                }
                850 => {
                    self.cycle_move(&ax, true, aa, bb, cc);
                    self.cycle_move(&ax, true, aa, bb, r);
                    self.cycle_move(&ax, false, aa, bb, clear_cc);
                }
                860 => {
                    self.cycle_move(&ax, true, aa, bb, cc);
                    self.emit(C::Dwell(dwell));
                    self.emit(C::StopSpindle { spindle: 0 });
                    self.cycle_move(&ax, false, aa, bb, clear_cc);
                    self.restart_spindle(direction);
                }
                870 => {
                    // The words of the plane's own axes offset the back-boring point; the
                    // word of its normal axis is the top of the bore.
                    let (off_a, off_b, middle) = match self.state.plane {
                        Plane::XY | Plane::UV => (ci, cj, ck),
                        Plane::XZ | Plane::WU => (ck, ci, cj),
                        Plane::YZ | Plane::VW => (cj, ck, ci),
                    };
                    let k = if self.state.absolute {
                        middle
                    } else {
                        cc + middle
                    };
                    let (oa, ob) = (aa + off_a, bb + off_b);
                    self.cycle_move(&ax, false, oa, ob, r);
                    self.emit(C::StopSpindle { spindle: 0 });
                    self.orient_for_cycle(direction);
                    self.cycle_move(&ax, false, oa, ob, cc);
                    self.cycle_move(&ax, false, aa, bb, cc);
                    self.restart_spindle(direction);
                    self.cycle_move(&ax, true, aa, bb, k);
                    self.cycle_move(&ax, true, aa, bb, cc);
                    self.emit(C::StopSpindle { spindle: 0 });
                    self.orient_for_cycle(direction);
                    self.cycle_move(&ax, false, oa, ob, cc);
                    self.cycle_move(&ax, false, oa, ob, clear_cc);
                    self.cycle_move(&ax, false, aa, bb, clear_cc);
                    self.restart_spindle(direction);
                }
                880 => {
                    self.cycle_move(&ax, true, aa, bb, cc);
                    self.emit(C::Dwell(dwell));
                    self.emit(C::StopSpindle { spindle: 0 });
                    self.emit(C::ProgramStop);
                    self.restart_spindle(direction);
                }
                _ => {
                    // G89
                    self.cycle_move(&ax, true, aa, bb, cc);
                    self.emit(C::Dwell(dwell));
                    self.cycle_move(&ax, true, aa, bb, clear_cc);
                }
            }
        }
        let mut p = self.state.position.to_array();
        p[ax.a] = aa;
        p[ax.b] = bb;
        p[ax.c] = clear_cc;
        self.state.position = Pose::from_array(p);
        if saved_mode != PathMode::ExactPath {
            self.emit(C::SetMotionControlMode(saved_mode));
            self.emit(C::SetNaivecamTolerance(saved_naive));
        }
        self.cycle.cc = c_word;
        self.cycle.r = r_word;
        if needs_p || matches!(motion, 740 | 840) {
            self.cycle.p = dwell;
        }
        if needs_q {
            self.cycle.q = delta;
        }
        if motion == 870 {
            self.cycle.i = ci;
            self.cycle.j = cj;
            self.cycle.k = ck;
        }
        self.state.motion = motion;
        Ok(())
    }

    fn restart_spindle(&mut self, direction: Option<SpindleDirection>) {
        if let Some(direction) = direction {
            self.emit(C::StartSpindle {
                spindle: 0,
                direction,
            });
        }
    }

    fn orient_for_cycle(&mut self, direction: Option<SpindleDirection>) {
        self.emit(C::OrientSpindle {
            spindle: 0,
            angle: 0.0,
            // LinuxCNC passes its direction code here: 2 clockwise, 3 counter-clockwise.
            mode: match direction {
                Some(SpindleDirection::CounterClockwise) => 3,
                _ => 2,
            },
        });
    }
}
