//! Fast fixed-point text for the CSV files of `rtcnc sim`: the same characters as
//! `format!("{v:.N}")` (exact decimal value, ties to even, a sign on every negative value
//! including those that round to zero), from integer arithmetic instead of the general
//! float formatter, which costs several times more per number. Values too large for the
//! integer path, and NaN and infinities, go through the standard formatter.

use std::io::Write as _;

/// Largest number of decimals this supports on the integer path.
const MAX_DECIMALS: u32 = 9;

/// Appends `v` with `decimals` digits after the point, exactly as `{:.decimals$}` would.
pub fn push_fixed(out: &mut Vec<u8>, v: f64, decimals: u32) {
    let a = v.abs();
    // 2^53: every value below is m·2^e with m < 2^53 and e < 0 or an exact integer.
    if !a.is_finite() || a >= 9_007_199_254_740_992.0 || decimals > MAX_DECIMALS {
        let _ = write!(out, "{v:.prec$}", prec = decimals as usize);
        return;
    }
    let scale = 10u128.pow(decimals);
    let q = scaled_round_half_even(a, scale);
    if v.is_sign_negative() {
        out.push(b'-');
    }
    push_u128(out, q / scale);
    if decimals > 0 {
        out.push(b'.');
        let frac = q % scale;
        let mut digits = [b'0'; MAX_DECIMALS as usize];
        let mut f = frac;
        for d in digits[..decimals as usize].iter_mut().rev() {
            *d = b'0' + (f % 10) as u8;
            f /= 10;
        }
        out.extend_from_slice(&digits[..decimals as usize]);
    }
}

/// Appends an unsigned integer in decimal.
pub fn push_u64(out: &mut Vec<u8>, v: u64) {
    push_u128(out, u128::from(v));
}

fn push_u128(out: &mut Vec<u8>, mut v: u128) {
    let mut digits = [0u8; 40];
    let mut n = digits.len();
    loop {
        n -= 1;
        digits[n] = b'0' + (v % 10) as u8;
        v /= 10;
        if v == 0 {
            break;
        }
    }
    out.extend_from_slice(&digits[n..]);
}

/// `round(a · scale)` for `0 <= a < 2^53`, exactly, ties to even.
fn scaled_round_half_even(a: f64, scale: u128) -> u128 {
    if a == 0.0 {
        return 0;
    }
    let bits = a.to_bits();
    let exponent = ((bits >> 52) & 0x7ff) as i32;
    let fraction = bits & ((1u64 << 52) - 1);
    // a = mantissa · 2^shift_exp exactly.
    let (mantissa, shift_exp) = if exponent == 0 {
        (fraction, -1074)
    } else {
        (fraction | (1u64 << 52), exponent - 1075)
    };
    let numerator = u128::from(mantissa) * scale;
    if shift_exp >= 0 {
        // An integer below 2^53: shifting stays far inside u128.
        return numerator << shift_exp;
    }
    let shift = (-shift_exp) as u32;
    if shift >= 128 {
        // Below 2^-75 · 10^9: far under a half unit of the last digit.
        return 0;
    }
    let q = numerator >> shift;
    let rem = numerator & ((1u128 << shift) - 1);
    let half = 1u128 << (shift - 1);
    if rem > half || (rem == half && q & 1 == 1) {
        q + 1
    } else {
        q
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fixed(v: f64, decimals: u32) -> String {
        let mut out = Vec::new();
        push_fixed(&mut out, v, decimals);
        String::from_utf8(out).unwrap()
    }

    #[test]
    fn same_text_as_the_standard_formatter_on_chosen_cases() {
        let cases = [
            0.0,
            -0.0,
            0.25,
            0.5,
            1.5,
            2.5,
            -2.5,
            1e-9,
            -1e-9,
            5e-7,
            1.5e-6,
            2.5e-6,
            0.0000005,
            123.456_789_5,
            -2.5e-7,
            299.999_999_5,
            1e15,
            9.007e15,
            1e300,
            -1e300,
            5e-324,
            f64::MIN_POSITIVE,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            0.1,
            0.7,
            100.0,
        ];
        for v in cases {
            for d in [0, 1, 6, 7, 9] {
                assert_eq!(
                    fixed(v, d),
                    format!("{v:.prec$}", prec = d as usize),
                    "{v:e} {d}"
                );
            }
        }
    }

    #[test]
    fn same_text_as_the_standard_formatter_on_many_values() {
        // Random bit patterns in the range the CSV files hold, and exact binary fractions,
        // whose last digit may be a tie.
        let mut x = 0x2545_f491_4f6c_dd1du64;
        let n = if cfg!(debug_assertions) {
            20_000
        } else {
            500_000
        };
        for i in 0..n {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let magnitude = 10f64.powi((x % 16) as i32 - 10);
            let v = (x >> 11) as f64 / (1u64 << 53) as f64 * magnitude;
            let v = if i % 3 == 0 { -v } else { v };
            let tie = (x % 4096) as f64 / 2f64.powi((x % 30) as i32);
            for value in [v, tie] {
                for d in [6, 7] {
                    assert_eq!(
                        fixed(value, d),
                        format!("{value:.prec$}", prec = d as usize),
                        "{value:e}"
                    );
                }
            }
        }
    }

    #[test]
    fn integers() {
        let mut out = Vec::new();
        for v in [0, 7, 10, 1234567890, u64::MAX] {
            out.clear();
            push_u64(&mut out, v);
            assert_eq!(out, v.to_string().as_bytes());
        }
    }
}
