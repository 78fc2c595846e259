//! G70 (finishing), G71 and G72 (roughing) lathe cycles, as LinuxCNC 2.9 reads them. The
//! profile is the subroutine `o<Q>`: it is called and its lines are read, not executed;
//! o-word control and parameter settings in it run, and of the other lines only the moves
//! count (G0 G1 G2 G3 with X Z, U W increments, I K or R for arcs, A fillets and C
//! chamfers at their ends). The cycle itself is computed in `lathe_profile.rs` and issued
//! as straight moves and arcs in the XZ plane.

use crate::block::{self, Block, fmt_code, gg};
use crate::canon::{Plane, Source};
use crate::error::{ErrorKind, GcodeError};
use crate::interp::Interpreter;
use crate::lathe_profile::{self as profile, Cut, Pockets, Roughing, Segment, Zx};
use crate::source::ReadLineError;

type Res<T> = Result<T, GcodeError>;

/// Most moves a profile may have (they are held until the cycle is computed).
const MAX_PROFILE_MOVES: usize = 100_000;

/// Values within this count as the same point for an arc of the cycle (LinuxCNC's
/// TOLERANCE_EQUAL): a shorter arc is left out.
const TOLERANCE_EQUAL: f64 = 0.0001;

impl Interpreter {
    /// G70, G71, G71.1, G71.2, G72, G72.1, G72.2 (`motion` in tenths).
    pub(crate) fn lathe_cycle(&mut self, b: &Block, motion: i32) -> Res<()> {
        let code = format!("G{}", fmt_code(motion));
        let col = usize::from(b.g_col[gg::MOTION]) + 1;
        let Some(q) = b.get(b'q') else {
            return Err(self.error_at(
                ErrorKind::MissingWord,
                col,
                format!("{code} needs a Q word: the number of the subroutine of the profile"),
            ));
        };
        if self.state.cutter.is_some() && motion != 700 {
            return Err(self.error_at(
                ErrorKind::State,
                col,
                format!("{code} cannot be used with cutter radius compensation on (G70 can)"),
            ));
        }
        if self.state.plane != Plane::XZ {
            return Err(self.error_at(
                ErrorKind::State,
                col,
                format!("{code} needs the XZ plane (G18)"),
            ));
        }
        // The rapid to X and Z of the block (in G91 LinuxCNC 2.9 takes their numbers as
        // absolute for this rapid only, then starts the cycle from the incremental point;
        // here both are the incremental point).
        self.straight(b, 0)?;
        let start = Zx::new(self.state.position.z, self.state.position.x);
        let label = q.round();
        if (q - label).abs() > 0.0001 {
            return Err(self.err(
                b,
                b'q',
                ErrorKind::BadValue,
                format!("Q of {code} must be a whole number (the number of a subroutine)"),
            ));
        }
        let label = format!("{}", label as i64);
        let here = self.source;
        let level = self.calls.len();
        let mdi = self.src.current().is_none();
        self.call(&label, &[], col)?;
        let segs = self.read_profile(&code, level, start);
        self.source = here;
        if mdi {
            // The profile was read for this line only: nothing more is to run after it.
            self.src.detach();
        }
        let segs = segs?;
        if segs.len() <= 1 {
            return Ok(());
        }
        let d = b.get(b'd').unwrap_or(0.0);
        let i = b.get(b'i').unwrap_or(1.0);
        if i <= 0.0 {
            return Err(self.err(
                b,
                b'i',
                ErrorKind::BadValue,
                format!("{code}: I (the depth of cut) must be greater than zero"),
            ));
        }
        let (cuts, failed) = if motion == 700 {
            let e = b.get(b'e').unwrap_or(0.0);
            let passes = b.get(b'p').unwrap_or(1.0);
            profile::finish(segs, start, d, e, passes)
        } else {
            let job = Roughing {
                pockets: match motion % 10 {
                    0 => Pockets::All,
                    1 => Pockets::None,
                    _ => Pockets::Only,
                },
                facing: motion >= 720,
                d,
                i,
                r: b.get(b'r').unwrap_or(0.5),
            };
            profile::rough(segs, start, job)
        };
        self.issue_cuts(b, &cuts)?;
        match failed {
            Some(e) => Err(self.error_at(ErrorKind::BadValue, col, e.message(&code))),
            None => Ok(()),
        }
    }

    /// Reads the profile subroutine (already called) up to its return to call level
    /// `level`. The first segment goes from `start` to the first point of the profile.
    fn read_profile(&mut self, code: &str, level: usize, mut start: Zx) -> Res<Vec<Segment>> {
        let mut segs = Vec::new();
        let mut pb: Box<Block> = Box::default();
        let mut lines: u64 = 0;
        loop {
            lines += 1;
            if lines > self.settings.max_lines_without_output {
                return Err(self.error_at(
                    ErrorKind::Flow,
                    0,
                    format!(
                        "the profile of {code} ran {lines} lines without ending: endless loop?"
                    ),
                ));
            }
            match self.src.read_line() {
                Ok(true) => {}
                Ok(false) => {
                    self.at_eof = true;
                    return Err(self.error_at(
                        ErrorKind::Flow,
                        0,
                        format!("file ended inside the profile of {code} (missing endsub)"),
                    ));
                }
                Err(ReadLineError::TooLong) => {
                    return Err(self.error_at(ErrorKind::Syntax, 0, "line too long"));
                }
                Err(ReadLineError::Io(e)) => return Err(self.io_error(e)),
            }
            let at = self.src.line_start;
            self.source = Source {
                file: at.file,
                line: at.line,
                n: None,
            };
            let line = std::mem::take(&mut self.src.line);
            let read = block::read_block(&line, &*self, &mut pb);
            self.src.line = line;
            if let Err(e) = read {
                return Err(self.error_at(e.kind, e.column + 1, e.message));
            }
            if pb.block_delete && self.settings.block_delete {
                continue;
            }
            if pb.percent {
                return Err(self.error_at(
                    ErrorKind::Syntax,
                    1,
                    format!("'%' cannot be inside the profile of {code}"),
                ));
            }
            self.source.n = pb.n;
            if let Some(kw) = pb.o_keyword {
                self.control(&mut pb, kw)?;
                if self.calls.len() <= level {
                    break;
                }
                continue;
            }
            if pb.m98 {
                self.m98(&pb)?;
                continue;
            }
            if pb.m[block::mg::STOP] == 99 {
                self.m99()?;
                if self.calls.len() <= level {
                    break;
                }
                continue;
            }
            if !pb.assigns.is_empty() {
                self.assign(&mut pb);
            }
            let motion = self.motion_to_be(&pb)?;
            self.check_words(&pb, motion)?;
            if self.state.lathe_diameter && pb.has(b'x') {
                pb.words[(b'x' - b'a') as usize] /= 2.0;
            }
            if let Some(seg) = self.profile_move(code, &pb, &mut start, &mut segs)? {
                if segs.len() >= MAX_PROFILE_MOVES {
                    return Err(self.error_at(
                        ErrorKind::BadValue,
                        0,
                        format!("the profile of {code} has more than {MAX_PROFILE_MOVES} moves"),
                    ));
                }
                segs.push(seg);
            }
        }
        Ok(segs)
    }

    /// The move of one profile line from `start`, if it makes one (a fillet or chamfer at
    /// its end is pushed onto `segs` after it). Updates `start` and the position.
    fn profile_move(
        &mut self,
        code: &str,
        pb: &Block,
        start: &mut Zx,
        segs: &mut Vec<Segment>,
    ) -> Res<Option<Segment>> {
        let incremental = !self.state.absolute;
        let mut end = if incremental {
            Zx::new(0.0, 0.0)
        } else {
            *start
        };
        for (inc, axis, radial) in [(b'u', b'x', true), (b'w', b'z', false)] {
            let inc_name = inc.to_ascii_uppercase() as char;
            if let Some(v) = pb.get(inc) {
                if incremental {
                    return Err(self.err(
                        pb,
                        inc,
                        ErrorKind::Conflict,
                        format!("{inc_name} cannot be used in the profile of {code} in G91"),
                    ));
                }
                if pb.has(axis) {
                    return Err(self.err(
                        pb,
                        inc,
                        ErrorKind::Conflict,
                        format!(
                            "{inc_name} and {} on one line of the profile of {code}",
                            axis.to_ascii_uppercase() as char
                        ),
                    ));
                }
                if radial {
                    let v = if self.state.lathe_diameter {
                        v / 2.0
                    } else {
                        v
                    };
                    end.im += v;
                } else {
                    end.re += v;
                }
            } else if let Some(v) = pb.get(axis) {
                if radial {
                    end.im = v;
                } else {
                    end.re = v;
                }
            }
        }
        let mut center = Zx::new(pb.get(b'k').unwrap_or(0.0), pb.get(b'i').unwrap_or(0.0));
        if incremental {
            end += *start;
        }
        if pb.g[gg::MOTION] != -1 {
            self.state.motion = pb.g[gg::MOTION];
        }
        if *start == end {
            return Ok(None);
        }
        let line = self.source.line;
        let motion = self.state.motion;
        let seg = match motion {
            0 | 10 => Some(Segment::line(*start, end, line)),
            20 | 30 => {
                if let Some(r) = pb.get(b'r') {
                    if pb.has(b'i') || pb.has(b'k') {
                        return Err(self.err(
                            pb,
                            b'r',
                            ErrorKind::Conflict,
                            format!("an arc of the profile of {code} has both R and I or K"),
                        ));
                    }
                    let chord = end - *start;
                    let n = chord.norm();
                    let h = Zx::new(0.0, ((r * r - n / 4.0) / n).sqrt()) * chord;
                    center = (*start + end).div_real(2.0);
                    center = if motion == 30 { center + h } else { center - h };
                } else {
                    if !pb.has(b'i') && !pb.has(b'k') {
                        let col = if pb.g[gg::MOTION] == -1 {
                            0
                        } else {
                            usize::from(pb.g_col[gg::MOTION]) + 1
                        };
                        return Err(self.error_at(
                            ErrorKind::MissingWord,
                            col,
                            format!("an arc of the profile of {code} needs I or K, or R"),
                        ));
                    }
                    if !self.state.ijk_absolute {
                        center += *start;
                    }
                }
                Some(Segment::arc(motion == 30, *start, center, end, line))
            }
            _ => None,
        };
        let mut corner = None;
        if matches!(motion, 0 | 10 | 20 | 30) {
            if pb.has(b'a') && pb.has(b'c') {
                return Err(self.err(
                    pb,
                    b'c',
                    ErrorKind::Conflict,
                    format!("A (fillet) and C (chamfer) on one corner of the profile of {code}"),
                ));
            }
            if let Some(a) = pb.get(b'a') {
                corner = Some(Segment::fillet(a, end, line));
            } else if let Some(c) = pb.get(b'c') {
                corner = Some(Segment::chamfer(c, end, line));
            }
        }
        self.state.position.x = end.im;
        self.state.position.z = end.re;
        *start = end;
        match (seg, corner) {
            (Some(s), Some(c)) => {
                segs.push(s);
                Ok(Some(c))
            }
            (None, c) => Ok(c),
            (s, None) => Ok(s),
        }
    }

    /// Issues the moves of a cycle as G0, G1, G2 and G3 in absolute coordinates, with the
    /// checks of those (feed rate, arc radii).
    fn issue_cuts(&mut self, b: &Block, cuts: &[Cut]) -> Res<()> {
        let saved = (self.state.absolute, self.state.ijk_absolute);
        self.state.absolute = true;
        self.state.ijk_absolute = true;
        let mut m: Box<Block> = Box::default();
        m.g_col = b.g_col;
        let r = cuts.iter().try_for_each(|cut| {
            m.has = 0;
            match *cut {
                Cut::Rapid(p) | Cut::Feed(p) => {
                    set_word(&mut m, b'x', p.im);
                    set_word(&mut m, b'z', p.re);
                    self.straight(&m, if matches!(cut, Cut::Rapid(_)) { 0 } else { 10 })
                }
                Cut::Arc { ccw, center, end } => {
                    let at = self.state.position;
                    if (at.z - end.re).abs() < TOLERANCE_EQUAL
                        && (at.x - end.im).abs() < TOLERANCE_EQUAL
                    {
                        return Ok(());
                    }
                    set_word(&mut m, b'x', end.im);
                    set_word(&mut m, b'z', end.re);
                    set_word(&mut m, b'i', center.im);
                    set_word(&mut m, b'k', center.re);
                    self.arc(&m, if ccw { 30 } else { 20 })
                }
            }
        });
        (self.state.absolute, self.state.ijk_absolute) = saved;
        r
    }
}

fn set_word(b: &mut Block, letter: u8, v: f64) {
    let i = usize::from(letter - b'a');
    b.words[i] = v;
    b.has |= 1 << i;
}
