//! Signal processing for logs: uniform resampling, Butterworth low-pass applied
//! forward and backward (zero phase, like SciPy's `filtfilt`), central differences,
//! and a scalar Kalman filter for motor current.

use std::f64::consts::PI;

/// One second-order section (biquad), transposed direct form II, `a0 = 1`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Biquad {
    /// Numerator b0, b1, b2.
    pub b: [f64; 3],
    /// Denominator a1, a2.
    pub a: [f64; 2],
}

/// A Butterworth low-pass as a cascade of biquads (bilinear transform, pre-warped).
#[derive(Debug, Clone, PartialEq)]
pub struct ButterworthLowPass {
    /// The sections, applied in order.
    pub sections: Vec<Biquad>,
}

impl ButterworthLowPass {
    /// Designs an even-order (2, 4, 6, ...) low-pass with cut-off `cutoff_hz` for
    /// sample rate `sample_hz`. `None` if the order is odd/zero or the cut-off is not
    /// below Nyquist.
    pub fn new(order: usize, cutoff_hz: f64, sample_hz: f64) -> Option<Self> {
        if order == 0
            || !order.is_multiple_of(2)
            || !(cutoff_hz > 0.0 && cutoff_hz < 0.5 * sample_hz)
        {
            return None;
        }
        let k = (PI * cutoff_hz / sample_hz).tan();
        let k2 = k * k;
        let sections = (0..order / 2)
            .map(|i| {
                // Pole pair angle of the analogue prototype; q = 1 / (2 cos θ).
                let theta = PI * (2 * i + 1) as f64 / (2 * order) as f64;
                let inv_q = 2.0 * theta.cos();
                let norm = 1.0 / (1.0 + inv_q * k + k2);
                Biquad {
                    b: [k2 * norm, 2.0 * k2 * norm, k2 * norm],
                    a: [2.0 * (k2 - 1.0) * norm, (1.0 - inv_q * k + k2) * norm],
                }
            })
            .collect();
        Some(Self { sections })
    }

    /// Filters forward only, starting in the steady state of `x[0]`.
    pub fn filter(&self, x: &mut [f64]) {
        for s in &self.sections {
            let Some(&x0) = x.first() else { return };
            // Steady state for constant input x0 (DC gain 1): y = x0.
            let mut z2 = (s.b[2] - s.a[1]) * x0;
            let mut z1 = (s.b[1] - s.a[0]) * x0 + z2;
            for v in x.iter_mut() {
                let xi = *v;
                let y = s.b[0] * xi + z1;
                z1 = s.b[1] * xi - s.a[0] * y + z2;
                z2 = s.b[2] * xi - s.a[1] * y;
                *v = y;
            }
        }
    }

    /// Zero-phase filtering: odd reflection padding at both ends, forward pass, backward
    /// pass (the magnitude response is squared, the phase is zero).
    pub fn filtfilt(&self, x: &[f64], pad: usize) -> Vec<f64> {
        let n = x.len();
        if n < 2 {
            return x.to_vec();
        }
        let pad = pad.min(n - 1);
        let mut ext = Vec::with_capacity(n + 2 * pad);
        for i in (1..=pad).rev() {
            ext.push(2.0 * x[0] - x[i]);
        }
        ext.extend_from_slice(x);
        for i in 1..=pad {
            ext.push(2.0 * x[n - 1] - x[n - 1 - i]);
        }
        self.filter(&mut ext);
        ext.reverse();
        self.filter(&mut ext);
        ext.reverse();
        ext[pad..pad + n].to_vec()
    }
}

/// Linear interpolation of `(t, y)` (t strictly increasing) at the points `grid`
/// (all inside `[t[0], t[last]]`).
pub fn interpolate(t: &[f64], y: &[f64], grid: &[f64]) -> Vec<f64> {
    let mut k = 0usize;
    grid.iter()
        .map(|&g| {
            while k + 2 < t.len() && t[k + 1] < g {
                k += 1;
            }
            let (t0, t1) = (t[k], t[k + 1]);
            let w = ((g - t0) / (t1 - t0)).clamp(0.0, 1.0);
            y[k] + w * (y[k + 1] - y[k])
        })
        .collect()
}

/// A uniform grid from `t0` to at most `t1` with step `dt`.
pub fn uniform_grid(t0: f64, t1: f64, dt: f64) -> Vec<f64> {
    let n = ((t1 - t0) / dt + 1e-9).floor() as usize + 1;
    (0..n).map(|i| t0 + i as f64 * dt).collect()
}

/// Median spacing of a strictly increasing time vector.
pub fn median_step(t: &[f64]) -> f64 {
    let mut d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    d.sort_by(|a, b| a.total_cmp(b));
    d[d.len() / 2]
}

/// Derivative of `y(t)` by second-order central differences valid for non-uniform
/// spacing (one-sided second-order formulas at the ends).
pub fn derivative(t: &[f64], y: &[f64]) -> Vec<f64> {
    let n = y.len();
    if n < 3 {
        return vec![0.0; n];
    }
    let mut d = vec![0.0; n];
    for i in 1..n - 1 {
        let h0 = t[i] - t[i - 1];
        let h1 = t[i + 1] - t[i];
        d[i] = (h0 * h0 * y[i + 1] - h1 * h1 * y[i - 1] + (h1 * h1 - h0 * h0) * y[i])
            / (h0 * h1 * (h0 + h1));
    }
    // Second-order one-sided at the ends (three-point Lagrange derivative).
    let end = |t0: f64, t1: f64, t2: f64, y0: f64, y1: f64, y2: f64| {
        let (a, b) = (t1 - t0, t2 - t0);
        -(a + b) / (a * b) * y0 + b / (a * (b - a)) * y1 - a / (b * (b - a)) * y2
    };
    d[0] = end(t[0], t[1], t[2], y[0], y[1], y[2]);
    d[n - 1] = end(t[n - 1], t[n - 2], t[n - 3], y[n - 1], y[n - 2], y[n - 3]);
    d
}

/// The scalar Kalman filter used for motor current: random-walk state
/// `i_k = i_{k-1} + w` (variance `process_var`), measurement `z_k = i_k + v`
/// (variance `measurement_var`). Returns the filtered estimates.
pub fn kalman_current(z: &[f64], process_var: f64, measurement_var: f64) -> Vec<f64> {
    let Some(&z0) = z.first() else {
        return Vec::new();
    };
    let (mut x, mut p) = (z0, measurement_var);
    z.iter()
        .map(|&zk| {
            p += process_var;
            let gain = p / (p + measurement_var);
            x += gain * (zk - x);
            p *= 1.0 - gain;
            x
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn butterworth_dc_gain_and_cutoff_attenuation() {
        let fs = 100.0;
        for order in [2, 4] {
            let f = ButterworthLowPass::new(order, 5.0, fs).unwrap();
            let y = f.filtfilt(&[3.0; 50], 10);
            assert!(y.iter().all(|v| (v - 3.0).abs() < 1e-12));
            // Sine at the cut-off: forward-backward gives |H|² = 1/2 in the steady state.
            let x: Vec<f64> = (0..2000)
                .map(|i| (2.0 * PI * 5.0 * i as f64 / fs).sin())
                .collect();
            let y = f.filtfilt(&x, 200);
            let amp = y[800..1200].iter().fold(0.0f64, |m, v| m.max(v.abs()));
            assert!((amp - 0.5).abs() < 0.01, "order {order}: {amp}");
        }
        assert!(ButterworthLowPass::new(3, 5.0, 100.0).is_none());
        assert!(ButterworthLowPass::new(2, 60.0, 100.0).is_none());
    }

    #[test]
    fn filtfilt_has_zero_phase() {
        let fs = 100.0;
        let f = ButterworthLowPass::new(4, 10.0, fs).unwrap();
        let x: Vec<f64> = (0..1000)
            .map(|i| (2.0 * PI * 1.0 * i as f64 / fs).sin())
            .collect();
        let y = f.filtfilt(&x, 100);
        for i in 100..900 {
            assert!((y[i] - x[i]).abs() < 1e-3, "{i}: {} vs {}", y[i], x[i]);
        }
    }

    #[test]
    fn nonuniform_derivative_is_exact_for_quadratics() {
        let t = [0.0, 0.01, 0.013, 0.025, 0.03, 0.045];
        let y: Vec<f64> = t.iter().map(|t| 3.0 * t * t - 2.0 * t + 1.0).collect();
        let d = derivative(&t, &y);
        for (ti, di) in t.iter().zip(&d) {
            assert!((di - (6.0 * ti - 2.0)).abs() < 1e-9, "{ti}: {di}");
        }
    }

    #[test]
    fn interpolation_and_grid() {
        let t = [0.0, 0.01, 0.03];
        let y = [0.0, 1.0, 3.0];
        let g = uniform_grid(0.0, 0.03, 0.005);
        assert_eq!(g.len(), 7);
        let v = interpolate(&t, &y, &g);
        for (gi, vi) in g.iter().zip(&v) {
            assert!((vi - gi * 100.0).abs() < 1e-9);
        }
        assert!((median_step(&[0.0, 0.01, 0.03, 0.04]) - 0.01).abs() < 1e-12);
    }

    #[test]
    fn kalman_reduces_noise_variance() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let noise = Normal::new(0.0, 0.2).unwrap();
        let z: Vec<f64> = (0..5000).map(|_| 1.0 + noise.sample(&mut rng)).collect();
        let x = kalman_current(&z, 1e-5, 0.04);
        let var = |v: &[f64]| v[1000..].iter().map(|a| (a - 1.0).powi(2)).sum::<f64>() / 4000.0;
        assert!(var(&x) < 0.1 * var(&z), "{} vs {}", var(&x), var(&z));
    }
}
