//! Field-oriented current control of a three-phase BLDC/PMSM motor (f32).
//!
//! Clarke and Park transforms (amplitude-invariant), PI current controllers with
//! anti-windup by back-calculation, a circle limit on the dq voltage vector by the bus
//! voltage, inverse Park and space-vector modulation (min-max zero-sequence
//! injection) to three duty cycles. Every function runs in a fixed number of
//! operations; none can panic.

use crate::math;

const FRAC_1_SQRT_3: f32 = 0.577_350_26;
const SQRT_3_2: f32 = 0.866_025_4;

/// A value in the stationary two-phase frame (alpha, beta).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AlphaBeta {
    /// alpha component (along phase a).
    pub alpha: f32,
    /// beta component (90 electrical degrees ahead of alpha).
    pub beta: f32,
}

/// A value in the rotor frame (d along the rotor flux, q in quadrature).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Dq {
    /// Direct-axis component.
    pub d: f32,
    /// Quadrature-axis (torque-producing) component.
    pub q: f32,
}

/// Clarke transform of balanced phase values (a + b + c = 0) given a and b.
#[inline]
pub fn clarke(a: f32, b: f32) -> AlphaBeta {
    AlphaBeta {
        alpha: a,
        beta: FRAC_1_SQRT_3 * (a + 2.0 * b),
    }
}

/// Clarke transform of three phase values; the zero-sequence part is dropped.
#[inline]
pub fn clarke3(a: f32, b: f32, c: f32) -> AlphaBeta {
    AlphaBeta {
        alpha: (2.0 * a - b - c) * (1.0 / 3.0),
        beta: FRAC_1_SQRT_3 * (b - c),
    }
}

/// Inverse Clarke transform: three balanced phase values.
#[inline]
pub fn inverse_clarke(v: AlphaBeta) -> [f32; 3] {
    let a = v.alpha;
    let b = -0.5 * v.alpha + SQRT_3_2 * v.beta;
    let c = -0.5 * v.alpha - SQRT_3_2 * v.beta;
    [a, b, c]
}

/// Park transform with the electrical angle's sine and cosine.
#[inline]
pub fn park(v: AlphaBeta, sin: f32, cos: f32) -> Dq {
    Dq {
        d: v.alpha * cos + v.beta * sin,
        q: -v.alpha * sin + v.beta * cos,
    }
}

/// Inverse Park transform with the electrical angle's sine and cosine.
#[inline]
pub fn inverse_park(v: Dq, sin: f32, cos: f32) -> AlphaBeta {
    AlphaBeta {
        alpha: v.d * cos - v.q * sin,
        beta: v.d * sin + v.q * cos,
    }
}

/// Space-vector modulation of a stationary-frame voltage into three duty cycles in
/// [0, 1] for a bus of `bus_v` volts (min-max zero-sequence injection, which gives
/// the same phase-to-phase voltages as sector-based SVPWM). The linear range is
/// |v| <= bus_v / sqrt(3); beyond it the duties saturate. A non-positive or
/// non-finite bus gives 0.5 on every phase (zero voltage).
#[inline]
pub fn space_vector_duties(v: AlphaBeta, bus_v: f32) -> [f32; 3] {
    if !(bus_v > 0.0 && bus_v.is_finite()) {
        return [0.5; 3];
    }
    let [a, b, c] = inverse_clarke(v);
    let max = a.max(b).max(c);
    let min = a.min(b).min(c);
    let offset = -0.5 * (max + min);
    let inv_bus = 1.0 / bus_v;
    let duty = |x: f32| {
        let d = 0.5 + (x + offset) * inv_bus;
        // NaN compares false: it becomes 0.5 (zero voltage).
        if d >= 0.0 {
            if d <= 1.0 { d } else { 1.0 }
        } else if d < 0.0 {
            0.0
        } else {
            0.5
        }
    };
    [duty(a), duty(b), duty(c)]
}

/// Phase voltages (relative to the motor's star point) that three duties produce on
/// average over a PWM period: the inverse of [`space_vector_duties`] in its linear range.
#[inline]
pub fn duties_to_phase_voltages(duties: [f32; 3], bus_v: f32) -> [f32; 3] {
    let mean = (duties[0] + duties[1] + duties[2]) * (1.0 / 3.0);
    [
        (duties[0] - mean) * bus_v,
        (duties[1] - mean) * bus_v,
        (duties[2] - mean) * bus_v,
    ]
}

/// Limit a dq vector to a circle of radius `max` (d keeps priority, as it sets the
/// flux); returns the limited vector and whether the limit acted.
#[inline]
pub fn circle_limit(v: Dq, max: f32) -> (Dq, bool) {
    let max = if max > 0.0 { max } else { 0.0 };
    let d = super::clamp_abs(v.d, max);
    let q_max = math::sqrt((max * max - d * d).max(0.0));
    let q = super::clamp_abs(v.q, q_max);
    let limited = d != v.d || q != v.q;
    (Dq { d, q }, limited)
}

/// A PI controller whose integrator is kept consistent with a saturated output
/// (anti-windup by back-calculation).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PiController {
    /// Proportional gain (output units per error unit).
    pub kp: f32,
    /// Integral gain (output units per error unit per second).
    pub ki: f32,
    /// Integrator state (output units).
    pub integral: f32,
}

impl PiController {
    /// A controller with the given gains and an empty integrator.
    pub const fn new(kp: f32, ki: f32) -> Self {
        Self {
            kp,
            ki,
            integral: 0.0,
        }
    }

    /// The unlimited output for `error` after integrating it over `dt_s`; call
    /// [`PiController::back_calculate`] with the output actually applied.
    #[inline]
    pub fn update(&mut self, error: f32, dt_s: f32) -> f32 {
        self.integral += self.ki * error * dt_s;
        self.kp * error + self.integral
    }

    /// Anti-windup: move the integrator by what the limiter removed, so that the
    /// controller's output equals the applied (limited) output.
    #[inline]
    pub fn back_calculate(&mut self, unlimited: f32, applied: f32) {
        self.integral += applied - unlimited;
    }

    /// Empty the integrator.
    pub fn reset(&mut self) {
        self.integral = 0.0;
    }
}

/// The motor and power stage as the current loop sees them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotorParameters {
    /// Pole pairs (electrical angle = pole pairs * mechanical angle).
    pub pole_pairs: u8,
    /// Phase resistance, ohm (star equivalent).
    pub phase_resistance_ohm: f32,
    /// Phase (synchronous) inductance, henry.
    pub phase_inductance_h: f32,
    /// Permanent-magnet flux linkage, V*s/rad (electrical); the motor-side torque
    /// constant is 1.5 * pole pairs * flux linkage N*m/A.
    pub flux_linkage_wb: f32,
}

impl MotorParameters {
    /// The board's joint motor (the STM32G474 drive's BLDC; also the tests' motor).
    pub const BOARD: MotorParameters = MotorParameters {
        pole_pairs: 7,
        phase_resistance_ohm: 0.3,
        phase_inductance_h: 3e-4,
        flux_linkage_wb: 0.01,
    };

    /// Motor-side torque constant, N*m per A of q current.
    pub const fn torque_constant_nm_per_a(&self) -> f32 {
        1.5 * self.pole_pairs as f32 * self.flux_linkage_wb
    }
}

/// Configuration of the current loop.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CurrentLoopConfig {
    /// The motor.
    pub motor: MotorParameters,
    /// PWM (and current-loop) rate, Hz.
    pub pwm_hz: f32,
    /// Closed-loop current bandwidth, rad/s (PI gains by pole-zero cancellation).
    pub bandwidth_rad_s: f32,
    /// Largest usable fraction of the linear SVM range (|v| <= this * bus/sqrt(3)).
    pub max_modulation: f32,
    /// Add the back-EMF and cross-coupling terms to the dq voltages.
    pub decoupling: bool,
}

impl CurrentLoopConfig {
    /// The standard tuning for `motor` at `pwm_hz`: 6 000 rad/s closed-loop bandwidth,
    /// 95 % of the linear SVM range, back-EMF and cross-coupling decoupling on.
    pub const fn tuned(motor: MotorParameters, pwm_hz: f32) -> Self {
        CurrentLoopConfig {
            motor,
            pwm_hz,
            bandwidth_rad_s: 6000.0,
            max_modulation: 0.95,
            decoupling: true,
        }
    }
}

/// Output of one current-loop step.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CurrentLoopOutput {
    /// Duty cycles of phases a, b, c in [0, 1].
    pub duties: [f32; 3],
    /// Measured dq currents, A.
    pub i_dq_a: Dq,
    /// Applied (limited) dq voltages, V.
    pub v_dq_v: Dq,
    /// The voltage circle limit acted.
    pub voltage_limited: bool,
}

/// Field-oriented current loop: Clarke, Park, PI on d and q with anti-windup and
/// the voltage circle limit, inverse Park, space-vector modulation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CurrentLoop {
    config: CurrentLoopConfig,
    dt_s: f32,
    /// d-axis current controller (V per A).
    pub pi_d: PiController,
    /// q-axis current controller (V per A).
    pub pi_q: PiController,
}

impl CurrentLoop {
    /// A current loop with PI gains kp = L * bandwidth, ki = R * bandwidth.
    pub fn new(config: CurrentLoopConfig) -> Self {
        let m = &config.motor;
        let kp = m.phase_inductance_h * config.bandwidth_rad_s;
        let ki = m.phase_resistance_ohm * config.bandwidth_rad_s;
        Self {
            config,
            dt_s: 1.0 / config.pwm_hz,
            pi_d: PiController::new(kp, ki),
            pi_q: PiController::new(kp, ki),
        }
    }

    /// The configuration.
    pub fn config(&self) -> &CurrentLoopConfig {
        &self.config
    }

    /// Empty both integrators.
    pub fn reset(&mut self) {
        self.pi_d.reset();
        self.pi_q.reset();
    }

    /// One step at the PWM rate: measured phase currents a and b (A, balanced),
    /// electrical angle (rad), electrical speed (rad/s), bus voltage (V) and the dq
    /// current references (A) -> three duties. Inputs are assumed validated. On the
    /// target it runs from CCM SRAM.
    #[cfg_attr(target_os = "none", unsafe(link_section = ".ccmram_text"))]
    pub fn step(
        &mut self,
        i_ab_a: [f32; 2],
        angle_el_rad: f32,
        speed_el_rad_s: f32,
        bus_v: f32,
        reference_a: Dq,
    ) -> CurrentLoopOutput {
        let (sin, cos) = math::sin_cos(angle_el_rad);
        let i_dq = park(clarke(i_ab_a[0], i_ab_a[1]), sin, cos);
        let dt = self.dt_s;
        let vd_pi = self.pi_d.update(reference_a.d - i_dq.d, dt);
        let vq_pi = self.pi_q.update(reference_a.q - i_dq.q, dt);
        let (mut vd, mut vq) = (vd_pi, vq_pi);
        if self.config.decoupling {
            let m = &self.config.motor;
            vd -= speed_el_rad_s * m.phase_inductance_h * i_dq.q;
            vq += speed_el_rad_s * (m.phase_inductance_h * i_dq.d + m.flux_linkage_wb);
        }
        let v_max = self.config.max_modulation * bus_v * FRAC_1_SQRT_3;
        let (v, limited) = circle_limit(Dq { d: vd, q: vq }, v_max);
        // The limiter's cut goes back into each integrator (anti-windup).
        self.pi_d.back_calculate(vd, v.d);
        self.pi_q.back_calculate(vq, v.q);
        let duties = space_vector_duties(inverse_park(v, sin, cos), bus_v);
        CurrentLoopOutput {
            duties,
            i_dq_a: i_dq,
            v_dq_v: v,
            voltage_limited: limited,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn clarke_park_round_trips() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        for _ in 0..10_000 {
            let ab = AlphaBeta {
                alpha: rng.gen_range(-50.0..50.0),
                beta: rng.gen_range(-50.0..50.0),
            };
            let th: f32 = rng.gen_range(-10.0..10.0);
            let (s, c) = math::sin_cos(th);
            let back = inverse_park(park(ab, s, c), s, c);
            assert!((back.alpha - ab.alpha).abs() < 1e-4 && (back.beta - ab.beta).abs() < 1e-4);
            let [a, b, cc] = inverse_clarke(ab);
            assert!((a + b + cc).abs() < 1e-4);
            let ab2 = clarke(a, b);
            let ab3 = clarke3(a, b, cc);
            for x in [ab2, ab3] {
                assert!((x.alpha - ab.alpha).abs() < 1e-4 && (x.beta - ab.beta).abs() < 1e-4);
            }
        }
    }

    #[test]
    fn park_of_balanced_sinusoid_is_constant() {
        // i_a = I cos(th), i_b = I cos(th - 120 deg): d = I, q = 0 in the rotor frame.
        for k in 0..360 {
            let th = k as f32 * core::f32::consts::PI / 180.0;
            let ia = 3.0 * math::cos(th);
            let ib = 3.0 * math::cos(th - 2.094_395_1);
            let (s, c) = math::sin_cos(th);
            let dq = park(clarke(ia, ib), s, c);
            assert!((dq.d - 3.0).abs() < 1e-4 && dq.q.abs() < 1e-4, "{dq:?}");
        }
    }

    #[test]
    fn svm_duties_in_range_and_reproduce_voltage() {
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let bus = 48.0f32;
        for _ in 0..10_000 {
            // Inside the linear range: the averaged phase voltages reproduce v.
            let r = rng.gen_range(0.0..1.0f32) * bus * FRAC_1_SQRT_3 * 0.999;
            let th: f32 = rng.gen_range(-4.0..4.0);
            let v = AlphaBeta {
                alpha: r * math::cos(th),
                beta: r * math::sin(th),
            };
            let d = space_vector_duties(v, bus);
            assert!(d.iter().all(|x| (0.0..=1.0).contains(x)), "{d:?}");
            let back = clarke3(
                duties_to_phase_voltages(d, bus)[0],
                duties_to_phase_voltages(d, bus)[1],
                duties_to_phase_voltages(d, bus)[2],
            );
            assert!((back.alpha - v.alpha).abs() < 1e-3 && (back.beta - v.beta).abs() < 1e-3);
            // Far outside (and garbage): still in range.
            let huge = AlphaBeta {
                alpha: rng.gen_range(-1e30..1e30),
                beta: f32::NAN,
            };
            let d = space_vector_duties(huge, bus);
            assert!(d.iter().all(|x| (0.0..=1.0).contains(x)), "{d:?}");
        }
        assert_eq!(
            space_vector_duties(
                AlphaBeta {
                    alpha: 1.0,
                    beta: 0.0
                },
                f32::NAN
            ),
            [0.5; 3]
        );
        assert_eq!(
            space_vector_duties(
                AlphaBeta {
                    alpha: 1.0,
                    beta: 0.0
                },
                -3.0
            ),
            [0.5; 3]
        );
    }

    #[test]
    fn circle_limit_keeps_d_priority() {
        let (v, lim) = circle_limit(Dq { d: 3.0, q: 10.0 }, 5.0);
        assert!(lim && v.d == 3.0 && (v.q - 4.0).abs() < 1e-6);
        let (v, lim) = circle_limit(Dq { d: 1.0, q: 1.0 }, 5.0);
        assert!(!lim && v == Dq { d: 1.0, q: 1.0 });
        let (v, lim) = circle_limit(Dq { d: -9.0, q: 0.0 }, 5.0);
        assert!(lim && v.d == -5.0 && v.q == 0.0);
    }

    fn test_loop() -> CurrentLoop {
        CurrentLoop::new(CurrentLoopConfig {
            decoupling: false,
            ..CurrentLoopConfig::tuned(MotorParameters::BOARD, 20_000.0)
        })
    }

    #[test]
    fn anti_windup_bounds_integrator_and_recovers_fast() {
        let mut cl = test_loop();
        let bus = 24.0;
        let v_max = 0.95 * bus * FRAC_1_SQRT_3;
        // A locked rotor with zero measured current and a huge request: the output
        // saturates for a long time, the integrator stays at the limit.
        for _ in 0..20_000 {
            let out = cl.step([0.0, 0.0], 0.3, 0.0, bus, Dq { d: 0.0, q: 1000.0 });
            assert!(out.voltage_limited);
            assert!((out.v_dq_v.q - v_max).abs() < 1e-4);
        }
        assert!(
            cl.pi_q.integral <= v_max + 1e-3,
            "integrator wound up: {}",
            cl.pi_q.integral
        );
        // Request reversed: the output leaves saturation on the first step (no
        // wind-up to unwind).
        let out = cl.step([0.0, 0.0], 0.3, 0.0, bus, Dq { d: 0.0, q: -1.0 });
        assert!(out.v_dq_v.q < 0.0, "{:?}", out.v_dq_v);
        // Without back-calculation the integrator would be huge.
        let mut naive = PiController::new(cl.pi_q.kp, cl.pi_q.ki);
        for _ in 0..20_000 {
            naive.update(1000.0, 5e-5);
        }
        assert!(naive.integral > 100.0 * v_max);
    }
}
