//! One joint's true drive, stepped at the internal rate: friction (viscous, Coulomb,
//! Stribeck, LuGre presliding, load-dependent), transmission ripple, reflected rotor
//! inertia and the first-order thermal node that makes viscous friction drift.
use super::PlantEffects;
use super::params::JointDrive;

/// The torque a joint's motor must deliver at one instant, split by cause [N*m, joint side].
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct DriveTorque {
    /// Friction (all friction effects together).
    pub friction_nm: f64,
    /// Transmission ripple.
    pub ripple_nm: f64,
    /// Reflected rotor inertia times joint acceleration.
    pub rotor_nm: f64,
}

/// Memory of one joint's drive: LuGre bristle deflection and thermal-node temperature.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DriveState {
    /// LuGre average bristle deflection z [rad].
    pub bristle_rad: f64,
    /// Thermal-node temperature [degC].
    pub temperature_c: f64,
}

impl DriveState {
    /// At rest, unloaded, at the given temperature.
    pub fn at_rest(temperature_c: f64) -> Self {
        DriveState {
            bristle_rad: 0.0,
            temperature_c,
        }
    }
}

impl DriveTorque {
    /// Sum of the parts [N*m].
    pub fn total_nm(&self) -> f64 {
        self.friction_nm + self.ripple_nm + self.rotor_nm
    }
}

/// One joint's drive over one step of `dt_s`: advances the friction memory (LuGre) at
/// velocity `qd` with transmitted (rigid-body) torque `load_nm`, and returns the torque
/// the drive adds beyond the rigid body at position `q` and acceleration `qdd`: friction
/// (viscous at the node's temperature, see [`viscous_at`]), ripple and the reflected
/// rotor inertia, each as `effects` selects. The plant simulator (inverse dynamics
/// along a trajectory) and the closed-loop SIL (forward dynamics, `qdd = 0`: the rotor
/// is in its mass matrix) both call it. The thermal node is advanced separately
/// ([`thermal_step`]) because it needs the motor current.
#[allow(clippy::too_many_arguments)]
pub fn drive_torque_step(
    drive: &JointDrive,
    effects: &PlantEffects,
    state: &mut DriveState,
    q: f64,
    qd: f64,
    qdd: f64,
    load_nm: f64,
    ambient_c: f64,
    dt_s: f64,
) -> DriveTorque {
    let viscous = viscous_at(drive, state.temperature_c, ambient_c, effects.thermal);
    let friction_nm = friction_step(drive, effects, state, qd, load_nm, viscous, dt_s);
    let ripple_nm = if effects.ripple {
        ripple_at(drive, q)
    } else {
        0.0
    };
    let rotor_nm = if effects.rotor_inertia {
        drive.reflected_rotor_inertia_kgm2() * qdd
    } else {
        0.0
    };
    DriveTorque {
        friction_nm,
        ripple_nm,
        rotor_nm,
    }
}

/// Viscous coefficient at temperature T: `D(T) = D0 exp(-kappa (T - T_ref))` [N*m*s/rad].
pub fn viscous_at(drive: &JointDrive, temperature_c: f64, reference_c: f64, thermal: bool) -> f64 {
    if thermal {
        drive.viscous_nms_rad
            * (-drive.viscous_temperature_coeff_per_k * (temperature_c - reference_c)).exp()
    } else {
        drive.viscous_nms_rad
    }
}

/// Ripple torque `sum_k A_k sin(c_k q + phi_k)` [N*m].
pub fn ripple_at(drive: &JointDrive, q_rad: f64) -> f64 {
    drive
        .ripple
        .iter()
        .map(|h| h.amplitude_nm * (h.cycles_per_rev * q_rad + h.phase_rad).sin())
        .sum()
}

/// Advances one joint's friction memory over `dt_s` at joint velocity `qd` and returns the
/// friction torque at the end of the step.
///
/// `g(v) = Fc' + (Fs' - Fc') exp(-(v/vs)^2)` with `Fc' = Fc + mu_L |tau_load|` (and `Fs'`
/// likewise); LuGre: `dz/dt = v - sigma0 |v| z / g(v)`, `F = sigma0 z + sigma1 dz/dt + D v`,
/// integrated exactly for constant `v` over the step (unconditionally stable); without
/// LuGre the static map `F = g(v) sgn(v) + D v`.
pub fn friction_step(
    drive: &JointDrive,
    effects: &PlantEffects,
    state: &mut DriveState,
    qd: f64,
    load_nm: f64,
    viscous: f64,
    dt_s: f64,
) -> f64 {
    let load = if effects.load_friction {
        drive.load_friction_per_nm * load_nm.abs()
    } else {
        0.0
    };
    let fc = drive.coulomb_nm + load;
    let g = if effects.stribeck {
        let fs = drive.static_nm + load;
        let r = qd / drive.stribeck_velocity_rad_s;
        fc + (fs - fc) * (-r * r).exp()
    } else {
        fc
    };
    if effects.presliding {
        let sigma0 = drive.lugre_stiffness_nm_rad;
        if g <= 0.0 {
            state.bristle_rad = 0.0;
            return viscous * qd;
        }
        let rate = sigma0 * qd.abs() / g;
        let z = if rate > 0.0 {
            let z_ss = qd / rate;
            z_ss + (state.bristle_rad - z_ss) * (-rate * dt_s).exp()
        } else {
            state.bristle_rad
        };
        state.bristle_rad = z;
        let zd = qd - rate * z;
        sigma0 * z + drive.lugre_damping_nms_rad * zd + viscous * qd
    } else {
        g * sign(qd) + viscous * qd
    }
}

/// Advances the thermal node over `dt_s`, heated by the winding's I^2 R loss at current
/// `current_a` plus the share `friction_heat_share` of the friction power `|tau_f qd|`:
/// `C dT/dt = i^2 R + s |tau_f qd| - (T - T_amb)/R_th`, integrated exactly for constant power.
pub fn thermal_step(
    drive: &JointDrive,
    state: &mut DriveState,
    current_a: f64,
    friction_power_w: f64,
    ambient_c: f64,
    dt_s: f64,
) {
    let power_w = current_a * current_a * drive.winding_resistance_ohm
        + drive.friction_heat_share * friction_power_w.abs();
    let t_ss = ambient_c + power_w * drive.thermal_resistance_k_w;
    let decay = (-dt_s / drive.thermal_time_constant_s).exp();
    state.temperature_c = t_ss + (state.temperature_c - t_ss) * decay;
}

/// `sgn` with `sgn(0) = 0` (the identification model's convention).
pub fn sign(x: f64) -> f64 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::PlantParameters;

    fn wrist() -> JointDrive {
        PlantParameters::default_robot().joints[4].clone()
    }

    #[test]
    fn lugre_steady_state_is_stribeck_curve() {
        let d = wrist();
        let fx = PlantEffects::all();
        for v in [0.01, 0.05, 0.3, -0.2] {
            let mut s = DriveState::at_rest(25.0);
            let mut f = 0.0;
            for _ in 0..60_000 {
                f = friction_step(
                    &d,
                    &PlantEffects {
                        load_friction: false,
                        ..fx
                    },
                    &mut s,
                    v,
                    0.0,
                    d.viscous_nms_rad,
                    1e-3,
                );
            }
            let r: f64 = v / d.stribeck_velocity_rad_s;
            let expect = (d.coulomb_nm + (d.static_nm - d.coulomb_nm) * (-r * r).exp()) * sign(v)
                + d.viscous_nms_rad * v;
            assert!((f - expect).abs() < 1e-9, "v {v}: {f} vs {expect}");
        }
    }

    #[test]
    fn presliding_has_hysteresis_memory() {
        // Small back-and-forth motion: friction at the same (q, qd) differs depending on
        // the direction it came from, i.e. the state carries memory.
        let d = wrist();
        let fx = PlantEffects::all();
        let mut s = DriveState::at_rest(25.0);
        let dt = 1e-3;
        let mut first = None;
        let mut second = None;
        for k in 0..4000 {
            let t = k as f64 * dt;
            let w = std::f64::consts::TAU * 0.5;
            let qd = 0.002 * w * (w * t).cos();
            let f = friction_step(&d, &fx, &mut s, qd, 0.0, d.viscous_nms_rad, dt);
            if k == 500 {
                first = Some(f); // q = max, moving from positive side
            }
            if k == 1500 {
                second = Some(f); // q = min
            }
        }
        let (a, b) = (first.unwrap(), second.unwrap());
        assert!(a > 0.1 && b < -0.1, "{a} {b}");
    }

    #[test]
    fn thermal_node_reaches_steady_state() {
        let d = wrist();
        let mut s = DriveState::at_rest(25.0);
        for _ in 0..(20.0 * d.thermal_time_constant_s) as usize {
            thermal_step(&d, &mut s, 2.0, 0.0, 25.0, 1.0);
        }
        let expect = 25.0 + 4.0 * d.winding_resistance_ohm * d.thermal_resistance_k_w;
        assert!((s.temperature_c - expect).abs() < 1e-6);
    }
}
