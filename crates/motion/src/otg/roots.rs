//! Real roots of low-degree polynomials inside an interval.
//!
//! Roots are isolated with the roots of the derivative (between two neighbouring critical
//! points a polynomial is monotone), then each bracket is solved by Newton steps safeguarded
//! with bisection. This finds every simple root in the interval without the cancellation
//! troubles of closed-form quartic formulas, and with a bounded amount of work.

/// Up to four roots, ascending.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Roots {
    values: [f64; 4],
    len: usize,
}

impl Roots {
    fn push(&mut self, x: f64) {
        if self.len < self.values.len() {
            if self.len > 0 {
                let last = self.values[self.len - 1];
                if (x - last).abs() <= 1e-14 * x.abs().max(last.abs()).max(1e-300) {
                    return;
                }
            }
            self.values[self.len] = x;
            self.len += 1;
        }
    }

    pub(crate) fn as_slice(&self) -> &[f64] {
        &self.values[..self.len]
    }
}

/// Horner evaluation of `c[0] x^n + c[1] x^(n-1) + ... + c[n]`.
#[inline]
fn eval(c: &[f64], x: f64) -> f64 {
    c.iter().fold(0.0, |acc, &ci| acc * x + ci)
}

/// Sum of the magnitudes of the terms: the scale against which "zero" is judged.
fn magnitude(c: &[f64], x: f64) -> f64 {
    let ax = x.abs();
    c.iter().fold(0.0, |acc, &ci| acc * ax + ci.abs())
}

/// Real roots in `[lo, hi]` of the polynomial with coefficients `c` (highest degree first,
/// degree at most 4). Tangent (double) roots are reported when the polynomial comes within
/// rounding distance of zero at a critical point.
pub(crate) fn real_roots_in(c: &[f64], lo: f64, hi: f64) -> Roots {
    roots_to(c, lo, hi, 2.0 * f64::EPSILON)
}

/// Roots to a relative precision `tol`. The critical points that split the interval into
/// monotone pieces need far less precision than the roots themselves.
fn roots_to(c: &[f64], lo: f64, hi: f64, tol: f64) -> Roots {
    let mut out = Roots::default();
    if lo.is_nan() || hi.is_nan() || lo > hi || c.len() > 5 || c.iter().any(|x| !x.is_finite()) {
        return out;
    }
    // Drop vanishing leading coefficients.
    let scale = c.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let mut start = 0;
    while start < c.len() && c[start].abs() <= 1e-300 * scale.max(1e-300) {
        start += 1;
    }
    let c = &c[start..];
    match c.len() {
        0 | 1 => out,
        2 => {
            let x = -c[1] / c[0];
            if x >= lo && x <= hi {
                out.push(x);
            }
            out
        }
        3 => {
            let (a, b, cc) = (c[0], c[1], c[2]);
            let disc = b * b - 4.0 * a * cc;
            if disc < 0.0 {
                // A double root hiding under rounding.
                let x = -b / (2.0 * a);
                if x >= lo && x <= hi && eval(c, x).abs() <= 1e-13 * magnitude(c, x) {
                    out.push(x);
                }
                return out;
            }
            let q = -0.5 * (b + b.signum() * disc.sqrt());
            let (mut x1, mut x2) = if q != 0.0 {
                (q / a, cc / q)
            } else {
                (0.0, 0.0)
            };
            if x1 > x2 {
                std::mem::swap(&mut x1, &mut x2);
            }
            for x in [x1, x2] {
                if x >= lo && x <= hi {
                    out.push(x);
                }
            }
            out
        }
        _ => {
            let n = c.len() - 1;
            let mut derivative = [0.0; 4];
            for (i, ci) in c.iter().take(n).enumerate() {
                derivative[i] = ci * (n - i) as f64;
            }
            let critical = roots_to(&derivative[..n], lo, hi, 1e-9);
            let mut left = lo;
            for &point in critical.as_slice().iter().chain(std::iter::once(&hi)) {
                let right = point;
                if right > left || (right == left && left == lo) {
                    bracket(c, left, right, tol, &mut out);
                }
                if right < hi && eval(c, right).abs() <= 1e-13 * magnitude(c, right) {
                    out.push(right);
                }
                left = right;
            }
            out
        }
    }
}

/// Value and derivative in one Horner pass.
#[inline]
fn eval_with_derivative(c: &[f64], x: f64) -> (f64, f64) {
    let mut p = 0.0;
    let mut dp = 0.0;
    for &ci in c {
        dp = dp * x + p;
        p = p * x + ci;
    }
    (p, dp)
}

/// Solves a monotone bracket `[a, b]` if the sign changes over it.
fn bracket(c: &[f64], a: f64, b: f64, tol: f64, out: &mut Roots) {
    let (fa, fb) = (eval(c, a), eval(c, b));
    if fa == 0.0 {
        out.push(a);
        return;
    }
    if fb == 0.0 {
        out.push(b);
        return;
    }
    if fa.signum() == fb.signum() {
        return;
    }
    // Below the rounding noise at x the sign of the evaluation means nothing: the root is as
    // good as the polynomial allows. The term magnitudes grow with |x|, so the ends give a
    // cheap first bound before the exact one is computed.
    let noise = 4.0 * f64::EPSILON * magnitude(c, a).max(magnitude(c, b));
    let (mut lo, mut hi) = if fa < 0.0 { (a, b) } else { (b, a) };
    // In a monotone bracket the secant point is a good start for Newton.
    let mut x = a - fa * (b - a) / (fb - fa);
    if !(x > a.min(b) && x < a.max(b)) {
        x = 0.5 * (a + b);
    }
    for _ in 0..100 {
        let (f, df) = eval_with_derivative(c, x);
        if f.abs() <= noise && f.abs() <= 4.0 * f64::EPSILON * magnitude(c, x) {
            break;
        }
        if f < 0.0 {
            lo = x;
        } else {
            hi = x;
        }
        if (hi - lo).abs() <= tol * lo.abs().max(hi.abs()) {
            break;
        }
        let newton = x - f / df;
        let next = if df != 0.0 && (newton - lo) * (newton - hi) < 0.0 {
            newton
        } else {
            0.5 * (lo + hi)
        };
        if (next - x).abs() <= tol * x.abs() {
            x = next;
            break;
        }
        x = next;
    }
    out.push(x);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quartic_with_four_known_roots() {
        // (x-1)(x-2)(x-3)(x-4) = x^4 - 10x^3 + 35x^2 - 50x + 24
        let roots = real_roots_in(&[1.0, -10.0, 35.0, -50.0, 24.0], 0.0, 10.0);
        let r = roots.as_slice();
        assert_eq!(r.len(), 4);
        for (got, want) in r.iter().zip([1.0, 2.0, 3.0, 4.0]) {
            assert!((got - want).abs() < 1e-12, "{got} vs {want}");
        }
    }

    #[test]
    fn interval_filters_roots() {
        let roots = real_roots_in(&[1.0, -10.0, 35.0, -50.0, 24.0], 1.5, 3.5);
        assert_eq!(roots.as_slice().len(), 2);
    }

    #[test]
    fn double_root_is_found() {
        // (x-2)^2 (x+1) = x^3 - 3x^2 + 4
        let roots = real_roots_in(&[1.0, -3.0, 0.0, 4.0], 0.0, 5.0);
        assert_eq!(roots.as_slice().len(), 1);
        assert!((roots.as_slice()[0] - 2.0).abs() < 1e-7);
    }

    #[test]
    fn cubic_root_of_two() {
        let roots = real_roots_in(&[1.0, 0.0, 0.0, -2.0], 0.0, 2.0);
        assert!((roots.as_slice()[0] - 2f64.cbrt()).abs() < 1e-15);
    }
}
