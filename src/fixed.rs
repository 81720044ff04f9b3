//! Small fixed-point helpers shared by the twin, the estimator and the classifier.
//!
//! Every quantity documents its Q format where it is declared (`Qm.n`: n fractional bits).
//! Products are formed in `i64` and shifted back; right shifts of negative values round
//! toward minus infinity (arithmetic shift), which is the same on every target.

/// Rounding arithmetic right shift: `round(a / 2^s)` with ties toward +∞. `s` must be 1..=62.
#[inline(always)]
pub const fn rshr(a: i64, s: u32) -> i64 {
    (a + (1i64 << (s - 1))) >> s
}

/// Saturating conversion of an `i64` to `i32`.
#[inline(always)]
pub const fn sat_i32(a: i64) -> i32 {
    if a > i32::MAX as i64 {
        i32::MAX
    } else if a < i32::MIN as i64 {
        i32::MIN
    } else {
        a as i32
    }
}

/// Converts a float to fixed point with `frac` fractional bits, rounding to nearest and
/// saturating to `i32` (init-time only; never called in a per-sample path).
pub fn to_q_i32(x: f64, frac: u32) -> i32 {
    let q = libm::round(x * libm::ldexp(1.0, frac as i32));
    q as i32 // saturating, NaN -> 0
}

/// As [`to_q_i32`] into an `i64`.
pub fn to_q_i64(x: f64, frac: u32) -> i64 {
    let q = libm::round(x * libm::ldexp(1.0, frac as i32));
    q as i64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rounding_shift_rounds_to_nearest() {
        assert_eq!(rshr(5, 1), 3); // 2.5 -> 3
        assert_eq!(rshr(-5, 1), -2); // -2.5 -> -2 (ties toward +inf)
        assert_eq!(rshr(6, 2), 2); // 1.5 -> 2
        assert_eq!(rshr(1 << 40, 40), 1);
    }

    #[test]
    fn saturation() {
        assert_eq!(sat_i32(i64::MAX), i32::MAX);
        assert_eq!(sat_i32(i64::MIN), i32::MIN);
        assert_eq!(sat_i32(-7), -7);
        assert_eq!(to_q_i32(f64::NAN, 8), 0);
        assert_eq!(to_q_i32(1e30, 8), i32::MAX);
        assert_eq!(to_q_i32(1.5, 1), 3);
    }
}
