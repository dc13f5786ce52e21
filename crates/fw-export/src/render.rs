//! The generated Rust source file: literals, the network in its format, the
//! dynamics, the joint profiles, the self-check and the header ([`render`]).
use super::*;

pub(crate) fn f32_lit(x: f32) -> String {
    let s = format!("{x:?}");
    if s.contains('.') || s.contains('e') || s.contains("inf") || s.contains("NaN") {
        s
    } else {
        format!("{s}.0")
    }
}

pub(crate) fn list<T>(v: &[T], f: impl Fn(&T) -> String) -> String {
    let items: Vec<String> = v.iter().map(f).collect();
    format!("[{}]", items.join(", "))
}

pub(crate) fn quads_i16(q: &[[u32; 4]; 2]) -> String {
    format!(
        "[{}, {}]",
        list(&q[0], |w| format!("{w:#010x}")),
        list(&q[1], |w| format!("{w:#010x}"))
    )
}

pub(crate) fn quads_i8(q: &[u32; 4]) -> String {
    list(q, |w| format!("{w:#010x}"))
}

pub(crate) fn nested<T: Copy>(flat: &[T], per: usize, f: impl Fn(&T) -> String) -> String {
    if flat.is_empty() {
        return "[]".into();
    }
    let chunks: Vec<String> = flat.chunks(per.max(1)).map(|c| list(c, &f)).collect();
    format!("[\n    {}\n]", chunks.join(",\n    "))
}

pub(crate) fn write_quant<F: WeightFormat>(
    s: &mut String,
    section: &str,
    tables: Placement,
    n: &QuantNet<F>,
    fmt: &str,
    quad: impl Fn(&F::Quad) -> String,
) {
    let d = n.dims;
    let (i, iq, eb, h, hq, zq, o, ob) = (
        d.input,
        d.input_quads,
        d.embed_blocks,
        d.hidden,
        d.hidden / 4,
        d.z_quads(),
        d.output,
        d.output_blocks,
    );
    let _ = writeln!(
        s,
        "/// The network's integer format: `{}` weights, the input activation, the \
         activation-index shifts of its power-of-two scales and the activation tables' \
         placement.",
        F::NAME
    );
    let _ = writeln!(s, "pub struct Format;");
    let _ = writeln!(s, "impl QuantFormat for Format {{");
    let _ = writeln!(s, "    type Weights = {fmt};");
    let _ = writeln!(
        s,
        "    const INPUT_ACTIVATION: InputActivation = InputActivation::{};",
        activation_variant(n.in_activation)
    );
    let _ = writeln!(s, "    const INPUT_SHIFT: u32 = {};", n.in_shift);
    let _ = writeln!(
        s,
        "    const GATE_SHIFTS: [u32; 4] = {};",
        list(&n.gate_shift, |x| x.to_string())
    );
    // A closed set of paths (never input text).
    let tables = match tables {
        Placement::Sram => "ACT_TABLES_SRAM",
        Placement::Flash => "ACT_TABLES_FLASH",
    };
    let _ = writeln!(
        s,
        "    const ACT_TABLES: &'static firmware::nn::act::ActTables = &firmware::nn::act::{tables};"
    );
    let _ = writeln!(s, "}}");
    let _ = writeln!(s, "/// The network's type: sizes from the exporter.");
    let _ = writeln!(
        s,
        "pub type Network = QuantLstm<Format, {i}, {iq}, {eb}, {h}, {hq}, {zq}, {o}, {ob}>;"
    );
    let _ = writeln!(s, "/// The network's recurrent state.");
    let _ = writeln!(s, "pub type State = QuantState<{zq}, {h}>;");
    let _ = writeln!(s, "/// The network.");
    let _ = write!(s, "{section}");
    let _ = writeln!(s, "pub static NETWORK: Network = QuantLstm {{");
    let _ = writeln!(
        s,
        "    input_mean: {},",
        list(&n.input_mean, |x| f32_lit(*x))
    );
    let _ = writeln!(
        s,
        "    input_scale: {},",
        list(&n.input_scale, |x| f32_lit(*x))
    );
    let _ = writeln!(s, "    in_w: {},", nested(&n.in_w, iq, &quad));
    let _ = writeln!(
        s,
        "    in_bias: {},",
        list(&n.in_bias, |b| list(b, |x| x.to_string()))
    );
    let _ = writeln!(s, "    gate_w: {},", nested(&n.gate_w, zq, &quad));
    let _ = writeln!(
        s,
        "    gate_bias: {},",
        list(&n.gate_bias, |b| list(b, |x| x.to_string()))
    );
    let _ = writeln!(s, "    out_w: {},", nested(&n.out_w, hq, &quad));
    let _ = writeln!(
        s,
        "    out_scale: {},",
        list(&n.out_scale, |b| list(b, |x| f32_lit(*x)))
    );
    let _ = writeln!(
        s,
        "    out_offset: {},",
        list(&n.out_offset, |b| list(b, |x| f32_lit(*x)))
    );
    let _ = writeln!(s, "}};");
}

/// The `InputActivation` variant's name in a generated file (a closed set, never text
/// from the input).
pub(crate) fn activation_variant(a: InputActivation) -> &'static str {
    match a {
        InputActivation::Tanh => "Tanh",
        InputActivation::Linear => "Linear",
    }
}

/// The `firmware::nn::kernels::InputLayer` type of an activation.
pub(crate) fn input_layer_type(a: InputActivation) -> &'static str {
    match a {
        InputActivation::Tanh => "TanhInput",
        InputActivation::Linear => "LinearInput",
    }
}

/// `head_blocks`: how many blocks of the gate matrix go to `GATES_HEAD` (placed by
/// `head_section`); the rest go to `GATES_TAIL`, placed with the network (`section`).
pub(crate) fn write_f32(
    s: &mut String,
    section: &str,
    head_section: &str,
    split: [usize; 2],
    n: &F32Net,
) {
    let d = n.dims;
    let (i, eb, h, o, ob) = (d.input, d.embed_blocks, d.hidden, d.output, d.output_blocks);
    let e = 4 * eb;
    let z = e + h;
    let v4 = |b: &[f32; 4]| list(b, |x| f32_lit(*x));
    let layer = input_layer_type(n.input_activation);
    let _ = writeln!(
        s,
        "/// The network's type: f32, sizes and input activation from the exporter."
    );
    let _ = writeln!(
        s,
        "pub type Network = F32Lstm<{i}, {e}, {eb}, {h}, {z}, {o}, {ob}, {layer}>;"
    );
    let _ = writeln!(s, "/// The network's recurrent state.");
    let _ = writeln!(s, "pub type State = F32State<{z}, {h}>;");
    let head_blocks = split[0].min(h);
    let middle_blocks = split[1].min(h - head_blocks);
    let (head, rest) = n.w_gates.split_at((head_blocks * z).min(n.w_gates.len()));
    let (middle, tail) = rest.split_at((middle_blocks * z).min(rest.len()));
    let _ = writeln!(
        s,
        "/// The gate matrix's first {head_blocks} blocks ({} bytes; `F32GateRows`).",
        head.len() * 16
    );
    let head_section = if head.is_empty() { "" } else { head_section };
    let _ = write!(s, "{head_section}");
    let _ = writeln!(
        s,
        "pub static GATES_HEAD: [[[f32; 4]; {z}]; {head_blocks}] = {};",
        nested(head, z, v4)
    );
    let _ = writeln!(
        s,
        "/// The gate matrix's next {middle_blocks} blocks ({} bytes).",
        middle.len() * 16
    );
    // An empty part needs no placement.
    if !middle.is_empty() {
        let _ = writeln!(s, "{CCM_SECTION_ATTRIBUTE}");
    }
    let _ = writeln!(
        s,
        "pub static GATES_MIDDLE: [[[f32; 4]; {z}]; {middle_blocks}] = {};",
        nested(middle, z, v4)
    );
    let tail_blocks = h - head_blocks - middle_blocks;
    let _ = writeln!(
        s,
        "/// The gate matrix's other {tail_blocks} blocks ({} bytes).",
        tail.len() * 16
    );
    let tail_section = if tail.is_empty() { "" } else { section };
    let _ = write!(s, "{tail_section}");
    let _ = writeln!(
        s,
        "pub static GATES_TAIL: [[[f32; 4]; {z}]; {tail_blocks}] = {};",
        nested(tail, z, v4)
    );
    let _ = writeln!(
        s,
        "const _: () = assert!(GATES_HEAD.len() + GATES_MIDDLE.len() + GATES_TAIL.len() == {h}, \"the gate matrix has H blocks\");"
    );
    let _ = writeln!(s, "/// The network.");
    let _ = write!(s, "{section}");
    let _ = writeln!(s, "pub static NETWORK: Network = F32Lstm {{");
    let _ = writeln!(
        s,
        "    input_mean: {},",
        list(&n.input_mean, |x| f32_lit(*x))
    );
    let _ = writeln!(
        s,
        "    input_inv_std: {},",
        list(&n.input_inv_std, |x| f32_lit(*x))
    );
    let _ = writeln!(s, "    w_in: {},", nested(&n.w_in, i, v4));
    let _ = writeln!(s, "    b_in: {},", list(&n.b_in, v4));
    let _ = writeln!(s, "    input_layer: {layer},");
    let _ = writeln!(
        s,
        "    w_gates: F32GateRows {{ head: &GATES_HEAD, middle: &GATES_MIDDLE, tail: &GATES_TAIL }},"
    );
    let _ = writeln!(s, "    b_gates: {},", list(&n.b_gates, v4));
    let _ = writeln!(s, "    w_out: {},", nested(&n.w_out, h, v4));
    let _ = writeln!(s, "    b_out: {},", list(&n.b_out, v4));
    let _ = writeln!(s, "    output_std: {},", list(&n.output_std, v4));
    let _ = writeln!(s, "    output_mean: {},", list(&n.output_mean, v4));
    let _ = writeln!(s, "}};");
}

pub(crate) fn write_dynamics<const N: usize>(s: &mut String, section: &str, m: &RigidBodyModel<N>) {
    let v3 = |v: &[f32; 3]| list(v, |x| f32_lit(*x));
    let _ = writeln!(s, "/// Number of joints of the rigid-body model.");
    let _ = writeln!(s, "pub const DYNAMICS_JOINTS: usize = {N};");
    let _ = writeln!(s, "/// The identified (or nominal) rigid-body model, f32.");
    let _ = write!(s, "{section}");
    let _ = writeln!(
        s,
        "pub static DYNAMICS: RigidBodyModel<{N}> = RigidBodyModel {{"
    );
    let _ = writeln!(s, "    joints: [");
    for j in &m.joints {
        let _ = writeln!(s, "        JointModel {{");
        let _ = writeln!(
            s,
            "            origin_rotation: {},",
            list(&j.origin_rotation, v3)
        );
        let _ = writeln!(
            s,
            "            origin_translation_m: {},",
            v3(&j.origin_translation_m)
        );
        let _ = writeln!(s, "            axis: {},", v3(&j.axis));
        let _ = writeln!(
            s,
            "            inertial: {},",
            list(&j.inertial, |x| f32_lit(*x))
        );
        let _ = writeln!(
            s,
            "            viscous_nm_s_rad: {},",
            f32_lit(j.viscous_nm_s_rad)
        );
        let _ = writeln!(s, "            coulomb_nm: {},", f32_lit(j.coulomb_nm));
        let _ = writeln!(s, "            offset_nm: {},", f32_lit(j.offset_nm));
        let _ = writeln!(
            s,
            "            rotor_inertia_kg_m2: {},",
            f32_lit(j.rotor_inertia_kg_m2)
        );
        let f = |x: &f32| f32_lit(*x);
        let _ = writeln!(s, "            stribeck_nm: {},", list(&j.stribeck_nm, f));
        let _ = writeln!(
            s,
            "            quadratic_nm_s2_rad2: {},",
            f32_lit(j.quadratic_nm_s2_rad2)
        );
        let _ = writeln!(s, "            q_range_rad: {},", list(&j.q_range_rad, f));
        let _ = writeln!(
            s,
            "            qd_range_rad_s: {},",
            list(&j.qd_range_rad_s, f)
        );
        let _ = writeln!(
            s,
            "            qdd_range_rad_s2: {},",
            list(&j.qdd_range_rad_s2, f)
        );
        let _ = writeln!(s, "        }},");
    }
    let _ = writeln!(s, "    ],");
    let _ = writeln!(s, "    gravity_m_s2: {},", v3(&m.gravity_m_s2));
    let _ = writeln!(
        s,
        "    coulomb_inv_eps_s_rad: {},",
        f32_lit(m.coulomb_inv_eps_s_rad)
    );
    let _ = writeln!(s, "}};");
}

/// Bytes of the `DYNAMICS` static of a model of any joint count.
pub fn dynamics_bytes(d: &FirmwareModel) -> usize {
    match d {
        FirmwareModel::J1(m) => std::mem::size_of_val(m),
        FirmwareModel::J2(m) => std::mem::size_of_val(m),
        FirmwareModel::J3(m) => std::mem::size_of_val(m),
        FirmwareModel::J4(m) => std::mem::size_of_val(m),
        FirmwareModel::J5(m) => std::mem::size_of_val(m),
        FirmwareModel::J6(m) => std::mem::size_of_val(m),
        FirmwareModel::J7(m) => std::mem::size_of_val(m),
    }
}

/// Writes the `DYNAMICS` items of the generated file for a model of any joint count.
pub(crate) fn write_any_dynamics(s: &mut String, section: &str, d: &FirmwareModel) {
    match d {
        FirmwareModel::J1(m) => write_dynamics(s, section, m),
        FirmwareModel::J2(m) => write_dynamics(s, section, m),
        FirmwareModel::J3(m) => write_dynamics(s, section, m),
        FirmwareModel::J4(m) => write_dynamics(s, section, m),
        FirmwareModel::J5(m) => write_dynamics(s, section, m),
        FirmwareModel::J6(m) => write_dynamics(s, section, m),
        FirmwareModel::J7(m) => write_dynamics(s, section, m),
    }
}

/// The golden inputs of the self-check: `firmware::model::self_check::input`.
pub fn golden_inputs(n_inputs: usize, steps: usize) -> Vec<Vec<f32>> {
    (0..steps)
        .map(|t| (0..n_inputs).map(|k| self_check::input(t, k)).collect())
        .collect()
}

/// Writes `JOINT_PROFILES`: one `JointProfile` literal per compensated joint (numbers
/// only, each f32 written so that it reads back to the same bits).
pub(crate) fn write_profiles(s: &mut String, profiles: &[firmware::control::JointProfile]) {
    use firmware::control::BusClock;
    let _ = writeln!(
        s,
        "/// Drive profile of each compensated joint, in `JOINT_INDICES` order: motor, gear,\n\
         /// limits, gains and bus settings (`control::JointProfile`)."
    );
    let _ = writeln!(
        s,
        "pub const JOINT_PROFILES: [firmware::control::JointProfile; {}] = [",
        profiles.len()
    );
    for p in profiles {
        let m = &p.motor;
        let c = &p.cascade;
        let l = &p.state_limits;
        let bus_clock = match p.bus_clock {
            BusClock::Synchronised => "firmware::control::BusClock::Synchronised".to_string(),
            BusClock::FreeRunning { max_rate_error_ppm } => format!(
                "firmware::control::BusClock::FreeRunning {{ max_rate_error_ppm: {max_rate_error_ppm} }}"
            ),
        };
        let _ = writeln!(s, "    firmware::control::JointProfile {{");
        let _ = writeln!(
            s,
            "        motor: firmware::control::MotorParameters {{ pole_pairs: {}, phase_resistance_ohm: {}, phase_inductance_h: {}, flux_linkage_wb: {} }},",
            m.pole_pairs,
            f32_lit(m.phase_resistance_ohm),
            f32_lit(m.phase_inductance_h),
            f32_lit(m.flux_linkage_wb)
        );
        let _ = writeln!(
            s,
            "        gear_ratio: {}, gear_efficiency: {}, encoder_offset_rad: {},",
            f32_lit(p.gear_ratio),
            f32_lit(p.gear_efficiency),
            f32_lit(p.encoder_offset_rad)
        );
        let _ = writeln!(
            s,
            "        cascade: firmware::control::CascadeConfig {{ rate_hz: {}, position_kp: {}, position_ki: {}, position_kd: {}, max_velocity_rad_s: {}, velocity_kp: {}, velocity_ki: {}, velocity_kd: {}, max_current_a: {}, velocity_filter_alpha: {} }},",
            f32_lit(c.rate_hz),
            f32_lit(c.position_kp),
            f32_lit(c.position_ki),
            f32_lit(c.position_kd),
            f32_lit(c.max_velocity_rad_s),
            f32_lit(c.velocity_kp),
            f32_lit(c.velocity_ki),
            f32_lit(c.velocity_kd),
            f32_lit(c.max_current_a),
            f32_lit(c.velocity_filter_alpha)
        );
        let _ = writeln!(
            s,
            "        max_current_a: {}, overcurrent_trip_a: {}, bus_min_v: {}, bus_max_v: {}, max_abs_q_ref_rad: {},",
            f32_lit(p.max_current_a),
            f32_lit(p.overcurrent_trip_a),
            f32_lit(p.bus_min_v),
            f32_lit(p.bus_max_v),
            f32_lit(p.max_abs_q_ref_rad)
        );
        let _ = writeln!(
            s,
            "        state_limits: firmware::control::StateLimits {{ max_abs_q_rad: {}, max_abs_qd_rad_s: {}, max_abs_qdd_rad_s2: {}, max_abs_tau_nm: {} }},",
            f32_lit(l.max_abs_q_rad),
            f32_lit(l.max_abs_qd_rad_s),
            f32_lit(l.max_abs_qdd_rad_s2),
            f32_lit(l.max_abs_tau_nm)
        );
        let _ = writeln!(
            s,
            "        watchdog_ticks: {}, max_message_age_ticks: {}, bus_clock: {bus_clock},",
            p.watchdog_ticks, p.max_message_age_ticks
        );
        let _ = writeln!(
            s,
            "        max_torque_nm: {}, max_torque_rate_nm_s: {}, max_lstm_correction_nm: {}, warmup_ticks: {}, lstm_retry_ticks: {},",
            f32_lit(p.max_torque_nm),
            f32_lit(p.max_torque_rate_nm_s),
            f32_lit(p.max_lstm_correction_nm),
            p.warmup_ticks,
            p.lstm_retry_ticks
        );
        let _ = writeln!(
            s,
            "        feedforward_max_current_a: {}, bus_baud: {},",
            f32_lit(p.feedforward_max_current_a),
            p.bus_baud
        );
        let _ = writeln!(
            s,
            "        adaptation: firmware::adaptation::AdaptationConfig {{ time_constant_s: {}, max_correction_nm: {} }},",
            f32_lit(p.adaptation.time_constant_s),
            f32_lit(p.adaptation.max_correction_nm)
        );
        let _ = writeln!(
            s,
            "        monitor: firmware::monitor::MonitorConfig {{ window_s: {}, fade_s: {}, hysteresis: {} }},",
            f32_lit(p.monitor.window_s),
            f32_lit(p.monitor.fade_s),
            f32_lit(p.monitor.hysteresis)
        );
        let _ = writeln!(s, "    }},");
    }
    let _ = writeln!(s, "];");
}

/// Renders the whole generated file.
pub fn render(
    m: &LstmModel,
    net: &Exported,
    meta: &ExportMeta,
    dynamics: Option<&FirmwareModel>,
) -> String {
    let mut body = String::new();
    // The attribute line placing a static in SRAM (a closed set, never input text).
    let attribute = |p: Placement| match p {
        Placement::Sram => format!("{SRAM_SECTION_ATTRIBUTE}\n"),
        Placement::Flash => String::new(),
    };
    let (network_section, dynamics_section, section) = (
        attribute(meta.placement.network),
        attribute(meta.placement.dynamics),
        attribute(meta.placement.linear_stage),
    );
    let section = section.as_str();
    let tables = meta.placement.act_tables.unwrap_or(Placement::Flash);
    // The variant of a known preset name; anything else is `Custom` (never input text).
    let preset = format!(
        "{:?}",
        FeaturePreset::from_name(&meta.preset).unwrap_or(FeaturePreset::Custom)
    );
    let s = &mut body;
    let _ = writeln!(
        s,
        "/// Layout version of this file (`fw_export::SCHEMA_VERSION`)."
    );
    let _ = writeln!(s, "pub const SCHEMA_VERSION: u32 = {SCHEMA_VERSION};");
    let prec = match net {
        Exported::F32(_) => "F32",
        Exported::Int16(_) => "Int16",
        Exported::Int8(_) => "Int8",
    };
    let _ = writeln!(s, "/// Numeric precision of the network.");
    let _ = writeln!(s, "pub const PRECISION: Precision = Precision::{prec};");
    let _ = writeln!(s, "/// Activation after the network's input layer.");
    let _ = writeln!(
        s,
        "pub const INPUT_ACTIVATION: InputActivation = InputActivation::{};",
        activation_variant(net.input_activation())
    );
    let _ = writeln!(s, "/// Feature preset the network was trained with.");
    let _ = writeln!(
        s,
        "pub const FEATURE_PRESET: FeaturePreset = FeaturePreset::{preset};"
    );
    let _ = writeln!(s, "/// Number of inputs.");
    let _ = writeln!(s, "pub const INPUTS: usize = {};", m.dims.input);
    let _ = writeln!(s, "/// Number of outputs.");
    let _ = writeln!(s, "pub const OUTPUTS: usize = {};", m.dims.output);
    let _ = writeln!(
        s,
        "/// The `drive` preset's linear stage: per output, coefficients [N*m per unit] of\n\
         /// `features::FRICTION_FEATURE_NAMES` (zero for other presets)."
    );
    let f = firmware::features::FRICTION_FEATURES;
    // Without a linear stage the file does not depend on the number of features.
    let stage = if m.linear.iter().all(|&x| x == 0.0) {
        "[[0.0; firmware::features::FRICTION_FEATURES]; OUTPUTS]".to_string()
    } else {
        let rows: Vec<Vec<f32>> = (0..m.dims.output)
            .map(|k| {
                m.linear
                    .get(k * f..(k + 1) * f)
                    .map_or_else(|| vec![0.0; f], <[f32]>::to_vec)
            })
            .collect();
        list(&rows, |r| list(r, |x| f32_lit(*x)))
    };
    let _ = write!(s, "{section}");
    let _ = writeln!(
        s,
        "pub static LINEAR_STAGE: [[f32; firmware::features::FRICTION_FEATURES]; OUTPUTS] = {stage};"
    );
    let _ = writeln!(s, "/// Input feature names, in input order.");
    let _ = writeln!(
        s,
        "pub const INPUT_NAMES: [&str; {}] = {};",
        m.dims.input,
        list(&m.input_names, |n| format!("{n:?}"))
    );
    let _ = writeln!(s, "/// Output names, in output order.");
    let _ = writeln!(
        s,
        "pub const OUTPUT_NAMES: [&str; {}] = {};",
        m.dims.output,
        list(&m.output_names, |n| format!("{n:?}"))
    );
    let _ = writeln!(s, "/// Indices (0-based) of the compensated joints.");
    let _ = writeln!(
        s,
        "pub const JOINT_INDICES: [usize; {}] = {};",
        meta.joints.len(),
        list(&meta.joints, |j| j.to_string())
    );
    let _ = writeln!(
        s,
        "/// Control (compensator) rate the network was trained for [Hz]."
    );
    let _ = writeln!(
        s,
        "pub const CONTROL_RATE_HZ: u32 = {};",
        meta.control_rate_hz
    );
    write_profiles(s, &meta.profiles);
    envelope::write_envelope(s, m);
    match net {
        Exported::F32(n) => {
            // The whole gate matrix goes with the network, or its first blocks to SRAM
            // and the next to CCM SRAM.
            let (head_section, split) = match meta.placement.network {
                Placement::Sram => (network_section.clone(), [n.dims.hidden, 0]),
                Placement::Flash => (
                    attribute(Placement::Sram),
                    [
                        meta.placement.gate_blocks_in_sram,
                        meta.placement.gate_blocks_in_ccm,
                    ],
                ),
            };
            write_f32(s, &network_section, &head_section, split, n)
        }
        Exported::Int16(n) => write_quant(s, &network_section, tables, n, "I16Weights", quads_i16),
        Exported::Int8(n) => write_quant(s, &network_section, tables, n, "I8Weights", quads_i8),
    }
    if let Some(d) = dynamics {
        write_any_dynamics(s, &dynamics_section, d);
    } else {
        let _ = writeln!(
            s,
            "/// Number of joints of the rigid-body model (0: none exported)."
        );
        let _ = writeln!(s, "pub const DYNAMICS_JOINTS: usize = 0;");
    }
    let outs = net.stream(&golden_inputs(m.dims.input, meta.self_check_steps));
    let _ = writeln!(
        s,
        "/// Self-check: streaming steps of `test_kit::golden::network::input` from the zero state."
    );
    let _ = writeln!(
        s,
        "pub const SELF_CHECK_STEPS: usize = {};",
        meta.self_check_steps
    );
    let _ = writeln!(
        s,
        "/// Self-check: FNV-1a of the output bits of those steps, computed by the exporter."
    );
    let _ = writeln!(
        s,
        "pub const SELF_CHECK_FNV: u64 = {:#018x};",
        output_digest(&outs)
    );
    let hash = Sha256::digest(body.as_bytes());
    let hash64 = u64::from_be_bytes(hash[..8].try_into().unwrap_or([0; 8]));
    let mut out = String::new();
    let _ = writeln!(
        out,
        "// Generated by `model-export export` (schema {SCHEMA_VERSION}); do not edit."
    );
    let _ = writeln!(
        out,
        "// Network {}x{}x{}x{} ({}), preset {}, joints {:?}, {} Hz.",
        m.dims.input,
        m.dims.embed,
        m.dims.hidden,
        m.dims.output,
        prec,
        // The closed set's name, never the model file's text.
        preset,
        meta.joints,
        meta.control_rate_hz
    );
    let _ = writeln!(out, "// Placement: {}.", meta.placement.describe());
    let _ = writeln!(out, "#[allow(unused_imports)]");
    let _ = writeln!(
        out,
        "use firmware::dynamics::{{JointModel, RigidBodyModel}};"
    );
    let _ = writeln!(out, "#[allow(unused_imports)]");
    let _ = writeln!(
        out,
        "use firmware::nn::format::{{FeaturePreset, I8Weights, I16Weights, InputActivation, Precision, QuantFormat, QuantState}};"
    );
    let _ = writeln!(out, "#[allow(unused_imports)]");
    let _ = writeln!(
        out,
        "use firmware::nn::kernels::{{F32GateRows, F32Lstm, F32State, LinearInput, QuantLstm, TanhInput}};"
    );
    let _ = writeln!(
        out,
        "/// SHA-256 (first 8 bytes) of everything below this line."
    );
    let _ = writeln!(out, "pub const CONTENT_HASH: u64 = {hash64:#018x};");
    out.push_str(&body);
    out
}
