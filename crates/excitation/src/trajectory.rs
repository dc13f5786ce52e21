//! The finite Fourier-series trajectory family of Swevers et al., as used by Zhang et al. 2020:
//! per joint `q_i(t) = q_i0 + Σ_{k=1..N} (a_ik sin(k ω_f t) + b_ik cos(k ω_f t))`.
//!
//! The trajectory is periodic with period `T = 2π / ω_f`, so whatever holds at `t = 0`
//! (rest pose, zero velocity, zero acceleration) holds again at `t = T`: the end conditions
//! follow from the start conditions by construction.

use anyhow::ensure;
use serde::{Deserialize, Serialize};
use std::f64::consts::TAU;

/// Default number of harmonics (the paper uses 5).
pub const DEFAULT_HARMONICS: usize = 5;
/// Default period in seconds (ω_f = 2π / 10 s = 0.628 rad/s; the paper's trajectories last 10 s).
pub const DEFAULT_PERIOD_S: f64 = 10.0;
/// Default controller (playback) rate in Hz (the paper logs at 100 Hz).
pub const DEFAULT_RATE_HZ: f64 = 100.0;

/// Fourier coefficients of one joint, in radians.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JointFourier {
    /// Constant offset `q_i0` in rad.
    pub q0_rad: f64,
    /// Sine coefficients `a_ik`, k = 1..N, in rad.
    pub a_rad: Vec<f64>,
    /// Cosine coefficients `b_ik`, k = 1..N, in rad.
    pub b_rad: Vec<f64>,
}

impl JointFourier {
    /// The coefficients packed as `[q0, a_1..a_N, b_1..b_N]` (the order [`basis`] uses).
    pub fn packed(&self) -> Vec<f64> {
        let mut c = Vec::with_capacity(1 + 2 * self.a_rad.len());
        c.push(self.q0_rad);
        c.extend_from_slice(&self.a_rad);
        c.extend_from_slice(&self.b_rad);
        c
    }

    /// Unpacks `[q0, a_1..a_N, b_1..b_N]`.
    pub fn from_packed(c: &[f64]) -> Self {
        let n = (c.len() - 1) / 2;
        Self {
            q0_rad: c[0],
            a_rad: c[1..1 + n].to_vec(),
            b_rad: c[1 + n..1 + 2 * n].to_vec(),
        }
    }
}

/// Which derivative of the position a basis row or a constraint is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Derivative {
    /// Position `q` (rad).
    Position,
    /// Velocity `q̇` (rad/s).
    Velocity,
    /// Acceleration `q̈` (rad/s²).
    Acceleration,
}

/// Basis row at time `t_s`: the value of the chosen derivative is `basis · [q0, a, b]`.
/// `out` has length `1 + 2N`.
pub fn basis(
    derivative: Derivative,
    harmonics: usize,
    omega_rad_s: f64,
    t_s: f64,
    out: &mut [f64],
) {
    debug_assert_eq!(out.len(), 1 + 2 * harmonics);
    out[0] = if derivative == Derivative::Position {
        1.0
    } else {
        0.0
    };
    for k in 1..=harmonics {
        let w = k as f64 * omega_rad_s;
        let (s, c) = (w * t_s).sin_cos();
        let (da, db) = match derivative {
            Derivative::Position => (s, c),
            Derivative::Velocity => (w * c, -w * s),
            Derivative::Acceleration => (-w * w * s, -w * w * c),
        };
        out[k] = da;
        out[harmonics + k] = db;
    }
}

/// An excitation trajectory: Fourier coefficients for each moving joint.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ExcitationTrajectory {
    /// Period `T` in seconds; `ω_f = 2π / T`.
    pub period_s: f64,
    /// Number of harmonics `N`.
    pub harmonics: usize,
    /// Coefficients of each moving joint, in trajectory order.
    pub joints: Vec<JointFourier>,
}

/// Positions, velocities and accelerations of all moving joints at one instant.
#[derive(Debug, Clone, PartialEq)]
pub struct TrajectoryPoint {
    /// Joint positions in rad.
    pub q_rad: Vec<f64>,
    /// Joint velocities in rad/s.
    pub qd_rad_s: Vec<f64>,
    /// Joint accelerations in rad/s².
    pub qdd_rad_s2: Vec<f64>,
}

/// A trajectory sampled on a uniform time grid (row `k` is time `t_s[k]`).
#[derive(Debug, Clone, PartialEq)]
pub struct SampledTrajectory {
    /// Sample times in s.
    pub t_s: Vec<f64>,
    /// Positions, one `Vec` per sample, in rad.
    pub q_rad: Vec<Vec<f64>>,
    /// Velocities, one `Vec` per sample, in rad/s.
    pub qd_rad_s: Vec<Vec<f64>>,
    /// Accelerations, one `Vec` per sample, in rad/s².
    pub qdd_rad_s2: Vec<Vec<f64>>,
}

impl ExcitationTrajectory {
    /// Fundamental angular frequency `ω_f` in rad/s.
    pub fn omega_rad_s(&self) -> f64 {
        TAU / self.period_s
    }

    /// Number of moving joints.
    pub fn joint_count(&self) -> usize {
        self.joints.len()
    }

    /// Evaluates position, velocity and acceleration of every joint at `t_s` into the slices.
    pub fn eval_into(&self, t_s: f64, q: &mut [f64], qd: &mut [f64], qdd: &mut [f64]) {
        let w0 = self.omega_rad_s();
        for (j, jf) in self.joints.iter().enumerate() {
            let (mut p, mut v, mut a) = (jf.q0_rad, 0.0, 0.0);
            for k in 1..=self.harmonics {
                let w = k as f64 * w0;
                let (s, c) = (w * t_s).sin_cos();
                let (ak, bk) = (jf.a_rad[k - 1], jf.b_rad[k - 1]);
                p += ak * s + bk * c;
                v += w * (ak * c - bk * s);
                a -= w * w * (ak * s + bk * c);
            }
            q[j] = p;
            qd[j] = v;
            qdd[j] = a;
        }
    }

    /// Evaluates the trajectory at one instant.
    pub fn eval(&self, t_s: f64) -> TrajectoryPoint {
        let n = self.joint_count();
        let mut p = TrajectoryPoint {
            q_rad: vec![0.0; n],
            qd_rad_s: vec![0.0; n],
            qdd_rad_s2: vec![0.0; n],
        };
        self.eval_into(t_s, &mut p.q_rad, &mut p.qd_rad_s, &mut p.qdd_rad_s2);
        p
    }

    /// Samples `periods` periods at `rate_hz`, both ends included (`t = 0` and `t = periods·T`).
    pub fn sample(&self, rate_hz: f64, periods: usize) -> SampledTrajectory {
        let count = sample_count(self.period_s * periods as f64, rate_hz);
        let dt = self.period_s * periods as f64 / (count - 1) as f64;
        let mut out = SampledTrajectory {
            t_s: Vec::with_capacity(count),
            q_rad: Vec::with_capacity(count),
            qd_rad_s: Vec::with_capacity(count),
            qdd_rad_s2: Vec::with_capacity(count),
        };
        for i in 0..count {
            let t = i as f64 * dt;
            let p = self.eval(t);
            out.t_s.push(t);
            out.q_rad.push(p.q_rad);
            out.qd_rad_s.push(p.qd_rad_s);
            out.qdd_rad_s2.push(p.qdd_rad_s2);
        }
        out
    }
}

/// Number of samples (both ends included) of a `duration_s` grid at `rate_hz`, so that the step
/// is at most `1 / rate_hz`.
pub fn sample_count(duration_s: f64, rate_hz: f64) -> usize {
    (duration_s * rate_hz - 1e-9).ceil().max(1.0) as usize + 1
}

/// Largest harmonic count of a Fourier trajectory file (the designer uses 5).
pub const MAX_HARMONICS: usize = 1000;

/// Largest position bound |q0| + sum(|a_k| + |b_k|) a Fourier trajectory may imply [rad].
pub const MAX_TRAJECTORY_Q_RAD: f64 = 1e3;
/// Largest velocity bound sum(k w (|a_k| + |b_k|)) a Fourier trajectory may imply [rad/s].
pub const MAX_TRAJECTORY_QD_RAD_S: f64 = 1e4;
/// Largest acceleration bound sum((k w)^2 (|a_k| + |b_k|)) a Fourier trajectory may imply
/// [rad/s^2].
pub const MAX_TRAJECTORY_QDD_RAD_S2: f64 = 1e6;

/// Seeded trajectories for tests and demos, and the checks of a trajectory read from a file.
impl ExcitationTrajectory {
    /// A seeded rest-to-rest trajectory (`q = q_rest`, `qd = qdd = 0` at `t = 0` and at
    /// every period, by construction: `a_1`, `b_1` and `q0` are solved from the other
    /// coefficients), scaled so `|q - q_rest| <= q_max`, `|qd| <= qd_max`, `|qdd| <= qdd_max`
    /// on a grid 20x finer than 100 Hz. For tests and demos; the optimised excitation comes
    /// from `model-export excite`.
    pub fn seeded_rest_to_rest(
        seed: u64,
        q_rest_rad: &[f64],
        harmonics: usize,
        period_s: f64,
        limits: (f64, f64, f64),
    ) -> Self {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let mut joints = Vec::new();
        for _ in q_rest_rad {
            let mut a: Vec<f64> = (0..harmonics).map(|_| rng.gen_range(-1.0..1.0)).collect();
            let mut b: Vec<f64> = (0..harmonics).map(|_| rng.gen_range(-1.0..1.0)).collect();
            // qd(0) = w sum k a_k = 0, qdd(0) = -w^2 sum k^2 b_k = 0.
            a[0] = -(2..=harmonics).map(|k| k as f64 * a[k - 1]).sum::<f64>();
            b[0] = -(2..=harmonics)
                .map(|k| (k * k) as f64 * b[k - 1])
                .sum::<f64>();
            joints.push(JointFourier {
                q0_rad: 0.0,
                a_rad: a,
                b_rad: b,
            });
        }
        let mut tr = ExcitationTrajectory {
            period_s,
            harmonics,
            joints,
        };
        let (q_max, qd_max, qdd_max) = limits;
        let n = tr.joints.len();
        let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        let mut peak = vec![(0.0f64, 0.0f64, 0.0f64); n];
        let grid = (period_s * 2000.0) as usize;
        for i in 0..=grid {
            tr.eval_into(period_s * i as f64 / grid as f64, &mut q, &mut qd, &mut qdd);
            for j in 0..n {
                // Position about the offset-free series value at t = 0.
                peak[j].0 = peak[j].0.max(q[j].abs());
                peak[j].1 = peak[j].1.max(qd[j].abs());
                peak[j].2 = peak[j].2.max(qdd[j].abs());
            }
        }
        for (j, jf) in tr.joints.iter_mut().enumerate() {
            // |q - q(0)| <= |q| + |q(0)| <= 2 peak.
            let s = (q_max / (2.0 * peak[j].0))
                .min(qd_max / peak[j].1)
                .min(qdd_max / peak[j].2);
            jf.a_rad
                .iter_mut()
                .chain(jf.b_rad.iter_mut())
                .for_each(|c| *c *= s);
            jf.q0_rad = q_rest_rad[j] - jf.b_rad.iter().sum::<f64>();
        }
        tr
    }

    /// Checks a trajectory read from a file: a positive period, at most [`MAX_HARMONICS`]
    /// harmonics, matching coefficient counts, and finite bounds of q, q̇ and q̈.
    pub fn validate(&self) -> anyhow::Result<()> {
        ensure!(
            self.period_s.is_finite() && self.period_s > 0.0,
            "period_s = {} must be > 0",
            self.period_s
        );
        ensure!(!self.joints.is_empty(), "no joints");
        ensure!(
            self.harmonics <= MAX_HARMONICS,
            "field harmonics = {}: at most {MAX_HARMONICS}",
            self.harmonics
        );
        for (j, jf) in self.joints.iter().enumerate() {
            ensure!(
                jf.a_rad.len() == self.harmonics && jf.b_rad.len() == self.harmonics,
                "joint {}: a_rad and b_rad must have {} entries",
                j + 1,
                self.harmonics
            );
            ensure!(
                jf.q0_rad.is_finite() && jf.a_rad.iter().chain(&jf.b_rad).all(|x| x.is_finite()),
                "joint {}: non-finite coefficient",
                j + 1
            );
            // Finite coefficients can still overflow once scaled by k w and (k w)^2:
            // the bounds of q, qd and qdd they imply are checked, not only the inputs.
            let w = self.omega_rad_s();
            let (mut q, mut qd, mut qdd) = (jf.q0_rad.abs(), 0.0f64, 0.0f64);
            for (k, (a, b)) in jf.a_rad.iter().zip(&jf.b_rad).enumerate() {
                let (amp, kw) = (a.abs() + b.abs(), (k + 1) as f64 * w);
                q += amp;
                qd += kw * amp;
                qdd += kw * kw * amp;
            }
            for (field, bound, max) in [
                ("q0_rad, a_rad, b_rad: |q|", q, MAX_TRAJECTORY_Q_RAD),
                ("a_rad, b_rad, period_s: |qd|", qd, MAX_TRAJECTORY_QD_RAD_S),
                (
                    "a_rad, b_rad, period_s: |qdd|",
                    qdd,
                    MAX_TRAJECTORY_QDD_RAD_S2,
                ),
            ] {
                ensure!(
                    bound <= max,
                    "joint {}, fields {field} can reach {bound:e}, above the limit {max:e}",
                    j + 1
                );
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn example() -> ExcitationTrajectory {
        ExcitationTrajectory {
            period_s: 10.0,
            harmonics: 3,
            joints: vec![
                JointFourier {
                    q0_rad: 0.1,
                    a_rad: vec![0.2, -0.1, 0.05],
                    b_rad: vec![0.3, 0.0, -0.02],
                },
                JointFourier {
                    q0_rad: -0.4,
                    a_rad: vec![0.0, 0.1, 0.0],
                    b_rad: vec![0.1, 0.1, 0.1],
                },
            ],
        }
    }

    #[test]
    fn derivatives_match_finite_differences() {
        let tr = example();
        let h = 1e-5;
        for &t in &[0.0, 1.3, 4.7, 9.99] {
            let (m, p, c) = (tr.eval(t - h), tr.eval(t + h), tr.eval(t));
            for j in 0..2 {
                let v = (p.q_rad[j] - m.q_rad[j]) / (2.0 * h);
                let a = (p.qd_rad_s[j] - m.qd_rad_s[j]) / (2.0 * h);
                assert!(
                    (v - c.qd_rad_s[j]).abs() < 1e-7,
                    "velocity {v} vs {}",
                    c.qd_rad_s[j]
                );
                assert!((a - c.qdd_rad_s2[j]).abs() < 1e-7, "acceleration {a}");
            }
        }
    }

    #[test]
    fn basis_rows_reproduce_evaluation() {
        let tr = example();
        let w = tr.omega_rad_s();
        let mut row = vec![0.0; 7];
        let t = 2.345;
        let pt = tr.eval(t);
        for (j, jf) in tr.joints.iter().enumerate() {
            let c = jf.packed();
            for (d, want) in [
                (Derivative::Position, pt.q_rad[j]),
                (Derivative::Velocity, pt.qd_rad_s[j]),
                (Derivative::Acceleration, pt.qdd_rad_s2[j]),
            ] {
                basis(d, 3, w, t, &mut row);
                let got: f64 = row.iter().zip(&c).map(|(r, c)| r * c).sum();
                assert!((got - want).abs() < 1e-12);
            }
            assert_eq!(JointFourier::from_packed(&c), *jf);
        }
    }

    #[test]
    fn sampling_includes_both_ends_at_the_requested_rate() {
        let s = example().sample(100.0, 1);
        assert_eq!(s.t_s.len(), 1001);
        assert_eq!(s.t_s[0], 0.0);
        assert!((s.t_s[1000] - 10.0).abs() < 1e-12);
        assert!((s.t_s[1] - 0.01).abs() < 1e-12);
    }
}
