//! Scalar and fixed-size vector math used by the dynamics model and the LSTM.
//!
//! Everything is pure software (libm, or f32-only code here for sin/cos and the f32
//! kernels' sigmoid/tanh) or a single IEEE-754 operation (`sqrt`), with a fixed
//! evaluation order and no fused multiply-add, so host and Cortex-M4F give the same
//! bits.

/// e^x.
#[inline]
pub fn exp(x: f32) -> f32 {
    libm::expf(x)
}

/// Hyperbolic tangent.
#[inline]
pub fn tanh(x: f32) -> f32 {
    libm::tanhf(x)
}

/// Logistic sigmoid 1 / (1 + e^-x), evaluated without overflow for any finite x.
#[inline]
pub fn sigmoid(x: f32) -> f32 {
    if x >= 0.0 {
        1.0 / (1.0 + libm::expf(-x))
    } else {
        let e = libm::expf(x);
        e / (1.0 + e)
    }
}

// e^r on [-ln2/2, ln2/2] (Cephes expf): 1 + r + r^2 (P0 r^5 + ... + P5), ~1 ulp.
const EXP_P0: f32 = 1.987_569_2e-4;
const EXP_P1: f32 = 1.398_199_9e-3;
const EXP_P2: f32 = 8.333_452e-3;
const EXP_P3: f32 = 4.166_579_6e-2;
const EXP_P4: f32 = 0.166_666_65;
const EXP_P5: f32 = 0.5;
// ln 2 = LN2_HI + LN2_LO; LN2_HI = 355/512 has 9 significant bits, so k * LN2_HI is
// exact for the k < 2^7 used here.
const LN2_HI: f32 = 0.693_359_4;
const LN2_LO: f32 = -2.121_944_4e-4;

/// The constants of [`lstm_gates_fast`] in the order `dsp::lstm_cells_f32`'s assembly
/// loads them: the clamp -87, -log2 e, 0.5 (also P5), ln 2 high and low parts, P0-P4,
/// 1 and the tanh clamp 9; all but the first are [`tanh_fast4`]'s, in the order
/// `dsp::mul_tanh4_f32`'s and `dsp::tanh4_bias_f32`'s assembly loads them.
#[cfg_attr(not(fw_dsp_asm), allow(dead_code))]
pub(crate) static LSTM_CELL_CONSTANTS: [f32; 12] = [
    -87.0,
    -core::f32::consts::LOG2_E,
    0.5,
    LN2_HI,
    LN2_LO,
    EXP_P0,
    EXP_P1,
    EXP_P2,
    EXP_P3,
    EXP_P4,
    1.0,
    9.0,
];

/// e^y for y <= 0 in f32 only (no f64, no division): k = round(-y / ln 2), r = y + k ln 2
/// (two-part ln 2), the Cephes `expf` polynomial for e^r, times 2^-k built from its
/// bits. y is clamped to >= -87 (e^-87 = 1.6e-38, still normal); NaN stays NaN.
#[inline(always)]
fn exp_nonpositive(y: f32) -> f32 {
    let y = if y < -87.0 { -87.0 } else { y };
    let u = y * -core::f32::consts::LOG2_E;
    // u in [0, 125.6]: truncating u + 0.5 rounds to nearest (NaN gives 0).
    let k = (u + 0.5) as i32;
    let kf = k as f32;
    let r = (y + kf * LN2_HI) + kf * LN2_LO;
    let z = r * r;
    let p = (((((EXP_P0 * r + EXP_P1) * r + EXP_P2) * r + EXP_P3) * r + EXP_P4) * r + EXP_P5) * z
        + r
        + 1.0;
    p * f32::from_bits(((127 - k) as u32) << 23)
}

/// [`exp_nonpositive`] of four values at once: lane for lane the same operations in
/// the same order (the same bits), written one operation at a time across the four
/// lanes, which gives the compiler four independent chains to interleave (on the
/// Cortex-M4 FPU a result read by the next instruction stalls a cycle).
#[inline(always)]
fn exp_nonpositive4(y: [f32; 4]) -> [f32; 4] {
    let lanes = |f: &dyn Fn(usize) -> f32| [f(0), f(1), f(2), f(3)];
    let y = y.map(|v| if v < -87.0 { -87.0 } else { v });
    let u = lanes(&|l| y[l] * -core::f32::consts::LOG2_E);
    let u = lanes(&|l| u[l] + 0.5);
    let k = u.map(|v| v as i32);
    let kf = k.map(|v| v as f32);
    let hi = lanes(&|l| kf[l] * LN2_HI);
    let lo = lanes(&|l| kf[l] * LN2_LO);
    let r = lanes(&|l| y[l] + hi[l]);
    let r = lanes(&|l| r[l] + lo[l]);
    let z = lanes(&|l| r[l] * r[l]);
    let mut p = lanes(&|l| EXP_P0 * r[l]);
    for c in [EXP_P1, EXP_P2, EXP_P3, EXP_P4] {
        p = lanes(&|l| p[l] + c);
        p = lanes(&|l| p[l] * r[l]);
    }
    let p = lanes(&|l| p[l] + EXP_P5);
    let p = lanes(&|l| p[l] * z[l]);
    let p = lanes(&|l| p[l] + r[l]);
    let p = lanes(&|l| p[l] + 1.0);
    [0, 1, 2, 3].map(|l| p[l] * f32::from_bits(((127 - k[l]) as u32) << 23))
}

/// The four gate activations of one LSTM cell, `[sigmoid(i), sigmoid(f), tanh(g),
/// sigmoid(o)]`: bit for bit [`sigmoid_fast`] and [`tanh_fast`], with the four
/// exponentials computed side by side ([`exp_nonpositive4`]).
#[inline(always)]
pub fn lstm_gates_fast(x: [f32; 4]) -> [f32; 4] {
    let a = x.map(f32::abs);
    let a2 = if a[2] > 9.0 { 9.0 } else { a[2] };
    let e = exp_nonpositive4([-a[0], -a[1], -2.0 * a2, -a[3]]);
    let sig = |l: usize| {
        let num = if x[l] >= 0.0 { 1.0 } else { e[l] };
        num / (1.0 + e[l])
    };
    let t = (1.0 - e[2]) / (1.0 + e[2]);
    [sig(0), sig(1), if x[2] < 0.0 { -t } else { t }, sig(3)]
}

/// [`tanh_fast`] of four values, bit for bit, the exponentials side by side.
#[inline(always)]
pub fn tanh_fast4(x: [f32; 4]) -> [f32; 4] {
    let a = x.map(|v| {
        let a = v.abs();
        if a > 9.0 { 9.0 } else { a }
    });
    let e = exp_nonpositive4(a.map(|v| -2.0 * v));
    [0, 1, 2, 3].map(|l| {
        let t = (1.0 - e[l]) / (1.0 + e[l]);
        if x[l] < 0.0 { -t } else { t }
    })
}

/// Logistic sigmoid for the f32 kernels (`nn::kernels::F32Lstm`): `1 / (1 + e^-x)` for
/// x >= 0, `e^x / (1 + e^x)` below, with an f32-only e^-|x| (Cephes polynomial, no
/// special cases beyond the clamp) and one division: about half the estimated
/// Cortex-M4 cycles of [`sigmoid`] (libm `expf`), measured in the f32 LSTM step. Same
/// bits on host and target (IEEE single adds, multiplies and one division in a fixed
/// order, no FMA).
/// Accuracy against f64 (measured by `math::tests`): relative error <= 4e-7.
#[inline]
pub fn sigmoid_fast(x: f32) -> f32 {
    let e = exp_nonpositive(-x.abs());
    let num = if x >= 0.0 { 1.0 } else { e };
    num / (1.0 + e)
}

/// Hyperbolic tangent for the f32 kernels (`nn::kernels::F32Lstm`): `sign(x) (1 - e) /
/// (1 + e)` with `e = e^-2|x|` from the f32-only exponential of [`sigmoid_fast`]
/// (|x| clamped to 9, where tanh rounds to 1). Same bits on host and target.
/// Accuracy against f64 (measured by `math::tests`): absolute error <= 2e-7 (near 0
/// the result is `1 - e` of an e accurate to an ulp, so small |x| has a larger
/// relative error; the absolute error is what the LSTM's sums see).
#[inline]
pub fn tanh_fast(x: f32) -> f32 {
    let a = x.abs();
    let a = if a > 9.0 { 9.0 } else { a };
    let e = exp_nonpositive(-2.0 * a);
    let t = (1.0 - e) / (1.0 + e);
    if x < 0.0 { -t } else { t }
}

/// Square root (IEEE-754 correctly rounded on both host and target).
#[inline]
pub fn sqrt(x: f32) -> f32 {
    libm::sqrtf(x)
}

/// Largest |x| (rad) for which [`sin_cos`] uses the three-part Cody-Waite reduction
/// (2^12 rad); beyond it the angle is first reduced with the exact `fmodf` by 2π in
/// f32 (see [`sin_cos`]).
pub const SIN_COS_REDUCTION_LIMIT_RAD: f32 = 4096.0;

// pi/2 = PIO2_HI + PIO2_MID + PIO2_LO. HI and MID have 12 significant bits each, so
// k * HI and k * MID are exact for |k| < 2^12 (|x| <= 2^12 rad gives |k| <= 2608), and
// x - k * HI is exact (Sterbenz-like: both are multiples of 2^-24 and |result| < 1).
const PIO2_HI: f32 = 3217.0 / 2048.0; // exact: 1.57080078125
const PIO2_MID: f32 = -2391.0 / 536_870_912.0; // exact: -2391 / 2^29
const PIO2_LO: f32 = -8.705_516_3e-10; // pi/2 - HI - MID rounded to f32
const TWO_OVER_PI: f32 = core::f32::consts::FRAC_2_PI;
const TWO_PI: f32 = core::f32::consts::TAU;

// Minimax polynomials on [-pi/4, pi/4] (the Cephes sinf/cosf coefficients):
// sin r = r + r^3 (S1 + r^2 (S2 + r^2 S3)), cos r = 1 - r^2/2 + r^4 (C1 + r^2 (C2 + r^2 C3)).
const S1: f32 = -0.166_666_55;
const S2: f32 = 0.008_332_161;
const S3: f32 = -0.000_195_152_96;
const C1: f32 = 0.041_666_646;
const C2: f32 = -0.001_388_731_6;
const C3: f32 = 2.443_315_7e-5;

/// Sine of an angle in radians (see [`sin_cos`] for accuracy and method).
#[inline]
pub fn sin(x: f32) -> f32 {
    sin_cos(x).0
}

/// Cosine of an angle in radians (see [`sin_cos`] for accuracy and method).
#[inline]
pub fn cos(x: f32) -> f32 {
    sin_cos(x).1
}

/// Sine and cosine of one angle in radians, computed entirely in f32.
///
/// libm's `sincosf` works in f64, which the Cortex-M4F runs in software; this one uses
/// only single-precision adds and multiplies in a fixed order (no division, no FMA, no
/// f64), so it is fast on the FPU and bit-identical on host and target.
///
/// Method: k = round(x * 2/π); r = ((x - k·HI) - k·MID) - k·LO with a three-part π/2
/// (Cody-Waite), valid for |x| <= [`SIN_COS_REDUCTION_LIMIT_RAD`] (2^12 rad); then
/// minimax polynomials for sin and cos on [-π/4, π/4] and the quadrant k mod 4.
/// For 2^12 < |x| the angle is first reduced exactly by the f32 value of 2π with
/// `libm::fmodf` (integer arithmetic): the result is then the sine of an angle off by
/// (|x| / 2π) · 1.7e-7 rad, below 3e-5 rad·|x|/1000 — less than the spacing of f32
/// inputs there (2^-11 rad at 2^12). Non-finite x gives NaN for both.
///
/// Accuracy (measured against f64 `sin`/`cos` by `math::tests`, 2·10^6 points): absolute
/// error <= 1.2e-7 (measured 1.11e-7, about 2 ulp of values near 1) for |x| <= 2^12 rad.
#[inline]
pub fn sin_cos(x: f32) -> (f32, f32) {
    // |x| as its bit pattern: non-negative floats order as their bits, so the range
    // check is one integer compare, and NaN and the infinities are beyond it too.
    let abs_bits = x.to_bits() & 0x7fff_ffff;
    let x = if abs_bits > SIN_COS_REDUCTION_LIMIT_RAD.to_bits() {
        if abs_bits >= f32::INFINITY.to_bits() {
            return (f32::NAN, f32::NAN);
        }
        libm::fmodf(x, TWO_PI)
    } else {
        x
    };
    let kf = x * TWO_OVER_PI;
    // Round half away from zero (kf + 0.5 or kf - 0.5, written as one add of the signed
    // half: the same bits, one conversion); |kf| <= 2608 so it cannot saturate. kf has
    // the sign of x (or is -0.0 for a tiny negative x, where either half gives k = 0),
    // so the half is chosen from x, which is ready earlier.
    let half = if x >= 0.0 { 0.5 } else { -0.5 };
    let k = (kf + half) as i32;
    let kf = k as f32;
    let r = ((x - kf * PIO2_HI) - kf * PIO2_MID) - kf * PIO2_LO;
    let z = r * r;
    let s = r + (r * z) * (S1 + z * (S2 + z * S3));
    let c = (1.0 - 0.5 * z) + (z * z) * (C1 + z * (C2 + z * C3));
    match k & 3 {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

/// Dot product of two fixed-size vectors, summed left to right.
#[inline]
pub fn dot<const N: usize>(a: &[f32; N], b: &[f32; N]) -> f32 {
    let mut acc = 0.0f32;
    for (x, y) in a.iter().zip(b.iter()) {
        acc += x * y;
    }
    acc
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fast_sigmoid_and_tanh_error_against_f64() {
        let (mut es, mut et) = (0.0f64, 0.0f64);
        for i in 0..=2_000_000u32 {
            let x = -40.0 + 80.0 * (i as f32 / 2_000_000.0);
            let xd = x as f64;
            let s = 1.0 / (1.0 + (-xd).exp());
            es = es.max(((sigmoid_fast(x) as f64 - s) / s).abs());
            et = et.max((tanh_fast(x) as f64 - xd.tanh()).abs());
        }
        std::println!("sigmoid_fast max rel error {es:.2e}, tanh_fast max abs error {et:.2e}");
        assert!(es <= 4e-7, "sigmoid {es}");
        assert!(et <= 2e-7, "tanh {et}");
        assert_eq!(tanh_fast(0.0), 0.0);
        assert_eq!(sigmoid_fast(0.0), 0.5);
        assert_eq!(tanh_fast(100.0), 1.0);
        assert_eq!(tanh_fast(-100.0), -1.0);
        assert_eq!(sigmoid_fast(200.0), 1.0);
        assert!(sigmoid_fast(-200.0) >= 0.0 && sigmoid_fast(-200.0) < 1e-37);
        assert!(sigmoid_fast(f32::NAN).is_nan() && tanh_fast(f32::NAN).is_nan());
    }

    #[test]
    fn four_lane_activations_are_bit_for_bit_the_scalar_ones() {
        let mut seed = 0x2545_f491u32;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            // Mostly [-24, 24], some raw bit patterns (huge, tiny, NaN, infinities).
            if seed.is_multiple_of(8) {
                f32::from_bits(seed.rotate_left(7))
            } else {
                (seed as f32 / u32::MAX as f32 - 0.5) * 48.0
            }
        };
        let special = [
            0.0f32,
            -0.0,
            9.0,
            -9.0,
            87.0,
            -87.0,
            1e-30,
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
        ];
        let same = |a: f32, b: f32| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
        for n in 0..200_000 {
            let x: [f32; 4] = if n < special.len() {
                [special[n]; 4]
            } else {
                [next(), next(), next(), next()]
            };
            let g = lstm_gates_fast(x);
            let want = [
                sigmoid_fast(x[0]),
                sigmoid_fast(x[1]),
                tanh_fast(x[2]),
                sigmoid_fast(x[3]),
            ];
            let t = tanh_fast4(x);
            for l in 0..4 {
                assert!(
                    same(g[l], want[l]),
                    "gates {x:?} lane {l}: {} vs {}",
                    g[l],
                    want[l]
                );
                assert!(same(t[l], tanh_fast(x[l])), "tanh {x:?} lane {l}");
            }
        }
    }

    #[test]
    fn sigmoid_is_symmetric_and_saturates() {
        for &x in &[0.0f32, 0.5, 3.0, 20.0, 100.0] {
            assert!((sigmoid(x) + sigmoid(-x) - 1.0).abs() < 1e-6);
        }
        assert_eq!(sigmoid(-200.0), 0.0);
        assert_eq!(sigmoid(200.0), 1.0);
        assert!(sigmoid(f32::MAX).is_finite() && sigmoid(f32::MIN).is_finite());
    }

    #[test]
    fn primitives_agree_with_std() {
        for i in 0..1000 {
            let x = -8.0 + 16.0 * i as f32 / 999.0;
            assert!((exp(x) - x.exp()).abs() <= 2e-6 * x.exp());
            assert!((tanh(x) - x.tanh()).abs() < 1e-6);
            assert!((sin(x) - x.sin()).abs() < 2e-7);
            assert!((cos(x) - x.cos()).abs() < 2e-7);
            assert_eq!(sqrt(x.abs()), x.abs().sqrt());
        }
    }

    /// Largest |f32 result - f64 reference| of sin and cos over `n` evenly spread
    /// f32 inputs in [-limit, limit].
    fn max_sin_cos_error(limit: f32, n: u32) -> (f64, f64) {
        let (mut es, mut ec) = (0.0f64, 0.0f64);
        for i in 0..=n {
            let x = -limit + 2.0 * limit * (i as f32 / n as f32);
            let (s, c) = sin_cos(x);
            assert_eq!(
                (s.to_bits(), c.to_bits()),
                (sin(x).to_bits(), cos(x).to_bits())
            );
            let xd = x as f64;
            es = es.max((s as f64 - xd.sin()).abs());
            ec = ec.max((c as f64 - xd.cos()).abs());
        }
        (es, ec)
    }

    #[test]
    fn sin_cos_error_against_f64_is_as_documented() {
        let (es, ec) = max_sin_cos_error(100.0, 2_000_000);
        std::println!("|x| <= 100: max abs error sin {es:.3e}, cos {ec:.3e}");
        assert!(es <= 1.2e-7 && ec <= 1.2e-7, "{es} {ec}");
        let (es, ec) = max_sin_cos_error(SIN_COS_REDUCTION_LIMIT_RAD, 2_000_000);
        std::println!("|x| <= 2^12: max abs error sin {es:.3e}, cos {ec:.3e}");
        assert!(es <= 1.2e-7 && ec <= 1.2e-7, "{es} {ec}");
        // Near pi/4 quadrant edges and exact multiples of pi/2 in f32.
        for k in -2600i32..=2600 {
            let x = k as f32 * core::f32::consts::FRAC_PI_2;
            for x in [
                x,
                f32::from_bits(x.to_bits() + 1),
                f32::from_bits(x.to_bits().max(1) - 1),
            ] {
                let (s, c) = sin_cos(x);
                let xd = x as f64;
                assert!((s as f64 - xd.sin()).abs() <= 1.2e-7, "sin {x}");
                assert!((c as f64 - xd.cos()).abs() <= 1.2e-7, "cos {x}");
            }
        }
    }

    #[test]
    fn sin_cos_beyond_reduction_limit_and_non_finite() {
        // Beyond 2^12 rad: exact fmod by 2pi_f32 then the same kernel; the angle error
        // is (|x| / 2pi) * |2pi - 2pi_f32| (1.75e-7 rad per turn), plus the kernel's.
        for &x in &[4097.0f32, -5000.5, 1.0e5, -3.3e6, 1.0e9, f32::MAX] {
            let (s, c) = sin_cos(x);
            let turns = (x as f64).abs() / core::f64::consts::TAU;
            let tol = 1.2e-7 + turns * 1.75e-7 * 1.01;
            let xd = x as f64;
            assert!((s as f64 - xd.sin()).abs() <= tol, "sin {x}");
            assert!((c as f64 - xd.cos()).abs() <= tol, "cos {x}");
            assert!(s.abs() <= 1.0 && c.abs() <= 1.0);
        }
        for x in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            let (s, c) = sin_cos(x);
            assert!(s.is_nan() && c.is_nan());
        }
        assert_eq!(sin_cos(0.0), (0.0, 1.0));
    }

    #[test]
    fn dot_sums_in_order() {
        let a = [1.0f32, 2.0, 3.0];
        let b = [4.0f32, -5.0, 6.0];
        assert_eq!(dot(&a, &b), 12.0);
    }
}
