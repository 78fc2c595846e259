//! The compressor (G64 P, dense CAM polylines): a run of short feed lines (at most
//! `MAX_LEN`, turning at most `MAX_TURN` at each vertex, one feed and path mode) is held
//! back `LOOK` lines, so that each inner vertex gets a state (point, tangent, curvature)
//! from a curve fitted over its neighbours: the weighted least-squares parabola in the
//! chord length through the vertex and up to `LOOK` vertices on each side (fewer at the
//! ends of the run), its point moved towards the vertex to within `SHIFT_SHARE` of P. The
//! builder takes that state where its local smoothing refuses the vertex (a turn over
//! 0.35 rad, unequal chords), instead of a corner blend, when the span into it keeps P of
//! its segment and the next line can straighten out of it within P
//! (`Builder::fitted_vertex`). The run ends at anything that is not such a line (a rapid,
//! an arc, a spline, a dwell, another feed or mode, a long line, a sharper turn): no curve
//! is fitted across it.
//!
//! Tried on FreeCAD's adaptive programs (planner alone): the fitted state first at every
//! vertex of a run (the local smoothing's only where it fails), with a cubic over 2·3 + 1
//! vertices: 6.6 % slower on the adaptive profile, whose gentle stretches the local
//! smoothing follows with steadier curvature; first only where a turn nearby exceeds
//! 0.35 rad: 2-3 % slower; rapids in runs: 1.4 % slower (as smoothing them was); one vertex
//! before and two after (an asymmetric fit): 0.1-0.7 % faster on the four adaptive
//! programs, but a tight circle polyline (0.2 mm chords turning 0.36 rad) took 14 % longer
//! (the fit's tangent leans, and the spans' curvature swings by ±11 %).
//!
//! Memory: a fixed array of `LOOK` lines and `LOOK` earlier vertices in the builder; work
//! per line: one solve of at most 4 × 4 over at most `2·LOOK + 1` points. No allocation,
//! no panic on any input (a degenerate fit gives no state).

use super::{LineP, State, unit};
use crate::axes::{AXES, AxisVec, add_scaled, dot, norm, scale, sub};
use crate::input::PathMode;

/// Vertices each side of a vertex that its fitted curve takes in (and lines held back).
pub(crate) const LOOK: usize = 2;
/// Longest line (mm) a run takes.
const MAX_LEN: f64 = 1.0;
/// Largest turn (rad) at a vertex inside a run.
const MAX_TURN: f64 = 0.8;
/// Largest distance of a fitted point from its vertex, as a share of P.
const SHIFT_SHARE: f64 = 0.75;

/// The lines held back and the vertices before them in the current run.
#[derive(Debug, Clone, Copy)]
pub(super) struct Compressor {
    pending: [Option<LineP>; LOOK],
    n: usize,
    /// Start points of the last lines of the run passed on, oldest first.
    before: [AxisVec; LOOK],
    nb: usize,
}

impl Compressor {
    pub fn new() -> Compressor {
        Compressor {
            pending: [None; LOOK],
            n: 0,
            before: [[0.0; AXES]; LOOK],
            nb: 0,
        }
    }

    /// Whether `l` may be part of a run at all.
    pub fn eligible(l: &LineP) -> bool {
        let tol = match l.mode {
            PathMode::Blend { tolerance, .. } => tolerance,
            _ => 0.0,
        };
        !l.rapid && tol > 0.0 && l.len <= MAX_LEN && l.feed.is_finite()
    }

    /// Whether `l` continues the run of the lines held (an eligible line).
    pub fn continues(&self, l: &LineP) -> bool {
        let last = if self.n > 0 {
            self.pending[self.n - 1]
        } else {
            None
        };
        match last {
            Some(p) => {
                p.feed == l.feed
                    && p.rapid == l.rapid
                    && p.mode == l.mode
                    && p.b == l.a
                    && dot(&p.dir, &l.dir).clamp(-1.0, 1.0).acos() <= MAX_TURN
            }
            None => false,
        }
    }

    /// Whether `LOOK` lines are held: the oldest has its `LOOK` vertices after it.
    pub fn full(&self) -> bool {
        self.n == LOOK
    }

    /// Holds `l` (the caller has checked that it continues the run, or ended the run, and
    /// popped a full compressor).
    pub fn hold(&mut self, l: LineP) {
        if self.n < LOOK {
            self.pending[self.n] = Some(l);
            self.n += 1;
        }
    }

    /// Ends the run: nothing earlier is fitted with what comes next.
    pub fn end_run(&mut self) {
        self.nb = 0;
    }

    pub fn clear(&mut self) {
        self.n = 0;
        self.nb = 0;
        self.pending = [None; LOOK];
    }

    /// The oldest line held and, when its start is an inner vertex of the run, the state
    /// fitted there.
    pub fn pop(&mut self) -> Option<(LineP, Option<State>)> {
        if self.n == 0 {
            return None;
        }
        let l = self.pending[0]?;
        let tol = match l.mode {
            PathMode::Blend { tolerance, .. } => tolerance,
            _ => 0.0,
        };
        let hint = if self.nb > 0 {
            let mut pts = [[0.0; AXES]; 2 * LOOK + 1];
            let mut m = 0;
            for p in &self.before[LOOK - self.nb..] {
                pts[m] = *p;
                m += 1;
            }
            let centre = m;
            pts[m] = l.a;
            m += 1;
            for q in self.pending[..self.n].iter().flatten() {
                pts[m] = q.b;
                m += 1;
            }
            fit_state(&pts[..m], centre, tol)
        } else {
            None
        };
        for i in 1..self.n {
            self.pending[i - 1] = self.pending[i];
        }
        self.n -= 1;
        self.pending[self.n] = None;
        self.before.copy_within(1.., 0);
        self.before[LOOK - 1] = l.a;
        self.nb = (self.nb + 1).min(LOOK);
        Some((l, hint))
    }
}

/// The state at `pts[centre]` of the weighted least-squares cubic (a quadratic with fewer
/// than six points) through `pts` in their chord length, its point moved towards the
/// vertex to within `SHIFT_SHARE · tol` of it. None where the fit is degenerate or turns
/// against the chords.
pub(super) fn fit_state(pts: &[AxisVec], centre: usize, tol: f64) -> Option<State> {
    let m = pts.len();
    if m < 3 || centre == 0 || centre + 1 >= m || !(tol > 0.0) {
        return None;
    }
    // Chord length from the centre, signed.
    let mut s = [0.0f64; 2 * LOOK + 1];
    for j in (0..centre).rev() {
        s[j] = s[j + 1] - norm(&sub(&pts[j + 1], &pts[j]));
    }
    for j in centre + 1..m {
        s[j] = s[j - 1] + norm(&sub(&pts[j], &pts[j - 1]));
    }
    let h = (-s[0]).max(s[m - 1]);
    if !(h > 1e-9) {
        return None;
    }
    // A cubic from six points on (a longer `LOOK`), else a parabola.
    let nb = if m >= 6 { 4 } else { 3 };
    // Normal equations in u = s / h: basis 1, u, u²/2, u³/6.
    let reach = (centre.max(m - 1 - centre) + 1) as f64;
    let mut a = [[0.0f64; 4]; 4];
    let mut r = [[0.0f64; AXES]; 4];
    for j in 0..m {
        let u = s[j] / h;
        let d = (j as f64 - centre as f64).abs() / reach;
        let w = (1.0 - d * d * d).powi(3);
        let phi = [1.0, u, 0.5 * u * u, u * u * u / 6.0];
        for p in 0..nb {
            for q in 0..nb {
                a[p][q] += w * phi[p] * phi[q];
            }
            for i in 0..AXES {
                r[p][i] += w * phi[p] * pts[j][i];
            }
        }
    }
    // Gaussian elimination with partial pivoting.
    for c in 0..nb {
        let piv = (c..nb).max_by(|&x, &y| a[x][c].abs().total_cmp(&a[y][c].abs()))?;
        if !(a[piv][c].abs() > 1e-12) {
            return None;
        }
        a.swap(c, piv);
        r.swap(c, piv);
        for row in c + 1..nb {
            let f = a[row][c] / a[c][c];
            for q in c..nb {
                a[row][q] -= f * a[c][q];
            }
            for i in 0..AXES {
                r[row][i] -= f * r[c][i];
            }
        }
    }
    let mut x = [[0.0f64; AXES]; 4];
    for c in (0..nb).rev() {
        for i in 0..AXES {
            let mut v = r[c][i];
            for q in c + 1..nb {
                v -= a[c][q] * x[q][i];
            }
            x[c][i] = v / a[c][c];
        }
    }
    let p = x[0];
    let d1 = scale(&x[1], 1.0 / h);
    let d2 = scale(&x[2], 1.0 / (h * h));
    let speed = norm(&d1);
    if !(speed > 0.5) || !p.iter().chain(&d1).chain(&d2).all(|v| v.is_finite()) {
        return None;
    }
    let t = unit(&d1);
    let k = scale(&add_scaled(&d2, &t, -dot(&d2, &t)), 1.0 / (speed * speed));
    // Along both chords at the vertex.
    let v = pts[centre];
    let into = sub(&v, &pts[centre - 1]);
    let out = sub(&pts[centre + 1], &v);
    if dot(&t, &into) <= 0.0 || dot(&t, &out) <= 0.0 {
        return None;
    }
    let off = sub(&p, &v);
    let dist = norm(&off);
    let most = SHIFT_SHARE * tol;
    let p = if dist > most {
        add_scaled(&v, &off, most / dist)
    } else {
        p
    };
    Some(State { p, t, k })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::axes::AXES;

    fn p(x: f64, y: f64) -> AxisVec {
        let mut v = [0.0; AXES];
        v[0] = x;
        v[1] = y;
        v
    }

    /// Three points on a circle of radius r, the middle one at (0, r), the others φ away
    /// on either side: the parabola through them in chord length c = 2r·sin(φ/2) passes
    /// through the middle one along the circle's tangent (−1, 0) (by symmetry), its first
    /// derivative (P₊ − P₋)/(2c) has length cos(φ/2) and its second (P₊ − 2P + P₋)/c²
    /// is −1/r along y, so its curvature is 1/(r·cos²(φ/2)) towards the centre.
    #[test]
    fn three_points_on_a_circle_give_its_tangent_and_the_parabolas_curvature() {
        let (r, phi) = (2.0f64, 0.3f64);
        let at = |a: f64| p(-r * a.sin(), r * a.cos());
        let pts = [at(-phi), at(0.0), at(phi)];
        let st = fit_state(&pts, 1, 0.01).unwrap();
        let want_k = 1.0 / (r * (0.5 * phi).cos().powi(2));
        assert!((st.p[0] - 0.0).abs() < 1e-12 && (st.p[1] - r).abs() < 1e-12);
        assert!((st.t[0] + 1.0).abs() < 1e-12 && st.t[1].abs() < 1e-12);
        assert!(
            st.k[0].abs() < 1e-9 && (st.k[1] + want_k).abs() < 1e-9,
            "{:?}",
            st.k
        );
    }

    /// Collinear points (unequal spacing): the vertex itself, the line's direction, no
    /// curvature.
    #[test]
    fn collinear_points_give_the_line() {
        let d = [0.6, 0.8];
        let pts = [0.0, 0.3, 0.45, 1.0].map(|s| p(1.0 + s * d[0], 2.0 + s * d[1]));
        let st = fit_state(&pts, 1, 0.01).unwrap();
        assert!((st.p[0] - pts[1][0]).abs() < 1e-12 && (st.p[1] - pts[1][1]).abs() < 1e-12);
        assert!((st.t[0] - 0.6).abs() < 1e-12 && (st.t[1] - 0.8).abs() < 1e-12);
        assert!(st.k.iter().all(|k| k.abs() < 1e-9), "{:?}", st.k);
    }

    /// A vertex that sticks out of its neighbours' line (a spike 1 mm high on 1 mm chords,
    /// P 0.01): the fitted point moves at most 0.75 P from the vertex.
    #[test]
    fn the_fitted_point_stays_within_its_share_of_p() {
        let pts = [p(0.0, 0.0), p(1.0, 0.0), p(2.0, 1.0), p(3.0, 0.0)];
        let st = fit_state(&pts, 1, 0.01).unwrap();
        let d = ((st.p[0] - 1.0).powi(2) + st.p[1].powi(2)).sqrt();
        assert!(d <= 0.75 * 0.01 * (1.0 + 1e-12), "moved {d}");
    }

    /// Degenerate input gives no state and no panic: repeated points, a reversal, NaN,
    /// too few points, a centre at an end.
    #[test]
    fn degenerate_input_gives_no_state() {
        let a = p(1.0, 1.0);
        assert!(fit_state(&[a, a, a], 1, 0.01).is_none());
        assert!(fit_state(&[p(0.0, 0.0), p(1.0, 0.0), p(0.0, 0.0)], 1, 0.01).is_none());
        assert!(fit_state(&[p(0.0, 0.0), p(f64::NAN, 0.0), p(2.0, 0.0)], 1, 0.01).is_none());
        assert!(fit_state(&[p(0.0, 0.0), p(1.0, 0.0)], 1, 0.01).is_none());
        assert!(fit_state(&[p(0.0, 0.0), p(1.0, 0.0), p(2.0, 0.0)], 0, 0.01).is_none());
        assert!(fit_state(&[p(0.0, 0.0), p(1.0, 0.0), p(2.0, 0.0)], 1, 0.0).is_none());
    }
}
