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

/// The levels of a cycle along the plane's normal axis.
struct Levels {
    /// Where the tool is when the first hole is approached.
    start: f64,
    /// The R plane: feeding starts there.
    r: f64,
    /// The bottom of the holes.
    bottom: f64,
    /// Where the tool goes between holes and after the last: the level before the cycle
    /// (G98) or the R plane (G99).
    retract: f64,
}

/// Where the holes are in the plane: the point the first step starts from and the step to
/// each hole (incremental mode: the plane's words, or polar words under G17).
struct Holes {
    a: f64,
    b: f64,
    step_a: f64,
    step_b: f64,
    step_radius: Option<f64>,
    step_angle: Option<f64>,
}

/// The words that only some cycles use, with the cycle's remembered values where a repeat
/// of the same cycle leaves them out.
struct CycleParameters {
    /// P: the dwell at the bottom (seconds).
    dwell: f64,
    /// Q: the depth of each peck.
    peck: f64,
    /// I, J, K of G87: the back-boring offsets and the top of the bore.
    back_bore: (f64, f64, f64),
}

/// Cycles that take a dwell time (P) and refuse to start without one.
fn needs_dwell(motion: i32) -> bool {
    matches!(motion, 820 | 860 | 880 | 890)
}

/// Cycles that peck (Q).
fn pecks(motion: i32) -> bool {
    matches!(motion, 730 | 830)
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

    /// Runs one canned-cycle block (`motion` is the G code times ten: 810 for G81) as
    /// LinuxCNC's interpreter does: the checks of the modal state and the words, the rise to
    /// the R plane, then each repeat's hole, in exact-path mode.
    pub(crate) fn canned_cycle(&mut self, b: &Block, motion: i32) -> Res<()> {
        self.check_cycle_state(b)?;
        let ax = axes(self.state.plane);
        self.check_cycle_axes(b)?;
        // A block repeating the cycle in force may leave out the words it keeps.
        let same = self.state.motion == motion;
        let r_word = self.clearance_word(b, same)?;
        let repeats = self.cycle_repeats(b)?;
        let bottom_word = self.bottom_word(b, &ax, same)?;
        let (mut holes, mut levels) = self.cycle_layout(b, &ax, r_word, bottom_word)?;
        self.rise_to_r_plane(&ax, &mut levels);
        let saved_mode = self.state.path_mode;
        let saved_naive = self.state.naivecam_tolerance;
        if saved_mode != PathMode::ExactPath {
            self.emit(C::SetMotionControlMode(PathMode::ExactPath));
        }
        let parameters = self.cycle_parameters(b, motion, same, &levels, repeats)?;
        let direction = self.state.spindle;
        for repeat in (1..=repeats).rev() {
            let first = repeat == repeats;
            self.step_to_next_hole(b, &mut holes)?;
            self.approach_hole(&ax, holes.a, holes.b, &levels, first);
            if first {
                self.check_cycle_spindle(b, motion, direction)?;
            }
            self.cut_hole(
                motion,
                &ax,
                (holes.a, holes.b),
                &levels,
                &parameters,
                direction,
            );
        }
        let mut p = self.state.position.to_array();
        p[ax.a] = holes.a;
        p[ax.b] = holes.b;
        p[ax.c] = levels.retract;
        self.state.position = Pose::from_array(p);
        if saved_mode != PathMode::ExactPath {
            self.emit(C::SetMotionControlMode(saved_mode));
            self.emit(C::SetNaivecamTolerance(saved_naive));
        }
        self.remember_cycle_words(motion, r_word, bottom_word, &parameters);
        self.state.motion = motion;
        Ok(())
    }

    /// Refuses a cycle at zero feed rate, in inverse time or with cutter compensation on.
    fn check_cycle_state(&self, b: &Block) -> Res<()> {
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
        Ok(())
    }

    /// Refuses the words of the other triple of linear axes, which cannot move in a cycle.
    fn check_cycle_axes(&self, b: &Block) -> Res<()> {
        let others = if uvw_plane(self.state.plane) {
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
        Ok(())
    }

    /// The R word, or the one remembered when the block repeats the cycle in force.
    fn clearance_word(&self, b: &Block, same: bool) -> Res<f64> {
        match b.get(b'r') {
            Some(r) => Ok(r),
            None if same => Ok(self.cycle.r),
            None => Err(self.cycle_err(
                b,
                ErrorKind::MissingWord,
                "R clearance plane unspecified in canned cycle",
            )),
        }
    }

    /// The number of holes (L, rounded; 1 without it).
    fn cycle_repeats(&self, b: &Block) -> Res<u64> {
        let Some(l) = b.get(b'l') else {
            return Ok(1);
        };
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
        Ok(l as u64)
    }

    /// The word of the plane's normal axis (the bottom), or the one remembered when the
    /// block repeats the cycle in force.
    fn bottom_word(&self, b: &Block, ax: &Axes, same: bool) -> Res<f64> {
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
        Ok(b.get(ax.lc).unwrap_or(self.cycle.cc))
    }

    /// Where the holes and the levels are: absolute words as they stand; incremental ones
    /// from the level before the cycle (R) and from R (the bottom), the plane's words as the
    /// step between holes. The first cycle after another motion remembers the level before
    /// it, which G98 returns to.
    fn cycle_layout(
        &mut self,
        b: &Block,
        ax: &Axes,
        r_word: f64,
        bottom_word: f64,
    ) -> Res<(Holes, Levels)> {
        let pos = self.state.position.to_array();
        let start = pos[ax.c];
        let initial = match self.cycle.initial_level {
            Some(l) => l,
            None => {
                self.cycle.initial_level = Some(start);
                start
            }
        };
        let (holes, r, bottom) = if self.state.absolute {
            let (mut a, mut b_) = (
                b.get(ax.la).unwrap_or(pos[ax.a]),
                b.get(ax.lb).unwrap_or(pos[ax.b]),
            );
            if b.has_polar() {
                (a, b_) = polar_end(pos[0], pos[1], b.polar_radius, b.polar_angle, true);
            }
            let holes = Holes {
                a,
                b: b_,
                step_a: 0.0,
                step_b: 0.0,
                step_radius: None,
                step_angle: None,
            };
            (holes, r_word, bottom_word)
        } else {
            let r = r_word + initial;
            let holes = Holes {
                a: pos[ax.a],
                b: pos[ax.b],
                step_a: b.get(ax.la).unwrap_or(0.0),
                step_b: b.get(ax.lb).unwrap_or(0.0),
                step_radius: b.polar_radius,
                step_angle: b.polar_angle,
            };
            (holes, r, r + bottom_word)
        };
        if r < bottom {
            return Err(self.cycle_err(
                b,
                ErrorKind::BadValue,
                format!(
                    "R less than {} in canned cycle",
                    ax.lc.to_ascii_uppercase() as char
                ),
            ));
        }
        let levels = Levels {
            start,
            r,
            bottom,
            // The rise to R may still lift it (rise_to_r_plane).
            retract: initial,
        };
        Ok((holes, levels))
    }

    /// Rises at rapid to the R plane when the tool starts below it (then the level before
    /// the cycle counts as R), and settles the retract level: that level under G98, R under
    /// G99.
    fn rise_to_r_plane(&mut self, ax: &Axes, levels: &mut Levels) {
        let mut initial = levels.retract;
        if initial < levels.r {
            let mut p = self.state.position.to_array();
            p[ax.c] = levels.r;
            let p = Pose::from_array(p);
            self.emit(C::StraightTraverse(p));
            self.state.position = p;
            initial = levels.r;
            levels.start = initial;
        }
        levels.retract = if self.state.retract_old_z {
            initial
        } else {
            levels.r
        };
    }

    /// The dwell, peck and back-boring words the cycle needs, checked where LinuxCNC checks
    /// them (after the move to R).
    fn cycle_parameters(
        &self,
        b: &Block,
        motion: i32,
        same: bool,
        levels: &Levels,
        repeats: u64,
    ) -> Res<CycleParameters> {
        let p_word = b.get(b'p');
        let q_word = b.get(b'q');
        if needs_dwell(motion) && !same && p_word.is_none() {
            return Err(self.cycle_err(
                b,
                ErrorKind::MissingWord,
                format!("dwell time P word missing with G{}", motion / 10),
            ));
        }
        let dwell = p_word.unwrap_or(self.cycle.p);
        if pecks(motion) && !same && q_word.is_none() {
            return Err(self.cycle_err(
                b,
                ErrorKind::MissingWord,
                format!("Q word missing with G{}", motion / 10),
            ));
        }
        let peck = q_word.unwrap_or(self.cycle.q);
        if pecks(motion) && peck <= 0.0 {
            return Err(self.cycle_err(
                b,
                ErrorKind::BadValue,
                "negative or zero Q value in peck cycle",
            ));
        }
        // The pecks of every repeat are queued at once: their number is bounded.
        let count = ((levels.r - levels.bottom) / peck).ceil() * repeats as f64;
        if pecks(motion) && (count.is_nan() || count > MAX_PECKS) {
            return Err(self.cycle_err(
                b,
                ErrorKind::BadValue,
                format!("Q too small: more than {MAX_PECKS} pecks in one peck-cycle block"),
            ));
        }
        let back_bore = if motion == 870 {
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
        Ok(CycleParameters {
            dwell,
            peck,
            back_bore,
        })
    }

    /// Steps to the next hole in incremental mode (straight, then in radius and angle for
    /// polar words); in absolute mode the hole stays where it is.
    fn step_to_next_hole(&self, b: &Block, holes: &mut Holes) -> Res<()> {
        holes.a += holes.step_a;
        holes.b += holes.step_b;
        if holes.step_radius.is_some() || holes.step_angle.is_some() {
            if holes.a == 0.0 && holes.b == 0.0 {
                return Err(self.cycle_err(
                    b,
                    ErrorKind::BadValue,
                    "incremental motion with polar coordinates is indeterminate at the origin",
                ));
            }
            (holes.a, holes.b) = polar_end(holes.a, holes.b, holes.step_radius, None, false);
            (holes.a, holes.b) = polar_end(holes.a, holes.b, None, holes.step_angle, false);
        }
        Ok(())
    }

    /// Rapids over the hole and down to R: the first hole at the level the tool is at when
    /// that is above R, every other one at the retract level.
    fn approach_hole(&mut self, ax: &Axes, a: f64, b: f64, levels: &Levels, first: bool) {
        if first && levels.start > levels.r {
            self.cycle_move(ax, false, a, b, levels.start);
            self.cycle_move(ax, false, a, b, levels.r);
        } else {
            self.cycle_move(ax, false, a, b, levels.retract);
            if levels.retract > levels.r {
                self.cycle_move(ax, false, a, b, levels.r);
            }
        }
    }

    /// Refuses a tapping or boring cycle whose spindle does not turn the way it needs.
    fn check_cycle_spindle(
        &self,
        b: &Block,
        motion: i32,
        direction: Option<SpindleDirection>,
    ) -> Res<()> {
        match motion {
            740 if direction != Some(SpindleDirection::CounterClockwise) => Err(self.cycle_err(
                b,
                ErrorKind::State,
                match direction {
                    None => "spindle not turning in G74",
                    _ => "spindle turning clockwise in G74",
                },
            )),
            840 if direction != Some(SpindleDirection::Clockwise) => Err(self.cycle_err(
                b,
                ErrorKind::State,
                match direction {
                    None => "spindle not turning in G84",
                    _ => "spindle turning counter-clockwise in G84",
                },
            )),
            860 | 870 | 880 if direction.is_none() => Err(self.cycle_err(
                b,
                ErrorKind::State,
                format!("spindle not turning in G{}", motion / 10),
            )),
            _ => Ok(()),
        }
    }

    /// One hole, from R down and back to the retract level, the way the cycle cuts it.
    fn cut_hole(
        &mut self,
        motion: i32,
        ax: &Axes,
        (a, b): (f64, f64),
        levels: &Levels,
        parameters: &CycleParameters,
        direction: Option<SpindleDirection>,
    ) {
        let (bottom, retract) = (levels.bottom, levels.retract);
        match motion {
            810 => {
                self.cycle_move(ax, true, a, b, bottom);
                self.cycle_move(ax, false, a, b, retract);
            }
            820 => {
                self.cycle_move(ax, true, a, b, bottom);
                self.emit(C::Dwell(parameters.dwell));
                self.cycle_move(ax, false, a, b, retract);
            }
            730 | 830 => self.peck_hole(motion == 830, ax, (a, b), levels, parameters.peck),
            740 | 840 => self.tap_hole(motion == 840, ax, (a, b), levels, parameters.dwell),
            850 => {
                self.cycle_move(ax, true, a, b, bottom);
                self.cycle_move(ax, true, a, b, levels.r);
                self.cycle_move(ax, false, a, b, retract);
            }
            860 => {
                self.cycle_move(ax, true, a, b, bottom);
                self.emit(C::Dwell(parameters.dwell));
                self.emit(C::StopSpindle { spindle: 0 });
                self.cycle_move(ax, false, a, b, retract);
                self.restart_spindle(direction);
            }
            870 => self.back_bore_hole(ax, (a, b), levels, parameters.back_bore, direction),
            880 => {
                self.cycle_move(ax, true, a, b, bottom);
                self.emit(C::Dwell(parameters.dwell));
                self.emit(C::StopSpindle { spindle: 0 });
                self.emit(C::ProgramStop);
                self.restart_spindle(direction);
            }
            _ => {
                // G89
                self.cycle_move(ax, true, a, b, bottom);
                self.emit(C::Dwell(parameters.dwell));
                self.cycle_move(ax, true, a, b, retract);
            }
        }
    }

    /// G73 (chip breaking: back up a little after each peck) and G83 (`full_retract`: out
    /// to R after each peck), then down to the last small clearance above the cut.
    fn peck_hole(
        &mut self,
        full_retract: bool,
        ax: &Axes,
        (a, b): (f64, f64),
        levels: &Levels,
        peck: f64,
    ) {
        let rapid_delta = if self.state.units == Units::Mm {
            0.254
        } else {
            0.01
        };
        let mut depth = levels.r - peck;
        while depth > levels.bottom {
            self.cycle_move(ax, true, a, b, depth);
            if full_retract {
                self.cycle_move(ax, false, a, b, levels.r);
            }
            self.cycle_move(ax, false, a, b, depth + rapid_delta);
            depth -= peck;
        }
        self.cycle_move(ax, true, a, b, levels.bottom);
        self.cycle_move(ax, false, a, b, levels.retract);
    }

    /// G84 (`right_hand`) and G74: in at feed, reverse the spindle, dwell, out at feed,
    /// restore the spindle, with the overrides off meanwhile.
    fn tap_hole(
        &mut self,
        right_hand: bool,
        ax: &Axes,
        (a, b): (f64, f64),
        levels: &Levels,
        dwell: f64,
    ) {
        let (down, up) = if right_hand {
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
        self.cycle_move(ax, true, a, b, levels.bottom);
        self.emit(C::StopSpindle { spindle: 0 });
        self.emit(C::StartSpindle {
            spindle: 0,
            direction: up,
        });
        self.emit(C::Dwell(dwell));
        self.cycle_move(ax, true, a, b, levels.retract);
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

    /// G87: down beside the hole with the spindle oriented and stopped, over under the
    /// bore's bottom, cut up to the top of the bore (the normal axis's I, J or K) and back,
    /// then out the way it came.
    fn back_bore_hole(
        &mut self,
        ax: &Axes,
        (a, b): (f64, f64),
        levels: &Levels,
        (i, j, k): (f64, f64, f64),
        direction: Option<SpindleDirection>,
    ) {
        let (r, bottom, retract) = (levels.r, levels.bottom, levels.retract);
        // The words of the plane's own axes offset the back-boring point; the word of its
        // normal axis is the top of the bore.
        let (off_a, off_b, middle) = match self.state.plane {
            Plane::XY | Plane::UV => (i, j, k),
            Plane::XZ | Plane::WU => (k, i, j),
            Plane::YZ | Plane::VW => (j, k, i),
        };
        let top = if self.state.absolute {
            middle
        } else {
            bottom + middle
        };
        let (oa, ob) = (a + off_a, b + off_b);
        self.cycle_move(ax, false, oa, ob, r);
        self.emit(C::StopSpindle { spindle: 0 });
        self.orient_for_cycle(direction);
        self.cycle_move(ax, false, oa, ob, bottom);
        self.cycle_move(ax, false, a, b, bottom);
        self.restart_spindle(direction);
        self.cycle_move(ax, true, a, b, top);
        self.cycle_move(ax, true, a, b, bottom);
        self.emit(C::StopSpindle { spindle: 0 });
        self.orient_for_cycle(direction);
        self.cycle_move(ax, false, oa, ob, bottom);
        self.cycle_move(ax, false, oa, ob, retract);
        self.cycle_move(ax, false, a, b, retract);
        self.restart_spindle(direction);
    }

    /// Keeps the block's words for a following block that repeats the cycle.
    fn remember_cycle_words(
        &mut self,
        motion: i32,
        r_word: f64,
        bottom_word: f64,
        parameters: &CycleParameters,
    ) {
        self.cycle.cc = bottom_word;
        self.cycle.r = r_word;
        if needs_dwell(motion) || matches!(motion, 740 | 840) {
            self.cycle.p = parameters.dwell;
        }
        if pecks(motion) {
            self.cycle.q = parameters.peck;
        }
        if motion == 870 {
            (self.cycle.i, self.cycle.j, self.cycle.k) = parameters.back_bore;
        }
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
