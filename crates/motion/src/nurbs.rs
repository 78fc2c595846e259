//! NURBS curves (G5.2/G5.3): evaluation (de Boor's algorithm on the homogeneous control
//! points) and the curve as a chain of cubic Bézier curves, which the planner follows as
//! exact polynomials ([`crate::MoveKind::Spline`]).
//!
//! On each knot span the chain takes the cubic with the curve's end points and first
//! derivatives (Hermite), halving the span until it lies within the tolerance of the curve
//! at every parameter: a polynomial NURBS of order 4 or less (all weights equal) is that
//! cubic exactly, so its chain is the curve itself; a rational one (other weights) or of
//! higher order comes within the tolerance, the error falling with the fourth power of the
//! length. Consecutive cubics share their point and their tangent's direction, so the path
//! runs through the joints without a corner. LinuxCNC approximates the curve with biarcs
//! instead.

use crate::axes::{AXES, AxisVec};

/// Why a NURBS curve was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NurbsError {
    /// Fewer than two control points, an order below 2, or more than the points.
    Order,
    /// A weight is not positive and finite, or a coordinate not finite.
    Value,
    /// Reaching the tolerance would take more cubics than [`MAX_CUBICS`].
    TooManyCubics,
}

impl std::fmt::Display for NurbsError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            NurbsError::Order => {
                "a NURBS needs at least two points and an order from 2 to their number"
            }
            NurbsError::Value => "a NURBS weight must be positive and every value finite",
            NurbsError::TooManyCubics => {
                "the NURBS needs more cubic pieces than allowed to reach the tolerance"
            }
        })
    }
}

impl std::error::Error for NurbsError {}

/// Most cubics one curve becomes.
pub const MAX_CUBICS: usize = 100_000;
/// Halvings of one knot span at most.
const MAX_DEPTH: u32 = 16;
/// Parameters at which a cubic is compared with the curve, inside its interval.
const CHECKS: usize = 16;

/// A NURBS curve on LinuxCNC's clamped uniform knot vector: for `n + 1` control points
/// and order `k`, `k` knots 0, then `1, 2, ..., n - k + 1`, then `k` knots `n - k + 2`;
/// the parameter runs from 0 to `n - k + 2`, the curve from the first control point to
/// the last.
#[derive(Debug, Clone)]
pub struct NurbsCurve {
    order: usize,
    /// Homogeneous control points: (w·P, w).
    homogeneous: Vec<(AxisVec, f64)>,
    knots: Vec<f64>,
}

impl NurbsCurve {
    /// The curve of order `order` through `points` with `weights`.
    ///
    /// Real-time: no (allocates its control points and knots).
    pub fn clamped_uniform(
        order: usize,
        points: &[AxisVec],
        weights: &[f64],
    ) -> Result<NurbsCurve, NurbsError> {
        let count = points.len();
        if count < 2 || order < 2 || order > count || weights.len() != count {
            return Err(NurbsError::Order);
        }
        if !weights.iter().all(|w| w.is_finite() && *w > 0.0)
            || !points.iter().all(|p| p.iter().all(|x| x.is_finite()))
        {
            return Err(NurbsError::Value);
        }
        let n = count - 1;
        let last = (n + 2 - order) as f64;
        let mut knots = vec![0.0; order];
        knots.extend((1..=n + 1 - order).map(|i| i as f64));
        knots.extend(std::iter::repeat_n(last, order));
        let homogeneous = points
            .iter()
            .zip(weights)
            .map(|(p, &w)| (p.map(|x| x * w), w))
            .collect();
        Ok(NurbsCurve {
            order,
            homogeneous,
            knots,
        })
    }

    /// The parameter's range: from 0 to this.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn end_parameter(&self) -> f64 {
        self.knots[self.knots.len() - 1]
    }

    /// The knot span `[knots[s], knots[s + 1])` that holds `u` (the last non-empty one for
    /// the end).
    fn span(&self, u: f64) -> usize {
        let p = self.order - 1;
        let last = self.homogeneous.len() - 1;
        if u >= self.knots[last + 1] {
            return last;
        }
        let mut s = p;
        while s < last && u >= self.knots[s + 1] {
            s += 1;
        }
        s
    }

    /// The homogeneous point and its first derivative at `u` (de Boor on the points, and
    /// on the derivative's control points).
    fn homogeneous_at(&self, u: f64) -> ((AxisVec, f64), (AxisVec, f64)) {
        let p = self.order - 1;
        let s = self.span(u);
        let t = &self.knots;
        // The p + 1 points that act on span s, and de Boor's triangle over them.
        let mut d: Vec<(AxisVec, f64)> = (0..=p).map(|j| self.homogeneous[s - p + j]).collect();
        // The derivative's control points (degree p - 1): p (d[j+1] - d[j]) / (t - t).
        let mut q: Vec<(AxisVec, f64)> = (0..p)
            .map(|j| {
                let i = s - p + j;
                let h = t[i + p + 1] - t[i + 1];
                let f = if h > 0.0 { p as f64 / h } else { 0.0 };
                let (a, b) = (self.homogeneous[i], self.homogeneous[i + 1]);
                let mut v = [0.0; AXES];
                for k in 0..AXES {
                    v[k] = f * (b.0[k] - a.0[k]);
                }
                (v, f * (b.1 - a.1))
            })
            .collect();
        de_boor(&mut d, t, s, p, u);
        // The derivative's knots are the curve's without the first and last.
        if p >= 1 {
            de_boor_shifted(&mut q, t, s, p - 1, u);
        }
        let first = d[p];
        let derivative = if p >= 1 { q[p - 1] } else { ([0.0; AXES], 0.0) };
        (first, derivative)
    }

    /// The point at parameter `u` (clamped to the range).
    ///
    /// Real-time: no (allocates its working triangle).
    pub fn point(&self, u: f64) -> AxisVec {
        self.point_and_derivative(u).0
    }

    /// The point and its first derivative with respect to the parameter at `u`.
    ///
    /// Real-time: no (allocates its working triangle).
    pub fn point_and_derivative(&self, u: f64) -> (AxisVec, AxisVec) {
        let u = u.clamp(0.0, self.end_parameter());
        let ((a, w), (da, dw)) = self.homogeneous_at(u);
        let mut c = [0.0; AXES];
        let mut dc = [0.0; AXES];
        for k in 0..AXES {
            c[k] = a[k] / w;
            // (A / W)' = (A' - W' C) / W.
            dc[k] = (da[k] - dw * c[k]) / w;
        }
        (c, dc)
    }

    /// The curve as cubic Bézier curves `[start, control 1, control 2, end]`, each within
    /// `tolerance` of the curve at every parameter (compared at 16 inner points of
    /// its interval), appended to `out` in order; the first starts at the first control
    /// point, the last ends at the last one.
    ///
    /// Real-time: no (allocates).
    pub fn to_cubics(&self, tolerance: f64, out: &mut Vec<[AxisVec; 4]>) -> Result<(), NurbsError> {
        self.cubics_over(tolerance, out, &mut None)
    }

    /// [`to_cubics`](Self::to_cubics), also giving each cubic's parameter interval.
    fn cubics_over(
        &self,
        tolerance: f64,
        out: &mut Vec<[AxisVec; 4]>,
        intervals: &mut Option<Vec<(f64, f64)>>,
    ) -> Result<(), NurbsError> {
        let p = self.order - 1;
        let start = out.len();
        for s in p..self.homogeneous.len() {
            let (a, b) = (self.knots[s], self.knots[s + 1]);
            if b > a {
                self.approximate(a, b, tolerance, 0, out, intervals)?;
            }
        }
        // The ends exactly on the first and last control points (the clamped curve passes
        // through them; the division by the weight may round).
        let first = self.homogeneous[0];
        let last = self.homogeneous[self.homogeneous.len() - 1];
        if let Some(c) = out.get_mut(start) {
            c[0] = first.0.map(|x| x / first.1);
        }
        if let Some(c) = out.last_mut() {
            c[3] = last.0.map(|x| x / last.1);
        }
        Ok(())
    }

    fn approximate(
        &self,
        a: f64,
        b: f64,
        tolerance: f64,
        depth: u32,
        out: &mut Vec<[AxisVec; 4]>,
        intervals: &mut Option<Vec<(f64, f64)>>,
    ) -> Result<(), NurbsError> {
        let (p0, d0) = self.point_and_derivative(a);
        let (p3, d3) = self.point_and_derivative(b);
        let h = (b - a) / 3.0;
        let mut cubic = [p0, p0, p3, p3];
        for k in 0..AXES {
            cubic[1][k] = p0[k] + h * d0[k];
            cubic[2][k] = p3[k] - h * d3[k];
        }
        let within = (1..=CHECKS).all(|i| {
            let t = i as f64 / (CHECKS + 1) as f64;
            let on_curve = self.point(a + t * (b - a));
            let on_cubic = bezier(&cubic, t);
            let d2: f64 = (0..AXES).map(|k| (on_curve[k] - on_cubic[k]).powi(2)).sum();
            d2.sqrt() <= tolerance
        });
        if within || depth >= MAX_DEPTH {
            if out.len() >= MAX_CUBICS || !within {
                return Err(NurbsError::TooManyCubics);
            }
            out.push(cubic);
            if let Some(v) = intervals {
                v.push((a, b));
            }
            return Ok(());
        }
        let m = 0.5 * (a + b);
        self.approximate(a, m, tolerance, depth + 1, out, intervals)?;
        self.approximate(m, b, tolerance, depth + 1, out, intervals)
    }
}

/// The cubic Bézier curve `c` at `t`.
fn bezier(c: &[AxisVec; 4], t: f64) -> AxisVec {
    let s = 1.0 - t;
    let (b0, b1, b2, b3) = (s * s * s, 3.0 * s * s * t, 3.0 * s * t * t, t * t * t);
    let mut p = [0.0; AXES];
    for k in 0..AXES {
        p[k] = b0 * c[0][k] + b1 * c[1][k] + b2 * c[2][k] + b3 * c[3][k];
    }
    p
}

/// De Boor's triangle in place: `d` holds the `p + 1` points of span `s` of a curve of
/// degree `p` on knots `t`; on return `d[p]` is the point at `u`.
fn de_boor(d: &mut [(AxisVec, f64)], t: &[f64], s: usize, p: usize, u: f64) {
    for r in 1..=p {
        for j in (r..=p).rev() {
            let i = s - p + j;
            let h = t[i + p + 1 - r] - t[i];
            let alpha = if h > 0.0 { (u - t[i]) / h } else { 0.0 };
            let (lo, hi) = (d[j - 1], d[j]);
            for k in 0..AXES {
                d[j].0[k] = (1.0 - alpha) * lo.0[k] + alpha * hi.0[k];
            }
            d[j].1 = (1.0 - alpha) * lo.1 + alpha * hi.1;
        }
    }
}

/// De Boor's triangle for the derivative curve (degree `p`, its knots those of `t` without
/// the first and the last): its span `s - 1`, so the knot indices shift by one.
fn de_boor_shifted(d: &mut [(AxisVec, f64)], t: &[f64], s: usize, p: usize, u: f64) {
    for r in 1..=p {
        for j in (r..=p).rev() {
            // Point j of span s is derivative control point s - p - 1 + j, whose knots
            // are t[.. + 1].
            let i = s - p - 1 + j;
            let h = t[i + p + 2 - r] - t[i + 1];
            let alpha = if h > 0.0 { (u - t[i + 1]) / h } else { 0.0 };
            let (lo, hi) = (d[j - 1], d[j]);
            for k in 0..AXES {
                d[j].0[k] = (1.0 - alpha) * lo.0[k] + alpha * hi.0[k];
            }
            d[j].1 = (1.0 - alpha) * lo.1 + alpha * hi.1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn xy(x: f64, y: f64) -> AxisVec {
        let mut p = [0.0; AXES];
        p[0] = x;
        p[1] = y;
        p
    }

    /// The quarter circle of radius 10 as a rational quadratic: (10,0), (10,10) with
    /// weight √2/2, (0,10). Every point lies on the circle (a closed form).
    fn quarter_circle() -> NurbsCurve {
        let w = std::f64::consts::FRAC_1_SQRT_2;
        NurbsCurve::clamped_uniform(
            3,
            &[xy(10.0, 0.0), xy(10.0, 10.0), xy(0.0, 10.0)],
            &[1.0, w, 1.0],
        )
        .unwrap()
    }

    #[test]
    fn a_rational_quadratic_quarter_circle_lies_on_the_circle() {
        let c = quarter_circle();
        assert_eq!(c.end_parameter(), 1.0);
        for i in 0..=100 {
            let p = c.point(i as f64 / 100.0);
            assert!((p[0].hypot(p[1]) - 10.0).abs() < 1e-12, "{p:?}");
        }
        // At u = 1/2 the point is at 45°: (5√2, 5√2) (the standard conic's shoulder).
        let mid = c.point(0.5);
        let h = 5.0 * std::f64::consts::SQRT_2;
        assert!((mid[0] - h).abs() < 1e-12 && (mid[1] - h).abs() < 1e-12);
        // The tangent at the start points along +Y, at the end along -X; the derivative's
        // size at the ends is 2·w·|P1 − P0| / w0 = 2·(√2/2)·10 (the rational derivative).
        let (_, d0) = c.point_and_derivative(0.0);
        assert!(d0[0].abs() < 1e-12);
        assert!((d0[1] - 2.0 * std::f64::consts::FRAC_1_SQRT_2 * 10.0).abs() < 1e-9);
        let (_, d1) = c.point_and_derivative(1.0);
        assert!(d1[1].abs() < 1e-12 && d1[0] < 0.0);
    }

    #[test]
    fn its_cubics_stay_on_the_circle_within_the_tolerance() {
        let c = quarter_circle();
        let mut cubics = Vec::new();
        c.to_cubics(1e-4, &mut cubics).unwrap();
        // Compared parameter by parameter (an upper bound of the distance to the curve).
        assert!(cubics.len() >= 2 && cubics.len() <= 32, "{}", cubics.len());
        assert_eq!(cubics[0][0], xy(10.0, 0.0));
        assert_eq!(cubics[cubics.len() - 1][3], xy(0.0, 10.0));
        for w in cubics.windows(2) {
            assert_eq!(w[0][3], w[1][0]);
            // The same tangent direction on both sides of a joint.
            let t0 = [w[0][3][0] - w[0][2][0], w[0][3][1] - w[0][2][1]];
            let t1 = [w[1][1][0] - w[1][0][0], w[1][1][1] - w[1][0][1]];
            let cross = t0[0] * t1[1] - t0[1] * t1[0];
            assert!(cross.abs() <= 1e-12 * t0[0].hypot(t0[1]) * t1[0].hypot(t1[1]));
        }
        for cubic in &cubics {
            for i in 0..=200 {
                let p = bezier(cubic, i as f64 / 200.0);
                assert!((p[0].hypot(p[1]) - 10.0).abs() <= 1e-4, "{p:?}");
            }
        }
    }

    #[test]
    fn a_polynomial_cubic_nurbs_becomes_its_own_bezier_pieces() {
        // Order 4 with equal weights on 5 points: two knot spans, each a cubic polynomial;
        // the chain is one cubic per span, the curve's own. By hand (Cox-de Boor on the
        // knots 0 0 0 0 1 2 2 2 2): the basis at u = 1 is (0, 1/4, 1/2, 1/4, 0) on P0..P4,
        // so the point there is (P1 + 2 P2 + P3) / 4.
        let pts = [
            xy(0.0, 0.0),
            xy(4.0, 8.0),
            xy(8.0, 0.0),
            xy(12.0, 8.0),
            xy(16.0, 0.0),
        ];
        let c = NurbsCurve::clamped_uniform(4, &pts, &[2.0; 5]).unwrap();
        assert_eq!(c.end_parameter(), 2.0);
        let at1 = c.point(1.0);
        let expect_x = 0.25 * 4.0 + 0.5 * 8.0 + 0.25 * 12.0;
        let expect_y = 0.25 * 8.0 + 0.5 * 0.0 + 0.25 * 8.0;
        assert!((at1[0] - expect_x).abs() < 1e-12 && (at1[1] - expect_y).abs() < 1e-12);
        let mut cubics = Vec::new();
        c.to_cubics(1e-9, &mut cubics).unwrap();
        assert_eq!(cubics.len(), 2);
        for (span, cubic) in cubics.iter().enumerate() {
            for i in 0..=50 {
                let t = i as f64 / 50.0;
                let on_curve = c.point(span as f64 + t);
                let on_cubic = bezier(cubic, t);
                assert!((on_curve[0] - on_cubic[0]).abs() < 1e-12);
                assert!((on_curve[1] - on_cubic[1]).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn a_higher_order_rational_curve_comes_within_the_tolerance() {
        let pts = [
            xy(0.0, 0.0),
            xy(2.0, 6.0),
            xy(6.0, -3.0),
            xy(9.0, 7.0),
            xy(13.0, 1.0),
            xy(15.0, 4.0),
        ];
        let weights = [1.0, 3.0, 0.5, 2.0, 1.5, 1.0];
        let c = NurbsCurve::clamped_uniform(5, &pts, &weights).unwrap();
        let mut cubics = Vec::new();
        let mut intervals = Some(Vec::new());
        c.cubics_over(1e-5, &mut cubics, &mut intervals).unwrap();
        let intervals = intervals.unwrap();
        assert!(cubics.len() > 2, "{}", cubics.len());
        // The intervals tile the parameter range; on each, the cubic stays within the
        // tolerance of the curve, compared by de Boor's evaluation at 41 parameters.
        assert_eq!(intervals[0].0, 0.0);
        assert_eq!(intervals[intervals.len() - 1].1, c.end_parameter());
        for w in intervals.windows(2) {
            assert_eq!(w[0].1, w[1].0);
        }
        for (cubic, &(a, b)) in cubics.iter().zip(&intervals) {
            for i in 0..=40 {
                let t = i as f64 / 40.0;
                let on_curve = c.point(a + t * (b - a));
                let on_cubic = bezier(cubic, t);
                let d = (on_curve[0] - on_cubic[0]).hypot(on_curve[1] - on_cubic[1]);
                // Checked at 16 inner points when built: between them the error curve is
                // smooth, within a few per cent of the bound.
                assert!(d <= 1.1e-5, "{d}");
            }
        }
    }

    #[test]
    fn bad_curves_are_refused() {
        let pts = [xy(0.0, 0.0), xy(1.0, 1.0), xy(2.0, 0.0)];
        assert_eq!(
            NurbsCurve::clamped_uniform(4, &pts, &[1.0; 3]).unwrap_err(),
            NurbsError::Order
        );
        assert_eq!(
            NurbsCurve::clamped_uniform(3, &pts, &[1.0, 0.0, 1.0]).unwrap_err(),
            NurbsError::Value
        );
    }
}
