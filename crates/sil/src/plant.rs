//! The joint plant for software-in-the-loop runs (host, f64): a three-phase PMSM/BLDC
//! motor driven through PWM duties averaged over the PWM period, a gear, inertias,
//! a joint load behind [`JointLoad`], a quantised encoder and noisy, quantised
//! current sensing (seeded).

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use std::f64::consts::{PI, TAU};

/// The load a joint drives, seen at the joint (output) side of the gear.
///
/// The full multi-joint plant implements this per joint from the robot's dynamics
/// (coupling through the other joints' states), true friction and ripple.
pub trait JointLoad {
    /// Load inertia at the joint side, kg*m^2 (excluding the motor rotor).
    fn inertia_kg_m2(&self) -> f64;
    /// Torque the load opposes the motion with (friction, gravity, ...), N*m, at
    /// time `t_s` in joint position `q_rad` and velocity `qd_rad_s`.
    fn torque_nm(&mut self, t_s: f64, q_rad: f64, qd_rad_s: f64) -> f64;
}

/// A single joint: inertia, viscous and Coulomb friction, and gravity on a lever.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SingleJointLoad {
    /// Inertia, kg*m^2.
    pub inertia_kg_m2: f64,
    /// Viscous friction, N*m*s/rad.
    pub viscous_nm_s_rad: f64,
    /// Coulomb friction, N*m.
    pub coulomb_nm: f64,
    /// Velocity over which the Coulomb friction changes sign (tanh smoothing), rad/s.
    pub coulomb_smoothing_rad_s: f64,
    /// Gravity torque amplitude m*g*l, N*m (torque = m g l sin q).
    pub gravity_nm: f64,
}

impl SingleJointLoad {
    /// The load's torque at a velocity and position (the same formula [`JointLoad`] uses).
    pub fn torque_at(&self, q_rad: f64, qd_rad_s: f64) -> f64 {
        self.viscous_nm_s_rad * qd_rad_s
            + self.coulomb_nm * (qd_rad_s / self.coulomb_smoothing_rad_s).tanh()
            + self.gravity_nm * q_rad.sin()
    }
}

impl JointLoad for SingleJointLoad {
    fn inertia_kg_m2(&self) -> f64 {
        self.inertia_kg_m2
    }
    fn torque_nm(&mut self, _t_s: f64, q_rad: f64, qd_rad_s: f64) -> f64 {
        self.torque_at(q_rad, qd_rad_s)
    }
}

/// Motor, gear and sensors of one joint.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointPlantConfig {
    /// Pole pairs.
    pub pole_pairs: u8,
    /// Phase resistance, ohm.
    pub phase_resistance_ohm: f64,
    /// Phase inductance, H.
    pub phase_inductance_h: f64,
    /// Magnet flux linkage, V*s/rad (electrical).
    pub flux_linkage_wb: f64,
    /// Rotor inertia, kg*m^2 (motor side).
    pub rotor_inertia_kg_m2: f64,
    /// Gear ratio (motor turns per joint turn).
    pub gear_ratio: f64,
    /// Gear efficiency (motor torque to joint torque).
    pub gear_efficiency: f64,
    /// Bus voltage, V.
    pub bus_v: f64,
    /// PWM frequency, Hz.
    pub pwm_hz: f64,
    /// Integration steps per PWM period.
    pub substeps: u32,
    /// Encoder resolution, bits per motor turn.
    pub encoder_bits: u32,
    /// Encoder reading at electrical angle zero, rad (motor mechanical).
    pub encoder_offset_rad: f64,
    /// Current-sensor noise, A (standard deviation).
    pub current_noise_a: f64,
    /// Current ADC step, A.
    pub current_lsb_a: f64,
    /// Bus-voltage sensor noise, V (standard deviation).
    pub bus_noise_v: f64,
    /// Seed of the sensor noise.
    pub seed: u64,
}

impl JointPlantConfig {
    /// The motor as the firmware's current loop sees it (f32).
    pub fn motor(&self) -> firmware::control::MotorParameters {
        firmware::control::MotorParameters {
            pole_pairs: self.pole_pairs,
            phase_resistance_ohm: self.phase_resistance_ohm as f32,
            phase_inductance_h: self.phase_inductance_h as f32,
            flux_linkage_wb: self.flux_linkage_wb as f32,
        }
    }
}

/// What the firmware reads each PWM period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensedSample {
    /// Phase currents a, b, A.
    pub phase_current_a: [f64; 2],
    /// Encoder motor angle, rad in [0, 2 pi).
    pub motor_angle_rad: f64,
    /// Bus voltage, V.
    pub bus_v: f64,
}

/// One joint's motor, gear and load, integrated over PWM periods.
pub struct JointPlant<L: JointLoad> {
    config: JointPlantConfig,
    /// The load.
    pub load: L,
    i_abc_a: [f64; 3],
    motor_angle_rad: f64,
    motor_speed_rad_s: f64,
    t_s: f64,
    rng: ChaCha8Rng,
    current_noise: Normal<f64>,
    bus_noise: Normal<f64>,
    last_motor_torque_nm: f64,
}

impl<L: JointLoad> JointPlant<L> {
    /// A plant at rest at joint position `q0_rad`.
    pub fn new(config: JointPlantConfig, load: L, q0_rad: f64) -> Self {
        Self {
            config,
            load,
            i_abc_a: [0.0; 3],
            motor_angle_rad: q0_rad * config.gear_ratio,
            motor_speed_rad_s: 0.0,
            t_s: 0.0,
            rng: ChaCha8Rng::seed_from_u64(config.seed),
            current_noise: noise(config.current_noise_a),
            bus_noise: noise(config.bus_noise_v),
            last_motor_torque_nm: 0.0,
        }
    }

    /// Joint position, rad.
    pub fn q_rad(&self) -> f64 {
        self.motor_angle_rad / self.config.gear_ratio
    }

    /// Joint velocity, rad/s.
    pub fn qd_rad_s(&self) -> f64 {
        self.motor_speed_rad_s / self.config.gear_ratio
    }

    /// Time, s.
    pub fn t_s(&self) -> f64 {
        self.t_s
    }

    /// True phase currents, A.
    pub fn phase_currents_a(&self) -> [f64; 3] {
        self.i_abc_a
    }

    /// True q current, A.
    pub fn iq_a(&self) -> f64 {
        q_current_a(self.i_abc_a, self.electrical_angle_rad())
    }

    /// Motor electromagnetic torque of the last step, N*m (motor side).
    pub fn motor_torque_nm(&self) -> f64 {
        self.last_motor_torque_nm
    }

    /// Joint-side inertia the motor sees: load + rotor * ratio^2, kg*m^2.
    pub fn effective_inertia_kg_m2(&self) -> f64 {
        self.load.inertia_kg_m2() + self.config.rotor_inertia_kg_m2 * self.config.gear_ratio.powi(2)
    }

    fn electrical_angle_rad(&self) -> f64 {
        self.config.pole_pairs as f64 * (self.motor_angle_rad - self.config.encoder_offset_rad)
    }

    /// The sensors at the start of a PWM period: current noise and ADC steps, the
    /// encoder quantised to its bits.
    pub fn sense(&mut self) -> SensedSample {
        sense_joint(
            &self.config,
            self.i_abc_a,
            self.motor_angle_rad,
            &mut self.rng,
            &self.current_noise,
            &self.bus_noise,
        )
    }

    /// Apply three duties for one PWM period (averaged switching) and integrate.
    pub fn step_pwm_period(&mut self, duties: [f64; 3]) {
        let c = self.config;
        let n = c.substeps.max(1);
        let dt = 1.0 / (c.pwm_hz * n as f64);
        let d = duties.map(|x| {
            if x.is_finite() {
                x.clamp(0.0, 1.0)
            } else {
                0.5
            }
        });
        let mean = (d[0] + d[1] + d[2]) / 3.0;
        let v = d.map(|x| (x - mean) * c.bus_v);
        let j_eff = self.effective_inertia_kg_m2();
        let p = c.pole_pairs as f64;
        let lambda = c.flux_linkage_wb;
        for _ in 0..n {
            let th = self.electrical_angle_rad();
            motor_electrical_step(&c, &mut self.i_abc_a, v, th, self.motor_speed_rad_s, dt);
            let iq = self.iq_a();
            let t_motor = 1.5 * p * lambda * iq;
            self.last_motor_torque_nm = t_motor;
            let q = self.q_rad();
            let qd = self.qd_rad_s();
            let t_load = self.load.torque_nm(self.t_s, q, qd);
            let qdd = (t_motor * c.gear_ratio * c.gear_efficiency - t_load) / j_eff;
            // Semi-implicit Euler: speed first, then angle.
            self.motor_speed_rad_s += qdd * c.gear_ratio * dt;
            self.motor_angle_rad += self.motor_speed_rad_s * dt;
            self.t_s += dt;
        }
    }
}

/// Phase voltages (star point) that three duties give on average over a PWM period.
pub fn phase_voltages(c: &JointPlantConfig, duties: [f64; 3]) -> [f64; 3] {
    let d = duties.map(|x| {
        if x.is_finite() {
            x.clamp(0.0, 1.0)
        } else {
            0.5
        }
    });
    let mean = (d[0] + d[1] + d[2]) / 3.0;
    d.map(|x| (x - mean) * c.bus_v)
}

/// One explicit-Euler step of the three phase currents: L di/dt = v - R i - e, with
/// sinusoidal back-EMF and a floating star point (currents sum to zero).
pub fn motor_electrical_step(
    c: &JointPlantConfig,
    i_abc_a: &mut [f64; 3],
    v: [f64; 3],
    electrical_angle_rad: f64,
    motor_speed_rad_s: f64,
    dt_s: f64,
) {
    let th = electrical_angle_rad;
    let w_e = c.pole_pairs as f64 * motor_speed_rad_s;
    let lambda = c.flux_linkage_wb;
    let bemf = [
        -lambda * w_e * th.sin(),
        -lambda * w_e * (th - 2.0 * PI / 3.0).sin(),
        -lambda * w_e * (th + 2.0 * PI / 3.0).sin(),
    ];
    for k in 0..3 {
        let di = (v[k] - c.phase_resistance_ohm * i_abc_a[k] - bemf[k]) / c.phase_inductance_h;
        i_abc_a[k] += di * dt_s;
    }
    let s = (i_abc_a[0] + i_abc_a[1] + i_abc_a[2]) / 3.0;
    for i in i_abc_a.iter_mut() {
        *i -= s;
    }
}

/// q current of three phase currents at an electrical angle.
pub fn q_current_a(i_abc_a: [f64; 3], electrical_angle_rad: f64) -> f64 {
    let (alpha, beta) = clarke(i_abc_a);
    -alpha * electrical_angle_rad.sin() + beta * electrical_angle_rad.cos()
}

/// Sensor model shared by the plants: noisy, quantised phase currents a and b, the
/// encoder quantised to its bits, a noisy bus voltage.
pub fn sense_joint(
    c: &JointPlantConfig,
    i_abc_a: [f64; 3],
    motor_angle_rad: f64,
    rng: &mut ChaCha8Rng,
    current_noise: &Normal<f64>,
    bus_noise: &Normal<f64>,
) -> SensedSample {
    let mut adc = |i: f64| {
        let noisy = i + current_noise.sample(rng);
        if c.current_lsb_a > 0.0 {
            (noisy / c.current_lsb_a).round() * c.current_lsb_a
        } else {
            noisy
        }
    };
    let ia = adc(i_abc_a[0]);
    let ib = adc(i_abc_a[1]);
    let counts = (1u64 << c.encoder_bits) as f64;
    let wrapped = motor_angle_rad.rem_euclid(TAU);
    let code = (wrapped / TAU * counts).floor().rem_euclid(counts);
    SensedSample {
        phase_current_a: [ia, ib],
        motor_angle_rad: code * TAU / counts,
        bus_v: c.bus_v + bus_noise.sample(rng),
    }
}

/// A zero-mean normal distribution with standard deviation `sd` (0 when negative).
pub fn noise(sd: f64) -> Normal<f64> {
    Normal::new(0.0, if sd > 0.0 && sd.is_finite() { sd } else { 0.0 })
        .unwrap_or(Normal::new(0.0, 0.0).expect("zero sd is valid"))
}

fn clarke(i: [f64; 3]) -> (f64, f64) {
    (
        (2.0 * i[0] - i[1] - i[2]) / 3.0,
        (i[1] - i[2]) / 3f64.sqrt(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The SIL's wrist-sized joint without sensor noise, ADC steps or encoder offset.
    pub(crate) fn config() -> JointPlantConfig {
        JointPlantConfig {
            encoder_offset_rad: 0.0,
            current_noise_a: 0.0,
            current_lsb_a: 0.0,
            bus_noise_v: 0.0,
            seed: 1,
            ..crate::SingleJointSetup::wrist_joint(1000, 1).plant()
        }
    }

    #[test]
    fn dc_voltage_gives_steady_current_and_energy_balance() {
        // Rotor locked by a huge inertia: a DC d-axis voltage settles at V/R.
        let load = SingleJointLoad {
            inertia_kg_m2: 1e12,
            viscous_nm_s_rad: 0.0,
            coulomb_nm: 0.0,
            coulomb_smoothing_rad_s: 1.0,
            gravity_nm: 0.0,
        };
        let mut p = JointPlant::new(config(), load, 0.0);
        // alpha = 1.2 V along phase a at electrical angle 0 (d axis).
        let v = firmware::control::foc::space_vector_duties(
            firmware::control::foc::AlphaBeta {
                alpha: 1.2,
                beta: 0.0,
            },
            48.0,
        );
        for _ in 0..2000 {
            p.step_pwm_period(v.map(f64::from));
        }
        let ia = p.phase_currents_a()[0];
        assert!((ia - 4.0).abs() < 1e-3, "ia = {ia}");
        assert!(p.iq_a().abs() < 1e-3);
    }

    #[test]
    fn encoder_is_quantised_and_wrapped() {
        let load = SingleJointLoad {
            inertia_kg_m2: 1.0,
            viscous_nm_s_rad: 0.0,
            coulomb_nm: 0.0,
            coulomb_smoothing_rad_s: 1.0,
            gravity_nm: 0.0,
        };
        let mut p = JointPlant::new(config(), load, 0.123);
        let s = p.sense();
        let lsb = TAU / 16384.0;
        assert!((s.motor_angle_rad / lsb - (s.motor_angle_rad / lsb).round()).abs() < 1e-9);
        assert!((0.0..TAU).contains(&s.motor_angle_rad));
        assert!(((12.3f64).rem_euclid(TAU) - s.motor_angle_rad).abs() < lsb);
    }
}
