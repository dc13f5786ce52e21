//! Scalar and fixed-size vector math used by the dynamics model and the LSTM.
//!
//! Everything is pure software (libm) or a single IEEE-754 operation (`sqrt`), with
//! a fixed evaluation order and no fused multiply-add, so host and Cortex-M4F give
//! the same bits.

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

/// Square root (IEEE-754 correctly rounded on both host and target).
#[inline]
pub fn sqrt(x: f32) -> f32 {
    libm::sqrtf(x)
}

/// Sine of an angle in radians.
#[inline]
pub fn sin(x: f32) -> f32 {
    libm::sinf(x)
}

/// Cosine of an angle in radians.
#[inline]
pub fn cos(x: f32) -> f32 {
    libm::cosf(x)
}

/// Sine and cosine of one angle in radians.
#[inline]
pub fn sin_cos(x: f32) -> (f32, f32) {
    libm::sincosf(x)
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
            assert!((sin(x) - x.sin()).abs() < 1e-6);
            assert!((cos(x) - x.cos()).abs() < 1e-6);
            assert_eq!(sqrt(x.abs()), x.abs().sqrt());
        }
    }

    #[test]
    fn dot_sums_in_order() {
        let a = [1.0f32, 2.0, 3.0];
        let b = [4.0f32, -5.0, 6.0];
        assert_eq!(dot(&a, &b), 12.0);
    }
}
