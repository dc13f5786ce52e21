//! Several joints on one mechanism: one motor model per joint (the same electrical
//! model and sensors as [`super::plant`]) and coupled joint-side mechanics behind
//! [`JointMechanics`]; the firmware instances exchange their states as
//! `JointStateMessage` wire frames with one compensator tick of bus latency.

use super::plant::{
    JointPlantConfig, SensedSample, motor_electrical_step, noise, phase_voltages, q_current_a,
    sense_joint,
};
use super::{FeedforwardMode, Trajectory};
use firmware::control::{
    Compensator, CompensatorConfig, DriveConfig, DriveOutput, FaultFlags, FeedforwardSource,
    JointDrive, JointReference, JointState, NoPredictor, PredictorInput, SensorSample,
    TorquePredictor,
};
use nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::Normal;

/// Joint-side mechanics of `J` coupled joints: M(q) qdd + h(q, qd) = tau (a test
/// mechanism; the plant simulator's true wrist runs in [`super::wrist`]); the motors'
/// rotor inertias are added by the plant.
pub trait JointMechanics<const J: usize> {
    /// Mass matrix M(q), kg*m^2 (without the rotors).
    fn mass_matrix(&mut self, q_rad: &[f64; J]) -> [[f64; J]; J];
    /// Everything else h(q, qd) (Coriolis, gravity, friction, ripple), N*m, at time `t_s`.
    fn bias_torques_nm(&mut self, t_s: f64, q_rad: &[f64; J], qd_rad_s: &[f64; J]) -> [f64; J];
}

/// A test mechanism: constant inertia matrix with coupling, per-joint viscous and
/// Coulomb friction and gravity (tau_g = g_j sin q_j).
#[derive(Clone, Debug, PartialEq)]
pub struct CoupledJoints<const J: usize> {
    /// Inertia matrix (symmetric, positive definite), kg*m^2.
    pub inertia_kg_m2: [[f64; J]; J],
    /// Viscous friction, N*m*s/rad.
    pub viscous_nm_s_rad: [f64; J],
    /// Coulomb friction, N*m.
    pub coulomb_nm: [f64; J],
    /// tanh smoothing of the Coulomb term, rad/s.
    pub coulomb_smoothing_rad_s: f64,
    /// Gravity amplitude, N*m.
    pub gravity_nm: [f64; J],
}

impl<const J: usize> CoupledJoints<J> {
    fn bias(&self, q: &[f64; J], qd: &[f64; J]) -> [f64; J] {
        let mut h = [0.0; J];
        for j in 0..J {
            h[j] = self.viscous_nm_s_rad[j] * qd[j]
                + self.coulomb_nm[j] * (qd[j] / self.coulomb_smoothing_rad_s).tanh()
                + self.gravity_nm[j] * q[j].sin();
        }
        h
    }
}

impl<const J: usize> JointMechanics<J> for CoupledJoints<J> {
    fn mass_matrix(&mut self, _q: &[f64; J]) -> [[f64; J]; J] {
        self.inertia_kg_m2
    }
    fn bias_torques_nm(&mut self, _t: f64, q: &[f64; J], qd: &[f64; J]) -> [f64; J] {
        self.bias(q, qd)
    }
}

/// The exact inverse dynamics of a [`CoupledJoints`] mechanism (plus rotors) on every
/// joint's reference, as a firmware `TorquePredictor`: it needs the other joints'
/// states from the bus.
#[derive(Clone, Debug)]
pub struct CoupledInverseDynamics<const J: usize> {
    /// The mechanism.
    pub mechanics: CoupledJoints<J>,
    /// Rotor inertia reflected to the joint, per joint, kg*m^2.
    pub rotor_reflected_kg_m2: [f64; J],
    /// Output scale (1 = exact).
    pub scale: f64,
    /// Ignore the other joints (zero their acceleration): what a drive could do alone.
    pub decoupled: bool,
}

impl<const J: usize> TorquePredictor<J> for CoupledInverseDynamics<J> {
    fn predict_nm(&mut self, input: &PredictorInput<J>) -> [f32; J] {
        let q = input.joints.map(|s| s.q_ref_rad as f64);
        let qd = input.joints.map(|s| s.qd_ref_rad_s as f64);
        let mut qdd = input.joints.map(|s| s.qdd_ref_rad_s2 as f64);
        if self.decoupled {
            for (j, a) in qdd.iter_mut().enumerate() {
                if j != input.own_joint {
                    *a = 0.0;
                }
            }
        }
        let h = self.mechanics.bias(&q, &qd);
        let mut out = [0.0f32; J];
        for i in 0..J {
            let mut t = h[i] + self.rotor_reflected_kg_m2[i] * qdd[i];
            for (j, a) in qdd.iter().enumerate() {
                t += self.mechanics.inertia_kg_m2[i][j] * a;
            }
            out[i] = (self.scale * t) as f32;
        }
        out
    }
    fn reset(&mut self) {}
}

/// Which feedforward each joint gets in a multi-joint run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MultiFeedforward {
    /// As in the single-joint run (`None`, or the coupled inverse dynamics scaled).
    Mode(FeedforwardMode),
    /// Exact inverse dynamics, but each drive ignores the other joints' accelerations.
    Decoupled,
}

/// Everything a multi-joint run needs.
#[derive(Clone, Debug)]
pub struct MultiJointSetup<const J: usize> {
    /// Per-joint motor, gear and sensors (the seeds should differ).
    pub plants: [JointPlantConfig; J],
    /// The mechanism.
    pub mechanics: CoupledJoints<J>,
    /// Per-joint firmware drive configuration.
    pub drives: [DriveConfig; J],
    /// Compensator configuration (its `own_joint` is set per joint).
    pub compensator: CompensatorConfig,
    /// Per-joint reference trajectory.
    pub trajectories: [Trajectory; J],
    /// Simulated time, s.
    pub duration_s: f64,
}

impl MultiJointSetup<3> {
    /// A wrist of three wrist-sized joints (as `SingleJointSetup::wrist_joint`) with
    /// inertial coupling between them.
    pub fn wrist(compensator_hz: f64, seed: u64) -> Self {
        let base = super::SingleJointSetup::wrist_joint(compensator_hz, seed);
        let mut plants = [base.plant; 3];
        for (j, p) in plants.iter_mut().enumerate() {
            p.seed = seed.wrapping_mul(31).wrapping_add(j as u64);
        }
        let mechanics = CoupledJoints {
            inertia_kg_m2: [[0.5, 0.3, 0.15], [0.3, 0.4, 0.2], [0.15, 0.2, 0.3]],
            viscous_nm_s_rad: [3.0, 2.5, 2.0],
            coulomb_nm: [5.0, 4.0, 3.0],
            coulomb_smoothing_rad_s: 0.02,
            gravity_nm: [20.0, 12.0, 5.0],
        };
        let trajectories = [
            Trajectory {
                offset_rad: 0.2,
                fundamental_hz: 0.4,
                amplitudes_rad: vec![0.5, 0.15, 0.05],
            },
            Trajectory {
                offset_rad: -0.3,
                fundamental_hz: 0.3,
                amplitudes_rad: vec![0.6, -0.2, 0.1],
            },
            Trajectory {
                offset_rad: 0.5,
                fundamental_hz: 0.5,
                amplitudes_rad: vec![-0.4, 0.1, 0.08],
            },
        ];
        Self {
            plants,
            mechanics,
            drives: [base.drive; 3],
            compensator: base.compensator,
            trajectories,
            duration_s: base.duration_s,
        }
    }
}

/// Per-joint results of a multi-joint run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointReport {
    /// RMS position-tracking error, rad.
    pub rms_error_rad: f64,
    /// RMS true q current, A.
    pub rms_iq_a: f64,
    /// Faults raised by this joint's drive, and by its compensator after its first
    /// tick (which has not heard from the other joints yet).
    pub faults: FaultFlags,
    /// Compensator ticks whose feedforward target was zero (no usable prediction).
    pub zero_feedforward_ticks: u64,
}

struct Motor {
    i_abc_a: [f64; 3],
    rng: ChaCha8Rng,
    current_noise: Normal<f64>,
    bus_noise: Normal<f64>,
}

/// Run the wrist: one firmware `JointDrive` + `Compensator<J>` per joint, states
/// exchanged as wire frames each compensator tick and delivered at the next one.
pub fn run_multi_joint<const J: usize>(
    setup: &MultiJointSetup<J>,
    mode: MultiFeedforward,
) -> anyhow::Result<[JointReport; J]> {
    let pwm_hz = setup.plants[0].pwm_hz;
    anyhow::ensure!(
        setup.plants.iter().all(|p| p.pwm_hz == pwm_hz),
        "all joints need one PWM rate"
    );
    let reflected: [f64; J] = std::array::from_fn(|j| {
        setup.plants[j].rotor_inertia_kg_m2 * setup.plants[j].gear_ratio.powi(2)
    });
    let (scale, decoupled) = match mode {
        MultiFeedforward::Mode(FeedforwardMode::None) => (0.0, false),
        MultiFeedforward::Mode(FeedforwardMode::InverseDynamics(s)) => (s, false),
        MultiFeedforward::Decoupled => (1.0, true),
    };
    let mut comps = Vec::with_capacity(J);
    for j in 0..J {
        let predictor = CoupledInverseDynamics {
            mechanics: setup.mechanics.clone(),
            rotor_reflected_kg_m2: reflected,
            scale,
            decoupled,
        };
        let cfg = CompensatorConfig {
            own_joint: j,
            ..setup.compensator
        };
        comps.push(
            Compensator::<J, _, NoPredictor>::new(cfg, predictor, NoPredictor)
                .map_err(|e| anyhow::anyhow!("compensator of joint {j}: {e:?}"))?,
        );
    }
    let mut drives: Vec<JointDrive> = setup.drives.iter().map(|d| JointDrive::new(*d)).collect();
    let mut motors: Vec<Motor> = setup
        .plants
        .iter()
        .map(|p| Motor {
            i_abc_a: [0.0; 3],
            rng: ChaCha8Rng::seed_from_u64(p.seed),
            current_noise: noise(p.current_noise_a),
            bus_noise: noise(p.bus_noise_v),
        })
        .collect();
    let mut q: [f64; J] = std::array::from_fn(|j| setup.trajectories[j].offset_rad);
    let mut qd = [0.0f64; J];
    for (d, q0) in drives.iter_mut().zip(q.iter()) {
        d.set_position_origin(*q0 as f32);
    }
    let mut mech = setup.mechanics.clone();
    let comp_every = (pwm_hz / setup.compensator.rate_hz as f64).round().max(1.0) as u64;
    let n = (setup.duration_s * pwm_hz).round() as u64;
    let substeps = setup.plants[0].substeps.max(1);
    let dt = 1.0 / (pwm_hz * substeps as f64);
    let mut duties = vec![[0.5f64; 3]; J];
    let mut last_out = vec![DriveOutput::default(); J];
    let mut bus = super::StateBus::default();
    let (mut se, mut siq) = ([0.0f64; J], [0.0f64; J]);
    let mut faults = [FaultFlags::NONE; J];
    let mut zero_ticks = [0u64; J];
    let mut t = 0.0f64;
    for k in 0..n {
        let t_tick = k as f64 / pwm_hz;
        if k % comp_every == 0 {
            bus.deliver(&mut comps)?;
            let t_mid = t_tick + 0.5 * comp_every as f64 / pwm_hz;
            for j in 0..J {
                let (qa, qda, qdda) = setup.trajectories[j].at(t_mid);
                let gain = setup.compensator.drive_gain_nm_per_a;
                let own = JointState {
                    q_ref_rad: qa as f32,
                    qd_ref_rad_s: qda as f32,
                    qdd_ref_rad_s2: qdda as f32,
                    q_meas_rad: last_out[j].q_rad,
                    qd_meas_rad_s: last_out[j].qd_rad_s,
                    tau_meas_nm: last_out[j].iq_meas_a * gain,
                };
                let o = comps[j].tick(&own, (t_tick * 1e6) as u32);
                drives[j].set_feedforward_current(o.current_a);
                if k > 0 {
                    faults[j] |= o.faults;
                }
                zero_ticks[j] += u64::from(o.source == FeedforwardSource::Zero);
                bus.send(j, (t_tick * 1e6) as u32, own);
            }
        }
        for j in 0..J {
            let c = &setup.plants[j];
            let (qr, qdr, qddr) = setup.trajectories[j].at(t_tick);
            drives[j].set_reference(&JointReference {
                q_rad: qr as f32,
                qd_rad_s: qdr as f32,
                qdd_rad_s2: qddr as f32,
            });
            let m = &mut motors[j];
            let s: SensedSample = sense_joint(
                c,
                m.i_abc_a,
                q[j] * c.gear_ratio,
                &mut m.rng,
                &m.current_noise,
                &m.bus_noise,
            );
            last_out[j] = drives[j].pwm_tick(&SensorSample {
                phase_current_a: [s.phase_current_a[0] as f32, s.phase_current_a[1] as f32],
                motor_angle_rad: s.motor_angle_rad as f32,
                bus_v: s.bus_v as f32,
            });
            faults[j] |= last_out[j].faults;
        }
        // Integrate one PWM period with the duties computed one period ago.
        let v: Vec<[f64; 3]> = (0..J)
            .map(|j| phase_voltages(&setup.plants[j], duties[j]))
            .collect();
        for _ in 0..substeps {
            let mut tau = [0.0f64; J];
            for j in 0..J {
                let c = &setup.plants[j];
                let motor_angle = q[j] * c.gear_ratio;
                let th = c.pole_pairs as f64 * (motor_angle - c.encoder_offset_rad);
                motor_electrical_step(
                    c,
                    &mut motors[j].i_abc_a,
                    v[j],
                    th,
                    qd[j] * c.gear_ratio,
                    dt,
                );
                let t_motor = 1.5
                    * c.pole_pairs as f64
                    * c.flux_linkage_wb
                    * q_current_a(motors[j].i_abc_a, th);
                tau[j] = t_motor * c.gear_ratio * c.gear_efficiency;
            }
            let m = mech.mass_matrix(&q);
            let h = mech.bias_torques_nm(t, &q, &qd);
            let mm = DMatrix::<f64>::from_fn(J, J, |r, c| {
                m[r][c] + if r == c { reflected[r] } else { 0.0 }
            });
            let rhs = DVector::<f64>::from_fn(J, |r, _| tau[r] - h[r]);
            let qdd = mm
                .lu()
                .solve(&rhs)
                .ok_or_else(|| anyhow::anyhow!("singular mass matrix at t = {t}"))?;
            for j in 0..J {
                qd[j] += qdd[j] * dt;
                q[j] += qd[j] * dt;
            }
            t += dt;
        }
        for j in 0..J {
            duties[j] = last_out[j].duties.map(f64::from);
            let e = setup.trajectories[j].at(t).0 - q[j];
            se[j] += e * e;
            let c = &setup.plants[j];
            let th = c.pole_pairs as f64 * (q[j] * c.gear_ratio - c.encoder_offset_rad);
            siq[j] += q_current_a(motors[j].i_abc_a, th).powi(2);
        }
    }
    let nf = n.max(1) as f64;
    Ok(std::array::from_fn(|j| JointReport {
        rms_error_rad: (se[j] / nf).sqrt(),
        rms_iq_a: (siq[j] / nf).sqrt(),
        faults: faults[j],
        zero_feedforward_ticks: zero_ticks[j],
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrist_exchanges_states_and_coupled_feedforward_wins_on_every_joint() {
        let mut setup = MultiJointSetup::wrist(1000.0, 3);
        setup.duration_s = 3.0;
        let none = run_multi_joint(&setup, MultiFeedforward::Mode(FeedforwardMode::None)).unwrap();
        let alone = run_multi_joint(&setup, MultiFeedforward::Decoupled).unwrap();
        let coupled = run_multi_joint(
            &setup,
            MultiFeedforward::Mode(FeedforwardMode::InverseDynamics(1.0)),
        )
        .unwrap();
        for j in 0..3 {
            println!(
                "joint {j}: none {:?}\n   alone {:?}\n   coupled {:?}",
                none[j], alone[j], coupled[j]
            );
            assert!(coupled[j].rms_error_rad < none[j].rms_error_rad / 2.0);
            // The bus delivered every joint's state: no watchdog or rejection.
            let bus = FaultFlags::STATE_STALE
                | FaultFlags::STATE_REJECTED
                | FaultFlags::STATE_OUT_OF_ORDER;
            assert!(
                !coupled[j].faults.intersects(bus),
                "{:?}",
                coupled[j].faults
            );
            assert_eq!(
                coupled[j].zero_feedforward_ticks, 1,
                "only the first tick lacks the others' states"
            );
        }
        // Using the other joints' states (from the bus) beats each drive alone on the
        // wrist as a whole (per joint: clearly on joints 0 and 1, about even on joint 2).
        let ms = |r: &[JointReport; 3]| r.iter().map(|x| x.rms_error_rad.powi(2)).sum::<f64>();
        assert!(
            ms(&coupled) < 0.8 * ms(&alone),
            "{} vs {}",
            ms(&coupled),
            ms(&alone)
        );
    }
}
