//! The geometry of the G70, G71 and G72 lathe cycles: a profile of lines and arcs in the
//! ZX plane, offset by a distance, and the passes that rough out the material between the
//! start point and it, or finish along it. The algorithm is LinuxCNC 2.9's, step for step
//! (the same turns, the same tolerances, the same order of arithmetic), so that the moves
//! are the ones `rs274` prints; it is written anew here.
//!
//! Points are complex numbers with Z as the real and X as the imaginary part. Before
//! cutting, the profile is turned (G72) and mirrored so that it runs towards -Z and -X; the
//! moves are mapped back on the way out.

use std::ops::{Add, AddAssign, Div, Mul, Neg, Sub};

/// Distances below this count as zero.
const TOLERANCE: f64 = 1e-6;

/// A point (or vector) of the ZX plane: `re` is Z, `im` is X.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Zx {
    pub re: f64,
    pub im: f64,
}

impl Zx {
    pub(crate) const fn new(z: f64, x: f64) -> Zx {
        Zx { re: z, im: x }
    }
    fn conj(self) -> Zx {
        Zx::new(self.re, -self.im)
    }
    fn abs(self) -> f64 {
        self.re.hypot(self.im)
    }
    /// The squared magnitude.
    pub(crate) fn norm(self) -> f64 {
        self.re * self.re + self.im * self.im
    }
    fn scale(self, f: f64) -> Zx {
        Zx::new(self.re * f, self.im * f)
    }
    pub(crate) fn div_real(self, d: f64) -> Zx {
        Zx::new(self.re / d, self.im / d)
    }
    /// Multiplication by i (a quarter turn counter-clockwise).
    fn times_i(self) -> Zx {
        Zx::new(-self.im, self.re)
    }
}

impl Add for Zx {
    type Output = Zx;
    fn add(self, o: Zx) -> Zx {
        Zx::new(self.re + o.re, self.im + o.im)
    }
}
impl AddAssign for Zx {
    fn add_assign(&mut self, o: Zx) {
        *self = *self + o;
    }
}
impl Sub for Zx {
    type Output = Zx;
    fn sub(self, o: Zx) -> Zx {
        Zx::new(self.re - o.re, self.im - o.im)
    }
}
impl Neg for Zx {
    type Output = Zx;
    fn neg(self) -> Zx {
        Zx::new(-self.re, -self.im)
    }
}
impl Mul for Zx {
    type Output = Zx;
    fn mul(self, o: Zx) -> Zx {
        Zx::new(
            self.re * o.re - self.im * o.im,
            self.re * o.im + self.im * o.re,
        )
    }
}
impl Div for Zx {
    type Output = Zx;
    /// Smith's method, as the C runtime divides complex doubles (the same roundings).
    fn div(self, o: Zx) -> Zx {
        let (a, b, c, d) = (self.re, self.im, o.re, o.im);
        if c.abs() < d.abs() {
            let ratio = c / d;
            let denom = c * ratio + d;
            if ratio.abs() > f64::MIN_POSITIVE {
                Zx::new((a * ratio + b) / denom, (b * ratio - a) / denom)
            } else {
                Zx::new((c * (a / d) + b) / denom, (c * (b / d) - a) / denom)
            }
        } else {
            let ratio = d / c;
            let denom = d * ratio + c;
            if ratio.abs() > f64::MIN_POSITIVE {
                Zx::new((b * ratio + a) / denom, (b - a * ratio) / denom)
            } else {
                Zx::new((a + d * (b / c)) / denom, (b - d * (a / c)) / denom)
            }
        }
    }
}

/// `std::min` of C++: the first unless the second is smaller (a NaN second is ignored).
fn min_first(a: f64, b: f64) -> f64 {
    if b < a { b } else { a }
}

/// `std::max` of C++: the first unless the second is larger.
fn max_first(a: f64, b: f64) -> f64 {
    if a < b { b } else { a }
}

/// A line or an arc of the profile.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Shape {
    Line,
    Arc { ccw: bool, center: Zx },
}

/// What a segment is for: a programmed move, or a fillet (A word) or chamfer (C word) to
/// be fitted into the corner between its neighbours.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Corner {
    None,
    Fillet,
    Chamfer,
}

/// One element of the profile.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Segment {
    pub start: Zx,
    pub end: Zx,
    pub shape: Shape,
    corner: Corner,
    /// Radius of the fillet or size of the chamfer still to fit (0 once fitted).
    finish: f64,
    /// The program line the segment came from (for errors).
    pub line: u32,
}

/// Why a cycle cannot be made.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum ProfileError {
    /// The profile (or an offset of it) goes back in the cutting direction.
    NotMonotonic { line: u32 },
    /// A fillet or chamfer does not fit into its corner.
    CornerFinish { line: u32 },
    /// Two parallel lines were to be joined at a corner.
    ParallelLines { line: u32 },
    /// A roughing pass starts beyond the profile.
    DiveTooDeep { line: u32 },
    /// A pass met the profile where none should start.
    Lost { line: u32 },
    /// Offsetting left nothing of the profile.
    Vanished,
    /// More passes or moves than a block may make.
    TooManyMoves,
}

impl ProfileError {
    pub(crate) fn message(&self, code: &str) -> String {
        match self {
            ProfileError::NotMonotonic { line } => format!(
                "{code}: the profile is not monotonic: the move of line {line} turns back \
                 (each move must advance in Z for G71 and G70, in X for G72)"
            ),
            ProfileError::CornerFinish { line } => {
                format!("{code}: the fillet or chamfer of line {line} does not fit into its corner")
            }
            ProfileError::ParallelLines { line } => {
                format!("{code}: cannot join two parallel lines at line {line} (offset profile)")
            }
            ProfileError::DiveTooDeep { line } => {
                format!("{code}: a roughing pass goes deeper than the move of line {line} reaches")
            }
            ProfileError::Lost { line } => format!(
                "{code}: the cut lost track of the profile at the move of line {line} \
                 (LinuxCNC 2.9 repeats the same pass for ever here)"
            ),
            ProfileError::Vanished => {
                format!("{code}: nothing is left of the profile at this distance (D, E)")
            }
            ProfileError::TooManyMoves => format!(
                "{code} would make more than {MAX_MOVES} moves (is I, the depth of cut, too \
                 small?)"
            ),
        }
    }
}

type Res<T> = Result<T, ProfileError>;

/// Most moves one cycle block may make (they are queued together).
pub(crate) const MAX_MOVES: usize = 100_000;
/// Most steps of the cutting loops of one block (a profile that leads nowhere stops here
/// with an error instead of looping).
const MAX_STEPS: u64 = 20_000_000;

/// A move of the cycle, in program coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Cut {
    Rapid(Zx),
    Feed(Zx),
    Arc { ccw: bool, center: Zx, end: Zx },
}

/// Collects the moves, mapping them from the turned and mirrored frame back to the
/// program's; counts the steps taken.
struct Output<'a> {
    flip: u8,
    cuts: &'a mut Vec<Cut>,
    steps: u64,
}

impl Output<'_> {
    /// Undoes the turn (bit 2) and mirrors (bits 1 and 0) applied to the profile.
    fn unmap(&self, p: Zx) -> Zx {
        match self.flip {
            0 => p,
            1 => -p.conj(),
            2 => p.conj(),
            3 => -p,
            4 => p.times_i(),
            5 => p.times_i().conj(),
            6 => -p.times_i().conj(),
            _ => -p.times_i(),
        }
    }
    fn mirrored(&self) -> bool {
        matches!(self.flip, 1 | 2 | 5 | 6)
    }
    fn push(&mut self, cut: Cut) -> Res<()> {
        if self.cuts.len() >= MAX_MOVES {
            return Err(ProfileError::TooManyMoves);
        }
        self.cuts.push(cut);
        Ok(())
    }
    fn feed(&mut self, p: Zx) -> Res<()> {
        let p = self.unmap(p);
        self.push(Cut::Feed(p))
    }
    fn rapid(&mut self, p: Zx) -> Res<()> {
        let p = self.unmap(p);
        self.push(Cut::Rapid(p))
    }
    fn arc(&mut self, ccw: bool, center: Zx, end: Zx) -> Res<()> {
        let cut = Cut::Arc {
            ccw: ccw != self.mirrored(),
            center: self.unmap(center),
            end: self.unmap(end),
        };
        self.push(cut)
    }
    fn step(&mut self) -> Res<()> {
        self.steps += 1;
        if self.steps > MAX_STEPS {
            return Err(ProfileError::TooManyMoves);
        }
        Ok(())
    }
}

/// Up to two Z values where a segment crosses a line of constant X.
#[derive(Clone, Copy, Default)]
struct Hits {
    z: [f64; 2],
    n: usize,
}

impl Hits {
    fn push(&mut self, z: f64) {
        if self.n < 2 {
            self.z[self.n] = z;
            self.n += 1;
        }
    }
    fn is_empty(&self) -> bool {
        self.n == 0
    }
    fn front(&self) -> f64 {
        self.z[0]
    }
    fn back(&self) -> f64 {
        self.z[self.n.saturating_sub(1)]
    }
}

impl Segment {
    pub(crate) fn line(start: Zx, end: Zx, line: u32) -> Segment {
        Segment {
            start,
            end,
            shape: Shape::Line,
            corner: Corner::None,
            finish: 0.0,
            line,
        }
    }

    pub(crate) fn arc(ccw: bool, start: Zx, center: Zx, end: Zx, line: u32) -> Segment {
        Segment {
            start,
            end,
            shape: Shape::Arc { ccw, center },
            corner: Corner::None,
            finish: 0.0,
            line,
        }
    }

    /// A fillet of radius `r` to be fitted at the corner `at`.
    pub(crate) fn fillet(r: f64, at: Zx, line: u32) -> Segment {
        Segment {
            start: at,
            end: at,
            shape: Shape::Arc {
                ccw: false,
                center: at,
            },
            corner: Corner::Fillet,
            finish: r,
            line,
        }
    }

    /// A chamfer of size `c` (the ends a fillet of radius `c` would have) at `at`.
    pub(crate) fn chamfer(c: f64, at: Zx, line: u32) -> Segment {
        Segment {
            start: at,
            end: at,
            shape: Shape::Line,
            corner: Corner::Chamfer,
            finish: c,
            line,
        }
    }

    fn monotonic(&self) -> bool {
        match self.shape {
            Shape::Line => (self.end - self.start).re <= 1e-3,
            Shape::Arc { ccw, center } => {
                if self.finish != 0.0 {
                    return true;
                }
                let entry = (self.start - center).im;
                let exit = (self.end - center).im;
                let dz = (self.end - self.start).re;
                if ccw {
                    entry >= -1e-3 && exit >= -1e-3 && dz <= -1e-3
                } else {
                    entry <= 1e-3 && exit <= 1e-3 && dz <= -1e-3
                }
            }
        }
    }

    /// Size of the segment: its length, or for an arc the smaller of chord and radius.
    fn radius(&self) -> f64 {
        match self.shape {
            Shape::Line => (self.start - self.end).abs(),
            Shape::Arc { center, .. } => {
                min_first((self.start - self.end).abs(), (self.start - center).abs())
            }
        }
    }

    /// Moves the segment sideways by `distance` (to the left of its direction for a line;
    /// away from the centre of a counter-clockwise arc).
    fn offset(&mut self, distance: f64) {
        match self.shape {
            Shape::Line => {
                let d = Zx::new(0.0, distance) * (self.start - self.end);
                let d = d.div_real((self.start - self.end).abs());
                self.start += d;
                self.end += d;
            }
            Shape::Arc { ccw, center } => {
                let r = (self.start - center).abs();
                let sign = if ccw { 1.0 } else { -1.0 };
                let factor = (r + sign * distance) / r;
                self.start = (self.start - center).scale(factor) + center;
                self.end = (self.end - center).scale(factor) + center;
            }
        }
    }

    fn flip_x(&mut self) {
        self.start = self.start.conj();
        self.end = self.end.conj();
        if let Shape::Arc { ccw, center } = self.shape {
            self.shape = Shape::Arc {
                ccw: !ccw,
                center: center.conj(),
            };
        }
    }

    fn flip_z(&mut self) {
        self.start = -self.start.conj();
        self.end = -self.end.conj();
        if let Shape::Arc { ccw, center } = self.shape {
            self.shape = Shape::Arc {
                ccw: !ccw,
                center: -center.conj(),
            };
        }
    }

    /// A quarter turn clockwise.
    fn rotate(&mut self) {
        let turn = |p: Zx| -p.times_i();
        self.start = turn(self.start);
        self.end = turn(self.end);
        if let Shape::Arc { ccw, center } = self.shape {
            self.shape = Shape::Arc {
                ccw,
                center: turn(center),
            };
        }
    }

    fn on_arc(&self, ccw: bool, center: Zx, p: Zx) -> bool {
        let a = ((self.start - center).conj() * (p - center)).im;
        let b = ((self.end - center).conj() * (p - center)).im;
        if ccw {
            a >= -TOLERANCE && b <= TOLERANCE
        } else {
            a <= TOLERANCE && b >= -TOLERANCE
        }
    }

    /// Where the segment crosses X = `x`.
    fn intersection_z(&self, x: f64) -> Hits {
        let mut is = Hits::default();
        match self.shape {
            Shape::Line => {
                let (s, e) = (self.start, self.end);
                if min_first(s.im, e.im) > x + TOLERANCE || max_first(s.im, e.im) < x - TOLERANCE {
                    return is;
                }
                if (s - e).im.abs() < TOLERANCE {
                    is.push(s.re);
                    is.push(e.re);
                } else {
                    is.push((x - s.im) / (e.im - s.im) * (e.re - s.re) + s.re);
                }
            }
            Shape::Arc { ccw, center } => {
                let r = (self.start - center).abs();
                let mut s = -((x - r - center.im) * (x + r - center.im));
                if s < -TOLERANCE {
                    return is;
                }
                if s < 0.0 {
                    s = 0.0;
                }
                let s = s.sqrt();
                let p1 = Zx::new(center.re + s, x);
                if self.on_arc(ccw, center, p1) {
                    is.push(p1.re);
                }
                let p2 = Zx::new(center.re - s, x);
                if self.on_arc(ccw, center, p2) {
                    is.push(p2.re);
                }
            }
        }
        is
    }

    fn draw(&self, out: &mut Output) -> Res<()> {
        match self.shape {
            Shape::Line => out.feed(self.end),
            Shape::Arc { ccw, center } => out.arc(ccw, center, self.end),
        }
    }

    /// Follows the segment up from `location` if it climbs; true if it does not.
    fn climb(&self, location: &mut Zx, out: &mut Output) -> Res<bool> {
        match self.shape {
            Shape::Line => {
                if self.end.im + TOLERANCE < self.start.im {
                    return Ok(true);
                }
                if (*location - self.start).abs() > TOLERANCE {
                    return Err(ProfileError::Lost { line: self.line });
                }
                out.feed(self.end)?;
                *location = self.end;
                Ok(false)
            }
            Shape::Arc { ccw: false, center } => {
                if location.re > center.re {
                    return Ok(true);
                }
                if (*location - self.end).abs() > 1e-3 {
                    out.arc(false, center, self.end)?;
                }
                *location = self.end;
                Ok(false)
            }
            Shape::Arc { ccw: true, center } => {
                if location.re < center.re {
                    return Ok(true);
                }
                let ep = self.top_of_ccw(center);
                if (*location - ep).abs() > 1e-3 {
                    out.arc(true, center, ep)?;
                }
                *location = ep;
                Ok(true)
            }
        }
    }

    /// The end of a counter-clockwise arc, or its highest point if it goes on past it.
    fn top_of_ccw(&self, center: Zx) -> Zx {
        if self.end.re < center.re {
            Zx::new(center.re, center.im + (self.start - center).abs())
        } else {
            self.end
        }
    }

    /// After the roughing passes (G7x.1): from the level of `location`, up the rising
    /// part of the segment.
    fn climb_only(&self, location: &mut Zx, out: &mut Output) -> Res<()> {
        match self.shape {
            Shape::Line => {
                if self.end.im < self.start.im {
                    return Ok(());
                }
                let is = self.intersection_z(location.im);
                if is.is_empty() {
                    return Ok(());
                }
                location.re = is.front();
                out.feed(*location)?;
                out.feed(self.end)?;
                *location = self.end;
            }
            Shape::Arc { ccw, center } => {
                let is = self.intersection_z(location.im);
                if is.is_empty() {
                    return Ok(());
                }
                if !ccw {
                    if is.back() > center.re {
                        return Ok(());
                    }
                    location.re = is.back();
                    out.feed(*location)?;
                    if (*location - self.end).abs() > 1e-3 {
                        out.arc(false, center, self.end)?;
                    }
                    *location = self.end;
                } else {
                    if is.front() < center.re {
                        return Ok(());
                    }
                    location.re = is.front();
                    out.feed(*location)?;
                    let ep = self.top_of_ccw(center);
                    if (*location - ep).abs() > 1e-3 {
                        out.arc(true, center, ep)?;
                    }
                    *location = ep;
                }
            }
        }
        Ok(())
    }

    /// Follows the segment down from `location` to level `x` (or its end); true if the
    /// segment does not descend from there.
    fn dive(&self, location: &mut Zx, x: f64, out: &mut Output, fast: bool) -> Res<bool> {
        match self.shape {
            Shape::Line => {
                if self.start.im <= self.end.im + TOLERANCE {
                    return Ok(true);
                }
                if x < self.end.im {
                    if fast {
                        out.rapid(self.end)?;
                    } else {
                        out.feed(self.end)?;
                    }
                    *location = self.end;
                    return Ok(false);
                }
                let is = self.intersection_z(x);
                if is.is_empty() {
                    return Err(ProfileError::DiveTooDeep { line: self.line });
                }
                let ep = Zx::new(is.front(), x);
                if fast {
                    out.rapid(ep)?;
                } else {
                    out.feed(ep)?;
                }
                *location = ep;
                Ok(false)
            }
            Shape::Arc { ccw, center } => {
                if (*location - self.end).abs() < TOLERANCE
                    || (*location - self.end).re <= TOLERANCE
                {
                    *location = self.end;
                    return Ok(false);
                }
                let mut is = self.intersection_z(x);
                if is.is_empty() {
                    is = self.intersection_z(x - TOLERANCE);
                }
                if ccw {
                    if location.re - TOLERANCE > center.re {
                        return Ok(true);
                    }
                    if is.is_empty() || is.back() > center.re {
                        out.arc(true, center, self.end)?;
                        *location = self.end;
                    } else {
                        let ep = Zx::new(is.back(), x);
                        out.arc(true, center, ep)?;
                        *location = ep;
                    }
                    Ok(false)
                } else {
                    if location.re <= center.re {
                        return Ok(true);
                    }
                    if is.is_empty() {
                        out.arc(false, center, self.end)?;
                        *location = self.end;
                    } else if is.front() < center.re {
                        // Met on its far side only: the next pass goes lower.
                    } else {
                        let ep = Zx::new(is.front(), x);
                        out.arc(false, center, ep)?;
                        *location = ep;
                    }
                    Ok(false)
                }
            }
        }
    }
}

/// Joins two consecutive segments where they (or their extensions) meet: moves the end of
/// `prev` and the start of `next` to that point.
fn join(prev: &mut Segment, next: &mut Segment) -> Res<()> {
    match (prev.shape, next.shape) {
        (Shape::Line, Shape::Line) => {
            let rot = (next.start - next.end)
                .conj()
                .div_real((next.start - next.end).abs());
            let ps = (prev.start - next.end) * rot;
            let pe = (prev.end - next.end) * rot;
            if (ps - pe).im == 0.0 {
                return Err(ProfileError::ParallelLines { line: next.line });
            }
            let f = ps.im / (ps - pe).im;
            let is = (ps + (pe - ps).scale(f)) / rot + next.end;
            next.start = is;
            prev.end = is;
        }
        (Shape::Arc { center, .. }, Shape::Line) => {
            if (next.start - prev.end).abs() < TOLERANCE {
                return Ok(());
            }
            let rot = (next.start - next.end)
                .conj()
                .div_real((next.start - next.end).abs());
            let pe = (prev.end - next.end) * rot;
            let pc = (center - next.end) * rot;
            let s = line_circle(rot, pc, pe, next.end, next.start);
            next.start = s;
            prev.end = s;
        }
        (Shape::Line, Shape::Arc { center, .. }) => {
            if (next.start - prev.end).abs() < TOLERANCE {
                return Ok(());
            }
            let rot = (prev.start - prev.end)
                .conj()
                .div_real((prev.start - prev.end).abs());
            let pe = (next.end - prev.end) * rot;
            let pc = (center - prev.end) * rot;
            let s = line_circle(rot, pc, pe, prev.end, next.start);
            next.start = s;
            prev.end = s;
        }
        (Shape::Arc { center: pc, .. }, Shape::Arc { center: nc, .. }) => {
            let a = (next.start - nc).abs();
            let b = (prev.start - pc).abs();
            let c = (nc - pc).abs();
            let cos_b = (c * c + a * a - b * b) / 2.0 / a / c;
            let mut cos_b2 = cos_b * cos_b;
            if cos_b2 > 1.0 {
                cos_b2 = 1.0;
            }
            let rot = Zx::new(cos_b, (1.0 - cos_b2).sqrt());
            let is = (rot * (pc - nc)).div_real(c).scale(a) + nc;
            prev.end = is;
            next.start = is;
        }
    }
    Ok(())
}

/// Of the two points where a line (through `origin`, turned onto the real axis by `rot`)
/// meets a circle (centre `pc`, through `pe`, both in the turned frame), the one nearer
/// `near`.
fn line_circle(rot: Zx, pc: Zx, pe: Zx, origin: Zx, near: Zx) -> Zx {
    let b = (pc - pe).norm() - pc.im * pc.im;
    let b = if b < 0.0 { 0.0 } else { b.sqrt() };
    let s1 = Zx::new(pc.re + b, 0.0) / rot + origin;
    let s2 = Zx::new(pc.re - b, 0.0) / rot + origin;
    if (near - s1).abs() < (near - s2).abs() {
        s1
    } else {
        s2
    }
}

/// Fits the fillet or chamfer `seg` into the corner between `prev` and `next`: both are
/// offset by its size, their meeting point is the fillet's centre, and the feet of it on
/// both are the new ends.
fn fit_corner(prev: &mut Segment, seg: &mut Segment, next: &mut Segment) -> Res<()> {
    let offsets = |finish: f64| -> (Segment, Segment) {
        let (mut p, mut n) = (*prev, *next);
        p.offset(finish);
        n.offset(finish);
        (p, n)
    };
    let (mut p, mut n) = offsets(seg.finish);
    if (p.end - n.start).re > 1e-2 {
        seg.finish = -seg.finish;
        (p, n) = offsets(seg.finish);
    }
    if (p.end - n.start).re > 1e-2 {
        return Err(ProfileError::CornerFinish { line: seg.line });
    }
    join(&mut p, &mut n)?;
    let center = (p.end + n.start).div_real(2.0);
    p.offset(-seg.finish);
    n.offset(-seg.finish);
    seg.start = p.end;
    prev.end = p.end;
    seg.end = n.start;
    next.start = n.start;
    if seg.corner == Corner::Fillet {
        let ccw = (seg.start - center).im > 0.0 || (seg.end - center).im > 0.0;
        seg.shape = Shape::Arc { ccw, center };
        seg.finish = 0.0;
    }
    Ok(())
}

/// A profile with the turn and mirrors applied to it so far.
#[derive(Clone)]
struct Profile {
    segs: Vec<Segment>,
    /// Bit 2: turned a quarter (G72); bit 1: mirrored in X; bit 0: mirrored in Z.
    flip: u8,
}

impl Profile {
    fn rotate(&mut self) {
        for s in &mut self.segs {
            s.rotate();
        }
        self.flip ^= 4;
    }

    /// Mirrors the profile so that it runs towards -Z and -X, from the end of its first
    /// segment to the end of its last.
    fn orient(&mut self) -> Res<()> {
        let (Some(first), Some(last)) = (self.segs.first(), self.segs.last()) else {
            return Err(ProfileError::Vanished);
        };
        let d = first.end - last.end;
        if d.im > 0.0 {
            for s in &mut self.segs {
                s.flip_x();
            }
            self.flip ^= 2;
        }
        if d.re < 0.0 {
            for s in &mut self.segs {
                s.flip_z();
            }
            self.flip ^= 1;
        }
        Ok(())
    }

    fn check_monotonic(&mut self) -> Res<()> {
        let Some(first) = self.segs.first_mut() else {
            return Err(ProfileError::Vanished);
        };
        if (first.end - first.start).re > 0.0 {
            first.start.re = first.end.re;
        }
        match self.segs.iter().find(|s| !s.monotonic()) {
            Some(s) => Err(ProfileError::NotMonotonic { line: s.line }),
            None => Ok(()),
        }
    }

    /// Fits fillets and chamfers into their corners and drops what is too small to cut.
    fn finish_corners(&mut self) -> Res<()> {
        let n = self.segs.len();
        for h in 1..n.saturating_sub(1) {
            if self.segs[h].corner == Corner::None {
                continue;
            }
            let (before, rest) = self.segs.split_at_mut(h);
            let (seg, after) = rest.split_at_mut(1);
            fit_corner(&mut before[h - 1], &mut seg[0], &mut after[0])?;
        }
        self.segs.retain(|s| s.radius() >= 1e-3);
        Ok(())
    }

    /// Offsets the profile (all but its first, approaching segment) by `distance` towards
    /// the start of the cycle, in steps no larger than half the smallest segment,
    /// re-joining the segments after each step and bridging gaps with arcs.
    fn add_distance(&mut self, distance: f64, steps: &mut u64) -> Res<()> {
        if self.segs.len() < 2 {
            return Err(ProfileError::Vanished);
        }
        let first = self.segs[0];
        let back_start = self.segs[self.segs.len() - 1].start;
        let angle = (first.end - first.start) / (back_start - first.start);
        let distance = if angle.im < 0.0 { -distance } else { distance };
        self.segs.remove(0);
        let mut current = 0.0;
        while current != distance {
            *steps += 1;
            if *steps > MAX_STEPS {
                return Err(ProfileError::TooManyMoves);
            }
            let mut step = 1e9;
            for s in &self.segs {
                step = min_first(step, s.radius() / 2.0);
            }
            step = min_first(step, (distance - current).abs());
            if distance < 0.0 {
                step = -step;
            }
            for s in &mut self.segs {
                s.offset(step);
            }
            self.segs.retain(|s| s.radius() >= 1e-3);
            // Bridge the gaps that opened at convex corners with arcs.
            let mut p = 0;
            while p + 1 < self.segs.len() {
                let n = p + 1;
                if (self.segs[p].end - self.segs[n].start).re > 1e-2 {
                    let (mut s, mut e) = (self.segs[p], self.segs[n]);
                    s.offset(-step);
                    e.offset(-step);
                    let center = (s.end + e.start).div_real(2.0);
                    let bridge = Segment::arc(
                        distance > 0.0,
                        self.segs[p].end,
                        center,
                        self.segs[n].start,
                        self.segs[p].line,
                    );
                    self.segs.insert(n, bridge);
                    p += 1;
                }
                p += 1;
            }
            // Re-join neighbours; a segment turned backwards by the offset gives way.
            let mut p = 0;
            while p + 1 < self.segs.len() {
                if !self.segs[p].monotonic() {
                    if p == 0 {
                        // LinuxCNC 2.9 compares with the segment before the first here
                        // (and crashes).
                        return Err(ProfileError::NotMonotonic {
                            line: self.segs[p].line,
                        });
                    }
                    if self.segs[p].radius() < self.segs[p - 1].radius() {
                        self.segs.remove(p);
                    } else {
                        self.segs.remove(p - 1);
                    }
                    p = 0;
                    if self.segs.len() < 2 {
                        break;
                    }
                }
                if self.segs[p].radius() < 1e-3 {
                    self.segs.remove(p);
                    p = 0;
                } else {
                    let (a, b) = self.segs.split_at_mut(p + 1);
                    join(&mut a[p], &mut b[0])?;
                }
                p += 1;
            }
            if self.segs.is_empty() {
                return Err(ProfileError::Vanished);
            }
            current += step;
        }
        for p in 0..self.segs.len().saturating_sub(1) {
            let mid = (self.segs[p].end + self.segs[p + 1].start).div_real(2.0);
            self.segs[p].end = mid;
            self.segs[p + 1].start = mid;
        }
        let mut first = first;
        first.end = self.segs[0].start;
        self.segs.insert(0, first);
        Ok(())
    }
}

/// G70: finishing passes along the profile. `segs` starts with the move from the cycle's
/// start point to the profile; `(z, x)` is where passes start from; the distance of pass
/// `n` (counted down from `passes` to 1) to the profile is `(n - 1) (d - e) / passes + e`.
pub(crate) fn finish(
    segs: Vec<Segment>,
    start: Zx,
    d: f64,
    e: f64,
    passes: f64,
) -> (Vec<Cut>, Option<ProfileError>) {
    let mut cuts = Vec::new();
    let r = finish_into(segs, start, d, e, passes, &mut cuts);
    (cuts, r.err())
}

fn finish_into(
    mut segs: Vec<Segment>,
    start: Zx,
    d: f64,
    e: f64,
    passes: f64,
    cuts: &mut Vec<Cut>,
) -> Res<()> {
    if segs.len() < 2 {
        return Err(ProfileError::Vanished);
    }
    segs[0].start = start;
    let mut this = Profile { segs, flip: 0 };
    // Which way the profile runs is found on it without the approach.
    let mut path = this.clone();
    path.segs.remove(0);
    path.orient()?;
    if path.segs.iter().any(|s| !s.monotonic()) {
        path.rotate();
        path.orient()?;
    }
    path.check_monotonic()?;
    if path.flip & 4 != 0 {
        this.rotate();
    }
    this.orient()?;
    this.finish_corners()?;
    this.check_monotonic()?;
    let mut out = Output {
        flip: this.flip,
        cuts,
        steps: 0,
    };
    if passes > MAX_MOVES as f64 {
        return Err(ProfileError::TooManyMoves);
    }
    // A fractional number of passes counts as its whole part, as in C.
    let mut pass = passes as i64;
    while pass > 0 {
        let distance = (pass - 1) as f64 * (d - e) / passes + e;
        let mut path = this.clone();
        path.add_distance(distance, &mut out.steps)?;
        out.rapid(path.segs[0].start)?;
        out.rapid(path.segs[0].end)?;
        for s in &path.segs[1..] {
            s.draw(&mut out)?;
        }
        pass -= 1;
    }
    Ok(())
}

/// How a roughing cycle treats pockets (type II profiles).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Pockets {
    /// G71, G72: cut everything, pockets included.
    All,
    /// G71.1, G72.1: no pockets; after the passes, along the profile up to the first one.
    None,
    /// G71.2, G72.2: only the pockets, from where G7x.1 stopped.
    Only,
}

/// Parameters of a roughing cycle.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Roughing {
    pub pockets: Pockets,
    /// G72: passes run along X (the profile is turned a quarter first).
    pub facing: bool,
    /// D: material left on the profile.
    pub d: f64,
    /// I: depth of cut.
    pub i: f64,
    /// R: retraction.
    pub r: f64,
}

/// G71, G72: roughing passes down to the profile offset by D.
pub(crate) fn rough(
    segs: Vec<Segment>,
    start: Zx,
    job: Roughing,
) -> (Vec<Cut>, Option<ProfileError>) {
    let mut cuts = Vec::new();
    let r = rough_into(segs, start, job, &mut cuts);
    (cuts, r.err())
}

fn rough_into(mut segs: Vec<Segment>, start: Zx, job: Roughing, cuts: &mut Vec<Cut>) -> Res<()> {
    if segs.len() < 2 {
        return Err(ProfileError::Vanished);
    }
    segs[0].start = start;
    let mut this = Profile { segs, flip: 0 };
    if job.facing {
        this.rotate();
    }
    this.orient()?;
    this.finish_corners()?;
    this.check_monotonic()?;
    let mut steps = 0;
    this.add_distance(job.d, &mut steps)?;
    let mut out = Output {
        flip: this.flip,
        cuts,
        steps,
    };
    let delta = max_first(job.i, 2.0 * TOLERANCE);
    let escape = Zx::new(job.r, job.r);
    let mut segs = this.segs;
    let front_start = segs[0].start;
    out.rapid(front_start)?;
    // The profile must end at least as high as it starts: extend it up if it does not.
    let back = segs[segs.len() - 1];
    if back.end.im < front_start.im {
        let up = Zx::new(back.end.re, front_start.im);
        segs.push(Segment::line(back.end, up, back.line));
    }
    let mut pocket_starts = vec![front_start];
    let cycle = match job.pockets {
        Pockets::All => Cycle::All,
        Pockets::None => Cycle::NoPockets,
        Pockets::Only => Cycle::SkipFirst,
    };
    pockets(
        &segs,
        cycle,
        front_start,
        delta,
        escape,
        &mut pocket_starts,
        &mut out,
    )
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Cycle {
    All,
    NoPockets,
    /// G7x.2 at its start: skip the passes G7x.1 made.
    SkipFirst,
    /// G7x.2 after that.
    PocketsOnly,
}

/// The roughing passes from `location` on, segment `p` onwards; a pocket found on the way
/// up starts the same again from its edge.
fn pockets(
    segs: &[Segment],
    mut cycle: Cycle,
    mut location: Zx,
    delta: f64,
    escape: Zx,
    pocket_starts: &mut Vec<Zx>,
    out: &mut Output,
) -> Res<()> {
    let len = segs.len();
    let mut p = 0;
    'pocket: loop {
        let mut x = pocket_starts.last().map_or(location.im, |s| s.im);
        if cycle == Cycle::SkipFirst {
            while p < len {
                out.step()?;
                if segs[p].dive(&mut location, -1e9, out, p == 0)? {
                    break;
                }
                p += 1;
            }
            cycle = Cycle::PocketsOnly;
        }
        while p < len {
            out.step()?;
            let before = (p, x, location);
            while x - TOLERANCE > location.im {
                out.step()?;
                x -= delta;
            }
            if segs[p].dive(&mut location, x, out, p == 0)? {
                if cycle == Cycle::NoPockets {
                    // After the roughing passes, along the profile and done.
                    for s in &segs[p..] {
                        s.climb_only(&mut location, out)?;
                    }
                } else {
                    // Along the profile until a pocket, then cut that pocket.
                    while p < len {
                        if segs[p].climb(&mut location, out)? {
                            if cycle == Cycle::PocketsOnly {
                                let last_x = pocket_starts.last().map_or(location.im, |s| s.im);
                                if location.im > last_x && pocket_starts.len() > 1 {
                                    pocket_starts.pop();
                                }
                                if pocket_starts.len() == 1 {
                                    pocket_starts.push(location);
                                }
                            }
                            continue 'pocket;
                        }
                        p += 1;
                    }
                }
                return Ok(());
            }
            if (location.im - x).abs() > TOLERANCE {
                // Beyond this segment already: on to the next.
                p += 1;
                continue;
            }
            // A pass at level x: feed along it to the profile, then retract and return.
            for (ip, seg) in segs.iter().enumerate().skip(p) {
                let is = seg.intersection_z(location.im);
                if is.is_empty() {
                    continue;
                }
                let dest_z = if ip != p { is.front() } else { is.back() };
                let distance = (dest_z - location.re).abs();
                if dest_z - TOLERANCE > location.re {
                    continue;
                }
                if distance < TOLERANCE {
                    if p == ip {
                        continue;
                    } else if (location - seg.start).abs() < TOLERANCE {
                        p = ip;
                        break;
                    } else {
                        x -= delta;
                        break;
                    }
                }
                let mut dest = location;
                dest.re = dest_z;
                out.feed(dest)?;
                let escape_scale = min_first(1.0, distance / 2.0 / escape.re);
                let back = escape.scale(escape_scale);
                dest += back;
                out.rapid(dest)?;
                out.rapid(location - back.conj())?;
                if p == 0 {
                    out.rapid(location)?;
                } else {
                    out.feed(location)?;
                }
                x -= delta;
                break;
            }
            if before == (p, x, location) {
                // The next turn would be this one again (with the same moves, if any):
                // LinuxCNC 2.9 loops for ever here.
                return Err(ProfileError::Lost { line: segs[p].line });
            }
        }
        return Ok(());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn z(z: f64, x: f64) -> Zx {
        Zx::new(z, x)
    }

    #[test]
    fn a_step_profile_is_roughed_in_passes_of_depth_i() {
        // From (Z5, X20): down to X5 at Z0, along to Z-10, up to X20 at Z-20. With D0 and
        // I5 the passes are at X15 and X10 (X20 and X5 are the start and the profile).
        let segs = vec![
            Segment::line(z(5.0, 20.0), z(0.0, 5.0), 1),
            Segment::line(z(0.0, 5.0), z(-10.0, 5.0), 2),
            Segment::line(z(-10.0, 5.0), z(-10.0, 20.0), 3),
        ];
        let job = Roughing {
            pockets: Pockets::All,
            facing: false,
            d: 0.0,
            i: 5.0,
            r: 0.5,
        };
        let (cuts, err) = rough(segs, z(5.0, 20.0), job);
        assert_eq!(err, None);
        let feeds: Vec<Zx> = cuts
            .iter()
            .filter_map(|c| match c {
                Cut::Feed(p) => Some(*p),
                _ => None,
            })
            .collect();
        // Each pass feeds along Z to the step at Z-10, the last follows the profile.
        assert!(feeds.contains(&z(-10.0, 15.0)), "{cuts:?}");
        assert!(feeds.contains(&z(-10.0, 10.0)), "{cuts:?}");
        assert_eq!(feeds.last(), Some(&z(-10.0, 20.0)), "{cuts:?}");
    }

    #[test]
    fn a_profile_that_turns_back_is_refused_with_its_line() {
        let segs = vec![
            Segment::line(z(5.0, 20.0), z(0.0, 5.0), 1),
            Segment::line(z(0.0, 5.0), z(-10.0, 5.0), 2),
            Segment::line(z(-10.0, 5.0), z(-5.0, 10.0), 3),
            Segment::line(z(-5.0, 10.0), z(-20.0, 20.0), 4),
        ];
        let job = Roughing {
            pockets: Pockets::All,
            facing: false,
            d: 0.0,
            i: 1.0,
            r: 0.5,
        };
        let (_, err) = rough(segs, z(5.0, 20.0), job);
        assert_eq!(err, Some(ProfileError::NotMonotonic { line: 3 }));
    }
}
