//! Deterministic golden inputs shared by the QEMU binary and the host tests.
//!
//! Both sides generate the same inputs from integer arithmetic, run the same
//! firmware functions on them, and `host-tests` compares the outputs bit for bit.
//! The `envelope` suite ([`envelope_output`], [`envelope_stream`]) covers the training
//! envelope's weight, the faded prediction and the clamped linear stage.
//! [`network`]: the input stream of the compiled-in networks (the exporter's
//! self-check and the QEMU network suites).

pub mod network;

use firmware::adaptation;
use firmware::dynamics::{JointModel, RigidBodyModel};
use firmware::envelope::{self, JointEnvelope, Range};
use firmware::features;
use firmware::math;
use firmware::monitor;
use firmware::nn::format::InputActivation;
use firmware::nn::reference::{Lstm, LstmState};

/// Number of points per scalar function.
pub const MATH_POINTS: usize = 10_000;
/// Length of each dot-product vector.
pub const DOT_LEN: usize = 64;
/// Number of dot-product cases.
pub const DOT_CASES: usize = 1_000;

/// A scalar primitive under test.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MathFn {
    /// `math::exp`
    Exp,
    /// `math::tanh`
    Tanh,
    /// `math::sigmoid`
    Sigmoid,
    /// `math::sqrt`
    Sqrt,
    /// `math::sin`
    Sin,
    /// `math::cos`
    Cos,
}

impl MathFn {
    /// Every primitive, in report order.
    pub const ALL: [MathFn; 6] = [
        MathFn::Exp,
        MathFn::Tanh,
        MathFn::Sigmoid,
        MathFn::Sqrt,
        MathFn::Sin,
        MathFn::Cos,
    ];

    /// Short name used in the QEMU output and in mismatch reports.
    pub const fn name(self) -> &'static str {
        match self {
            MathFn::Exp => "exp",
            MathFn::Tanh => "tanh",
            MathFn::Sigmoid => "sigmoid",
            MathFn::Sqrt => "sqrt",
            MathFn::Sin => "sin",
            MathFn::Cos => "cos",
        }
    }

    /// Looks a primitive up by its `name`.
    pub fn from_name(name: &str) -> Option<MathFn> {
        MathFn::ALL.into_iter().find(|f| f.name() == name)
    }

    /// Input range covered: what an LSTM gate (±16 and beyond into saturation)
    /// and the dynamics (angles of several turns, inertia sums) need.
    pub const fn range(self) -> (f32, f32) {
        match self {
            MathFn::Exp => (-87.0, 88.0),
            MathFn::Tanh | MathFn::Sigmoid => (-20.0, 20.0),
            MathFn::Sqrt => (0.0, 1.0e4),
            MathFn::Sin | MathFn::Cos => (-25.0, 25.0),
        }
    }

    /// Evaluates the firmware primitive.
    pub fn eval(self, x: f32) -> f32 {
        match self {
            MathFn::Exp => math::exp(x),
            MathFn::Tanh => math::tanh(x),
            MathFn::Sigmoid => math::sigmoid(x),
            MathFn::Sqrt => math::sqrt(x),
            MathFn::Sin => math::sin(x),
            MathFn::Cos => math::cos(x),
        }
    }

    /// The `i`-th golden input: even indices sweep the range evenly, odd ones are
    /// pseudo-random in it (so the sweep also hits non-grid mantissas).
    pub fn input(self, i: usize) -> f32 {
        let (lo, hi) = self.range();
        let frac = if i.is_multiple_of(2) {
            i as f32 / (MATH_POINTS - 1) as f32
        } else {
            unit(hash(i as u32 ^ (self as u32) << 24))
        };
        lo + (hi - lo) * frac
    }
}

/// The `case`-th pair of dot-product vectors, entries in [-4, 4).
pub fn dot_case(case: usize) -> ([f32; DOT_LEN], [f32; DOT_LEN]) {
    let mut a = [0.0f32; DOT_LEN];
    let mut b = [0.0f32; DOT_LEN];
    for k in 0..DOT_LEN {
        let seed = (case * DOT_LEN + k) as u32;
        a[k] = 8.0 * unit(hash(seed.wrapping_mul(2))) - 4.0;
        b[k] = 8.0 * unit(hash(seed.wrapping_mul(2) + 1)) - 4.0;
    }
    (a, b)
}

/// Output of the `case`-th dot product.
pub fn dot_output(case: usize) -> f32 {
    let (a, b) = dot_case(case);
    math::dot(&a, &b)
}

/// Cells of the `cells` suite (`firmware::dsp::lstm_cells_f32`, the f32 LSTM's gate
/// activations and cell update; `tanh4_bias_f32` and `mul_tanh4_f32`, its tanh layers).
pub const CELL_CASES: usize = 512;

/// Gate sums, bias and cell state of the `cells` suite: sums over the activations'
/// whole range (|x| up to 128, past the clamps at 9 and 87), every 61st an infinity
/// or NaN.
pub fn cell_case(j: usize) -> ([f32; 4], [f32; 4], f32) {
    let v = |k: u32| 256.0 * unit(hash(k)) - 128.0;
    let special = [f32::INFINITY, f32::NEG_INFINITY, f32::NAN, -0.0];
    let acc: [f32; 4] = core::array::from_fn(|r| {
        let k = (4 * j + r) as u32;
        if k.is_multiple_of(61) {
            special[(k / 61) as usize % special.len()]
        } else {
            // Half of the sums small, where the exponentials' polynomials matter most.
            let x = v(k.wrapping_mul(3));
            if k.is_multiple_of(2) { x / 16.0 } else { x }
        }
    });
    let bias: [f32; 4] = core::array::from_fn(|r| unit(hash((4 * j + r) as u32 ^ 0x5a5a)) - 0.5);
    (acc, bias, 4.0 * unit(hash(j as u32 ^ 0xc311)) - 2.0)
}

/// Of every cell of the `cells` suite: the new cell state and `o` (one call of
/// `firmware::dsp::lstm_cells_f32`), `tanh(acc + bias)` of its four sums (one call of
/// `tanh4_bias_f32`) and `bias * tanh(acc)` (one call of `mul_tanh4_f32`).
#[allow(clippy::type_complexity)]
pub fn cells_output() -> (
    [f32; CELL_CASES],
    [f32; CELL_CASES],
    [[f32; 4]; CELL_CASES],
    [[f32; 4]; CELL_CASES],
) {
    let mut acc = [[0.0f32; 4]; CELL_CASES];
    let mut bias = [[0.0f32; 4]; CELL_CASES];
    let mut c = [0.0f32; CELL_CASES];
    for j in 0..CELL_CASES {
        (acc[j], bias[j], c[j]) = cell_case(j);
    }
    let mut h = [0.0f32; CELL_CASES];
    firmware::dsp::lstm_cells_f32(&acc, &bias, &mut c, &mut h);
    let mut t = acc;
    firmware::dsp::tanh4_bias_f32(&mut t, &bias);
    let mut m = bias;
    firmware::dsp::mul_tanh4_f32(&mut m, &acc);
    (c, h, t, m)
}

/// Number of dynamics golden cases (one record per joint torque each).
pub const DYNAMICS_CASES: usize = 500;
/// Joints of the golden dynamics model.
pub const DYNAMICS_JOINTS: usize = 6;

/// Modified-DH rows `(a_{i-1} [m], alpha_{i-1} [rad], d_i [m])` of the golden arm (UR5e-like).
const GOLDEN_DH: [(f32, f32, f32); DYNAMICS_JOINTS] = [
    (0.0, 0.0, 0.1625),
    (0.0, core::f32::consts::FRAC_PI_2, 0.0),
    (-0.425, 0.0, 0.0),
    (-0.3922, 0.0, 0.1333),
    (0.0, core::f32::consts::FRAC_PI_2, 0.0997),
    (0.0, -core::f32::consts::FRAC_PI_2, 0.0996),
];

/// Body-frame standard parameters `[m, mx, my, mz, Ixx, Iyy, Izz, Ixy, Ixz, Iyz]` of
/// the golden arm, and friction `(fv, fc, fo, Ia)`.
const GOLDEN_LINKS: [([f32; 10], [f32; 4]); DYNAMICS_JOINTS] = [
    (
        [
            3.7, 0.0, -0.0948, 0.0071, 0.0110, 0.0089, 0.0106, 0.0001, 0.0, 0.0003,
        ],
        [3.0, 5.0, 0.2, 0.3],
    ),
    (
        [
            8.393, 1.7835, 0.0, 0.9514, 0.1380, 0.6553, 0.5251, 0.0, 0.2032, 0.0,
        ],
        [2.5, 4.0, -0.1, 0.3],
    ),
    (
        [
            2.33, 0.3495, 0.0, 0.0617, 0.0056, 0.0865, 0.0835, 0.0, 0.0097, 0.0,
        ],
        [1.8, 3.0, 0.05, 0.1],
    ),
    (
        [
            1.219, 0.0, -0.0022, 0.0199, 0.0026, 0.0024, 0.0017, 0.0, 0.0, 0.0001,
        ],
        [1.0, 2.0, 0.0, 0.05],
    ),
    (
        [
            1.219, 0.0, 0.0022, 0.0199, 0.0026, 0.0024, 0.0017, 0.0, 0.0, 0.0,
        ],
        [1.0, 2.0, 0.0, 0.05],
    ),
    (
        [
            0.1879, 0.0, 0.0, -0.0002, 0.0001, 0.0001, 0.0001, 0.0, 0.0, 0.0,
        ],
        [0.8, 1.5, 0.0, 0.02],
    ),
];

/// The fixed 6-DoF model of the `dynamics` suite (smoothed Coulomb, eps = 0.02 rad/s).
pub fn dynamics_model() -> RigidBodyModel<DYNAMICS_JOINTS> {
    let mut joints = [JointModel::ZERO; DYNAMICS_JOINTS];
    for (j, ((a, alpha, d), (inertial, fr))) in joints
        .iter_mut()
        .zip(GOLDEN_DH.iter().zip(GOLDEN_LINKS.iter()))
    {
        let (s, c) = math::sin_cos(*alpha);
        // Rx(alpha); translation a x + Rx(alpha) d z.
        j.origin_rotation = [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]];
        j.origin_translation_m = [*a, -s * d, c * d];
        j.inertial = *inertial;
        j.viscous_nm_s_rad = fr[0];
        j.coulomb_nm = fr[1];
        j.offset_nm = fr[2];
        j.rotor_inertia_kg_m2 = fr[3];
        // The extended friction basis, so the suite covers its terms too.
        j.stribeck_nm = [0.3 * fr[1], -0.1 * fr[1], 0.05 * fr[0]];
        j.quadratic_nm_s2_rad2 = 0.2 * fr[0];
    }
    RigidBodyModel {
        joints,
        gravity_m_s2: [0.0, 0.0, -9.81],
        coulomb_inv_eps_s_rad: 50.0,
    }
}

/// The `case`-th golden state `(q [rad], qd [rad/s], qdd [rad/s^2])`: q in [-pi, pi),
/// qd in [-3, 3), qdd in [-10, 10); case 0 is the rest state at q = 0.
pub fn dynamics_state(
    case: usize,
) -> (
    [f32; DYNAMICS_JOINTS],
    [f32; DYNAMICS_JOINTS],
    [f32; DYNAMICS_JOINTS],
) {
    let mut q = [0.0f32; DYNAMICS_JOINTS];
    let mut qd = [0.0f32; DYNAMICS_JOINTS];
    let mut qdd = [0.0f32; DYNAMICS_JOINTS];
    if case == 0 {
        return (q, qd, qdd);
    }
    for k in 0..DYNAMICS_JOINTS {
        let seed = 0x0D1A_0000u32 ^ ((case * DYNAMICS_JOINTS + k) as u32).wrapping_mul(3);
        q[k] = core::f32::consts::PI * (2.0 * unit(hash(seed)) - 1.0);
        qd[k] = 3.0 * (2.0 * unit(hash(seed + 1)) - 1.0);
        qdd[k] = 10.0 * (2.0 * unit(hash(seed + 2)) - 1.0);
    }
    (q, qd, qdd)
}

/// Joint torques [N*m] of the golden model in the `case`-th state.
pub fn dynamics_output(
    model: &RigidBodyModel<DYNAMICS_JOINTS>,
    case: usize,
) -> [f32; DYNAMICS_JOINTS] {
    let (q, qd, qdd) = dynamics_state(case);
    model.torques(&q, &qd, &qdd)
}

/// Cases of the `features` suite.
pub const FEATURE_CASES: usize = 500;

/// Values per case of the `features` suite: the friction features, the linear
/// correction, the presliding states after a walk of angles, and the friction
/// adaptation's last correction and levels after a walk of ticks.
pub const FEATURE_VALUES: usize = features::FRICTION_FEATURES
    + 1
    + features::PRESLIDING_ELEMENTS
    + 1
    + adaptation::ADAPTED_LEVELS;

/// Ticks of the friction adaptation's walk in each `features` case.
pub const ADAPTATION_TICKS: u32 = 64;

/// The `features` suite's case: `drive_inputs` of q in [-2π, 2π), qd in [-2, 2) rad/s
/// (every fourth case inside the rest band), qdd in [-10, 10), model torque in
/// [-100, 100) N*m, rest direction -1, 0 or +1, presliding states in [-1, 1), measured
/// residual in [-20, 20) N*m; the
/// friction features, then the linear correction with fixed coefficients, then the
/// presliding states after eight steps of up to +-20 mrad from q; then the friction
/// adaptation (time constant 20-120 ms at 1 kHz, +-5 N*m) after [`ADAPTATION_TICKS`]
/// ticks of velocities in the case's band, predictions in [-50, 50) N*m and measured
/// torques up to 10 N*m off them (every seventh one NaN): its last correction, then its
/// levels.
pub fn feature_output(case: usize) -> [f32; FEATURE_VALUES] {
    let seed = 0x0FEA_0000u32 ^ (case as u32).wrapping_mul(5);
    let r = |k: u32| 2.0 * unit(hash(seed + k)) - 1.0;
    let band = if case.is_multiple_of(4) {
        features::REST_BAND_RAD_S
    } else {
        2.0
    };
    let x = features::drive_inputs(
        2.0 * core::f32::consts::TAU * r(0),
        band * r(1),
        10.0 * r(2),
        100.0 * r(3),
        (
            (case % 3) as f32 - 1.0,
            core::array::from_fn(|k| r(4 + k as u32)),
        ),
        20.0 * r(9),
    );
    let coefficients: [f32; features::FRICTION_FEATURES] =
        core::array::from_fn(|k| 0.5 * r(40 + k as u32));
    let f = features::friction_features(&x);
    let mut out = [0.0; FEATURE_VALUES];
    out[..features::FRICTION_FEATURES].copy_from_slice(&f);
    out[features::FRICTION_FEATURES] = features::linear_correction_nm(
        &coefficients,
        &firmware::envelope::JointEnvelope::UNBOUNDED,
        &x,
    );
    let mut presliding = features::Presliding::new();
    let mut q = 2.0 * core::f32::consts::TAU * r(0);
    let mut state = presliding.update(q);
    for k in 0..8 {
        q += 0.02 * r(60 + k);
        state = presliding.update(q);
    }
    let p = features::FRICTION_FEATURES + 1;
    out[p..p + features::PRESLIDING_ELEMENTS].copy_from_slice(&state);
    let config = adaptation::AdaptationConfig {
        time_constant_s: 0.07 + 0.05 * r(70),
        max_correction_nm: 5.0,
    };
    let mut a = adaptation::FrictionAdaptation::new(config, 1000.0);
    let mut rest = features::RestDirection::new();
    let (mut correction, mut measured) = (0.0, f32::NAN);
    for k in 0..ADAPTATION_TICKS {
        let qd = band * r(100 + 3 * k);
        let base = 50.0 * r(101 + 3 * k);
        correction = a.step(adaptation::regressors(qd, rest.update(qd)), base, measured);
        measured = if k % 7 == 6 {
            f32::NAN
        } else {
            base + 10.0 * r(102 + 3 * k)
        };
    }
    let p = p + features::PRESLIDING_ELEMENTS;
    out[p] = correction;
    out[p + 1..].copy_from_slice(&a.levels_nm());
    out
}

/// Cases of the `monitor` suite.
pub const MONITOR_CASES: usize = 200;

/// Ticks of the do-no-harm monitor's walk in each `monitor` case.
pub const MONITOR_TICKS: u32 = 256;

/// Values per case of the `monitor` suite: the monitor's output torque and gain after
/// every 32nd tick of the walk, then its two windowed scores at the end.
pub const MONITOR_VALUES: usize = 2 * (MONITOR_TICKS as usize / 32) + 2;

/// The `monitor` suite's case: the do-no-harm monitor (`firmware::monitor`; window
/// 10-60 ms, fade 5-25 ms, hysteresis 0-0.2 at 1 kHz) over [`MONITOR_TICKS`] ticks of
/// model torques in [-50, 50) N*m, compensations in [-5, 5) N*m and measured torques
/// near the model, the full compensation or neither (the case picks which, so that the
/// gain fades, returns and holds), every eleventh one NaN and every 97th candidate
/// infinite: the output torque and gain at every 32nd tick, then the scores.
pub fn monitor_output(case: usize) -> [f32; MONITOR_VALUES] {
    let seed = 0x0D0E_0000u32 ^ (case as u32).wrapping_mul(7);
    let r = |k: u32| 2.0 * unit(hash(seed + k)) - 1.0;
    let config = monitor::MonitorConfig {
        window_s: 0.035 + 0.025 * r(0),
        fade_s: 0.015 + 0.01 * r(1),
        hysteresis: 0.1 + 0.1 * r(2),
    };
    let mut m = monitor::DoNoHarmMonitor::new(config, 1000.0);
    let mut out = [0.0; MONITOR_VALUES];
    let mut measured = f32::NAN;
    for k in 0..MONITOR_TICKS {
        let base = 50.0 * r(10 + 3 * k);
        let comp = 5.0 * r(11 + 3 * k);
        let full = if k % 97 == 96 {
            f32::INFINITY
        } else {
            base + comp
        };
        let y = m.step(base, full, measured);
        // Which candidate the joint follows changes every 64 ticks, per case.
        let truth = match (case as u32 + k / 64) % 3 {
            0 => base,
            1 => base + comp,
            _ => base - comp,
        };
        measured = if k % 11 == 10 {
            f32::NAN
        } else {
            truth + 0.5 * r(12 + 3 * k)
        };
        if k % 32 == 31 {
            let i = 2 * (k as usize / 32);
            out[i] = y;
            out[i + 1] = m.gain();
        }
    }
    let (a, b) = m.scores_nm2();
    out[MONITOR_VALUES - 2] = a;
    out[MONITOR_VALUES - 1] = b;
    out
}

/// Golden LSTM: number of inputs.
pub const LSTM_I: usize = 3;
/// Golden LSTM: input-layer width.
pub const LSTM_E: usize = 6;
/// Golden LSTM: number of cells.
pub const LSTM_H: usize = 8;
/// Golden LSTM: number of outputs.
pub const LSTM_O: usize = 2;
/// Golden LSTM: consecutive streaming steps compared.
pub const LSTM_STEPS: usize = 2_000;
/// The golden network type.
pub type GoldenLstm = Lstm<LSTM_I, LSTM_E, LSTM_H, LSTM_O>;

/// A value in [-scale, scale) from the hash of `seed`.
fn signed(seed: u32, scale: f32) -> f32 {
    scale * (2.0 * unit(hash(seed)) - 1.0)
}

/// The fixed small golden network: weights drawn from the hash with PyTorch's
/// U(±1/√H) scale (inflated so gates also saturate), non-trivial normalisation.
pub fn lstm_network() -> GoldenLstm {
    let mut n: u32 = 0x4c53_0000;
    let mut next = |scale: f32| {
        n += 1;
        signed(n, scale)
    };
    let k = 1.5;
    GoldenLstm {
        input_mean: core::array::from_fn(|_| next(2.0)),
        input_std: core::array::from_fn(|_| 0.5 + next(0.25)),
        w_in: core::array::from_fn(|_| core::array::from_fn(|_| next(k))),
        b_in: core::array::from_fn(|_| next(0.5)),
        input_activation: InputActivation::Tanh,
        w_ih: core::array::from_fn(|_| core::array::from_fn(|_| core::array::from_fn(|_| next(k)))),
        w_hh: core::array::from_fn(|_| core::array::from_fn(|_| core::array::from_fn(|_| next(k)))),
        b_gates: core::array::from_fn(|_| core::array::from_fn(|_| next(0.7))),
        w_out: core::array::from_fn(|_| core::array::from_fn(|_| next(k))),
        b_out: core::array::from_fn(|_| next(0.5)),
        output_mean: core::array::from_fn(|_| next(10.0)),
        output_std: core::array::from_fn(|_| 1.0 + next(0.5)),
    }
}

/// The golden input at step `t`: a slow sinusoid-like sweep plus hashed noise, so the
/// state sees both memory-worthy structure and saturation (inputs up to about ±6).
pub fn lstm_input(t: usize) -> [f32; LSTM_I] {
    core::array::from_fn(|k| {
        let phase = (t as f32) * (0.013 + 0.007 * k as f32);
        3.0 * math::sin(phase) + signed((t * LSTM_I + k) as u32 ^ 0x00ab_0000, 3.0)
    })
}

/// Streams the golden network from the zero state over `LSTM_STEPS` steps and calls
/// `emit(step, outputs)` after each; the state is reset at step `LSTM_STEPS / 2` so the
/// reset path is compared too.
pub fn lstm_stream(mut emit: impl FnMut(usize, &[f32; LSTM_O])) {
    let net = lstm_network();
    let mut state = LstmState::new();
    for t in 0..LSTM_STEPS {
        if t == LSTM_STEPS / 2 {
            state.reset();
        }
        let y = net.step(&mut state, &lstm_input(t));
        emit(t, &y);
    }
}

/// Cases of the `envelope` suite.
pub const ENVELOPE_CASES: usize = 500;

/// Values per case of the `envelope` suite: the weight, the faded prediction, the
/// clamped linear correction and whether the state is in a covered cell (0 or 1).
pub const ENVELOPE_VALUES: usize = 4;

/// Steps of the `envelope` suite's predictor stream.
pub const ENVELOPE_STEPS: usize = 2_000;

/// A training envelope from `seed`: each range between two values of `[-s, s)` (s = 3
/// for the angle and the drive inputs, 2 for the friction features), 64 hashed coverage
/// bits.
pub fn envelope_case(seed: u32) -> JointEnvelope {
    let r = |k: u32| 2.0 * unit(hash(seed.wrapping_add(k))) - 1.0;
    let range = |k: u32, s: f32| {
        let (a, b) = (s * r(k), s * r(k + 1));
        Range::new(a.min(b), a.max(b))
    };
    JointEnvelope {
        q_rad: range(0, 3.0),
        drive: core::array::from_fn(|i| range(2 + 2 * i as u32, 3.0)),
        friction: core::array::from_fn(|i| range(40 + 2 * i as u32, 2.0)),
        coverage: u64::from(hash(seed ^ 0xC0)) | (u64::from(hash(seed ^ 0xC1)) << 32),
    }
}

/// The `envelope` suite's case (`firmware::envelope`): an envelope from
/// [`envelope_case`] and a state with q, qd, qdd, model torque and measured residual in
/// [-4, 4) (every fourth case inside the envelope's ranges; every sixteenth case one of
/// them NaN, every sixteenth another infinite): the
/// weight, the faded prediction of a full prediction up to 5 N*m off the model, the linear
/// correction with the features clamped to the envelope (of the state with its
/// non-finite values replaced by 0), and the coverage check.
pub fn envelope_output(case: usize) -> [f32; ENVELOPE_VALUES] {
    let seed = 0x0E57_0000u32 ^ (case as u32).wrapping_mul(7);
    let r = |k: u32| 2.0 * unit(hash(seed.wrapping_add(0x100 + k))) - 1.0;
    let e = envelope_case(seed);
    let ranges = e.faded_ranges();
    let mut s: [f32; 5] = core::array::from_fn(|k| {
        if case.is_multiple_of(4) {
            // Inside: a point of the range.
            let t = 0.5 + 0.5 * r(k as u32);
            ranges[k].lo + t * (ranges[k].hi - ranges[k].lo)
        } else {
            4.0 * r(k as u32)
        }
    });
    if case % 16 == 3 {
        s[case % 5] = f32::NAN;
    } else if case % 16 == 11 {
        s[case % 5] = f32::INFINITY;
    }
    let [q, qd, qdd, model, residual] = s;
    let w = e.weight(q, qd, qdd, model, residual);
    let faded = envelope::fade_nm(w, model, model + 5.0 * r(5));
    // The linear stage on the finite state only (an infinite input makes NaNs whose sign
    // bit differs between targets; the compensator rejects any NaN).
    let [q, qd, qdd, model, residual] = s.map(|v| if v.is_finite() { v } else { 0.0 });
    let x = features::drive_inputs(
        q,
        qd,
        qdd,
        model,
        (
            (case % 3) as f32 - 1.0,
            core::array::from_fn(|k| r(6 + k as u32)),
        ),
        residual,
    );
    let coefficients: [f32; features::FRICTION_FEATURES] =
        core::array::from_fn(|k| 0.5 * r(20 + k as u32));
    let linear = features::linear_correction_nm(&coefficients, &e, &x);
    let covered = if e.covered(q, qd) { 1.0 } else { 0.0 };
    [w, faded, linear, covered]
}

/// The `envelope` suite's stream: the `drive` preset's predictor
/// (`firmware::control::LstmPredictor`) on the int16 drive fixture network with a linear
/// stage and an envelope whose faded inputs span [-2.5, 2.5] (the golden inputs reach
/// about 4, so the stream goes in and out of it), over [`ENVELOPE_STEPS`] steps of the
/// golden network inputs; emits per step the faded prediction and the weight. Then the
/// same predictor behind a whole `Compensator` (a decoupled joint model as its model
/// stage, the board's profile at 100 Hz) over the same steps: emits (from step
/// `ENVELOPE_STEPS`) its limited torque and its flags' bits as f32 bits.
pub fn envelope_stream(mut emit: impl FnMut(usize, f32, f32)) {
    use crate::fixtures::bench_drive_int16 as m;
    use firmware::control::{
        Compensator, DecoupledJointModel, JointProfile, JointState, LstmPredictor, PredictorInput,
        TorquePredictor,
    };
    let mut e = envelope_case(0x0E57_F00D);
    let wide = Range::new(-2.5, 2.5);
    e.q_rad = wide;
    for k in envelope::FADED_DRIVE_COLUMNS {
        e.drive[k] = wide;
    }
    let coefficients: [f32; features::FRICTION_FEATURES] =
        core::array::from_fn(|k| 0.5 * (2.0 * unit(hash(0x0E57_0A00 + k as u32)) - 1.0));
    let Some(p) = LstmPredictor::<_, 1, { features::DRIVE_INPUTS_PER_JOINT }>::new(
        &m::NETWORK,
        m::FEATURE_PRESET,
    ) else {
        return;
    };
    let mut p = p.with_linear_stage([coefficients]).with_envelope([e]);
    let state = |t: usize| {
        let [q, qd, qdd, tau, model] = network::inputs::<5>(t);
        (
            JointState {
                q_ref_rad: q,
                qd_ref_rad_s: qd,
                qdd_ref_rad_s2: qdd,
                tau_meas_nm: tau,
                ..Default::default()
            },
            model,
        )
    };
    for t in 0..ENVELOPE_STEPS {
        let (s, model) = state(t);
        let input = PredictorInput {
            joints: [s],
            own_joint: 0,
            model_nm: [model],
        };
        let y = p.predict_nm(&input)[0];
        emit(t, y, p.envelope_weights()[0]);
    }
    p.reset();
    let model = DecoupledJointModel::<1> {
        inertia_kg_m2: [0.5],
        viscous_nm_s_rad: [1.5],
        coulomb_nm: [2.0],
        coulomb_smoothing_rad_s: [0.02],
        gravity_nm: [3.0],
        gravity_phase_rad: [0.25],
    };
    let Ok(mut c) = Compensator::new(JointProfile::BOARD.compensator_config(100, 0), model, p)
    else {
        return;
    };
    for t in 0..ENVELOPE_STEPS {
        let o = c.tick(&state(t).0, t as u32 * 10_000);
        emit(
            ENVELOPE_STEPS + t,
            o.torque_nm,
            f32::from_bits(o.faults.bits()),
        );
    }
}

pub use firmware::model::self_check::{hash, unit};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_envelope_suite_goes_in_and_out_of_the_envelope() {
        let (mut inside, mut faded, mut zero, mut outside_flags) = (0, 0, 0, 0);
        envelope_stream(|t, y, w| {
            assert!(y.is_finite());
            if t >= ENVELOPE_STEPS {
                let flags = firmware::control::FaultFlags::from_bits(w.to_bits());
                if flags.contains(firmware::control::FaultFlags::ENVELOPE_OUTSIDE) {
                    outside_flags += 1;
                }
                return;
            }
            assert!((0.0..=1.0).contains(&w));
            match w {
                1.0 => inside += 1,
                0.0 => zero += 1,
                _ => faded += 1,
            }
        });
        assert!(
            inside > 0 && faded > 0 && zero > 0,
            "{inside} {faded} {zero}"
        );
        // The compensator flags the ticks outside, not all of them.
        assert!(
            outside_flags > 0 && outside_flags < ENVELOPE_STEPS,
            "{outside_flags}"
        );
        let cases: std::vec::Vec<_> = (0..ENVELOPE_CASES).map(envelope_output).collect();
        assert!(cases.iter().any(|c| c[0] == 1.0) && cases.iter().any(|c| c[0] == 0.0));
        assert!(cases.iter().any(|c| c[0] > 0.0 && c[0] < 1.0));
        assert!(cases.iter().any(|c| c[3] == 1.0) && cases.iter().any(|c| c[3] == 0.0));
    }

    #[test]
    fn dynamics_cases_are_finite_and_distinct() {
        let model = dynamics_model();
        let mut previous = [0.0f32; DYNAMICS_JOINTS];
        for case in 0..DYNAMICS_CASES {
            let tau = dynamics_output(&model, case);
            assert!(
                tau.iter().all(|t| t.is_finite() && t.abs() < 1.0e3),
                "{case}: {tau:?}"
            );
            assert_ne!(tau, previous);
            previous = tau;
        }
    }

    #[test]
    fn inputs_cover_the_range() {
        for f in MathFn::ALL {
            let (lo, hi) = f.range();
            assert_eq!(f.input(0), lo);
            assert_eq!(
                f.input(MATH_POINTS - 1 - (MATH_POINTS - 1) % 2),
                f.input(9998)
            );
            for i in 0..MATH_POINTS {
                let x = f.input(i);
                assert!(x >= lo && x <= hi, "{} {i} {x}", f.name());
            }
            assert_eq!(MathFn::from_name(f.name()), Some(f));
        }
    }
}
