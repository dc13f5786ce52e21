//! Measured workloads: the per-tick computations whose size and cycles the budget
//! checks track (`host-tests`, `cargo run -p host-tests --bin budget`).
//!
//! A workload is a type implementing [`Workload`]; its [`Workload::tick`] is the
//! measured entry point, marked `#[inline(never)]` so it keeps one address and one
//! stable symbol (`<test_kit::bench::Dot64 as test_kit::bench::Workload>::tick`).
//! Registering a workload is one line in [`visit_all`]. The QEMU bench binary
//! (`firmware/qemu/src/bench.rs`), the board bench binary and the host tests all drive
//! the registered workloads through a [`Visitor`].

use crate::golden;
use firmware::control::{JointState, LstmPredictor, PredictorInput, TorquePredictor};
use firmware::math;

/// A per-tick computation measured by the budget checks.
pub trait Workload {
    /// Stable name used in reports and in `host-tests/budgets.toml`.
    const NAME: &'static str;
    /// Multiply-accumulates per tick (0 when the workload is not MAC-bound); the
    /// reports print cycles per MAC beside it.
    const MACS: u32 = 0;
    /// The workload's state with deterministic inputs.
    fn new() -> Self;
    /// One control tick. Implementations mark it `#[inline(never)]`.
    fn tick(&mut self);
    /// A value derived from the last tick's result (keeps the work observable).
    fn output(&self) -> f32;
}

/// Something that runs workloads one type at a time (a benchmark driver, a test).
pub trait Visitor {
    /// Called once per registered workload.
    fn visit<W: Workload>(&mut self);
}

/// Calls `v.visit::<W>()` for every registered workload, in report order.
///
/// Adding a workload: implement [`Workload`] and add one line here.
pub fn visit_all<V: Visitor>(v: &mut V) {
    v.visit::<Dot64>();
    v.visit::<LstmGateActivations64>();
    v.visit::<JointTrig6>();
    v.visit::<LstmPaperF32>();
    v.visit::<LstmPaperInt16>();
    v.visit::<LstmPaperInt8>();
    v.visit::<LstmJointInt16>();
    v.visit::<DriveStageInt16>();
    v.visit::<Dynamics6F32>();
    v.visit::<LstmLinearF32>();
    v.visit::<LstmLinearInt16>();
    v.visit::<LstmLinearInt8>();
    v.visit::<StateFrameMac>();
    v.visit::<DrivePwmTick>();
}

/// Number of registered workloads.
pub fn workload_count() -> usize {
    struct Count(usize);
    impl Visitor for Count {
        fn visit<W: Workload>(&mut self) {
            self.0 += 1;
        }
    }
    let mut c = Count(0);
    visit_all(&mut c);
    c.0
}

/// Phase advance per tick: the inputs change every tick, so the data-dependent
/// paths of the math primitives show up in the min/max spread.
const PHASE_STEP: f32 = 0.013;

/// An f32 dot product of two 64-element vectors (one LSTM gate row of the paper's
/// 64-cell layer), `math::dot`.
pub struct Dot64 {
    a: [f32; golden::DOT_LEN],
    b: [f32; golden::DOT_LEN],
    out: f32,
}

impl Workload for Dot64 {
    const NAME: &'static str = "dot64";
    const MACS: u32 = golden::DOT_LEN as u32;

    fn new() -> Self {
        let (a, b) = golden::dot_case(0);
        Dot64 { a, b, out: 0.0 }
    }

    #[inline(never)]
    #[cfg_attr(target_os = "none", unsafe(link_section = ".ccmram_text"))]
    fn tick(&mut self) {
        self.out = math::dot(&self.a, &self.b);
        self.a[0] = self.out * 1.0e-3;
    }

    fn output(&self) -> f32 {
        self.out
    }
}

/// Number of cells of the paper's LSTM layer.
pub const LSTM_CELLS: usize = 64;

/// The activations of one LSTM step of 64 cells: sigmoid on the input, forget and
/// output gates (3 x 64), tanh on the candidate and the cell state (2 x 64),
/// `math::sigmoid` and `math::tanh`.
pub struct LstmGateActivations64 {
    pre: [f32; LSTM_CELLS],
    phase: f32,
    out: f32,
}

impl Workload for LstmGateActivations64 {
    const NAME: &'static str = "lstm_gate_activations64";

    fn new() -> Self {
        let mut pre = [0.0f32; LSTM_CELLS];
        for (k, p) in pre.iter_mut().enumerate() {
            *p = 12.0 * golden::unit(golden::hash(k as u32)) - 6.0;
        }
        LstmGateActivations64 {
            pre,
            phase: 0.0,
            out: 0.0,
        }
    }

    #[inline(never)]
    #[cfg_attr(target_os = "none", unsafe(link_section = ".ccmram_text"))]
    fn tick(&mut self) {
        let mut acc = 0.0f32;
        for &p in &self.pre {
            let x = p + self.phase;
            let i = math::sigmoid(x);
            let f = math::sigmoid(x - 1.0);
            let o = math::sigmoid(x + 1.0);
            let g = math::tanh(x * 0.5);
            let h = o * math::tanh(f * x + i * g);
            acc += h;
        }
        self.out = acc;
        self.phase = (self.phase + PHASE_STEP) % 1.0;
    }

    fn output(&self) -> f32 {
        self.out
    }
}

/// Number of joints of the arm.
pub const JOINTS: usize = 6;

/// Sine and cosine of the six joint angles, what the rigid-body dynamics model
/// needs first in every tick (`math::sin_cos`).
pub struct JointTrig6 {
    q_rad: [f32; JOINTS],
    out: f32,
}

impl Workload for JointTrig6 {
    const NAME: &'static str = "joint_trig6";

    fn new() -> Self {
        let mut q_rad = [0.0f32; JOINTS];
        for (k, q) in q_rad.iter_mut().enumerate() {
            *q = 6.0 * golden::unit(golden::hash(100 + k as u32)) - 3.0;
        }
        JointTrig6 { q_rad, out: 0.0 }
    }

    #[inline(never)]
    #[cfg_attr(target_os = "none", unsafe(link_section = ".ccmram_text"))]
    fn tick(&mut self) {
        let mut acc = 0.0f32;
        for q in self.q_rad.iter_mut() {
            let (s, c) = math::sin_cos(*q);
            acc += s * c;
            *q += PHASE_STEP;
        }
        self.out = acc;
    }

    fn output(&self) -> f32 {
        self.out
    }
}

/// Golden input vectors a model workload cycles through (computed in `new`, so the
/// measured tick is the network step alone, not the test-signal generator).
pub const MODEL_INPUT_STEPS: usize = 16;

/// One streaming step of a fixture model (`crate::fixtures`) per tick, on golden
/// inputs that change every tick.
macro_rules! model_workload {
    ($(#[$doc:meta])* $ty:ident, $name:literal, $m:ident) => {
        $(#[$doc])*
        pub struct $ty {
            state: crate::fixtures::$m::State,
            inputs: [[f32; crate::fixtures::$m::INPUTS]; MODEL_INPUT_STEPS],
            t: usize,
            out: f32,
        }

        impl Workload for $ty {
            const NAME: &'static str = $name;
            const MACS: u32 = crate::fixtures::$m::Network::MACS;

            fn new() -> Self {
                $ty {
                    state: crate::fixtures::$m::State::new(),
                    inputs: core::array::from_fn(crate::golden::network::inputs),
                    t: 0,
                    out: 0.0,
                }
            }

            #[inline(never)]
            #[cfg_attr(target_os = "none", unsafe(link_section = ".ccmram_text"))]
            fn tick(&mut self) {
                let x = self.inputs[self.t % MODEL_INPUT_STEPS];
                let y = crate::fixtures::$m::NETWORK.step(&mut self.state, &x);
                self.out = y[0];
                self.t += 1;
            }

            fn output(&self) -> f32 {
                self.out
            }
        }
    };
}

model_workload!(
    /// The paper's network (9 -> 64 -> LSTM 64 -> 3), f32 (`nn::kernels::F32Lstm`).
    LstmPaperF32, "lstm_paper_f32", bench_paper_f32
);
model_workload!(
    /// The paper's network, int16 weights and activations (`nn::kernels::QuantLstm`, SMLAD).
    LstmPaperInt16, "lstm_paper_int16", bench_paper_int16
);
model_workload!(
    /// The paper's network, int8 weights, int16 activations (SXTB16 + SMLAD).
    LstmPaperInt8, "lstm_paper_int8", bench_paper_int8
);
model_workload!(
    /// The per-joint network (3 -> 16 -> LSTM 16 -> 1), int16.
    LstmJointInt16, "lstm_joint_int16", bench_joint_int16
);

/// The drive compensator's per-joint stage as the drive runs it each tick
/// (`firmware::control::LstmPredictor`, preset `drive`): the drive features of the
/// reference, the residual measured over the previous tick, the 27-term linear stage and
/// the 11 -> 16 -> LSTM 16 -> 1 network, int16 (`crate::fixtures::bench_drive_int16`), on
/// golden joint states that change every tick.
pub struct DriveStageInt16 {
    // `Some`: the fixture's preset and sizes are checked at compile time
    // (`firmware::check_model!`).
    predictor: Option<
        LstmPredictor<
            &'static crate::fixtures::bench_drive_int16::Network,
            1,
            { crate::fixtures::bench_drive_int16::INPUTS },
        >,
    >,
    inputs: [PredictorInput<1>; MODEL_INPUT_STEPS],
    t: usize,
    out: f32,
}

impl Workload for DriveStageInt16 {
    const NAME: &'static str = "drive_stage_int16";
    const MACS: u32 = crate::fixtures::bench_drive_int16::Network::MACS
        + firmware::features::FRICTION_FEATURES as u32;

    fn new() -> Self {
        use crate::fixtures::bench_drive_int16 as m;
        DriveStageInt16 {
            predictor: LstmPredictor::new(&m::NETWORK, m::FEATURE_PRESET).map(|p| {
                p.with_linear_stage(m::LINEAR_STAGE)
                    .with_envelope(m::ENVELOPE)
            }),
            inputs: core::array::from_fn(|t| {
                let [q, qd, qdd, tau, model] = crate::golden::network::inputs::<5>(t);
                PredictorInput {
                    joints: [JointState {
                        q_ref_rad: q,
                        qd_ref_rad_s: qd,
                        qdd_ref_rad_s2: qdd,
                        tau_meas_nm: tau,
                        ..Default::default()
                    }],
                    own_joint: 0,
                    model_nm: [model],
                }
            }),
            t: 0,
            out: 0.0,
        }
    }

    #[inline(never)]
    #[cfg_attr(target_os = "none", unsafe(link_section = ".ccmram_text"))]
    fn tick(&mut self) {
        if let Some(p) = &mut self.predictor {
            self.out = p.predict_nm(&self.inputs[self.t % MODEL_INPUT_STEPS])[0];
        }
        self.t += 1;
    }

    fn output(&self) -> f32 {
        self.out
    }
}

model_workload!(
    /// A network with a linear input layer (the PyTorch fixture, 5 -> 12 -> LSTM 16 -> 2), f32.
    LstmLinearF32, "lstm_linear_f32", golden_linear_f32
);
model_workload!(
    /// The same network with a linear input layer, int16 (the fused `dsp::lstm_small_i16`).
    LstmLinearInt16, "lstm_linear_int16", golden_linear_int16
);
model_workload!(
    /// The same network with a linear input layer, int8 weights.
    LstmLinearInt8, "lstm_linear_int8", golden_linear_int8
);

/// The 6-DoF rigid-body model (`firmware::dynamics::RigidBodyModel<6>::torques`, f32) with the
/// nominal parameters of the default robot exported with the paper benchmark model.
pub struct Dynamics6F32 {
    q: [f32; 6],
    out: f32,
}

impl Workload for Dynamics6F32 {
    const NAME: &'static str = "dynamics6_f32";

    fn new() -> Self {
        Dynamics6F32 {
            q: core::array::from_fn(|k| 0.3 * k as f32 - 0.7),
            out: 0.0,
        }
    }

    #[inline(never)]
    #[cfg_attr(target_os = "none", unsafe(link_section = ".ccmram_text"))]
    fn tick(&mut self) {
        let qd = core::array::from_fn(|k| 0.5 - 0.2 * k as f32);
        let qdd = core::array::from_fn(|k| 1.0 - 0.3 * k as f32);
        let tau = crate::fixtures::bench_paper_f32::DYNAMICS.torques(&self.q, &qd, &qdd);
        self.out = tau[1];
        for q in self.q.iter_mut() {
            *q += PHASE_STEP;
        }
    }

    fn output(&self) -> f32 {
        self.out
    }
}

/// One state frame's authentication on the CAN-FD bus
/// (`firmware::control::canfd::StateFrame::decode`: AES-128-CMAC over the identifier
/// block and 40 payload bytes, three AES blocks, the truncated tag compared) and its
/// decoding, of golden frames that change every tick. A drive verifies one per
/// other joint and one SYNC, and seals its own (the same CMAC), per compensator tick.
pub struct StateFrameMac {
    auth: firmware::control::canfd::FrameAuth,
    frames: [firmware::control::canfd::CanFdFrame; MODEL_INPUT_STEPS],
    t: usize,
    out: f32,
}

impl Workload for StateFrameMac {
    const NAME: &'static str = "state_frame_mac";

    fn new() -> Self {
        use firmware::control::canfd::{CanFdFrame, FrameAuth, StateFrame};
        use firmware::control::{FaultFlags, JointStateMessage};
        let auth = FrameAuth::new(b"bench-robot-key!");
        let frames = core::array::from_fn(|t| {
            StateFrame {
                message: JointStateMessage {
                    joint: 2,
                    session: 0x5EED,
                    sequence: t as u16,
                    timestamp_us: 1000 * t as u32,
                    state: JointState::from_array(crate::golden::network::inputs::<6>(t)),
                },
                faults: FaultFlags::NONE,
                feedforward_nm: 1.0,
            }
            .encode(&auth)
            .unwrap_or(CanFdFrame {
                id: 0,
                len: 0,
                data: [0; 64],
            })
        });
        StateFrameMac {
            auth,
            frames,
            t: 0,
            out: 0.0,
        }
    }

    #[inline(never)]
    #[cfg_attr(target_os = "none", unsafe(link_section = ".ccmram_text"))]
    fn tick(&mut self) {
        use firmware::control::canfd::StateFrame;
        let frame = &self.frames[self.t % MODEL_INPUT_STEPS];
        self.out = match StateFrame::decode(&self.auth, frame) {
            Ok(d) => d.message.state.q_ref_rad + f32::from(d.message.sequence),
            Err(_) => f32::NAN,
        };
        self.t += 1;
    }

    fn output(&self) -> f32 {
        self.out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    struct RunAll {
        names: [&'static str; 16],
        n: usize,
    }
    impl Visitor for RunAll {
        fn visit<W: Workload>(&mut self) {
            let mut w = W::new();
            let mut prev = f32::NAN;
            for _ in 0..5 {
                w.tick();
                assert!(w.output().is_finite(), "{}", W::NAME);
                prev = w.output();
            }
            assert!(prev.is_finite());
            assert!(
                !self.names[..self.n].contains(&W::NAME),
                "duplicate {}",
                W::NAME
            );
            self.names[self.n] = W::NAME;
            self.n += 1;
        }
    }

    #[test]
    fn registered_workloads_run_and_have_unique_names() {
        let mut v = RunAll {
            names: [""; 16],
            n: 0,
        };
        visit_all(&mut v);
        assert_eq!(v.n, workload_count());
        assert!(v.n >= 3);
    }

    #[test]
    fn dot64_computes_the_golden_dot_product() {
        let mut w = Dot64::new();
        w.tick();
        assert_eq!(w.output().to_bits(), golden::dot_output(0).to_bits());
    }
}

/// One PWM-rate drive tick (`JointDrive::pwm_tick`: Clarke and Park transforms, the
/// current loop, space-vector modulation and, every fourth tick, the position and
/// velocity cascade) on the board's profile at 20 kHz: the control work of the board
/// image's PWM interrupt (`ADC1_2`), without its ADC, SPI and timer register accesses,
/// which the QEMU machine of the cycle model does not have.
pub struct DrivePwmTick {
    drive: firmware::control::JointDrive,
    t: u32,
    out: f32,
    bridge_enabled: bool,
}

impl Workload for DrivePwmTick {
    const NAME: &'static str = "drive_pwm_tick";

    fn new() -> Self {
        use firmware::control::{JointDrive, JointProfile, JointReference};
        let mut drive = JointDrive::new(JointProfile::BOARD.drive_config(20_000.0));
        drive.set_position_origin(0.0);
        drive.set_reference(&JointReference::default());
        DrivePwmTick {
            drive,
            t: 0,
            out: 0.0,
            bridge_enabled: false,
        }
    }

    #[inline(never)]
    #[cfg_attr(target_os = "none", unsafe(link_section = ".ccmram_text"))]
    fn tick(&mut self) {
        // Motor angle in [0, 2 pi): 480 steps of PHASE_STEP, then again.
        let phase = (self.t % 480) as f32 * PHASE_STEP;
        let (s, c) = math::sin_cos(phase);
        // Within the board profile's sensor limits (bus 36..56 V, trip 30 A), so the
        // whole control path runs, not a fault exit.
        let sample = firmware::control::SensorSample {
            phase_current_a: [0.5 * s, 0.5 * c],
            motor_angle_rad: phase,
            bus_v: 48.0,
        };
        let o = self.drive.pwm_tick(&sample);
        self.out = o.duties[0] + o.duties[1] + o.duties[2];
        self.bridge_enabled = o.bridge_enabled;
        self.t += 1;
    }

    fn output(&self) -> f32 {
        self.out
    }
}

#[cfg(test)]
mod drive_tests {
    use super::*;

    #[test]
    fn the_drive_workload_runs_the_control_path_not_a_fault_exit() {
        let mut w = DrivePwmTick::new();
        for _ in 0..1000 {
            w.tick();
            assert!(w.bridge_enabled, "tick {} left the bridge off", w.t);
            assert!(w.output().is_finite());
        }
    }
}
