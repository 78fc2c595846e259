//! Turns moves into path pieces: validation, feed resolution, soft limits, collinear merging
//! (G64 Q), corner blending and smoothing of dense polylines (G64 P), exact stops (G61,
//! G61.1). Runs when moves are pushed, not in the servo period.

use crate::axes::{AXES, Axis, AxisVec, add_scaled, dot, is_finite, norm, norm_xyz, scale, sub};
use crate::error::MotionError;
use crate::geometry::{ArcMap, CORNER_MIDDLE, Helix, Shape, corner_blend, quintic, quintic_axis};
use crate::input::{Feed, Move, MoveKind, PathMode};
use crate::limits::Lim;
use crate::piece::Piece;
use crate::planner::junction_speed;
use crate::spline::{SPLINE_PIECES, SplineMaps, SplineP};

mod arc_blend;
mod compressor;
#[cfg(test)]
mod smoothing_tests;

/// The servo period at which a tangent junction's curvature step is judged, blended or passed:
/// the seeds' fastest servo period, 100 µs. The decision, and with it the path, does
/// not depend on the machine's period; at a longer period the step could be passed faster
/// than judged here, at most by the square root of the ratio.
pub(crate) const STEP_REFERENCE_PERIOD: f64 = 100e-6;
/// Lines the compressor holds back at most (see `builder/compressor.rs`).
pub(crate) const COMPRESSOR_LOOK: usize = compressor::LOOK;
/// Direction changes up to this angle (rad) count as tangent: passed without a blend, at a
/// speed that keeps the velocity step inside the jerk limit.
pub(crate) const KINK: f64 = 1e-4;
/// Largest direction change at a vertex that may be smoothed through (rad).
const SMOOTH_MAX_ANGLE: f64 = 0.35;
/// How much longer than its neighbour a line is taken as a straight the neighbour joins.
const LONG_LINE_RATIO: f64 = 6.0;
/// Share of the jerk the curvature change of a smoothing span may take at the feed for its
/// vertex state to be taken without weighing the others (the speed limit takes 80 %).
const SMOOTH_JERK_SHARE: f64 = 0.8;
/// Sagitta of a vertex's circle over its chords, as a share of P, from which the vertex
/// moved towards the circle's centre is weighed with the states through the vertex.
const APPROXIMATE_FROM: f64 = 0.5;
/// Feed taken for rapids when a corner's blend is weighed against a stop (mm/s).
const V_RAPID_REF: f64 = 1e3;
/// Longest run of collinear segments merged into one.
const MERGE_MAX: usize = 64;
/// Rounding allowed on an arc's radius difference beyond the caller's tolerance, relative
/// to the size of the coordinates (the kernel's offsets, rotation and unit conversion).
const ARC_RADIUS_ROUNDING: f64 = 1e-9;

#[derive(Debug, Clone, Copy)]
struct LineP {
    a: AxisVec,
    b: AxisVec,
    dir: AxisVec,
    len: f64,
    feed: f64,
    rapid: bool,
    mode: PathMode,
    line: u32,
}

// One primitive is held at a time, by value (a spline's tables are kept apart, in the builder).
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, Copy)]
enum Prim {
    Line(LineP),
    Arc {
        h: Helix,
        /// Start of the part not yet emitted (the arc's start, or where a corner blend
        /// left it), at parameter `u0` of `h`.
        a: AxisVec,
        u0: f64,
        b: AxisVec,
        feed: f64,
        mode: PathMode,
        line: u32,
    },
    Spline(SplineP),
}

impl Prim {
    fn mode(&self) -> PathMode {
        match self {
            Prim::Line(l) => l.mode,
            Prim::Arc { mode, .. } => *mode,
            Prim::Spline(sp) => sp.mode,
        }
    }
    fn end(&self) -> AxisVec {
        match self {
            Prim::Line(l) => l.b,
            Prim::Arc { b, .. } => *b,
            Prim::Spline(sp) => sp.end(),
        }
    }
    fn start_tangent(&self) -> AxisVec {
        match self {
            Prim::Line(l) => l.dir,
            Prim::Arc { h, u0, .. } => unit(&Shape::Helix(*h).eval(*u0).d1),
            Prim::Spline(sp) => sp.start_tangent(),
        }
    }
    fn end_tangent(&self) -> AxisVec {
        match self {
            Prim::Line(l) => l.dir,
            Prim::Arc { h, .. } => unit(&Shape::Helix(*h).eval(1.0).d1),
            Prim::Spline(sp) => sp.end_tangent(),
        }
    }
}

/// Where the remaining part of a line starts: point, unit tangent, curvature vector.
#[derive(Debug, Clone, Copy)]
struct State {
    p: AxisVec,
    t: AxisVec,
    k: AxisVec,
}

fn unit(v: &AxisVec) -> AxisVec {
    let n = norm(v);
    if n > 0.0 { scale(v, 1.0 / n) } else { *v }
}

/// Statistics of the geometry stage.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct GeometryStats {
    /// Moves accepted.
    pub moves: u64,
    /// Line segments merged away by the collinear tolerance.
    pub merged: u64,
    /// Corners rounded by a blend curve.
    pub blends: u64,
    /// Vertices passed through by a smoothing span.
    pub smoothed: u64,
    /// Exact stops inserted.
    pub stops: u64,
    /// Smoothing spans that could not be kept within the blend tolerance (see docs).
    pub tolerance_exceeded: u64,
    /// Smoothed vertices whose curvature was reduced to keep the span within P.
    pub curvature_backoffs: u64,
    /// Smoothed vertices that took the compressor's fitted state.
    pub compressed: u64,
}

#[derive(Clone)]
pub(crate) struct Builder {
    pub pos: AxisVec,
    /// The line being merged (G64 Q) and how many inner vertices it has ...
    run: Option<(LineP, usize)>,
    /// ... held here, out of the option (moved on every push otherwise).
    run_vertices: [AxisVec; MERGE_MAX],
    prev: Option<Prim>,
    prev_state: Option<State>,
    /// The polyline point before the last smoothed vertex, and that vertex: `smooth_state`
    /// at the next vertex takes the curvature change from their circle and its own.
    smoothed_from: Option<(AxisVec, AxisVec)>,
    /// The held-back primitive was entered at speed through a tangent junction (no state
    /// carried over, yet not from rest).
    tangent_in: bool,
    /// Turn (outgoing minus incoming direction) of the vertex decided last, when it joined
    /// two lines in G64 P: a vertex is approximated only where the polyline bends the same
    /// way at the vertex before (a sampled curve, not a zigzag) or follows a stop.
    last_turn: Option<AxisVec>,
    /// Tables of the held-back spline and of a new one (`SplineP::slot`).
    spline_maps: [SplineMaps; 2],
    /// Lines held back by the compressor, and the state it fitted at the vertex that
    /// `vertex_stage` decides next.
    comp: compressor::Compressor,
    hint: Option<State>,
    pub stats: GeometryStats,
}

impl Builder {
    pub fn new(pos: AxisVec) -> Builder {
        Builder {
            pos,
            run: None,
            run_vertices: [[0.0; AXES]; MERGE_MAX],
            prev: None,
            prev_state: None,
            smoothed_from: None,
            tangent_in: false,
            last_turn: None,
            spline_maps: [[(ArcMap::Linear { k: 1.0 }, 0.0); SPLINE_PIECES]; 2],
            comp: compressor::Compressor::new(),
            hint: None,
            stats: GeometryStats::default(),
        }
    }

    pub fn clear(&mut self, pos: AxisVec) {
        self.pos = pos;
        self.run = None;
        self.prev = None;
        self.prev_state = None;
        self.smoothed_from = None;
        self.tangent_in = false;
        self.last_turn = None;
        self.comp.clear();
        self.hint = None;
    }

    /// Validates `mv` and feeds it through; finished pieces go to `out`.
    pub fn push(&mut self, mv: &Move, lim: &Lim, out: &mut Vec<Piece>) -> Result<(), MotionError> {
        let prim = self.validate(mv, lim)?;
        self.stats.moves += 1;
        match prim {
            None => {
                // Dwell.
                let MoveKind::Dwell { seconds } = mv.kind else {
                    return Ok(());
                };
                self.flush(lim, out);
                out.push(Piece::dwell(self.pos, seconds, mv.line));
                Ok(())
            }
            Some(p) => {
                self.pos = p.end();
                self.merge_stage(p, lim, out);
                Ok(())
            }
        }
    }

    /// Emits everything held back; the path stops at its end.
    pub fn flush(&mut self, lim: &Lim, out: &mut Vec<Piece>) {
        if let Some((l, _)) = self.run.take() {
            self.compress_stage(Prim::Line(l), lim, out);
        }
        self.release_run(lim, out);
        if let Some(prev) = self.prev.take() {
            let st = self.prev_state.take();
            self.emit_prim_to_end(&prev, st, true, lim, out);
        }
        self.prev_state = None;
        self.tangent_in = false;
    }

    fn validate(&mut self, mv: &Move, lim: &Lim) -> Result<Option<Prim>, MotionError> {
        let line = mv.line;
        let a = self.pos;
        match mv.mode {
            PathMode::Blend {
                tolerance,
                merge_tolerance,
            } => {
                for t in [tolerance, merge_tolerance] {
                    if !(t.is_finite() && t >= 0.0) {
                        return Err(MotionError::InvalidTolerance { line, value: t });
                    }
                }
            }
            PathMode::ExactPath | PathMode::ExactStop => {}
        }
        let (b, rapid) = match mv.kind {
            MoveKind::Dwell { seconds } => {
                if !(seconds.is_finite() && seconds >= 0.0) {
                    return Err(MotionError::NotFinite {
                        line,
                        what: "dwell time",
                    });
                }
                return Ok(None);
            }
            MoveKind::Line { end, rapid } => (end, rapid),
            MoveKind::Arc { end, .. } | MoveKind::Spline { end, .. } => (end, false),
        };
        if !is_finite(&b) {
            return Err(MotionError::NotFinite {
                line,
                what: "end point",
            });
        }
        for i in 0..AXES {
            if !lim.present[i] && b[i] != a[i] {
                return Err(MotionError::SoftLimit {
                    line,
                    axis: Axis::ALL[i].letter(),
                    position: b[i],
                    min: a[i],
                    max: a[i],
                });
            }
        }
        check_point(&b, lim, line)?;
        let d = sub(&b, &a);
        match mv.kind {
            MoveKind::Line { .. } => {
                let len = norm(&d);
                if !(len > 1e-12) {
                    return Err(MotionError::ZeroLength { line });
                }
                let feed = if rapid {
                    f64::INFINITY
                } else {
                    resolve_feed(&mv.feed, norm_xyz(&d), len, line)?
                };
                Ok(Some(Prim::Line(LineP {
                    a,
                    b,
                    dir: scale(&d, 1.0 / len),
                    len,
                    feed,
                    rapid,
                    mode: mv.mode,
                    line,
                })))
            }
            MoveKind::Arc {
                centre,
                normal,
                turns,
                radius_tolerance,
                ..
            } => {
                if !(centre.iter().all(|x| x.is_finite()) && normal.iter().all(|x| x.is_finite())) {
                    return Err(MotionError::NotFinite {
                        line,
                        what: "arc centre or normal",
                    });
                }
                if !(radius_tolerance.is_finite() && radius_tolerance >= 0.0) {
                    return Err(MotionError::InvalidTolerance {
                        line,
                        value: radius_tolerance,
                    });
                }
                let h = make_helix(&a, &b, centre, normal, turns, radius_tolerance, line)?;
                let shape = Shape::Helix(h);
                // A spiral's parametric speed changes with the radius: its length from the
                // arc-length table, the XYZ share from the start.
                let len = if h.dr == 0.0 {
                    shape.speed(0.0)
                } else {
                    ArcMap::table(&shape).1
                };
                let len_xyz = {
                    let d1 = shape.eval(0.0).d1;
                    len * norm_xyz(&d1) / norm(&d1)
                };
                let feed = resolve_feed(&mv.feed, len_xyz, len, line)?;
                check_helix_extent(&h, &a, &b, lim, line)?;
                Ok(Some(Prim::Arc {
                    h,
                    a,
                    u0: 0.0,
                    b,
                    feed,
                    mode: mv.mode,
                    line,
                }))
            }
            MoveKind::Spline { control, .. } => {
                // The held-back primitive is the only other spline alive.
                let slot = match &self.prev {
                    Some(Prim::Spline(held)) => 1 - held.slot,
                    _ => 0,
                };
                let maps = &mut self.spline_maps[slot];
                let mut sp = SplineP::new(&a, &b, &control, mv.mode, line, lim, maps, slot)?;
                sp.feed = resolve_feed(&mv.feed, sp.len_xyz, sp.len, line)?;
                Ok(Some(Prim::Spline(sp)))
            }
            MoveKind::Dwell { .. } => Ok(None),
        }
    }

    /// G64 Q: merges consecutive feed lines whose inner vertices stay within Q of one line.
    fn merge_stage(&mut self, p: Prim, lim: &Lim, out: &mut Vec<Piece>) {
        let (q, p_tol) = match p.mode() {
            PathMode::Blend {
                merge_tolerance,
                tolerance,
            } if merge_tolerance > 0.0 => (merge_tolerance, tolerance),
            _ => (0.0, 0.0),
        };
        let Prim::Line(l) = p else {
            if let Some((r, _)) = self.run.take() {
                self.compress_stage(Prim::Line(r), lim, out);
            }
            self.compress_stage(p, lim, out);
            return;
        };
        if q <= 0.0 || l.rapid {
            if let Some((r, _)) = self.run.take() {
                self.compress_stage(Prim::Line(r), lim, out);
            }
            self.compress_stage(p, lim, out);
            return;
        }
        if let Some((mut r, mut n)) = self.run.take() {
            let pts = &mut self.run_vertices;
            let compatible = r.mode == l.mode && r.feed == l.feed && n < MERGE_MAX;
            if compatible {
                // Candidate merged line r.a -> l.b; every inner vertex (pts[..n] and r.b) within q.
                let d = sub(&l.b, &r.a);
                let len = norm(&d);
                if len > 0.0 {
                    let dir = scale(&d, 1.0 / len);
                    let offset = |x: &AxisVec| {
                        let w = sub(x, &r.a);
                        let along = dot(&w, &dir);
                        (along, add_scaled(&w, &dir, -along))
                    };
                    let within = |x: &AxisVec| {
                        let (along, perp) = offset(x);
                        along > 0.0 && along < len && norm(&perp) <= q
                    };
                    // Inner vertices all on one side of the merged line: the run follows
                    // a curve, and the smoothing of the merged vertices must still bulge
                    // within P beyond the merged chord, which cuts the curve by the
                    // vertices' distance: they may be at most 0.85 P away (merging half
                    // of a circle's 0.27 mm chords at Q = P = 0.01, 0.0097 mm from the
                    // merged chords, made a trochoidal clearing 3.2 × LinuxCNC's time,
                    // 1.22 × without; merges 0.0065 mm off at P 0.01 still pay, 1.13 ×
                    // without, 1.01 × with; measured on the families of
                    // bench/cam_like.py). Vertices scattered about a line merge within Q.
                    let (_, side) = offset(&r.b);
                    let inner = || pts[..n].iter().chain([&r.b]);
                    let curve = inner().all(|x| dot(&offset(x).1, &side) > 0.0);
                    let close = inner().all(|x| norm(&offset(x).1) <= 0.85 * p_tol);
                    if (!curve || close)
                        && pts[..n].iter().all(within)
                        && within(&r.b)
                        && dot(&r.dir, &l.dir) > 0.0
                    {
                        pts[n] = r.b;
                        n += 1;
                        r.b = l.b;
                        r.dir = dir;
                        r.len = len;
                        self.stats.merged += 1;
                        self.run = Some((r, n));
                        return;
                    }
                }
            }
            self.compress_stage(Prim::Line(r), lim, out);
        }
        self.run = Some((l, 0));
    }

    /// The compressor (`builder/compressor.rs`): holds a run of short feed lines back
    /// so that each inner vertex gets the state of a curve fitted over its neighbours;
    /// anything else ends the run and goes on at once.
    fn compress_stage(&mut self, p: Prim, lim: &Lim, out: &mut Vec<Piece>) {
        if let Prim::Line(l) = p
            && compressor::Compressor::eligible(&l)
        {
            if !self.comp.continues(&l) {
                self.release_run(lim, out);
            }
            self.comp.hold(l);
            if self.comp.full()
                && let Some((line, hint)) = self.comp.pop()
            {
                self.hint = hint;
                self.vertex_stage(Prim::Line(line), lim, out);
            }
            return;
        }
        self.release_run(lim, out);
        self.vertex_stage(p, lim, out);
    }

    /// Passes on every line the compressor holds; the run ends.
    fn release_run(&mut self, lim: &Lim, out: &mut Vec<Piece>) {
        while let Some((line, hint)) = self.comp.pop() {
            self.hint = hint;
            self.vertex_stage(Prim::Line(line), lim, out);
        }
        self.comp.end_run();
    }

    /// Decides the junction between the held-back primitive and `cur`, emits the held-back
    /// one up to that junction and holds `cur`.
    fn vertex_stage(&mut self, cur: Prim, lim: &Lim, out: &mut Vec<Piece>) {
        let hint = self.hint.take();
        let entered_tangent = std::mem::take(&mut self.tangent_in);
        let turn_before = self.last_turn.take();
        let Some(prev) = self.prev.take() else {
            self.prev = Some(cur);
            self.prev_state = None;
            return;
        };
        let st = self.prev_state.take();
        let t_in = prev.end_tangent();
        let t_out = cur.start_tangent();
        let cos = dot(&t_in, &t_out).clamp(-1.0, 1.0);
        let theta = cos.acos();
        let mode = prev.mode();
        let stop = |this: &mut Builder, out: &mut Vec<Piece>| {
            this.stats.stops += 1;
            this.emit_prim_to_end(&prev, st, true, lim, out);
        };
        match mode {
            PathMode::ExactStop => stop(self, out),
            _ if theta <= KINK => {
                if let Some((next, next_state)) =
                    self.blend_curvature_step(&prev, st, &cur, lim, out)
                {
                    self.tangent_in = true;
                    self.prev = Some(next);
                    self.prev_state = next_state;
                    return;
                }
                self.emit_prim_to_end(&prev, st, false, lim, out);
                self.tangent_in = true;
                self.prev = Some(cur);
                self.prev_state = None;
                return;
            }
            PathMode::ExactPath => stop(self, out),
            PathMode::Blend { tolerance, .. } => {
                let (Prim::Line(lp), Prim::Line(lc)) = (prev, cur) else {
                    // A corner where an arc meets a line or another arc.
                    if theta <= 170f64.to_radians() && tolerance > 0.0 {
                        if let Some((next, next_state)) =
                            self.arc_corner(&prev, st, &cur, tolerance, lim, out)
                        {
                            self.prev = Some(next);
                            self.prev_state = next_state;
                            return;
                        }
                    }
                    stop(self, out);
                    self.prev = Some(cur);
                    return;
                };
                if theta > 170f64.to_radians() || tolerance <= 0.0 {
                    stop(self, out);
                } else {
                    let turn = sub(&lc.dir, &lp.dir);
                    self.last_turn = Some(turn);
                    let vx = LineVertex {
                        lp,
                        st,
                        lc,
                        theta,
                        tolerance,
                        turn,
                        turn_before,
                        entered_tangent,
                    };
                    // The compressor's fitted state, else smoothing through the vertex
                    // (dense CAM polylines), else a corner blend, else a stop.
                    if let Some(vk) = self.smooth_vertex(&vx, lim, out) {
                        self.prev = Some(cur);
                        self.prev_state = Some(vk);
                        self.smoothed_from = Some((lp.a, lp.b));
                        return;
                    }
                    if let Some(vk) = hint.and_then(|h| self.fitted_vertex(&vx, h, lim, out)) {
                        self.prev = Some(cur);
                        self.prev_state = Some(vk);
                        self.smoothed_from = None;
                        return;
                    }
                    if let Some(vs) =
                        self.onto_long_line(&lp, &lc, theta, tolerance, st.as_ref(), lim, out)
                    {
                        self.prev = Some(cur);
                        self.prev_state = Some(vs);
                        return;
                    }
                    self.prev_state = self.blend_corner(&vx, &prev, lim, out);
                    self.prev = Some(cur);
                    return;
                }
            }
        }
        self.prev = Some(cur);
        self.prev_state = None;
    }

    /// In G64 P, a tangent junction where the curvature steps and the step would be passed
    /// below the feed is rounded by a blend within P (see `arc_blend::tangent_corner`). The
    /// step's speed is taken at [`STEP_REFERENCE_PERIOD`], not at the servo period, so that
    /// the path is the same whatever the period.
    fn blend_curvature_step(
        &mut self,
        prev: &Prim,
        st: Option<State>,
        cur: &Prim,
        lim: &Lim,
        out: &mut Vec<Piece>,
    ) -> Option<(Prim, Option<State>)> {
        let PathMode::Blend { tolerance, .. } = prev.mode() else {
            return None;
        };
        if tolerance <= 0.0 || matches!((prev, cur), (Prim::Line(_), Prim::Line(_))) {
            return None;
        }
        let (k_in, k_out) = arc_blend::junction_curvatures(prev, cur);
        let dt = sub(&cur.start_tangent(), &prev.end_tangent());
        let v_pass = junction_speed(&dt, &sub(&k_out, &k_in), lim, STEP_REFERENCE_PERIOD);
        let feed = arc_blend::feed_of(prev).min(arc_blend::feed_of(cur));
        if v_pass >= feed {
            return None;
        }
        self.tangent_corner(prev, st, cur, tolerance, v_pass, lim, out)
    }

    /// Smoothing through the vertex between two short lines (dense CAM polylines): the
    /// span of `lp` up to a state at the vertex from the circle through three points,
    /// tried with that state and weaker ones, then (where the polyline bends the same way
    /// as at the vertex before) with the vertex moved towards the circle's centre. The
    /// vertex's state when a span was emitted; None when the vertex does not qualify or no
    /// span stays within P.
    fn smooth_vertex(&mut self, vx: &LineVertex, lim: &Lim, out: &mut Vec<Piece>) -> Option<State> {
        let LineVertex {
            lp,
            st,
            lc,
            theta,
            tolerance,
            turn,
            turn_before,
            entered_tangent,
        } = *vx;
        let vs = self.smooth_state(&lp, &lc, theta, tolerance, st.as_ref())?;
        let start = st.unwrap_or(State {
            p: lp.a,
            t: lp.dir,
            k: [0.0; AXES],
        });
        // The vertex curvature comes from the circle through three points;
        // a slightly smaller one keeps a span that bulges too far within P.
        // After a vertex that kept the circle's tangent (the first after a
        // stop), the span to the corrected tangent may bulge too far; one
        // halfway between recovers within a vertex or two.
        let (vs, t_plain) = vs;
        let t_half = unit(&add_scaled(&vs.t, &t_plain, 1.0));
        let cands = [
            (vs.t, 1.0),
            (t_half, 1.0),
            (vs.t, 0.95),
            (vs.t, 0.85),
            (t_plain, 1.0),
            (t_plain, 0.7),
            (t_plain, 0.3),
            // Weighed only when one of the above keeps P: where none does, the vertex
            // moves towards the circle's centre (below), which keeps the circle's speed.
            (vs.t, 0.7),
            (vs.t, 1.15),
            (t_half, 0.85),
            (t_half, 1.15),
            (vs.t, 0.5),
            (vs.t, 0.3),
            (t_half, 0.5),
        ];
        const FIRST_CANDIDATES: usize = 7;
        // Of the candidates that keep P, the one whose span changes its curvature least
        // (that bounds the speed, v³·|dK/ds| within the jerk): on a CAM polyline whose
        // discrete curvature jitters, the circle's state makes the span's curvature swing
        // between its ends. The first candidate is taken at once when that bound is above
        // the feed (as on a sampled curve).
        let j_path = lim
            .present_axes()
            .iter()
            .fold(f64::INFINITY, |m, &i| m.min(lim.j[i]));
        let mut best: Option<(f64, Span, State, f64)> = None;
        for (n, (tv, scale_k)) in cands.into_iter().enumerate() {
            if n == FIRST_CANDIDATES && best.is_none() {
                break;
            }
            let nrm = add_scaled(&vs.k, &tv, -dot(&vs.k, &tv));
            let vk = State {
                p: vs.p,
                t: tv,
                k: scale(&nrm, scale_k),
            };
            // After a stop the run may start already curved, like the arc
            // the polyline follows (mirror of the vertex state).
            // After a tangent junction passed at speed only where the
            // curved start turns less than a kink from the line's own
            // direction: a larger turn is a step of the tangent that forced
            // a stop there (a plain-G64 raster took 2.2 × LinuxCNC's time).
            let m = mirror(&vk, &lp.a, &lp.dir);
            let turn = dot(&m.t, &lp.dir).clamp(-1.0, 1.0).acos();
            let curved_start = if st.is_none() && (!entered_tangent || turn <= KINK) {
                span(&lp, &m, &vk, tolerance, lim)
            } else {
                None
            };
            let Some(pc) = curved_start.or_else(|| span(&lp, &start, &vk, tolerance, lim)) else {
                continue;
            };
            let change = curvature_change(&pc);
            let at_feed = change * lp.feed.powi(3) <= SMOOTH_JERK_SHARE * j_path;
            if best.is_none() && at_feed {
                best = Some((change, pc, vk, scale_k));
                break;
            }
            if best.as_ref().is_none_or(|b| change < b.0 * (1.0 - 1e-3)) {
                best = Some((change, pc, vk, scale_k));
            }
        }
        // Through the vertex the circle bulges beyond the chords by its
        // sagitta; moved towards the centre by up to P it bulges less and
        // cuts the vertex by as much: the curve approximates the polyline
        // (as COMPCAD's), twice the sagitta the interpolating one keeps.
        let kappa = norm(&vs.k);
        let sagitta = 0.125 * kappa * lp.len.max(lc.len).powi(2);
        // (The first vertex after a stop has nothing to alternate with.)
        let curve = match turn_before {
            Some(b) => dot(&b, &turn) > 0.0,
            None => st.is_none(),
        };
        let moved = |shift: f64| {
            let nrm = scale(&vs.k, 1.0 / kappa);
            State {
                p: add_scaled(&vs.p, &nrm, shift),
                t: vs.t,
                k: scale(&nrm, kappa / (1.0 - kappa * shift).max(0.5)),
            }
        };
        if let Some((change, ..)) = best
            && kappa > 0.0
            && curve
            && sagitta >= APPROXIMATE_FROM * tolerance
            && change * lp.feed.powi(3) > SMOOTH_JERK_SHARE * j_path
        {
            // Chords that bulge nearly as far as P (a curve sampled at the tolerance
            // P, as CAM systems write it) keep P only with a vertex state weaker than
            // the circle's, whose span's curvature swings between its ends (0.38-0.57
            // /mm on a rose's 2 mm tip, passed at 23 mm/s where its curvature allows
            // 47): the concentric circle through the moved vertex changes its
            // curvature less, and is weighed with them.
            let vk = moved(0.5 * sagitta);
            if let Some(pc) = span(&lp, &start, &vk, tolerance, lim) {
                let moved_change = curvature_change(&pc);
                if moved_change < change * (1.0 - 1e-3) {
                    best = Some((moved_change, pc, vk, 1.0));
                }
            }
        }
        if let Some((_, pc, vk, scale_k)) = best {
            out.push(pc.piece());
            self.stats.smoothed += 1;
            if scale_k < 1.0 {
                self.stats.curvature_backoffs += 1;
            }
            return Some(vk);
        }
        if kappa > 0.0 && curve {
            for shift in [0.5 * sagitta, 0.6 * tolerance, 0.9 * tolerance] {
                let shift = shift.min(0.9 * tolerance);
                if shift <= 1e-6 {
                    continue;
                }
                let vk = moved(shift);
                if let Some(pc) = span(&lp, &start, &vk, tolerance, lim) {
                    out.push(pc.piece());
                    self.stats.smoothed += 1;
                    return Some(vk);
                }
            }
        }
        None
    }

    /// The span of `lp` into the state the compressor fitted at its end vertex, where it
    /// keeps P and `lc` can straighten out of it within P (into its end, or its middle,
    /// where a corner blend at its end starts at the latest), so that whatever the next
    /// vertex becomes the path keeps P: that state (None: nothing pushed).
    fn fitted_vertex(
        &mut self,
        vx: &LineVertex,
        fitted: State,
        lim: &Lim,
        out: &mut Vec<Piece>,
    ) -> Option<State> {
        let LineVertex {
            lp,
            st,
            lc,
            tolerance,
            ..
        } = *vx;
        if norm(&sub(&fitted.p, &lp.b)) > tolerance {
            return None;
        }
        let straight_at = |p: AxisVec| State {
            p,
            t: lc.dir,
            k: [0.0; AXES],
        };
        let middle = add_scaled(&lc.a, &lc.dir, 0.5 * lc.len);
        for end in [lc.b, middle] {
            if !straightens(&lc, &fitted, &straight_at(end), tolerance, lim) {
                return None;
            }
        }
        let start = st.unwrap_or(State {
            p: lp.a,
            t: lp.dir,
            k: [0.0; AXES],
        });
        let pc = span(&lp, &start, &fitted, tolerance, lim)?;
        out.push(pc.piece());
        self.stats.smoothed += 1;
        self.stats.compressed += 1;
        Some(fitted)
    }

    /// Corner blend at the vertex between two lines, where it is estimated to take no
    /// longer than a stop: the state after the blend. Else the held-back line `prev` ends
    /// in a stop at the vertex (None).
    fn blend_corner(
        &mut self,
        vx: &LineVertex,
        prev: &Prim,
        lim: &Lim,
        out: &mut Vec<Piece>,
    ) -> Option<State> {
        let LineVertex {
            lp,
            st,
            lc,
            theta,
            tolerance,
            ..
        } = *vx;
        let v = lp.b;
        // Corner blend: its middle, at CORNER_MIDDLE·d·sin(θ/2) from the
        // corner, is cos(θ/2) of that from both lines.
        let d = (tolerance / (CORNER_MIDDLE * (0.5 * theta).sin() * (0.5 * theta).cos()))
            .min(0.5 * lp.len)
            .min(0.5 * lc.len);
        if d <= 1e-9 {
            self.stats.stops += 1;
            self.emit_prim_to_end(prev, st, true, lim, out);
            None
        } else {
            let p0 = add_scaled(&v, &lp.dir, -d);
            let p3 = add_scaled(&v, &lc.dir, d);
            let end_state = State {
                p: p0,
                t: lp.dir,
                k: [0.0; AXES],
            };
            let start = st.unwrap_or(State {
                p: lp.a,
                t: lp.dir,
                k: [0.0; AXES],
            });
            let first = self.span_or_exceed(&lp, &start, &end_state, tolerance, lim);
            let shape = corner_blend(&v, &lp.dir, &lc.dir, d);
            let mut b = Piece::new(
                shape,
                p0,
                p3,
                lp.feed.min(lc.feed),
                lp.rapid && lc.rapid,
                lp.line,
            );
            b.stop_at_end = false;
            b.corner_blend = true;
            // Blend only where that is estimated to take no longer than a
            // stop (a tiny tolerance on a sharp corner makes a crawl).
            b.sample(lim);
            let v_blend = b.smp[..=b.ns]
                .iter()
                .fold(f64::INFINITY, |m, x| m.min(x.v_curve));
            let h = b.len / b.ns as f64;
            let feed = lp.feed.min(lc.feed);
            let pass_time = b.smp[..=b.ns]
                .windows(2)
                .map(|w| h / w[0].v_curve.min(w[1].v_curve).min(feed))
                .sum();
            let choice = arc_blend::CornerChoice {
                feed,
                feeds: [lp.feed, lc.feed],
                v_blend,
                blend_len: b.len,
                pass_time,
                replaced_len: 2.0 * d,
                reach: norm(&sub(&lp.b, &start.p)).min(lc.len),
                t_in: lp.dir,
                t_out: lc.dir,
            };
            if !choice.blend_pays(lim) {
                self.stats.stops += 1;
                self.emit_prim_to_end(prev, st, true, lim, out);
                return None;
            }
            for pc in first.iter().flatten() {
                out.push(pc.piece());
            }
            out.push(b);
            self.stats.blends += 1;
            Some(State {
                p: p3,
                t: lc.dir,
                k: [0.0; AXES],
            })
        }
    }

    /// A short chord meeting a much longer line at a small turn (where a curved run of a
    /// CAM polyline joins a straight): the vertex takes the long line's direction with zero
    /// curvature, so that the short chord bends onto (or off) the line within P and the
    /// line needs no corner blend. The alternative, a blend on top of a span that must
    /// straighten within half the short chord, peaks in curvature change there (FreeCAD's
    /// adaptive clearing slowed to 10-14 mm/s at each such join, LinuxCNC 33).
    /// Returns the vertex state after pushing the piece before it, or None (nothing pushed).
    #[allow(clippy::too_many_arguments)]
    fn onto_long_line(
        &mut self,
        lp: &LineP,
        lc: &LineP,
        theta: f64,
        tol: f64,
        before: Option<&State>,
        lim: &Lim,
        out: &mut Vec<Piece>,
    ) -> Option<State> {
        if lp.rapid || lc.rapid || theta > SMOOTH_MAX_ANGLE || theta <= KINK {
            return None;
        }
        let start = before.copied().unwrap_or(State {
            p: lp.a,
            t: lp.dir,
            k: [0.0; AXES],
        });
        let dir = if lc.len >= LONG_LINE_RATIO * lp.len {
            lc.dir
        } else if lp.len >= LONG_LINE_RATIO * lc.len {
            lp.dir
        } else {
            return None;
        };
        let vs = State {
            p: lp.b,
            t: dir,
            k: [0.0; AXES],
        };
        let into = span(lp, &start, &vs, tol, lim)?;
        // Off a long line the short chord must be able to straighten again by its end (the
        // next vertex may not be smoothed), within P.
        if dir == lp.dir {
            let end = State {
                p: lc.b,
                t: lc.dir,
                k: [0.0; AXES],
            };
            span(lc, &vs, &end, tol, lim)?;
        }
        out.push(into.piece());
        self.stats.smoothed += 1;
        self.smoothed_from = None;
        Some(vs)
    }

    /// Tangent and curvature at the vertex between two short lines, from the circle through
    /// the three points, when the vertex qualifies for smoothing.
    fn smooth_state(
        &self,
        lp: &LineP,
        lc: &LineP,
        theta: f64,
        tol: f64,
        before: Option<&State>,
    ) -> Option<(State, AxisVec)> {
        if lp.rapid || lc.rapid || theta > SMOOTH_MAX_ANGLE || theta <= KINK {
            return None;
        }
        let (la, lb) = (lp.len, lc.len);
        if la > 6.0 * lb || lb > 6.0 * la || la.max(lb) * theta > 30.0 * tol {
            return None;
        }
        let a = sub(&lp.b, &lp.a);
        let b = sub(&lc.b, &lc.a);
        let (t, k) = circle_state(&a, &b, la, lb);
        let t_plain = t;
        // The circle's curvature is the curve's at (lb − la)/3 from the vertex and its
        // tangent is off by κ'·la·lb/6 where the curvature changes. Following a smoothed
        // vertex, κ' is the change between the two vertices' circles over the distance
        // between those points, (l0 + la + lb)/3; both are corrected with it (exact on a
        // circle; to first order in κ' elsewhere, as across an inflection between
        // unequal chords).
        if let (Some(prev), Some((q0, at))) = (before, self.smoothed_from) {
            let l0 = norm(&sub(&lp.a, &q0));
            if at == lp.a && prev.p == lp.a && l0 <= 6.0 * la && la <= 6.0 * l0 {
                let (_, k0) = circle_state(&sub(&lp.a, &q0), &a, l0, la);
                let dk = scale(&sub(&k, &k0), 3.0 / (l0 + la + lb));
                let t = unit(&add_scaled(&t, &dk, -la * lb / 6.0));
                let k = add_scaled(&k, &dk, -(lb - la) / 3.0);
                let k = add_scaled(&k, &t, -dot(&k, &t));
                return Some((State { p: lp.b, t, k }, t_plain));
            }
        }
        // Otherwise κ' comes from the state the run arrives with (signed along this normal).
        let kappa = norm(&k);
        let nrm = unit(&k);
        let t = match before {
            Some(prev) if norm(&prev.k) > 0.0 => {
                let kp = (kappa - dot(&prev.k, &nrm)) / la;
                unit(&add_scaled(&t, &nrm, -kp * la * lb / 6.0))
            }
            _ => t,
        };
        let nrm = unit(&add_scaled(&nrm, &t, -dot(&nrm, &t)));
        Some((
            State {
                p: lp.b,
                t,
                k: scale(&nrm, kappa),
            },
            t_plain,
        ))
    }

    /// A span that must exist (the path has to be continuous): when the smoothing span
    /// from a smoothed vertex to a line state exceeds the tolerance, it is still used and
    /// counted in `tolerance_exceeded`.
    fn span_or_exceed(
        &mut self,
        l: &LineP,
        s0: &State,
        s1: &State,
        tol: f64,
        lim: &Lim,
    ) -> [Option<Span>; 2] {
        if let Some(p) = span(l, s0, s1, tol, lim) {
            return [Some(p), None];
        }
        // Into a straight end: a shorter span out of the curved start bulges less; the rest
        // of the segment is a line.
        let straight1 = dot(&s1.t, &l.dir) >= 1.0 - 1e-15 && norm(&s1.k) == 0.0;
        if straight1 {
            for frac in [0.5, 0.25, 0.125] {
                let q = State {
                    p: add_scaled(&s0.p, &sub(&s1.p, &s0.p), frac),
                    t: l.dir,
                    k: [0.0; AXES],
                };
                if let (Some(a), Some(b)) = (span(l, s0, &q, tol, lim), span(l, &q, s1, tol, lim)) {
                    return [Some(a), Some(b)];
                }
            }
        }
        let p = span(l, s0, s1, f64::INFINITY, lim);
        if p.is_some() {
            self.stats.tolerance_exceeded += 1;
        }
        [p, None]
    }

    fn emit_prim_to_end(
        &mut self,
        prev: &Prim,
        st: Option<State>,
        stop: bool,
        lim: &Lim,
        out: &mut Vec<Piece>,
    ) {
        match prev {
            Prim::Line(l) => {
                let start = st.unwrap_or(State {
                    p: l.a,
                    t: l.dir,
                    k: [0.0; AXES],
                });
                let end = State {
                    p: l.b,
                    t: l.dir,
                    k: [0.0; AXES],
                };
                let tol = match l.mode {
                    PathMode::Blend { tolerance, .. } => tolerance,
                    _ => f64::INFINITY,
                };
                // Into a stop, a curved run may end curved (mirror of its start state).
                let curved_end = if stop && norm(&start.k) > 0.0 && tol.is_finite() {
                    span(l, &start, &mirror(&start, &l.b, &l.dir), tol, lim)
                } else {
                    None
                };
                let pieces = match curved_end {
                    Some(p) => [Some(p), None],
                    None => self.span_or_exceed(l, &start, &end, tol, lim),
                };
                for pc in pieces.iter().flatten() {
                    out.push(pc.piece());
                }
                if let Some(last) = out.last_mut() {
                    last.stop_at_end |= stop;
                }
            }
            Prim::Arc {
                h,
                a,
                u0,
                b,
                feed,
                line,
                ..
            } => {
                let h = if *u0 > 0.0 { h.sub(*u0, 1.0) } else { *h };
                let mut pc = Piece::new(Shape::Helix(h), *a, *b, *feed, false, *line);
                pc.stop_at_end = stop;
                out.push(pc);
            }
            Prim::Spline(sp) => sp.emit(&self.spline_maps[sp.slot], stop, out),
        }
    }
}

/// Whether [`Builder::span_or_exceed`] finds a span of `l` from `s0` into the straight
/// state `s1` within `tol` (without counting an excess).
fn straightens(l: &LineP, s0: &State, s1: &State, tol: f64, lim: &Lim) -> bool {
    if span(l, s0, s1, tol, lim).is_some() {
        return true;
    }
    [0.5, 0.25, 0.125].iter().any(|&frac| {
        let q = State {
            p: add_scaled(&s0.p, &sub(&s1.p, &s0.p), frac),
            t: l.dir,
            k: [0.0; AXES],
        };
        span(l, s0, &q, tol, lim).is_some() && span(l, &q, s1, tol, lim).is_some()
    })
}

/// The piece of line `l` from state `s0` to state `s1`: a line when both states lie on the
/// line's direction with zero curvature, else a quintic whose distance from the line is
/// checked against `tol` (None when it exceeds it or the span is empty).
fn span(l: &LineP, s0: &State, s1: &State, tol: f64, lim: &Lim) -> Option<Span> {
    let d = sub(&s1.p, &s0.p);
    let lc = norm(&d);
    if lc <= 1e-12 {
        return None;
    }
    // A state moved off the segment (an approximating vertex): the distance is measured
    // to the segment itself, and no span from or to it is a straight line.
    let off = |p: &AxisVec| {
        let w = sub(p, &l.a);
        norm(&add_scaled(&w, &l.dir, -dot(&w, &l.dir))) > 1e-9
    };
    let off_line = off(&s0.p) || off(&s1.p);
    let straight0 = !off_line && dot(&s0.t, &l.dir) >= 1.0 - 1e-15 && norm(&s0.k) == 0.0;
    let straight1 = !off_line && dot(&s1.t, &l.dir) >= 1.0 - 1e-15 && norm(&s1.k) == 0.0;
    if straight0 && straight1 {
        let dir = scale(&d, 1.0 / lc);
        return Some(Span {
            shape: Shape::Line { start: s0.p, dir },
            a: s0.p,
            b: s1.p,
            feed: l.feed,
            rapid: l.rapid,
            line: l.line,
        });
    }
    // Parameter length: arc length of the circular arc over the chord, from the mean curvature.
    let kap = 0.5 * (norm(&s0.k) + norm(&s1.k));
    let half = (0.5 * kap * lc).min(0.99);
    let lp = if half > 1e-12 {
        lc * half.asin() / half
    } else {
        lc
    };
    let dir = scale(&d, 1.0 / lc);
    // What the distance is measured to: the chord (it lies on the segment), or the
    // segment when an end is off it.
    let (origin, axis, range) = if off_line {
        (l.a, l.dir, l.len)
    } else {
        (s0.p, dir, lc)
    };
    // The middle sample first, on its own (where a span that bulges too far peaks, between
    // two vertices of similar curvature): a span already beyond the tolerance there is
    // refused before the quintic is built. The same arithmetic as the check of all samples
    // below, so the same decision (the peak estimate there is at least every sample's
    // distance); over the axes whose end states differ, a superset of the axes moved,
    // where the others add exact zeros.
    let lp2 = lp * lp;
    if lp.is_finite() && middle_deviation(s0, s1, &origin, &axis, range, lp) > tol * (1.0 - 1e-3) {
        return None;
    }
    let shape = quintic(
        &s0.p,
        &scale(&s0.t, lp),
        &scale(&s0.k, lp2),
        &s1.p,
        &scale(&s1.t, lp),
        &scale(&s1.k, lp2),
    );
    let Shape::Poly { c } = &shape else {
        unreachable!("quintic() builds a polynomial")
    };
    let (max_dev, outside) = sampled_deviation(c, &origin, &axis, range, lim);
    if max_dev > tol * (1.0 - 1e-3) || (outside && tol.is_finite()) {
        return None;
    }
    Some(Span {
        shape,
        a: s0.p,
        b: s1.p,
        feed: l.feed,
        rapid: false,
        line: l.line,
    })
}

/// Distance from the segment (`origin`, `axis`, `range`: see [`span`]) of the middle of
/// the quintic from `s0` to `s1` with parameter length `lp`, computed without building it.
fn middle_deviation(
    s0: &State,
    s1: &State,
    origin: &AxisVec,
    axis: &AxisVec,
    range: f64,
    lp: f64,
) -> f64 {
    let lp2 = lp * lp;
    let u = 0.5;
    let mut along = 0.0;
    let mut w = [0.0f64; AXES];
    let mut idx = [0usize; AXES];
    let mut m = 0;
    for i in 0..AXES {
        let still = s0.p[i] == s1.p[i]
            && origin[i] == s0.p[i]
            && s0.t[i] == 0.0
            && s1.t[i] == 0.0
            && s0.k[i] == 0.0
            && s1.k[i] == 0.0;
        if still {
            continue;
        }
        let ci = quintic_axis(
            s0.p[i],
            s0.t[i] * lp,
            s0.k[i] * lp2,
            s1.p[i],
            s1.t[i] * lp,
            s1.k[i] * lp2,
        );
        let p = ci[0] + u * (ci[1] + u * (ci[2] + u * (ci[3] + u * (ci[4] + u * ci[5]))));
        w[m] = p - origin[i];
        along += w[m] * axis[i];
        idx[m] = i;
        m += 1;
    }
    let along = along.clamp(0.0, range);
    let mut dev = 0.0;
    for (wj, &i) in w[..m].iter().zip(&idx[..m]) {
        let r = wj + axis[i] * -along;
        dev += r * r;
    }
    dev.sqrt()
}

/// Largest distance of the quintic `c` from the segment (`origin`, `axis`, `range`: see
/// [`span`]), and whether it leaves the soft limits, from 17 samples.
fn sampled_deviation(
    c: &[AxisVec; 6],
    origin: &AxisVec,
    axis: &AxisVec,
    range: f64,
    lim: &Lim,
) -> (f64, bool) {
    // Distance from the programmed segment (the chord lies on it) and the soft limits, at
    // 17 samples, over the axes the span or its chord moves along: on the others the sample
    // is exactly the start point and every term below an exact zero, so skipping them
    // gives the full nine-axis values bit for bit.
    let mut axes = [0usize; AXES];
    let mut na = 0;
    let mut outside = false;
    for i in 0..AXES {
        let moves = c[0][i] != origin[i] || axis[i] != 0.0 || (1..6).any(|k| c[k][i] != 0.0);
        if moves {
            axes[na] = i;
            na += 1;
        } else if lim.present[i] && (c[0][i] < lim.min[i] || c[0][i] > lim.max[i]) {
            outside = true;
        }
    }
    const US: [f64; 17] = {
        let mut u = [0.0; 17];
        let mut k = 0;
        while k < 17 {
            u[k] = k as f64 / 16.0;
            k += 1;
        }
        u
    };
    let axes = &axes[..na];
    // Sample by sample inside each axis: independent chains the processor overlaps (each
    // sample's sums still run over the axes in order, as `dot` and `norm` do).
    let mut w = [[0.0f64; 17]; AXES];
    let mut along = [0.0f64; 17];
    for (wj, &i) in w.iter_mut().zip(axes) {
        let ci = [c[0][i], c[1][i], c[2][i], c[3][i], c[4][i], c[5][i]];
        for k in 0..17 {
            let u = US[k];
            let p = ci[0] + u * (ci[1] + u * (ci[2] + u * (ci[3] + u * (ci[4] + u * ci[5]))));
            outside |= lim.present[i] && (p < lim.min[i] || p > lim.max[i]);
            wj[k] = p - origin[i];
            along[k] += wj[k] * axis[i];
        }
    }
    let mut dev = [0.0f64; 17];
    for a in along.iter_mut() {
        *a = a.clamp(0.0, range);
    }
    for (wj, &i) in w.iter().zip(axes) {
        for k in 0..17 {
            let r = wj[k] + axis[i] * -along[k];
            dev[k] += r * r;
        }
    }
    // (Squared distances: the roots only of the largest and its neighbours.)
    let (km, _) = dev.iter().enumerate().fold(
        (0, 0.0),
        |(bi, bv), (i, v)| if *v > bv { (i, *v) } else { (bi, bv) },
    );
    let mut max_dev = dev[km].sqrt();
    if km > 0 && km < 16 {
        // Peak of the parabola through the three samples around the largest.
        let (y0, y1, y2) = (dev[km - 1].sqrt(), max_dev, dev[km + 1].sqrt());
        let den = y0 - 2.0 * y1 + y2;
        if den < 0.0 {
            max_dev = max_dev.max(y1 - 0.125 * (y2 - y0) * (y2 - y0) / den);
        }
    }
    (max_dev, outside)
}

/// Two lines meeting at a vertex under G64 P`tolerance`, as [`Builder::vertex_stage`]
/// decides their junction.
#[derive(Clone, Copy)]
struct LineVertex {
    /// The held-back line, entered in state `st` (None: at its start, along the line).
    lp: LineP,
    st: Option<State>,
    /// The next line.
    lc: LineP,
    /// Angle between the two directions.
    theta: f64,
    tolerance: f64,
    /// Change of direction at this vertex, and at the vertex before (None after a stop).
    turn: AxisVec,
    turn_before: Option<AxisVec>,
    /// `lp` was entered through a tangent junction passed at speed.
    entered_tangent: bool,
}

/// A span `span` accepted: its shape and end points. The piece (a few kB, with its
/// arc-length table) is built only when it is emitted, not for every candidate.
#[derive(Debug, Clone, Copy)]
pub(super) struct Span {
    shape: Shape,
    a: AxisVec,
    b: AxisVec,
    feed: f64,
    rapid: bool,
    line: u32,
}

impl Span {
    fn piece(&self) -> Piece {
        Piece::new(self.shape, self.a, self.b, self.feed, self.rapid, self.line)
    }
}

/// The largest change of curvature per length along a span (17 samples): the speed bound
/// v³·|dK/ds| ≤ J of a smoothing span.
fn curvature_change(sp: &Span) -> f64 {
    let Shape::Poly { c } = &sp.shape else {
        return 0.0;
    };
    let mut prev: Option<(f64, f64)> = None;
    let mut worst: f64 = 0.0;
    let mut s_acc = 0.0;
    let mut last_p: Option<AxisVec> = None;
    for k in 0..=16 {
        let u = k as f64 / 16.0;
        let mut p = [0.0; AXES];
        let mut d1 = [0.0; AXES];
        let mut d2 = [0.0; AXES];
        for i in 0..AXES {
            let a = |j: usize| c[j][i];
            p[i] = a(0) + u * (a(1) + u * (a(2) + u * (a(3) + u * (a(4) + u * a(5)))));
            d1[i] = a(1) + u * (2.0 * a(2) + u * (3.0 * a(3) + u * (4.0 * a(4) + u * 5.0 * a(5))));
            d2[i] = 2.0 * a(2) + u * (6.0 * a(3) + u * (12.0 * a(4) + u * 20.0 * a(5)));
        }
        let v2 = dot(&d1, &d1);
        let cr = (v2 * dot(&d2, &d2) - dot(&d1, &d2).powi(2)).max(0.0).sqrt();
        let kap = cr / (v2 * v2.sqrt()).max(1e-300);
        if let Some(lp) = last_p {
            s_acc += norm(&sub(&p, &lp));
        }
        if let Some((k0, s0)) = prev {
            if s_acc > s0 {
                worst = worst.max((kap - k0).abs() / (s_acc - s0));
            }
        }
        prev = Some((kap, s_acc));
        last_p = Some(p);
    }
    worst
}

/// Unit tangent and curvature vector at the middle point of the circle through three points,
/// from the chords `a` into it and `b` out of it (lengths `la`, `lb`).
fn circle_state(a: &AxisVec, b: &AxisVec, la: f64, lb: f64) -> (AxisVec, AxisVec) {
    let t = unit(&add_scaled(&scale(a, lb / la), b, la / lb));
    let ab = dot(a, b);
    let cross2 = (la * la * lb * lb - ab * ab).max(0.0);
    let chord = norm(&add_scaled(a, b, 1.0));
    let kappa = 2.0 * cross2.sqrt() / (la * lb * chord);
    // Curvature direction: the turn from a to b, orthogonal to t.
    let turn = sub(&unit(b), &unit(a));
    let nrm = unit(&add_scaled(&turn, &t, -dot(&turn, &t)));
    (t, scale(&nrm, kappa))
}

/// The state at `at`, the other end of the chord with direction `chord`, that mirrors
/// `state` across the chord's perpendicular bisector (the two ends of a circular arc).
fn mirror(state: &State, at: &AxisVec, chord: &AxisVec) -> State {
    let t = sub(&scale(chord, 2.0 * dot(&state.t, chord)), &state.t);
    let k = add_scaled(&state.k, chord, -2.0 * dot(&state.k, chord));
    State { p: *at, t, k }
}

fn resolve_feed(feed: &Feed, len_xyz: f64, len: f64, line: u32) -> Result<f64, MotionError> {
    let f = match *feed {
        Feed::UnitsPerSecond(f) => f,
        Feed::InverseTime { seconds } => {
            if !(seconds.is_finite() && seconds > 0.0) {
                return Err(MotionError::InvalidFeed {
                    line,
                    feed: seconds,
                });
            }
            if len_xyz > 1e-12 {
                len_xyz / seconds
            } else {
                len / seconds
            }
        }
        Feed::PerRevolution {
            mm_per_rev,
            spindle_rev_per_s,
        } => mm_per_rev * spindle_rev_per_s,
    };
    if f.is_nan() {
        return Err(MotionError::NotFinite { line, what: "feed" });
    }
    if !(f > 0.0) || f.is_infinite() {
        return Err(MotionError::InvalidFeed { line, feed: f });
    }
    Ok(f)
}

fn check_point(p: &AxisVec, lim: &Lim, line: u32) -> Result<(), MotionError> {
    for i in 0..AXES {
        if lim.present[i] && (p[i] < lim.min[i] || p[i] > lim.max[i]) {
            return Err(MotionError::SoftLimit {
                line,
                axis: Axis::ALL[i].letter(),
                position: p[i],
                min: lim.min[i],
                max: lim.max[i],
            });
        }
    }
    Ok(())
}

fn make_helix(
    a: &AxisVec,
    b: &AxisVec,
    centre: [f64; 3],
    normal: [f64; 3],
    turns: u32,
    radius_tolerance: f64,
    line: u32,
) -> Result<Helix, MotionError> {
    let nn = (normal[0] * normal[0] + normal[1] * normal[1] + normal[2] * normal[2]).sqrt();
    if !(nn > 0.0) {
        return Err(MotionError::InvalidArc {
            line,
            why: "zero normal",
        });
    }
    let n = [normal[0] / nn, normal[1] / nn, normal[2] / nn];
    let d3 = |x: &[f64; 3], y: &[f64; 3]| x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
    let sa = [a[0] - centre[0], a[1] - centre[1], a[2] - centre[2]];
    let ha = d3(&sa, &n);
    let c0 = [
        centre[0] + ha * n[0],
        centre[1] + ha * n[1],
        centre[2] + ha * n[2],
    ];
    let ra_v = [a[0] - c0[0], a[1] - c0[1], a[2] - c0[2]];
    let r0 = d3(&ra_v, &ra_v).sqrt();
    if !(r0 > 1e-9) {
        return Err(MotionError::InvalidArc {
            line,
            why: "zero radius",
        });
    }
    let e1 = [ra_v[0] / r0, ra_v[1] / r0, ra_v[2] / r0];
    let e2 = [
        n[1] * e1[2] - n[2] * e1[1],
        n[2] * e1[0] - n[0] * e1[2],
        n[0] * e1[1] - n[1] * e1[0],
    ];
    let sb = [b[0] - c0[0], b[1] - c0[1], b[2] - c0[2]];
    let rise = d3(&sb, &n);
    let q = [
        sb[0] - rise * n[0],
        sb[1] - rise * n[1],
        sb[2] - rise * n[2],
    ];
    let r1 = d3(&q, &q).sqrt();
    let size = 1.0 + r0.max(r1) + centre.iter().fold(0.0f64, |m, c| m.max(c.abs()));
    if (r1 - r0).abs() > radius_tolerance + ARC_RADIUS_ROUNDING * size {
        return Err(MotionError::ArcRadiusMismatch {
            line,
            start_radius: r0,
            end_radius: r1,
            tolerance: radius_tolerance,
        });
    }
    let mut ang = d3(&q, &e2).atan2(d3(&q, &e1));
    if ang <= 1e-12 {
        ang += 2.0 * std::f64::consts::PI;
    }
    let sweep = ang + 2.0 * std::f64::consts::PI * turns as f64;
    let mut other0 = [0.0; AXES];
    let mut other_delta = [0.0; AXES];
    for i in 3..AXES {
        other0[i] = a[i];
        other_delta[i] = b[i] - a[i];
    }
    Ok(Helix {
        centre: c0,
        e1,
        e2,
        n,
        r0,
        dr: r1 - r0,
        sweep,
        rise,
        other0,
        other_delta,
    })
}

/// Refuses an arc whose extent leaves the envelope: per axis, the circle's extreme angles
/// inside the sweep, plus the helix rise (conservative when both act on one axis).
fn check_helix_extent(
    h: &Helix,
    a: &AxisVec,
    b: &AxisVec,
    lim: &Lim,
    line: u32,
) -> Result<(), MotionError> {
    for i in 0..3 {
        if !lim.present[i] {
            continue;
        }
        let amp = (h.e1[i] * h.e1[i] + h.e2[i] * h.e2[i]).sqrt();
        let mut lo = a[i].min(b[i]);
        let mut hi = a[i].max(b[i]);
        if amp > 0.0 {
            let r = h.r0.max(h.r0 + h.dr);
            let rise_lo = (h.rise * h.n[i]).min(0.0);
            let rise_hi = (h.rise * h.n[i]).max(0.0);
            let th_max = h.e2[i].atan2(h.e1[i]);
            for (th0, sign) in [(th_max, 1.0), (th_max + std::f64::consts::PI, -1.0)] {
                let th = th0.rem_euclid(2.0 * std::f64::consts::PI);
                if th <= h.sweep {
                    let x = h.centre[i] + sign * r * amp;
                    if sign > 0.0 {
                        hi = hi.max(x + rise_hi);
                    } else {
                        lo = lo.min(x + rise_lo);
                    }
                }
            }
        }
        for x in [lo, hi] {
            if x < lim.min[i] || x > lim.max[i] {
                return Err(MotionError::SoftLimit {
                    line,
                    axis: Axis::ALL[i].letter(),
                    position: x,
                    min: lim.min[i],
                    max: lim.max[i],
                });
            }
        }
    }
    Ok(())
}
