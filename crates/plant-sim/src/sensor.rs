//! Current sensing at the controller rate: white noise, ADC quantisation and, as an
//! option in the log chain, the paper's Kalman filter.
use rand::Rng;
use rand_distr::{Distribution, StandardNormal};

/// Quantises a current to the ADC's step `2 * full_scale / 2^bits`, saturating at the
/// full scale [A].
pub fn quantise(current_a: f64, full_scale_a: f64, bits: u32) -> f64 {
    let lsb = 2.0 * full_scale_a / f64::from(1u32 << bits);
    let max_code = f64::from((1u32 << (bits - 1)) - 1);
    let code = (current_a / lsb).round().clamp(-max_code - 1.0, max_code);
    code * lsb
}

/// Adds zero-mean Gaussian noise of standard deviation `std_a` [A].
pub fn add_noise<R: Rng>(rng: &mut R, current_a: f64, std_a: f64) -> f64 {
    if std_a > 0.0 {
        let n: f64 = StandardNormal.sample(rng);
        current_a + std_a * n
    } else {
        current_a
    }
}

/// Scalar Kalman filter of the paper's form for one motor current: random-walk state
/// `x_k = x_{k-1} + w_k`, measurement `z_k = x_k + v_k`, `w ~ N(0, Q)`, `v ~ N(0, R)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CurrentKalman {
    /// Process noise variance Q [A^2].
    pub process_var: f64,
    /// Measurement noise variance R [A^2].
    pub measurement_var: f64,
    estimate: f64,
    error_var: f64,
    started: bool,
}

impl CurrentKalman {
    /// A filter that takes its first measurement as the initial estimate.
    pub fn new(process_var: f64, measurement_var: f64) -> Self {
        CurrentKalman {
            process_var,
            measurement_var,
            estimate: 0.0,
            error_var: measurement_var,
            started: false,
        }
    }

    /// Feeds one measurement [A] and returns the filtered estimate [A].
    pub fn update(&mut self, measurement_a: f64) -> f64 {
        if !self.started {
            self.started = true;
            self.estimate = measurement_a;
            self.error_var = self.measurement_var;
            return self.estimate;
        }
        let p = self.error_var + self.process_var;
        let gain = p / (p + self.measurement_var);
        self.estimate += gain * (measurement_a - self.estimate);
        self.error_var = (1.0 - gain) * p;
        self.estimate
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn quantisation_is_round_to_nearest_and_saturates() {
        let lsb = 20.0 / 4096.0;
        assert_eq!(quantise(0.4 * lsb, 10.0, 12), 0.0);
        assert_eq!(quantise(0.6 * lsb, 10.0, 12), lsb);
        assert_eq!(quantise(1e3, 10.0, 12), 2047.0 * lsb);
        assert_eq!(quantise(-1e3, 10.0, 12), -2048.0 * lsb);
    }

    #[test]
    fn kalman_reduces_noise_on_a_constant() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let mut kf = CurrentKalman::new(1e-6, 1e-2);
        let (mut raw, mut filt) = (0.0, 0.0);
        for k in 0..2000 {
            let z = add_noise(&mut rng, 1.0, 0.1);
            let x = kf.update(z);
            if k >= 1000 {
                raw += (z - 1.0).powi(2);
                filt += (x - 1.0).powi(2);
            }
        }
        assert!(filt < 0.1 * raw, "{filt} {raw}");
    }
}
