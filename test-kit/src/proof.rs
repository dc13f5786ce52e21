//! The training envelope's proof on the target: one joint's `drive` compensator, trained
//! on the host on slow motion of [`true_torque_nm`]'s joint and compiled in as the
//! firmware's model, runs on the same joint moving [`FAST_SPEED`] times faster.
//!
//! Everything the compensator reads is computed here, in f32 through the firmware's own
//! math, so the QEMU image and the host compute the same stream from the same code: the
//! motion ([`motion`]), the torque the joint truly needs ([`true_torque_nm`]: a pendulum
//! with viscous, Coulomb, Stribeck and quadratic friction and a position ripple), the
//! identified model the compensator's first stage runs ([`MODEL`]: the pendulum with
//! viscous and Coulomb friction, slightly off). [`stream`] runs the firmware's
//! `Compensator` (the network, its linear stage and training envelope) over the motion,
//! the torque measured over the previous tick as its measured torque, and emits each
//! tick's output beside the model's and the true torque.
use firmware::control::{
    Compensator, DecoupledJointModel, JointProfile, JointState, LstmPredictor, TorqueNetwork,
};
use firmware::envelope::JointEnvelope;
use firmware::features::FRICTION_FEATURES;
use firmware::math;
use firmware::nn::format::FeaturePreset;

/// Compensator rate [Hz].
pub const RATE_HZ: u32 = 100;
/// The speed factor of the fast motion against the training motion.
pub const FAST_SPEED: f32 = 3.0;
/// Phase of the fast motion's first harmonic [rad].
pub const FAST_PHASE_RAD: f32 = 0.3;
/// Ticks of the fast motion (20 s).
pub const FAST_TICKS: usize = 2_000;

/// The identified model of the joint (what identification found: inertia and gravity
/// right, viscous and Coulomb friction low, no Stribeck, quadratic or ripple term).
pub const MODEL: DecoupledJointModel<1> = DecoupledJointModel {
    inertia_kg_m2: [0.4],
    viscous_nm_s_rad: [2.0],
    coulomb_nm: [1.5],
    coulomb_smoothing_rad_s: [0.02],
    gravity_nm: [12.0],
    gravity_phase_rad: [0.0],
};

/// Angle [rad], velocity [rad/s] and acceleration [rad/s^2] at tick `k` of
/// `q(t) = 0.7 sin(0.45 s t + phase) + 0.25 sin(1.1 s t)`, `s` the speed factor.
pub fn motion(speed: f32, phase_rad: f32, k: usize) -> (f32, f32, f32) {
    let t = k as f32 / RATE_HZ as f32;
    let (a1, w1, a2, w2) = (0.7f32, 0.45 * speed, 0.25f32, 1.1 * speed);
    let (x1, x2) = (w1 * t + phase_rad, w2 * t);
    let (s1, c1, s2, c2) = (math::sin(x1), math::cos(x1), math::sin(x2), math::cos(x2));
    (
        a1 * s1 + a2 * s2,
        a1 * w1 * c1 + a2 * w2 * c2,
        -a1 * w1 * w1 * s1 - a2 * w2 * w2 * s2,
    )
}

/// The torque the true joint needs [N*m]: inertia 0.4 kg m^2, gravity 12 N m, viscous
/// 2.3 N m s/rad, Coulomb 1.8 N m rising to a 2.6 N m breakaway below 0.08 rad/s
/// (Stribeck), quadratic friction 0.6 N m s^2/rad^2, a 0.15 N m ripple 8 times per turn.
pub fn true_torque_nm(q: f32, qd: f32, qdd: f32) -> f32 {
    let stribeck = 1.8 + 0.8 * math::exp(-(qd / 0.08) * (qd / 0.08));
    0.4 * qdd
        + 12.0 * math::sin(q)
        + 2.3 * qd
        + stribeck * math::tanh(qd / 0.005)
        + 0.6 * qd * qd.abs()
        + 0.15 * math::sin(8.0 * q)
}

/// The model torque of [`MODEL`] [N*m] (what a dataset's `tau_model_j1` holds).
pub fn model_torque_nm(q: f32, qd: f32, qdd: f32) -> f32 {
    let m = &MODEL;
    m.inertia_kg_m2[0] * qdd
        + m.viscous_nm_s_rad[0] * qd
        + m.coulomb_nm[0] * math::tanh(qd / m.coulomb_smoothing_rad_s[0])
        + m.gravity_nm[0] * math::sin(q + m.gravity_phase_rad[0])
}

/// One tick of [`stream`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProofTick {
    /// The compensator's torque feedforward [N*m].
    pub output_nm: f32,
    /// The identified model's torque on the same tick [N*m].
    pub model_nm: f32,
    /// The torque the joint truly needs [N*m].
    pub true_nm: f32,
    /// The compensator's fault flags (bits).
    pub faults: u32,
}

/// Runs a `J`-joint image's compensator (network `net` of preset `preset`, its linear
/// stage and training envelope, `profile`'s settings, [`MODEL`] as the first stage) over
/// `ticks` ticks of the motion at `speed`, and calls `emit(tick, ..)` on each. Only a
/// single-joint `drive` image runs (an image of another form emits nothing): the
/// compensator of a joint with peers would need their states.
#[allow(clippy::too_many_arguments)]
pub fn stream<const J: usize, const I: usize, N: TorqueNetwork<I, J>>(
    net: &N,
    preset: FeaturePreset,
    linear: [[f32; FRICTION_FEATURES]; J],
    envelope: [JointEnvelope; J],
    profile: &JointProfile,
    speed: f32,
    phase_rad: f32,
    ticks: usize,
    mut emit: impl FnMut(usize, ProofTick),
) {
    if J != 1 || preset != FeaturePreset::Drive {
        return;
    }
    let Some(lstm) = LstmPredictor::<_, J, I>::new(net, preset) else {
        return;
    };
    let lstm = lstm.with_linear_stage(linear).with_envelope(envelope);
    let model = DecoupledJointModel::<J> {
        inertia_kg_m2: [MODEL.inertia_kg_m2[0]; J],
        viscous_nm_s_rad: [MODEL.viscous_nm_s_rad[0]; J],
        coulomb_nm: [MODEL.coulomb_nm[0]; J],
        coulomb_smoothing_rad_s: [MODEL.coulomb_smoothing_rad_s[0]; J],
        gravity_nm: [MODEL.gravity_nm[0]; J],
        gravity_phase_rad: [MODEL.gravity_phase_rad[0]; J],
    };
    let Ok(mut c) = Compensator::new(profile.compensator_config(RATE_HZ, 0), model, lstm) else {
        return;
    };
    let (q0, qd0, qdd0) = motion(speed, phase_rad, 0);
    let mut measured = true_torque_nm(q0, qd0, qdd0);
    for k in 0..ticks {
        let (q, qd, qdd) = motion(speed, phase_rad, k);
        let own = JointState {
            q_ref_rad: q,
            qd_ref_rad_s: qd,
            qdd_ref_rad_s2: qdd,
            tau_meas_nm: measured,
            ..Default::default()
        };
        let true_nm = true_torque_nm(q, qd, qdd);
        measured = true_nm;
        let o = c.tick(&own, (k as u32).wrapping_mul(1_000_000 / RATE_HZ));
        emit(
            k,
            ProofTick {
                output_nm: o.torque_nm,
                model_nm: model_torque_nm(q, qd, qdd),
                true_nm,
                faults: o.faults.bits(),
            },
        );
    }
}
