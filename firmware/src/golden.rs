//! Deterministic golden inputs shared by the QEMU binary and the host tests.
//!
//! Both sides generate the same inputs from integer arithmetic, run the same
//! firmware functions on them, and `host-tests` compares the outputs bit for bit.

use crate::lstm::{Lstm, LstmState};
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

/// Golden LSTM: number of inputs.
pub const LSTM_I: usize = 3;
/// Golden LSTM: input-layer width.
pub const LSTM_E: usize = 6;
/// Golden LSTM: number of cells.
pub const LSTM_H: usize = 8;
/// Golden LSTM: number of outputs.
pub const LSTM_O: usize = 2;
/// Golden LSTM: consecutive streaming steps compared.
pub const LSTM_STEPS: usize = 2_000;
/// The golden network type.
pub type GoldenLstm = Lstm<LSTM_I, LSTM_E, LSTM_H, LSTM_O>;

/// A value in [-scale, scale) from the hash of `seed`.
fn signed(seed: u32, scale: f32) -> f32 {
    scale * (2.0 * unit(hash(seed)) - 1.0)
}

/// The fixed small golden network: weights drawn from the hash with PyTorch's
/// U(±1/√H) scale (inflated so gates also saturate), non-trivial normalisation.
pub fn lstm_network() -> GoldenLstm {
    let mut n: u32 = 0x4c53_0000;
    let mut next = |scale: f32| {
        n += 1;
        signed(n, scale)
    };
    let k = 1.5;
    GoldenLstm {
        input_mean: core::array::from_fn(|_| next(2.0)),
        input_std: core::array::from_fn(|_| 0.5 + next(0.25)),
        w_in: core::array::from_fn(|_| core::array::from_fn(|_| next(k))),
        b_in: core::array::from_fn(|_| next(0.5)),
        w_ih: core::array::from_fn(|_| core::array::from_fn(|_| core::array::from_fn(|_| next(k)))),
        w_hh: core::array::from_fn(|_| core::array::from_fn(|_| core::array::from_fn(|_| next(k)))),
        b_gates: core::array::from_fn(|_| core::array::from_fn(|_| next(0.7))),
        w_out: core::array::from_fn(|_| core::array::from_fn(|_| next(k))),
        b_out: core::array::from_fn(|_| next(0.5)),
        output_mean: core::array::from_fn(|_| next(10.0)),
        output_std: core::array::from_fn(|_| 1.0 + next(0.5)),
    }
}

/// The golden input at step `t`: a slow sinusoid-like sweep plus hashed noise, so the
/// state sees both memory-worthy structure and saturation (inputs up to about ±6).
pub fn lstm_input(t: usize) -> [f32; LSTM_I] {
    core::array::from_fn(|k| {
        let phase = (t as f32) * (0.013 + 0.007 * k as f32);
        3.0 * math::sin(phase) + signed((t * LSTM_I + k) as u32 ^ 0x00ab_0000, 3.0)
    })
}

/// Streams the golden network from the zero state over `LSTM_STEPS` steps and calls
/// `emit(step, outputs)` after each; the state is reset at step `LSTM_STEPS / 2` so the
/// reset path is compared too.
pub fn lstm_stream(mut emit: impl FnMut(usize, &[f32; LSTM_O])) {
    let net = lstm_network();
    let mut state = LstmState::new();
    for t in 0..LSTM_STEPS {
        if t == LSTM_STEPS / 2 {
            state.reset();
        }
        let y = net.step(&mut state, &lstm_input(t));
        emit(t, &y);
    }
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
