//! Parameters of the true plant beyond the rigid body: per-joint drive (gear, motor,
//! rotor, friction, thermal node, transmission ripple) and the current-sensing chain.
//!
//! Defaults are the built-in default robot (a UR5e-class arm); see crates/robot/README.md
//! ("The default robot") for where each number comes from.
use serde::{Deserialize, Serialize};

/// The default robot's plant file, compiled in.
pub const DEFAULT_PLANT_TOML: &str = include_str!("../../../robots/default.plant.toml");

/// One harmonic of the transmission's position-periodic torque ripple:
/// `amplitude_nm * sin(cycles_per_rev * q + phase_rad)` with `q` the joint (output) angle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RippleHarmonic {
    /// Periods per output revolution (2 * gear ratio for the wave generator's 2nd order).
    pub cycles_per_rev: f64,
    /// Amplitude at the joint [N*m].
    pub amplitude_nm: f64,
    /// Phase [rad].
    pub phase_rad: f64,
}

/// The true drive of one joint (all torques and inertias on the joint/output side unless
/// the name says motor side).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointDrive {
    /// Harmonic-drive reduction ratio N (motor turns per joint turn).
    pub gear_ratio: f64,
    /// Motor torque constant [N*m/A], motor side.
    pub motor_torque_constant_nm_a: f64,
    /// Rotor (motor + wave generator) inertia, motor side [kg*m^2]; reflected: N^2 times.
    pub rotor_inertia_kgm2: f64,
    /// Viscous friction at the reference temperature [N*m*s/rad].
    pub viscous_nms_rad: f64,
    /// Coulomb (sliding) friction level at no load [N*m].
    pub coulomb_nm: f64,
    /// Static (breakaway) friction level at no load [N*m], >= coulomb (Stribeck).
    pub static_nm: f64,
    /// Stribeck velocity [rad/s].
    pub stribeck_velocity_rad_s: f64,
    /// LuGre bristle stiffness sigma0 [N*m/rad] (presliding stiffness).
    pub lugre_stiffness_nm_rad: f64,
    /// LuGre bristle damping sigma1 [N*m*s/rad].
    pub lugre_damping_nms_rad: f64,
    /// Load-dependent friction: extra Coulomb level per N*m of transmitted torque [-].
    pub load_friction_per_nm: f64,
    /// Winding resistance [ohm] (I^2 R heating).
    pub winding_resistance_ohm: f64,
    /// Share of the friction power `|tau_f qd|` that heats the thermal node [-] (0: I^2 R only).
    pub friction_heat_share: f64,
    /// Thermal resistance from the drive's thermal node to ambient [K/W].
    pub thermal_resistance_k_w: f64,
    /// Thermal time constant of the node [s] (capacity = time constant / resistance).
    pub thermal_time_constant_s: f64,
    /// Relative drop of viscous friction per kelvin above the reference temperature [1/K].
    pub viscous_temperature_coeff_per_k: f64,
    /// Transmission torque ripple harmonics.
    pub ripple: Vec<RippleHarmonic>,
    /// Full-scale current of the drive's current ADC, +- [A].
    pub adc_full_scale_a: f64,
}

impl JointDrive {
    /// Joint-side torque per ampere: `Kt * N` [N*m/A] (efficiency is modelled as friction).
    pub fn drive_gain_nm_a(&self) -> f64 {
        self.motor_torque_constant_nm_a * self.gear_ratio
    }

    /// Rotor inertia reflected to the joint: `N^2 * J_rotor` [kg*m^2].
    pub fn reflected_rotor_inertia_kgm2(&self) -> f64 {
        self.gear_ratio * self.gear_ratio * self.rotor_inertia_kgm2
    }

    /// Thermal capacity of the node [J/K].
    pub fn thermal_capacity_j_k(&self) -> f64 {
        self.thermal_time_constant_s / self.thermal_resistance_k_w
    }
}

/// Current sensing and the controller's log chain.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorParameters {
    /// White measurement noise of each current sample, standard deviation [A].
    pub current_noise_a: f64,
    /// ADC resolution in bits over +- `adc_full_scale_a`.
    pub adc_bits: u32,
    /// Kalman filter process noise (random-walk variance per sample) [A^2].
    pub kalman_process_var_a2: f64,
    /// Kalman filter measurement noise variance [A^2].
    pub kalman_measurement_var_a2: f64,
}

/// Everything about the true plant that the rigid-body description does not hold.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlantParameters {
    /// Ambient (and default initial) temperature [degC]; also the friction reference.
    pub ambient_temperature_c: f64,
    /// Per-joint drives, base outwards.
    pub joints: Vec<JointDrive>,
    /// Current sensing.
    pub sensor: SensorParameters,
}

impl PlantParameters {
    /// The default robot's drives: `robots/default.plant.toml`, compiled in.
    pub fn default_robot() -> Self {
        Self::from_toml_str(DEFAULT_PLANT_TOML, "robots/default.plant.toml")
            .expect("the built-in plant file is valid (tested)")
    }

    /// Parses a plant file (TOML); errors name the file, line and field.
    pub fn from_toml_str(text: &str, file: &str) -> anyhow::Result<Self> {
        let p: PlantParameters = toml::from_str(text).map_err(|e| {
            let line = e
                .span()
                .map(|s| text[..s.start].bytes().filter(|&b| b == b'\n').count() + 1);
            match line {
                Some(l) => anyhow::anyhow!("{file}:{l}: {}", e.message()),
                None => anyhow::anyhow!("{file}: {}", e.message()),
            }
        })?;
        p.validate().map_err(|e| anyhow::anyhow!("{file}: {e}"))?;
        Ok(p)
    }

    /// Reads a plant file.
    pub fn load(path: &std::path::Path) -> anyhow::Result<Self> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| anyhow::anyhow!("{}: cannot read: {e}", path.display()))?;
        Self::from_toml_str(&text, &path.display().to_string())
    }

    /// Checks physical sanity: positive ratios and constants, non-negative friction,
    /// static >= Coulomb. Names the joint and field on failure.
    pub fn validate(&self) -> anyhow::Result<()> {
        for (j, d) in self.joints.iter().enumerate() {
            let name = j + 1;
            let positive = [
                ("gear_ratio", d.gear_ratio),
                ("motor_torque_constant_nm_a", d.motor_torque_constant_nm_a),
                ("stribeck_velocity_rad_s", d.stribeck_velocity_rad_s),
                ("lugre_stiffness_nm_rad", d.lugre_stiffness_nm_rad),
                ("thermal_resistance_k_w", d.thermal_resistance_k_w),
                ("thermal_time_constant_s", d.thermal_time_constant_s),
                ("adc_full_scale_a", d.adc_full_scale_a),
            ];
            for (field, v) in positive {
                anyhow::ensure!(
                    v.is_finite() && v > 0.0,
                    "joint {name}: {field} = {v} must be > 0"
                );
            }
            let non_negative = [
                ("rotor_inertia_kgm2", d.rotor_inertia_kgm2),
                ("viscous_nms_rad", d.viscous_nms_rad),
                ("coulomb_nm", d.coulomb_nm),
                ("lugre_damping_nms_rad", d.lugre_damping_nms_rad),
                ("load_friction_per_nm", d.load_friction_per_nm),
                ("winding_resistance_ohm", d.winding_resistance_ohm),
                ("friction_heat_share", d.friction_heat_share),
                (
                    "viscous_temperature_coeff_per_k",
                    d.viscous_temperature_coeff_per_k,
                ),
            ];
            for (field, v) in non_negative {
                anyhow::ensure!(
                    v.is_finite() && v >= 0.0,
                    "joint {name}: {field} = {v} must be >= 0"
                );
            }
            anyhow::ensure!(
                d.static_nm.is_finite() && d.static_nm >= d.coulomb_nm,
                "joint {name}: static_nm = {} must be >= coulomb_nm = {}",
                d.static_nm,
                d.coulomb_nm
            );
            for (k, h) in d.ripple.iter().enumerate() {
                anyhow::ensure!(
                    h.cycles_per_rev.is_finite()
                        && h.amplitude_nm.is_finite()
                        && h.phase_rad.is_finite(),
                    "joint {name}: ripple[{k}] has a non-finite field"
                );
            }
        }
        let s = &self.sensor;
        anyhow::ensure!(
            s.current_noise_a.is_finite() && s.current_noise_a >= 0.0,
            "sensor: current_noise_a must be >= 0"
        );
        anyhow::ensure!(
            (1..=24).contains(&s.adc_bits),
            "sensor: adc_bits = {} must be 1..=24",
            s.adc_bits
        );
        anyhow::ensure!(
            s.kalman_process_var_a2 > 0.0 && s.kalman_measurement_var_a2 > 0.0,
            "sensor: Kalman variances must be > 0"
        );
        Ok(())
    }
}
