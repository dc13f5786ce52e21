//! Deterministic golden inputs shared by the QEMU binary and the host tests.
//!
//! Both sides generate the same inputs from integer arithmetic, run the same
//! firmware functions on them, and `host-tests` compares the outputs bit for bit.

use crate::math;

/// Number of points per scalar function.
pub const MATH_POINTS: usize = 10_000;
/// Length of each dot-product vector.
pub const DOT_LEN: usize = 64;
/// Number of dot-product cases.
pub const DOT_CASES: usize = 1_000;

/// A scalar primitive under test.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MathFn {
    /// `math::exp`
    Exp,
    /// `math::tanh`
    Tanh,
    /// `math::sigmoid`
    Sigmoid,
    /// `math::sqrt`
    Sqrt,
    /// `math::sin`
    Sin,
    /// `math::cos`
    Cos,
}

impl MathFn {
    /// Every primitive, in report order.
    pub const ALL: [MathFn; 6] = [
        MathFn::Exp,
        MathFn::Tanh,
        MathFn::Sigmoid,
        MathFn::Sqrt,
        MathFn::Sin,
        MathFn::Cos,
    ];

    /// Short name used in the QEMU output and in mismatch reports.
    pub const fn name(self) -> &'static str {
        match self {
            MathFn::Exp => "exp",
            MathFn::Tanh => "tanh",
            MathFn::Sigmoid => "sigmoid",
            MathFn::Sqrt => "sqrt",
            MathFn::Sin => "sin",
            MathFn::Cos => "cos",
        }
    }

    /// Looks a primitive up by its `name`.
    pub fn from_name(name: &str) -> Option<MathFn> {
        MathFn::ALL.into_iter().find(|f| f.name() == name)
    }

    /// Input range covered: what an LSTM gate (±16 and beyond into saturation)
    /// and the dynamics (angles of several turns, inertia sums) need.
    pub const fn range(self) -> (f32, f32) {
        match self {
            MathFn::Exp => (-87.0, 88.0),
            MathFn::Tanh | MathFn::Sigmoid => (-20.0, 20.0),
            MathFn::Sqrt => (0.0, 1.0e4),
            MathFn::Sin | MathFn::Cos => (-25.0, 25.0),
        }
    }

    /// Evaluates the firmware primitive.
    pub fn eval(self, x: f32) -> f32 {
        match self {
            MathFn::Exp => math::exp(x),
            MathFn::Tanh => math::tanh(x),
            MathFn::Sigmoid => math::sigmoid(x),
            MathFn::Sqrt => math::sqrt(x),
            MathFn::Sin => math::sin(x),
            MathFn::Cos => math::cos(x),
        }
    }

    /// The `i`-th golden input: even indices sweep the range evenly, odd ones are
    /// pseudo-random in it (so the sweep also hits non-grid mantissas).
    pub fn input(self, i: usize) -> f32 {
        let (lo, hi) = self.range();
        let frac = if i % 2 == 0 {
            i as f32 / (MATH_POINTS - 1) as f32
        } else {
            unit(hash(i as u32 ^ (self as u32) << 24))
        };
        lo + (hi - lo) * frac
    }
}

/// The `case`-th pair of dot-product vectors, entries in [-4, 4).
pub fn dot_case(case: usize) -> ([f32; DOT_LEN], [f32; DOT_LEN]) {
    let mut a = [0.0f32; DOT_LEN];
    let mut b = [0.0f32; DOT_LEN];
    for k in 0..DOT_LEN {
        let seed = (case * DOT_LEN + k) as u32;
        a[k] = 8.0 * unit(hash(seed.wrapping_mul(2))) - 4.0;
        b[k] = 8.0 * unit(hash(seed.wrapping_mul(2) + 1)) - 4.0;
    }
    (a, b)
}

/// Output of the `case`-th dot product.
pub fn dot_output(case: usize) -> f32 {
    let (a, b) = dot_case(case);
    math::dot(&a, &b)
}

/// A 32-bit integer hash (lowbias32), the generator behind the golden inputs.
pub const fn hash(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

/// Maps a hash to [0, 1) with 24 bits of resolution (exact in f32).
pub fn unit(h: u32) -> f32 {
    (h >> 8) as f32 * (1.0 / 16_777_216.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inputs_cover_the_range() {
        for f in MathFn::ALL {
            let (lo, hi) = f.range();
            assert_eq!(f.input(0), lo);
            assert_eq!(f.input(MATH_POINTS - 1 - (MATH_POINTS - 1) % 2), f.input(9998));
            for i in 0..MATH_POINTS {
                let x = f.input(i);
                assert!(x >= lo && x <= hi, "{} {i} {x}", f.name());
            }
            assert_eq!(MathFn::from_name(f.name()), Some(f));
        }
    }
}
