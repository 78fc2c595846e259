//! Motion: end points (absolute, incremental, G53), straight moves, arcs (centre and radius
//! format, LinuxCNC's tolerances), splines, probing.

use crate::block::{AXES, Block, gg};
use crate::canon::{Arc, CanonCommand as C, FeedMode, Plane, Pose, ProbeKind, Spline, Units};
use crate::error::{ErrorKind, GcodeError};
use crate::interp::Interpreter;
use crate::params::sys;

/// Internal radius tolerance of R-format arcs (inch), as LinuxCNC.
const RADIUS_TOLERANCE_INCH: f64 = 0.00005;

type Res<T> = Result<T, GcodeError>;

/// The axes of an arc's plane: the first, second and normal one (indices into the pose),
/// the first two's letters and the letters of their centre offsets.
struct ArcAxes {
    first: usize,
    second: usize,
    normal: usize,
    letters: [u8; 2],
    offsets: [u8; 2],
}

impl Interpreter {
    /// End point of a move from the axis words (absolute, incremental, or G53 machine).
    pub(crate) fn find_ends(&self, b: &Block) -> Pose {
        let s = &self.state;
        let cur = s.position.to_array();
        let mut end = cur;
        if b.g[gg::NON_MODAL] == 530 {
            let m = self.machine_position().to_array();
            let mut target = m;
            for (i, letter) in AXES.iter().enumerate() {
                if let Some(v) = b.get(*letter) {
                    target[i] = v;
                }
            }
            let p = self
                .program_from_machine(&Pose::from_array(target))
                .to_array();
            for (i, letter) in AXES.iter().enumerate() {
                if b.has(*letter) {
                    end[i] = p[i];
                }
            }
            // X and Y change together through the rotation.
            if s.rotation != 0.0 && (b.has(b'x') || b.has(b'y')) {
                end[0] = p[0];
                end[1] = p[1];
            }
            return Pose::from_array(end);
        }
        for (i, letter) in AXES.iter().enumerate() {
            if let Some(v) = b.get(*letter) {
                end[i] = if s.absolute { v } else { cur[i] + v };
            }
        }
        if b.has_polar() {
            let (x, y) = polar_end(end[0], end[1], b.polar_radius, b.polar_angle, s.absolute);
            end[0] = x;
            end[1] = y;
        }
        Pose::from_array(end)
    }

    pub(crate) fn motion(&mut self, b: &Block, motion: i32) -> Res<()> {
        if b.has_polar() && !matches!(motion, 730 | 740 | 810..=890) {
            let col = usize::from(b.polar_col) + 1;
            let p = self.state.position;
            if p.x == 0.0 && p.y == 0.0 {
                if !self.state.absolute {
                    return Err(self.error_at(
                        ErrorKind::BadValue,
                        col,
                        "incremental motion with polar coordinates is indeterminate at the origin",
                    ));
                }
                if b.polar_angle.is_none() {
                    return Err(self.error_at(
                        ErrorKind::MissingWord,
                        col,
                        "give the angle (^) of a polar coordinate when at the origin",
                    ));
                }
            }
        }
        match motion {
            0 | 10 => self.straight(b, motion),
            20 | 30 => self.arc(b, motion),
            50 | 51 => self.spline(b, motion),
            52 => self.nurbs_point(b),
            700 | 710..=712 | 720..=722 => self.lathe_cycle(b, motion),
            382..=385 => self.probe(b, motion),
            330 => self.g33(b),
            331 => self.g33_1(b),
            760 => self.g76(b),
            800 => {
                self.emit(C::Comment("interpreter: motion mode set to none".into()));
                self.state.motion = 800;
                self.cycle.initial_level = None;
                Ok(())
            }
            _ => self.canned_cycle(b, motion),
        }
    }

    pub(crate) fn straight(&mut self, b: &Block, motion: i32) -> Res<()> {
        if motion == 10 {
            match self.state.feed_mode {
                FeedMode::UnitsPerMinute if self.state.feed_rate == 0.0 => {
                    return Err(self.g_err(
                        b,
                        gg::MOTION,
                        ErrorKind::State,
                        "cannot do G1 with zero feed rate",
                    ));
                }
                FeedMode::UnitsPerRevolution => {
                    if self.state.feed_rate == 0.0 {
                        return Err(self.g_err(
                            b,
                            gg::MOTION,
                            ErrorKind::State,
                            "cannot do G1 with zero feed rate",
                        ));
                    }
                    if self.state.speed == 0.0 {
                        return Err(self.g_err(
                            b,
                            gg::MOTION,
                            ErrorKind::State,
                            "cannot feed with zero spindle speed in feed per revolution mode (G95)",
                        ));
                    }
                }
                FeedMode::InverseTime if !b.has(b'f') => {
                    return Err(self.g_err(
                        b,
                        gg::MOTION,
                        ErrorKind::MissingWord,
                        "F word missing with inverse time (G93) G1 move",
                    ));
                }
                _ => {}
            }
        }
        if self.state.motion != motion {
            self.cycle.initial_level = None;
        }
        self.state.motion = motion;
        let end = self.find_ends(b);
        if motion == 10 && self.state.feed_mode == FeedMode::InverseTime {
            let length = straight_length(&self.state.position, &end);
            let rate = (length * b.get(b'f').unwrap_or(0.0)).max(0.1);
            self.state.feed_rate = rate;
            self.emit(C::SetFeedRate(rate));
        }
        self.emit(if motion == 0 {
            C::StraightTraverse(end)
        } else {
            C::StraightFeed(end)
        });
        self.state.position = end;
        Ok(())
    }

    pub(crate) fn arc(&mut self, b: &Block, motion: i32) -> Res<()> {
        let axes = self.arc_axes(b)?;
        let r_word = b.get(b'r');
        self.check_arc_words(b, &axes, r_word.is_some())?;
        self.check_arc_feed(b)?;
        if self.state.motion != motion {
            self.cycle.initial_level = None;
        }
        self.state.motion = motion;
        let end = self.find_ends(b);
        let cur = self.state.position.to_array();
        let e = end.to_array();
        let (a1, a2, a3) = (axes.first, axes.second, axes.normal);
        let (c1, c2) = (cur[a1], cur[a2]);
        let (e1, e2) = (e[a1], e[a2]);
        let turns = b.get(b'p').map_or(1, |p| p.round() as i32);
        let rotation = if motion == 20 { -turns } else { turns };
        let (center1, center2) = if let Some(r) = r_word {
            self.radius_format_centre(b, motion, r, (c1, c2), (e1, e2))?
        } else {
            self.centre_format_centre(b, &axes, (c1, c2), (e1, e2))?
        };
        if self.state.feed_mode == FeedMode::InverseTime {
            let length = arc_length(c1, c2, cur[a3], center1, center2, rotation, e1, e2, e[a3]);
            let rate = (length * b.get(b'f').unwrap_or(0.0)).max(0.1);
            self.state.feed_rate = rate;
            self.emit(C::SetFeedRate(rate));
        }
        self.emit(C::ArcFeed(Arc {
            first_end: e1,
            second_end: e2,
            first_axis: center1,
            second_axis: center2,
            rotation,
            axis_end_point: e[a3],
            a: end.a,
            b: end.b,
            c: end.c,
            u: end.u,
            v: end.v,
            w: end.w,
        }));
        self.state.position = end;
        Ok(())
    }

    /// The axes of the selected plane, which must be one of XY, XZ and YZ.
    fn arc_axes(&self, b: &Block) -> Res<ArcAxes> {
        let (first, second, normal, l1, l2, n1, n2) = match self.state.plane {
            Plane::XY => (0, 1, 2, b'x', b'y', b'i', b'j'),
            Plane::XZ => (2, 0, 1, b'z', b'x', b'k', b'i'),
            Plane::YZ => (1, 2, 0, b'y', b'z', b'j', b'k'),
            _ => {
                return Err(self.g_err(
                    b,
                    gg::MOTION,
                    ErrorKind::State,
                    "arcs are not supported in the UV, UW and VW planes",
                ));
            }
        };
        Ok(ArcAxes {
            first,
            second,
            normal,
            letters: [l1, l2],
            offsets: [n1, n2],
        })
    }

    /// The words an arc needs and the ones it may not have, in radius (`radius_format`) or
    /// centre format.
    fn check_arc_words(&self, b: &Block, axes: &ArcAxes, radius_format: bool) -> Res<()> {
        let s = &self.state;
        let [l1, l2] = axes.letters;
        let [n1, n2] = axes.offsets;
        let wrong_offset = match s.plane {
            Plane::XY => b'k',
            Plane::XZ => b'j',
            _ => b'i',
        };
        if radius_format {
            // A radius-format arc cannot be a full circle: it needs an end point.
            if !b.has(l1) && !b.has(l2) && !b.has_polar() {
                return Err(self.g_err(
                    b,
                    gg::MOTION,
                    ErrorKind::MissingWord,
                    format!(
                        "{} and {} words both missing for a radius-format arc in this plane",
                        l1.to_ascii_uppercase() as char,
                        l2.to_ascii_uppercase() as char
                    ),
                ));
            }
            if b.has(b'i') || b.has(b'j') || b.has(b'k') {
                return Err(self.err(
                    b,
                    b'r',
                    ErrorKind::Conflict,
                    "arc given with both R and I/J/K (mixed radius and centre format)",
                ));
            }
        } else {
            if !b.has(b'i') && !b.has(b'j') && !b.has(b'k') {
                return Err(self.g_err(
                    b,
                    gg::MOTION,
                    ErrorKind::MissingWord,
                    "R, I, J and K words all missing for the arc",
                ));
            }
            if b.has(wrong_offset) {
                return Err(self.err(
                    b,
                    wrong_offset,
                    ErrorKind::UnusedWord,
                    format!(
                        "{} word given for an arc in this plane",
                        wrong_offset.to_ascii_uppercase() as char
                    ),
                ));
            }
            if s.ijk_absolute {
                for n in [n1, n2] {
                    if !b.has(n) {
                        return Err(self.g_err(
                            b,
                            gg::MOTION,
                            ErrorKind::MissingWord,
                            format!(
                                "{} word missing in absolute centre arc (G90.1)",
                                n.to_ascii_uppercase() as char
                            ),
                        ));
                    }
                }
            }
        }
        Ok(())
    }

    /// An F word with inverse time, a feed rate otherwise.
    fn check_arc_feed(&self, b: &Block) -> Res<()> {
        let s = &self.state;
        match s.feed_mode {
            FeedMode::InverseTime if !b.has(b'f') => {
                return Err(self.g_err(
                    b,
                    gg::MOTION,
                    ErrorKind::MissingWord,
                    "F word missing with inverse time (G93) arc move",
                ));
            }
            FeedMode::InverseTime => {}
            _ if s.feed_rate == 0.0 => {
                return Err(self.g_err(
                    b,
                    gg::MOTION,
                    ErrorKind::State,
                    "cannot make an arc with zero feed rate",
                ));
            }
            _ => {}
        }
        Ok(())
    }

    /// The centre of an R-format arc of radius `r` from `(c1, c2)` to `(e1, e2)` in the
    /// plane's first and second axes.
    fn radius_format_centre(
        &self,
        b: &Block,
        motion: i32,
        r: f64,
        (c1, c2): (f64, f64),
        (e1, e2): (f64, f64),
    ) -> Res<(f64, f64)> {
        let inch = self.state.units == Units::Inches;
        let tol = if inch {
            RADIUS_TOLERANCE_INCH
        } else {
            RADIUS_TOLERANCE_INCH * 25.4
        };
        if e1 == c1 && e2 == c2 {
            return Err(self.err(
                b,
                b'r',
                ErrorKind::Arc,
                "current point same as end point of arc: an R-format arc needs distinct end points",
            ));
        }
        let abs_r = r.abs();
        let (m1, m2) = ((e1 + c1) / 2.0, (e2 + c2) / 2.0);
        let mut half = (m1 - e1).hypot(m2 - e2);
        if half - abs_r > tol {
            return Err(self.err(b, b'r', ErrorKind::Arc, format!("arc radius {abs_r} too small to reach the end point (half the chord is {half:.4})")));
        }
        if half / abs_r > 1.0 - 1e-12 {
            half = abs_r;
        }
        let theta = (e2 - c2).atan2(e1 - c1)
            + if (motion == 20 && r > 0.0) || (motion == 30 && r < 0.0) {
                -std::f64::consts::FRAC_PI_2
            } else {
                std::f64::consts::FRAC_PI_2
            };
        let turn2 = (half / abs_r).asin();
        let offset = abs_r * turn2.cos();
        Ok((m1 + offset * theta.cos(), m2 + offset * theta.sin()))
    }

    /// The centre of an arc given by its offsets (I, J, K) from `(c1, c2)` to `(e1, e2)` in
    /// the plane's first and second axes, which must be as far from both ends.
    fn centre_format_centre(
        &self,
        b: &Block,
        axes: &ArcAxes,
        (c1, c2): (f64, f64),
        (e1, e2): (f64, f64),
    ) -> Res<(f64, f64)> {
        let [l1, l2] = axes.letters;
        let [n1, n2] = axes.offsets;
        let inch = self.state.units == Units::Inches;
        let o1 = b.get(n1).unwrap_or(0.0);
        let o2 = b.get(n2).unwrap_or(0.0);
        let (cc1, cc2) = if self.state.ijk_absolute {
            (o1, o2)
        } else {
            (c1 + o1, c2 + o2)
        };
        let r1 = (cc1 - c1).hypot(cc2 - c2);
        let r2 = (cc1 - e1).hypot(cc2 - e2);
        let min_r = if inch {
            RADIUS_TOLERANCE_INCH
        } else {
            RADIUS_TOLERANCE_INCH * 25.4
        };
        let (n1c, n2c) = (
            l1.to_ascii_uppercase() as char,
            l2.to_ascii_uppercase() as char,
        );
        if r1 < min_r || r2 < min_r {
            return Err(self.g_err(b, gg::MOTION, ErrorKind::Arc, format!(
                "zero-radius arc: start=({n1c}{c1:.4},{n2c}{c2:.4}) center=({n1c}{cc1:.4},{n2c}{cc2:.4}) end=({n1c}{e1:.4},{n2c}{e2:.4}) r1={r1:.4} r2={r2:.4}"
            )));
        }
        let abs_err = (r1 - r2).abs();
        let rel_err = abs_err / r1.max(r2);
        if !self
            .settings
            .arc_radius_tolerance(self.state.units)
            .accepts(r1, r2)
        {
            return Err(self.g_err(b, gg::MOTION, ErrorKind::Arc, format!(
                "radius to end of arc differs from radius to start: start=({n1c}{c1:.4},{n2c}{c2:.4}) center=({n1c}{cc1:.4},{n2c}{cc2:.4}) end=({n1c}{e1:.4},{n2c}{e2:.4}) r1={r1:.4} r2={r2:.4} abs_err={abs_err:.4} rel_err={:.4}%",
                rel_err * 100.0
            )));
        }
        Ok((cc1, cc2))
    }

    pub(crate) fn spline(&mut self, b: &Block, motion: i32) -> Res<()> {
        let err = |this: &Self, kind, msg: &str| this.g_err(b, gg::MOTION, kind, msg);
        if self.state.cutter.is_some() {
            return Err(err(
                self,
                ErrorKind::State,
                "cannot make a spline with cutter radius compensation on",
            ));
        }
        match self.state.feed_mode {
            FeedMode::InverseTime if !b.has(b'f') => {
                return Err(err(
                    self,
                    ErrorKind::MissingWord,
                    "F word missing with inverse time (G93) spline",
                ));
            }
            FeedMode::UnitsPerMinute if self.state.feed_rate == 0.0 => {
                return Err(err(
                    self,
                    ErrorKind::State,
                    "cannot make a spline with zero feed rate",
                ));
            }
            _ => {}
        }
        if self.state.plane != Plane::XY {
            return Err(err(
                self,
                ErrorKind::State,
                "G5 and G5.1 need the XY plane (G17)",
            ));
        }
        // The spline command carries X and Y only: a U, V or W word would move the
        // program position without the machine.
        if [b'z', b'a', b'b', b'c', b'u', b'v', b'w']
            .iter()
            .any(|l| b.has(*l))
        {
            return Err(err(
                self,
                ErrorKind::UnusedWord,
                "splines may not move Z, A, B, C, U, V or W",
            ));
        }
        let start = self.state.position;
        self.state.motion = motion;
        let spline = if motion == 50 {
            // I J of the first control point; without them the reflection of the previous
            // G5's P Q (LinuxCNC keeps it with the G87 offsets).
            let ij = match (b.get(b'i'), b.get(b'j')) {
                (Some(i), Some(j)) => [i, j],
                (None, None) => [self.cycle.i, self.cycle.j],
                _ => {
                    return Err(err(
                        self,
                        ErrorKind::MissingWord,
                        "G5 needs both I and J, or neither",
                    ));
                }
            };
            let end = self.find_ends(b);
            let (Some(p), Some(q)) = (b.get(b'p'), b.get(b'q')) else {
                return Err(err(self, ErrorKind::MissingWord, "G5 needs both P and Q"));
            };
            self.cycle.i = -p;
            self.cycle.j = -q;
            self.state.position = end;
            Spline {
                order: 4,
                p1: [start.x + ij[0], start.y + ij[1]],
                p2: [end.x + p, end.y + q],
                end: [end.x, end.y],
            }
        } else {
            let (Some(i), Some(j)) = (b.get(b'i'), b.get(b'j')) else {
                return Err(err(self, ErrorKind::MissingWord, "G5.1 needs both I and J"));
            };
            let end = self.find_ends(b);
            self.state.position = end;
            let p1 = [start.x + i, start.y + j];
            Spline {
                order: 3,
                p1,
                p2: p1,
                end: [end.x, end.y],
            }
        };
        if self.state.feed_mode == FeedMode::InverseTime {
            // As for lines and arcs, the move's time 1/F becomes a rate over its length
            // (rs274 emits none: LinuxCNC runs a G93 spline at the last feed rate).
            let length = spline_length([start.x, start.y], &spline);
            let rate = (length * b.get(b'f').unwrap_or(0.0)).max(0.1);
            self.state.feed_rate = rate;
            self.emit(C::SetFeedRate(rate));
        }
        self.emit(C::SplineFeed(spline));
        Ok(())
    }

    pub(crate) fn probe(&mut self, b: &Block, motion: i32) -> Res<()> {
        if self.state.cutter.is_some() {
            return Err(self.g_err(
                b,
                gg::MOTION,
                ErrorKind::State,
                "cannot probe with cutter radius compensation on",
            ));
        }
        if self.state.feed_rate == 0.0 {
            return Err(self.g_err(
                b,
                gg::MOTION,
                ErrorKind::State,
                "cannot probe with zero feed rate",
            ));
        }
        if self.state.feed_mode == FeedMode::UnitsPerRevolution {
            return Err(self.g_err(
                b,
                gg::MOTION,
                ErrorKind::State,
                "cannot probe in feed per revolution mode (G95)",
            ));
        }
        let end = self.find_ends(b);
        let kind = match motion {
            382 => ProbeKind::TowardError,
            383 => ProbeKind::Toward,
            384 => ProbeKind::AwayError,
            _ => ProbeKind::Away,
        };
        let cur = self.state.position;
        if matches!(kind, ProbeKind::TowardError | ProbeKind::AwayError) && cur == end {
            return Err(self.g_err(
                b,
                gg::MOTION,
                ErrorKind::BadValue,
                "start point too close to probe point",
            ));
        }
        self.emit(C::TurnProbeOn);
        self.emit(C::StraightProbe { end, kind });
        self.emit(C::TurnProbeOff);
        self.state.motion = motion;
        self.cycle.initial_level = None;
        // Without a machine the probe result is the programmed end (not tripped, #5070 = 0)
        // and the tool backs off a little from it, as LinuxCNC's stand-alone interpreter
        // models it; a machine reports the real result with `set_probe_result`.
        for (i, v) in end.to_array().iter().enumerate() {
            self.params.set(sys::PROBE + i, *v);
        }
        self.params.set(sys::PROBE_OK, 0.0);
        let (dx, dy, dz) = (cur.x - end.x, cur.y - end.y, cur.z - end.z);
        let dist = (dx * dx + dy * dy + dz * dz).sqrt();
        let mut after = end;
        if dist != 0.0 {
            let backoff = if self.state.units == Units::Mm {
                0.254
            } else {
                0.01
            };
            after.x = end.x + backoff * dx / dist;
            after.y = end.y + backoff * dy / dist;
            after.z = end.z + backoff * dz / dist;
        }
        self.state.position = after;
        self.waiting = self.settings.wait_for_machine;
        Ok(())
    }
}

/// X and Y of a polar end point (`@` radius, `^` angle in degrees, about the origin of the
/// coordinate system). Absolute: a missing word keeps the current radius or angle;
/// incremental: the words add to them.
pub(crate) fn polar_end(
    x: f64,
    y: f64,
    radius: Option<f64>,
    angle: Option<f64>,
    absolute: bool,
) -> (f64, f64) {
    let (r0, t0) = (x.hypot(y), y.atan2(x));
    let (r, t) = if absolute {
        (radius.unwrap_or(r0), angle.map_or(t0, f64::to_radians))
    } else {
        (
            r0 + radius.unwrap_or(0.0),
            t0 + angle.unwrap_or(0.0).to_radians(),
        )
    };
    (r * t.cos(), r * t.sin())
}

/// Arc length of a spline in the XY plane (Gauss-Legendre, 64 intervals of three points;
/// exact to rounding for the smooth curves G5 and G5.1 make).
fn spline_length(start: [f64; 2], sp: &Spline) -> f64 {
    const X: [f64; 3] = [0.112_701_665_379_258_31, 0.5, 0.887_298_334_620_741_7];
    const W: [f64; 3] = [5.0 / 18.0, 8.0 / 18.0, 5.0 / 18.0];
    // Derivative of the Bézier curve (quadratic or cubic) at u.
    let d = |u: f64, i: usize| {
        let s = 1.0 - u;
        if sp.order == 3 {
            2.0 * (s * (sp.p1[i] - start[i]) + u * (sp.end[i] - sp.p1[i]))
        } else {
            3.0 * (s * s * (sp.p1[i] - start[i])
                + 2.0 * s * u * (sp.p2[i] - sp.p1[i])
                + u * u * (sp.end[i] - sp.p2[i]))
        }
    };
    let n = 64;
    let h = 1.0 / n as f64;
    let mut len = 0.0;
    for k in 0..n {
        for g in 0..3 {
            let u = (k as f64 + X[g]) * h;
            len += W[g] * h * d(u, 0).hypot(d(u, 1));
        }
    }
    len
}

/// Length of a straight move for inverse time feed: XYZ(UVW) distance, or the rotary
/// distance when only rotary axes move.
fn straight_length(a: &Pose, b: &Pose) -> f64 {
    let d = |x: f64, y: f64| (x - y) * (x - y);
    let lin = d(a.x, b.x) + d(a.y, b.y) + d(a.z, b.z) + d(a.u, b.u) + d(a.v, b.v) + d(a.w, b.w);
    if lin > 0.0 {
        lin.sqrt()
    } else {
        (d(a.a, b.a) + d(a.b, b.b) + d(a.c, b.c)).sqrt()
    }
}

/// Length of a helical arc (LinuxCNC's find_arc_length).
#[allow(clippy::too_many_arguments)]
fn arc_length(
    x1: f64,
    y1: f64,
    z1: f64,
    cx: f64,
    cy: f64,
    turn: i32,
    x2: f64,
    y2: f64,
    z2: f64,
) -> f64 {
    let radius = (cx - x1).hypot(cy - y1);
    let theta = find_turn(x1, y1, cx, cy, turn, x2, y2);
    if z2 == z1 {
        radius * theta.abs()
    } else {
        (radius * theta).hypot(z2 - z1)
    }
}

/// Angle swept by an arc with `turn` turns (sign = direction), radians.
fn find_turn(x1: f64, y1: f64, cx: f64, cy: f64, turn: i32, x2: f64, y2: f64) -> f64 {
    use std::f64::consts::TAU;
    if turn == 0 {
        return 0.0;
    }
    let mut alpha = (y1 - cy).atan2(x1 - cx);
    let mut beta = (y2 - cy).atan2(x2 - cx);
    if turn > 0 {
        if beta <= alpha {
            beta += TAU;
        }
        beta - alpha + f64::from(turn - 1) * TAU
    } else {
        if alpha <= beta {
            alpha += TAU;
        }
        beta - alpha + f64::from(turn + 1) * TAU
    }
}
