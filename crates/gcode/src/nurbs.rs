//! G5.2 / G5.3 NURBS blocks, as LinuxCNC 2.9 reads them: G5.2 opens the block and each
//! line in it adds a control point (X Y, weight P); L gives the order; G5.3 closes it and
//! issues the curve as one [`CanonCommand::NurbsFeed`](crate::canon::CanonCommand).

use crate::block::{Block, gg};
use crate::canon::{CanonCommand as C, FeedMode, Nurbs, NurbsPoint};
use crate::error::{ErrorKind, GcodeError};
use crate::interp::Interpreter;

type Res<T> = Result<T, GcodeError>;

/// Most control points of one curve (they are held until G5.3).
pub(crate) const MAX_NURBS_POINTS: usize = 10_000;

impl Interpreter {
    fn nurbs_err(&self, b: &Block, letter: u8, kind: ErrorKind, msg: &str) -> GcodeError {
        if b.has(letter) {
            self.err(b, letter, kind, msg)
        } else if b.g[gg::MOTION] == 52 {
            self.g_err(b, gg::MOTION, kind, msg)
        } else if b.has(b'x') {
            self.err(b, b'x', kind, msg)
        } else {
            self.error_at(kind, 0, msg)
        }
    }

    /// A G5.2 line: the first one takes the current point as the first control point (P
    /// alone gives its weight); every line with X and Y adds one.
    pub(crate) fn nurbs_point(&mut self, b: &Block) -> Res<()> {
        let (has_x, has_y) = (b.has(b'x'), b.has(b'y'));
        if has_x != has_y {
            let (given, missing) = if has_x { (b'x', b'y') } else { (b'y', b'x') };
            return Err(self.nurbs_err(
                b,
                given,
                ErrorKind::MissingWord,
                &format!(
                    "a NURBS control point needs both X and Y ({} is missing)",
                    missing.to_ascii_uppercase() as char
                ),
            ));
        }
        let weight = b.get(b'p');
        let open = !self.nurbs.is_empty();
        if !has_x && weight.is_some() && open {
            return Err(self.nurbs_err(
                b,
                b'p',
                ErrorKind::MissingWord,
                "P without X and Y gives the weight of the first control point only",
            ));
        }
        if weight.is_some_and(|w| w <= 0.0) || (weight.is_none() && open) {
            return Err(self.nurbs_err(
                b,
                b'p',
                ErrorKind::BadValue,
                "every NURBS control point needs a positive weight P",
            ));
        }
        if self.state.feed_mode == FeedMode::UnitsPerMinute && self.state.feed_rate == 0.0 {
            return Err(self.nurbs_err(
                b,
                b'f',
                ErrorKind::State,
                "cannot make a NURBS with zero feed rate",
            ));
        }
        if self.state.cutter.is_some() {
            return Err(self.nurbs_err(
                b,
                b'x',
                ErrorKind::State,
                "cannot make a NURBS with cutter radius compensation on",
            ));
        }
        // The curve carries X and Y only: another axis word would move the program
        // position without the machine (LinuxCNC drops such words).
        if let Some(l) = [b'z', b'a', b'b', b'c', b'u', b'v', b'w']
            .into_iter()
            .find(|l| b.has(*l))
        {
            return Err(self.nurbs_err(
                b,
                l,
                ErrorKind::UnusedWord,
                "NURBS control points may not move Z, A, B, C, U, V or W",
            ));
        }
        let order = match b.get(b'l') {
            Some(l) => {
                let whole = self.whole(b, b'l', l)?;
                if whole < 0 {
                    return Err(self.err(b, b'l', ErrorKind::BadValue, "negative L word"));
                }
                Some(whole)
            }
            None => None,
        };
        if self.state.motion != 52 {
            self.nurbs.clear();
        }
        if self.nurbs.is_empty() {
            let p = self.state.position;
            self.nurbs.push(NurbsPoint {
                x: p.x,
                y: p.y,
                weight: if has_x { 1.0 } else { weight.unwrap_or(1.0) },
            });
            self.nurbs_order = 3;
        }
        // An order of 3 or less keeps the one in force (LinuxCNC).
        if let Some(l) = order.filter(|l| *l > 3) {
            if l as usize > MAX_NURBS_POINTS {
                return Err(self.err(
                    b,
                    b'l',
                    ErrorKind::BadValue,
                    format!("NURBS order L may be at most {MAX_NURBS_POINTS}"),
                ));
            }
            self.nurbs_order = l as u32;
        }
        if has_x {
            if self.nurbs.len() >= MAX_NURBS_POINTS {
                return Err(self.nurbs_err(
                    b,
                    b'x',
                    ErrorKind::BadValue,
                    &format!("a NURBS may have at most {MAX_NURBS_POINTS} control points"),
                ));
            }
            // Incremental points are relative to the start of the curve: the position
            // moves only at G5.3, as in LinuxCNC.
            let end = self.find_ends(b);
            self.nurbs.push(NurbsPoint {
                x: end.x,
                y: end.y,
                // LinuxCNC 2.9 takes -1 for a point on the G5.2 line without P; its manual
                // says 1, the weight here.
                weight: weight.unwrap_or(1.0),
            });
        }
        self.state.motion = 52;
        Ok(())
    }

    /// G5.3: closes the NURBS block and issues the curve.
    pub(crate) fn nurbs_end(&mut self, b: &Block) -> Res<()> {
        if self.state.motion != 52 {
            return Err(self.g_err(
                b,
                gg::NON_MODAL,
                ErrorKind::State,
                "G5.3 without G5.2 first",
            ));
        }
        let order = self.nurbs_order;
        if self.nurbs.len() < order as usize {
            return Err(self.g_err(
                b,
                gg::NON_MODAL,
                ErrorKind::MissingWord,
                format!(
                    "a NURBS of order L{order} needs at least {order} control points, it has {}",
                    self.nurbs.len()
                ),
            ));
        }
        let points = std::mem::take(&mut self.nurbs);
        if let Some(last) = points.last() {
            self.state.position.x = last.x;
            self.state.position.y = last.y;
        }
        self.emit(C::NurbsFeed(Nurbs { order, points }));
        self.state.motion = -1;
        Ok(())
    }
}
