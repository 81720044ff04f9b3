//! Small fixed-point helpers shared by the twin, the estimator and the classifier.
//!
//! # Formats in types
//!
//! [`Q<T, F>`](Q) is an integer `T` that stands for `T / 2^F` (`F` fractional bits, written
//! `QF` or `Qm.F` in the documentation). The format is part of the type, so a coefficient
//! declared `Q<i64, 12>` cannot be added to a `Q<i64, 24>`, and a product names the format it
//! is shifted to: `let f: Q<i64, 12> = spring.mul_floor(x)` with `spring: Q<i64, 4>` and
//! `x: Q<i64, 32>` forms `spring · x` (Q36) and drops 24 bits. The shift is derived from the
//! three formats at compile time (a format that would need a negative shift does not compile).
//!
//! Every operation is the plain integer operation on the raw values, in the order written, so
//! code moved onto `Q` produces the same bits as the raw arithmetic it replaces, and with
//! `#[repr(transparent)]` and `#[inline(always)]` the same integer instructions (the twin's move
//! onto `Q` left the firmware's flash and per-sample instruction counts unchanged or lower):
//!
//! - products are formed in `i64` and shifted back; right shifts of negative values round
//!   toward minus infinity (arithmetic shift, `_floor`), the same on every target;
//!   [`Q::mul_round`] rounds to nearest (ties toward +∞, [`rshr`]);
//! - `+`, `-`, `*` by an integer and negation are the integer operators (overflow-checked in
//!   debug and test builds, like the raw code), no hidden saturation; saturation is explicit
//!   ([`Q::saturate`], [`Q::saturating_mul_floor`]);
//! - [`Q::from_f64`] (rounding, saturating) is for init time only; [`Q::to_f64`] for reports.
//!
//! Why not the `fixed` crate: its types fix one width and format per value and multiply within
//! one format (`FixedI64<U24> * FixedI64<U24>`), while the twin's arithmetic multiplies mixed
//! formats in a wide integer and chooses each shift (Q24 · Q32 → Q56, then 24 bits dropped).
//! Written with `fixed` every such product would go through `to_bits`/`from_bits` to keep the
//! exact shifts and roundings (the golden checkpoints must stay bit-identical), which is the
//! raw arithmetic again plus a dependency (`typenum`, `az`, `bytemuck`, `half`) in a `no_std`
//! core whose firmware image has a few dozen bytes of flash to spare. This type is a few lines,
//! carries the format the same way, and compiles to the raw integer code.

use core::ops::{Add, AddAssign, Div, Mul, Neg, Sub, SubAssign};

/// A fixed-point number with `F` fractional bits stored in the integer `T` (value = raw / 2^F).
///
/// `Copy`, `#[repr(transparent)]`: a `Q<i64, 24>` is an `i64` in memory and in registers.
/// Comparisons compare the raw values (formats are equal by type). The operations exist for
/// `T = i32` (state, storage) and `T = i64` (coefficients and the products of the per-sample
/// arithmetic); see the [module documentation](self) for the conventions.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
#[repr(transparent)]
pub struct Q<T, const F: u32>(pub T);

/// Shift that brings a product of formats `F` and `G` to format `H` (compile-time checked).
#[inline(always)]
const fn product_shift<const F: u32, const G: u32, const H: u32>() -> u32 {
    const { assert!(F + G >= H, "the product has fewer fractional bits than the result format") };
    F + G - H
}

/// Left shift of the dividend that brings a quotient of formats `F` / `G` to format `H`.
#[inline(always)]
const fn quotient_shift<const F: u32, const G: u32, const H: u32>() -> u32 {
    const { assert!(H + G >= F, "the quotient has fewer fractional bits than the result format") };
    H + G - F
}

mod sealed {
    pub trait Sealed {}
    impl Sealed for i32 {}
    impl Sealed for i64 {}
}

/// The integers a [`Q`] number is stored in: `i32` and `i64` (sealed).
pub trait QInt: Copy + sealed::Sealed {
    /// Zero.
    const ZERO: Self;
    /// A float already rounded to an integer, by an `as` cast (saturating, NaN to 0).
    fn from_rounded_f64(x: f64) -> Self;
    /// The integer as a float (exact for `i32`, rounded to nearest for `i64`).
    fn to_f64(self) -> f64;
}

/// `2^F` in the integer `Self` (a compile error where it does not fit): [`Q::ONE`].
pub trait QOne<const F: u32>: QInt {
    /// One in format `F`.
    const ONE: Self;
}

macro_rules! q_int {
    ($t:ty) => {
        impl QInt for $t {
            const ZERO: Self = 0;
            #[inline]
            fn from_rounded_f64(x: f64) -> Self {
                x as $t
            }
            #[inline]
            fn to_f64(self) -> f64 {
                self as f64
            }
        }
        impl<const F: u32> QOne<F> for $t {
            const ONE: Self = 1 << F;
        }
    };
}

q_int!(i32);
q_int!(i64);

// One inherent impl for both integers, so that `Q::ZERO`, `Q::ONE` and `Q::from_f64` resolve
// where the format comes from the context (a field, an argument).
impl<T: QInt, const F: u32> Q<T, F> {
    /// Number of fractional bits.
    pub const FRAC_BITS: u32 = F;
    /// Zero.
    pub const ZERO: Self = Self(T::ZERO);

    /// From a float, rounding to nearest and saturating to the integer range, NaN to 0 (init
    /// time only: `libm`, never in a per-sample path).
    pub fn from_f64(x: f64) -> Self {
        Self(T::from_rounded_f64(libm::round(x * libm::ldexp(1.0, F as i32))))
    }

    /// The value as a float (for reports; exact for `i32`).
    pub fn to_f64(self) -> f64 {
        self.0.to_f64() / libm::ldexp(1.0, F as i32)
    }
}

impl<T: QOne<F>, const F: u32> Q<T, F> {
    /// One (1.0); a compile error where `F` leaves no integer bit.
    pub const ONE: Self = Self(T::ONE);
}

macro_rules! q_common {
    ($t:ty) => {
        impl<const F: u32> Q<$t, F> {
            /// Quotient in format `H`: `(self << (H + G − F)) / rhs` (the integer division,
            /// truncating toward zero; the shifted dividend must fit in the integer).
            #[inline(always)]
            pub const fn div_trunc<const G: u32, const H: u32>(self, rhs: Q<$t, G>) -> Q<$t, H> {
                Q((self.0 << quotient_shift::<F, G, H>()) / rhs.0)
            }

            /// Absolute value (the integer's `abs`).
            #[inline(always)]
            pub const fn abs(self) -> Self {
                Self(self.0.abs())
            }
        }

        impl<const F: u32> Add for Q<$t, F> {
            type Output = Self;
            #[inline(always)]
            fn add(self, rhs: Self) -> Self {
                Self(self.0 + rhs.0)
            }
        }

        impl<const F: u32> Sub for Q<$t, F> {
            type Output = Self;
            #[inline(always)]
            fn sub(self, rhs: Self) -> Self {
                Self(self.0 - rhs.0)
            }
        }

        impl<const F: u32> AddAssign for Q<$t, F> {
            #[inline(always)]
            fn add_assign(&mut self, rhs: Self) {
                self.0 += rhs.0;
            }
        }

        impl<const F: u32> SubAssign for Q<$t, F> {
            #[inline(always)]
            fn sub_assign(&mut self, rhs: Self) {
                self.0 -= rhs.0;
            }
        }

        impl<const F: u32> Neg for Q<$t, F> {
            type Output = Self;
            #[inline(always)]
            fn neg(self) -> Self {
                Self(-self.0)
            }
        }

        /// Division by a plain integer (truncating toward zero): the format is unchanged.
        impl<const F: u32> Div<$t> for Q<$t, F> {
            type Output = Self;
            #[inline(always)]
            fn div(self, rhs: $t) -> Self {
                Self(self.0 / rhs)
            }
        }

        /// Scaling by a plain integer (a count, a sign): the format is unchanged.
        impl<const F: u32> Mul<$t> for Q<$t, F> {
            type Output = Self;
            #[inline(always)]
            fn mul(self, rhs: $t) -> Self {
                Self(self.0 * rhs)
            }
        }
    };
}

q_common!(i32);
q_common!(i64);

impl<const F: u32> Q<i32, F> {
    /// The same value in an `i64` (for products).
    #[inline(always)]
    pub const fn widen(self) -> Q<i64, F> {
        Q(self.0 as i64)
    }
}

impl<const F: u32> Q<i64, F> {
    /// Product in format `H`, rounded toward minus infinity: `(self · rhs) >> (F + G − H)`.
    #[inline(always)]
    pub const fn mul_floor<const G: u32, const H: u32>(self, rhs: Q<i64, G>) -> Q<i64, H> {
        Q(self.0 * rhs.0 >> product_shift::<F, G, H>())
    }

    /// Product in format `H`, rounded to nearest with ties toward +∞ ([`rshr`]). `F + G − H`
    /// must be at least 1.
    #[inline(always)]
    pub const fn mul_round<const G: u32, const H: u32>(self, rhs: Q<i64, G>) -> Q<i64, H> {
        Q(rshr(self.0 * rhs.0, product_shift::<F, G, H>()))
    }

    /// As [`Self::mul_floor`] with the product saturated to the `i64` range first.
    #[inline(always)]
    pub const fn saturating_mul_floor<const G: u32, const H: u32>(self, rhs: Q<i64, G>) -> Q<i64, H> {
        Q(self.0.saturating_mul(rhs.0) >> product_shift::<F, G, H>())
    }

    /// As [`Self::mul_floor`] with the product formed in `i128`, so it cannot overflow, and the
    /// shifted result saturated to the `i64` range: the same bits as [`Self::mul_floor`]
    /// wherever that does not overflow. For the extended twin's products of a Q40 increment
    /// and a Q24/Q30 factor, whose 64-bit product only fits for small orifices or volumes.
    #[inline(always)]
    pub const fn wide_mul_floor<const G: u32, const H: u32>(self, rhs: Q<i64, G>) -> Q<i64, H> {
        Q(sat_i64((self.0 as i128 * rhs.0 as i128) >> product_shift::<F, G, H>()))
    }

    /// The same value in format `G`: shifted left (exact) or right (rounded toward minus
    /// infinity).
    #[inline(always)]
    pub const fn rescale<const G: u32>(self) -> Q<i64, G> {
        let (left, right) = const {
            if G >= F {
                (G - F, 0)
            } else {
                (0, F - G)
            }
        };
        Q(self.0 << left >> right)
    }

    /// To `i32`, saturating ([`sat_i32`]).
    #[inline(always)]
    pub const fn saturate(self) -> Q<i32, F> {
        Q(sat_i32(self.0))
    }

    /// To `i32` by an `as` cast (keeps the low 32 bits): only for values the caller has
    /// already clamped into the `i32` range.
    #[inline(always)]
    pub const fn narrow(self) -> Q<i32, F> {
        Q(self.0 as i32)
    }
}

/// Rounding arithmetic right shift: `round(a / 2^s)` with ties toward +∞. `s` must be 1..=62.
#[inline(always)]
pub const fn rshr(a: i64, s: u32) -> i64 {
    (a + (1i64 << (s - 1))) >> s
}

/// Saturating conversion of an `i128` to `i64`.
#[inline(always)]
pub const fn sat_i64(a: i128) -> i64 {
    if a > i64::MAX as i128 {
        i64::MAX
    } else if a < i64::MIN as i128 {
        i64::MIN
    } else {
        a as i64
    }
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
        assert_eq!(Q::<i32, 8>::from_f64(f64::NAN), Q(0));
        assert_eq!(Q::<i32, 8>::from_f64(1e30), Q(i32::MAX));
        assert_eq!(Q::<i64, 8>::from_f64(-1e30), Q(i64::MIN));
        assert_eq!(Q::<i32, 1>::from_f64(1.5), Q(3));
        assert_eq!(Q::<i64, 40>(i64::MAX).saturate(), Q::<i32, 40>(i32::MAX));
        assert_eq!(Q::<i64, 4>(i64::MAX).saturating_mul_floor::<4, 4>(Q(2)), Q(i64::MAX >> 4));
    }

    #[test]
    fn conversions_round_trip() {
        assert_eq!(Q::<i32, 24>::ONE, Q(1 << 24));
        assert_eq!(Q::<i32, 32>::from_f64(0.06), Q(257_698_038));
        assert_eq!(Q::<i32, 32>(257_698_038).to_f64(), 257_698_038.0 / 4_294_967_296.0);
        assert_eq!(Q::<i64, 36>::from_f64(0.25).0, Q::<i64, 24>::from_f64(0.25 * 4096.0).0);
        assert_eq!(Q::<i64, 12>(-3 << 12).to_f64(), -3.0);
    }

    #[test]
    fn products_and_shifts_are_the_raw_integer_operations() {
        let a = Q::<i64, 24>(-123_456_789);
        let b = Q::<i64, 32>(987_654_321);
        let floor: Q<i64, 32> = a.mul_floor(b);
        assert_eq!(floor.0, -123_456_789i64 * 987_654_321 >> 24);
        let round: Q<i64, 24> = a.mul_round(b);
        assert_eq!(round.0, rshr(-123_456_789i64 * 987_654_321, 32));
        assert_eq!(Q::<i64, 12>(-4097).rescale::<4>(), Q(-4097 >> 8));
        assert_eq!(Q::<i64, 4>(-3).rescale::<12>(), Q(-3 << 8));
        assert_eq!(Q::<i32, 4>(-100).div_trunc::<4, 16>(Q(7)), Q((-100 << 16) / 7));
        assert_eq!(Q::<i32, 24>(-5).widen(), Q::<i64, 24>(-5));
        assert_eq!(Q::<i64, 0>(1 << 40 | 5).narrow(), Q::<i32, 0>(5));
        assert_eq!(Q::<i64, 3>(5) * -2 + Q(1) - Q(2), Q(-11));
        assert_eq!(-Q::<i64, 3>(5).abs(), Q(-5));
        // The wide forms equal the narrow ones where those fit, and saturate where not.
        let w: Q<i64, 32> = a.wide_mul_floor(b);
        assert_eq!(w, floor);
        let big = Q::<i64, 40>(1 << 40);
        assert_eq!(big.wide_mul_floor::<30, 40>(Q(1 << 30)), big);
        assert_eq!(Q::<i64, 0>(i64::MAX).wide_mul_floor::<0, 0>(Q(2)), Q(i64::MAX));
        assert_eq!(Q::<i64, 0>(i64::MIN).wide_mul_floor::<0, 0>(Q(2)), Q(i64::MIN));
    }
}
