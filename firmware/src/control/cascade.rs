//! Outer loops of the three-loop cascade (position -> velocity -> current): PID
//! controllers with feedforward, run at a decimation of the PWM rate.

/// A PID controller with output limit, conditional integration (anti-windup) and a
/// derivative on the measurement through a first-order filter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pid {
    /// Proportional gain.
    pub kp: f32,
    /// Integral gain, per second.
    pub ki: f32,
    /// Derivative gain, seconds.
    pub kd: f32,
    /// Derivative filter coefficient in (0, 1]: 1 = unfiltered.
    pub derivative_alpha: f32,
    /// Symmetric output limit (output units).
    pub output_limit: f32,
    integral: f32,
    last_measurement: f32,
    derivative: f32,
    primed: bool,
}

impl Pid {
    /// A PID with the given gains and symmetric output limit.
    pub const fn new(kp: f32, ki: f32, kd: f32, derivative_alpha: f32, output_limit: f32) -> Self {
        Self {
            kp,
            ki,
            kd,
            derivative_alpha,
            output_limit,
            integral: 0.0,
            last_measurement: 0.0,
            derivative: 0.0,
            primed: false,
        }
    }

    /// Empty the integrator and forget the derivative's history.
    pub fn reset(&mut self) {
        self.integral = 0.0;
        self.derivative = 0.0;
        self.primed = false;
    }

    /// The integrator's contribution to the output.
    pub fn integral(&self) -> f32 {
        self.integral
    }

    /// One step: `feedforward + kp e + ki int(e) - kd d(measurement)/dt`, limited;
    /// the integrator only integrates while that does not push further into the
    /// limit, and is itself bounded by the limit.
    pub fn update(&mut self, setpoint: f32, measurement: f32, feedforward: f32, dt_s: f32) -> f32 {
        let error = setpoint - measurement;
        let raw_derivative = if self.primed {
            (measurement - self.last_measurement) / dt_s
        } else {
            0.0
        };
        self.primed = true;
        self.last_measurement = measurement;
        self.derivative += self.derivative_alpha * (raw_derivative - self.derivative);
        let lim = self.output_limit;
        let candidate = super::clamp_abs(self.integral + self.ki * error * dt_s, lim);
        let unlimited = feedforward + self.kp * error + candidate - self.kd * self.derivative;
        let out = super::clamp_abs(unlimited, lim);
        // Conditional integration: keep the new integral unless the output is
        // saturated and the error drives it further into saturation.
        let pushing_out = (unlimited > lim && error > 0.0) || (unlimited < -lim && error < 0.0);
        if !pushing_out {
            self.integral = candidate;
        }
        if !self.derivative.is_finite() || !self.integral.is_finite() {
            self.reset();
        }
        if out.is_finite() { out } else { 0.0 }
    }
}

/// Gains and limits of the position and velocity loops (joint side).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CascadeConfig {
    /// Outer-loop rate, Hz.
    pub rate_hz: f32,
    /// Position loop: proportional gain, (rad/s) per rad.
    pub position_kp: f32,
    /// Position loop: integral gain, (rad/s) per rad per s.
    pub position_ki: f32,
    /// Position loop: derivative gain, (rad/s) per (rad/s).
    pub position_kd: f32,
    /// Velocity command limit, rad/s.
    pub max_velocity_rad_s: f32,
    /// Velocity loop: proportional gain, A per (rad/s).
    pub velocity_kp: f32,
    /// Velocity loop: integral gain, A per rad.
    pub velocity_ki: f32,
    /// Velocity loop: derivative gain, A per (rad/s^2).
    pub velocity_kd: f32,
    /// Velocity loop output (q-current command) limit, A.
    pub max_current_a: f32,
    /// Velocity estimate low-pass coefficient in (0, 1].
    pub velocity_filter_alpha: f32,
}

/// A joint trajectory point (the reference the cascade follows).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct JointReference {
    /// Position, rad.
    pub q_rad: f32,
    /// Velocity, rad/s (velocity feedforward of the position loop).
    pub qd_rad_s: f32,
    /// Acceleration, rad/s^2 (for the torque feedforward's predictors).
    pub qdd_rad_s2: f32,
}

/// Position -> velocity cascade with velocity feedforward; outputs the q-current
/// command (motor side, A) that the current loop adds the torque feedforward to.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PositionVelocityCascade {
    config: CascadeConfig,
    /// Position controller (output: velocity command, rad/s).
    pub position: Pid,
    /// Velocity controller (output: q current, A).
    pub velocity: Pid,
    dt_s: f32,
}

impl PositionVelocityCascade {
    /// A cascade with empty integrators.
    pub fn new(config: CascadeConfig) -> Self {
        Self {
            config,
            position: Pid::new(
                config.position_kp,
                config.position_ki,
                config.position_kd,
                1.0,
                config.max_velocity_rad_s,
            ),
            velocity: Pid::new(
                config.velocity_kp,
                config.velocity_ki,
                config.velocity_kd,
                0.5,
                config.max_current_a,
            ),
            dt_s: 1.0 / config.rate_hz,
        }
    }

    /// The configuration.
    pub fn config(&self) -> &CascadeConfig {
        &self.config
    }

    /// Empty the integrators.
    pub fn reset(&mut self) {
        self.position.reset();
        self.velocity.reset();
    }

    /// One outer-loop step: reference and measured position/velocity -> q-current
    /// command, A (within +-max_current_a). On the target it runs from CCM SRAM.
    #[cfg_attr(target_os = "none", unsafe(link_section = ".ccmram_text"))]
    pub fn step(&mut self, reference: &JointReference, q_rad: f32, qd_rad_s: f32) -> f32 {
        let v_cmd = self
            .position
            .update(reference.q_rad, q_rad, reference.qd_rad_s, self.dt_s);
        self.velocity.update(v_cmd, qd_rad_s, 0.0, self.dt_s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pid_anti_windup_and_limits() {
        let mut pid = Pid::new(1.0, 100.0, 0.0, 1.0, 2.0);
        for _ in 0..10_000 {
            let out = pid.update(100.0, 0.0, 0.0, 1e-3);
            assert!(out <= 2.0);
        }
        assert!(pid.integral() <= 2.0);
        // Error reverses: output leaves the limit immediately.
        let out = pid.update(-1.0, 0.0, 0.0, 1e-3);
        assert!(out < 2.0);
        let out = pid.update(f32::NAN, 0.0, 0.0, 1e-3);
        assert!(out.is_finite());
    }

    #[test]
    fn cascade_drives_a_double_integrator_to_the_reference() {
        // Unit inertia, current = torque: the cascade settles on a step.
        let cfg = CascadeConfig {
            rate_hz: 1000.0,
            position_kp: 20.0,
            position_ki: 0.0,
            position_kd: 0.0,
            max_velocity_rad_s: 5.0,
            velocity_kp: 20.0,
            velocity_ki: 100.0,
            velocity_kd: 0.0,
            max_current_a: 50.0,
            velocity_filter_alpha: 1.0,
        };
        let mut c = PositionVelocityCascade::new(cfg);
        let (mut q, mut qd) = (0.0f32, 0.0f32);
        let r = JointReference {
            q_rad: 1.0,
            qd_rad_s: 0.0,
            qdd_rad_s2: 0.0,
        };
        for _ in 0..3000 {
            let i = c.step(&r, q, qd);
            qd += i * 1e-3;
            q += qd * 1e-3;
        }
        assert!((q - 1.0).abs() < 1e-3, "q = {q}");
    }
}
