//! The network's formats, shared by the kernels (`nn::kernels`), the DSP assembly
//! (`dsp`) and the generated model files: the Q formats of the integer scheme (module
//! docs of `nn::kernels`), the weight storage formats ([`I16Weights`], [`I8Weights`]),
//! a compiled-in network's integer format ([`QuantFormat`]), the integer recurrent
//! state whose layout the assembly reads ([`QuantState`]), the input layer's activation
//! ([`InputActivation`]), the numeric precision ([`Precision`]) and the feature preset
//! ([`FeaturePreset`]). It uses no kernel: the kernels and `dsp` build on it.

use crate::math;
use crate::nn::act;

/// Fraction bits of the normalised input (Q3.12).
pub const INPUT_FRAC_BITS: u32 = 12;
/// Fraction bits of `e`, `h` and the gates (Q0.15).
pub const ACT_FRAC_BITS: u32 = 15;
/// Fraction bits of the int16 cell state (Q4.11).
pub const CELL_FRAC_BITS: u32 = 11;
/// Index shift of the cell state's tanh (`CELL_FRAC_BITS - act::GRID_FRAC_BITS`).
pub const CELL_TANH_SHIFT: u32 = CELL_FRAC_BITS - act::GRID_FRAC_BITS;

/// Right shift that brings `i * g` (Q0.30) onto the scale of `c * f` (Q4.26).
pub const CELL_IG_SHIFT: u32 = 2 * ACT_FRAC_BITS - (CELL_FRAC_BITS + ACT_FRAC_BITS);
/// Rounding term of the cell update's final `>> 15` (the constant of its SMLABB).
pub const CELL_ROUND: i32 = 1 << (ACT_FRAC_BITS - 1);

/// A weight storage format of the integer kernels: how one quad of 4 columns of a
/// 4-row block is stored and multiplied (the multiplications of [`I16Weights`] and
/// [`I8Weights`] are implemented in `nn::kernels`, on the `dsp` kernels).
pub trait WeightFormat {
    /// One quad of 4 columns of a 4-row block.
    type Quad: Copy + core::fmt::Debug + PartialEq;
    /// Name used in reports and generated files (`int16`, `int8`).
    const NAME: &'static str;
    /// Largest weight magnitude of the format.
    const MAX_WEIGHT: i32;
    /// Whether a quad is two SMLAD-ready int16 pairs per row (the fused kernel's format).
    const INT16_PAIRS: bool = false;
    /// `acc[r] + sum_k w[r][k] * x[k]` for the 4 rows of a block.
    fn dot4(acc: [i32; 4], w: &[Self::Quad], x: &[[u32; 2]]) -> [i32; 4];
    /// [`Self::dot4`] for every block `b` of a layer: `acc[b] = dot4(bias[b],
    /// w[b * Q..(b + 1) * Q], x)`, `Q = x.len()`.
    #[inline(always)]
    fn matvec4(acc: &mut [[i32; 4]], bias: &[[i32; 4]], w: &[Self::Quad], x: &[[u32; 2]]) {
        let blocks = acc.iter_mut().zip(bias);
        for ((a, b), wb) in blocks.zip(w.chunks_exact(x.len().max(1))) {
            *a = Self::dot4(*b, wb, x);
        }
    }
    /// Packs `w[r][k]` (4 rows x 4 columns, each within `MAX_WEIGHT`).
    fn pack(w: [[i32; 4]; 4]) -> Self::Quad;
    /// The quads as int16 pairs when that is the format ([`Self::INT16_PAIRS`]).
    fn int16_pairs(q: &[Self::Quad]) -> Option<&[[[u32; 4]; 2]]> {
        let _ = q;
        None
    }
}

/// int16 weights: per quad, the two packed pairs of the 4 rows (`[pair][row]`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct I16Weights;

/// int8 weights: per quad, one word of four int8 weights per row (`dsp::pack_i8`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct I8Weights;

/// The integer format of one compiled-in network: its weight format, its input
/// layer's activation and the activation-index shifts of its layers (from the
/// power-of-two scales the exporter chose), and where its activation tables live.
/// Constants, so that the assembly kernel can encode them as immediates; each generated
/// model file defines its own `Format` type.
pub trait QuantFormat {
    /// Weight storage format.
    type Weights: WeightFormat;
    /// Activation after the input layer.
    const INPUT_ACTIVATION: InputActivation;
    /// Shift of the input layer's accumulators, `1..=31`: the tanh index shift
    /// (`P_in + 12 - 9`), or for a linear input layer the requantisation shift to `e`'s
    /// format (`P_in + 12 - F`).
    const INPUT_SHIFT: u32;
    /// Index shift of each gate's accumulators (`P_g + 15 - 9`), order `i, f, g, o`,
    /// each `1..=31`.
    const GATE_SHIFTS: [u32; 4];
    /// The activation tables the network reads: [`act::ACT_TABLES_SRAM`] or
    /// [`act::ACT_TABLES_FLASH`], the exporter's placement for the model.
    const ACT_TABLES: &'static act::ActTables;
}

/// The recurrent state of an integer network: the packed `[e; h]` vector (the `h`
/// part is the state, the `e` part scratch), the int16 Q4.11 cell state, and the gate
/// accumulators as scratch (kept here so that a step need not clear `16 * H` bytes
/// of stack; every step overwrites them before reading). `repr(C)`: the fused kernel
/// addresses `z` and `c` from one pointer.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct QuantState<const ZQ: usize, const H: usize> {
    /// Packed `[e; h]`, Q0.15.
    pub z: [[u32; 2]; ZQ],
    /// Cell state, Q4.11.
    pub c: [i16; H],
    /// Scratch: the last step's gate accumulators (no meaning between steps).
    pub acc: [[i32; 4]; H],
}

impl<const ZQ: usize, const H: usize> QuantState<ZQ, H> {
    /// The zero state a sequence starts from.
    pub const fn new() -> Self {
        QuantState {
            z: [[0; 2]; ZQ],
            c: [0; H],
            acc: [[0; 4]; H],
        }
    }

    /// Forgets the past: back to the zero state.
    pub fn reset(&mut self) {
        *self = Self::new();
    }
}

impl<const ZQ: usize, const H: usize> Default for QuantState<ZQ, H> {
    fn default() -> Self {
        Self::new()
    }
}

/// The activation after the fully connected input layer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InputActivation {
    /// `e = tanh(W_in x_n + b_in)`.
    Tanh,
    /// `e = W_in x_n + b_in` (identity: a plain `nn.Linear`).
    Linear,
}

impl InputActivation {
    /// Whether the input layer is linear (usable in constant expressions).
    pub const fn is_linear(self) -> bool {
        matches!(self, InputActivation::Linear)
    }

    /// Name in model files and metadata (`tanh`, `linear`).
    pub const fn name(self) -> &'static str {
        match self {
            InputActivation::Tanh => "tanh",
            InputActivation::Linear => "linear",
        }
    }

    /// The activation of a name ([`Self::name`]).
    pub fn from_name(name: &str) -> Option<Self> {
        [InputActivation::Tanh, InputActivation::Linear]
            .into_iter()
            .find(|a| a.name() == name)
    }

    /// Applies the activation to an input-layer sum.
    #[inline(always)]
    pub fn apply(self, x: f32) -> f32 {
        match self {
            InputActivation::Tanh => math::tanh(x),
            InputActivation::Linear => x,
        }
    }
}

/// Numeric precision of a compiled-in network.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Precision {
    /// f32 weights and activations (`nn::kernels::F32Lstm`).
    F32,
    /// int16 weights and activations (`nn::kernels::QuantLstm` with [`I16Weights`]).
    Int16,
    /// int8 weights, int16 activations (`nn::kernels::QuantLstm` with [`I8Weights`]).
    Int8,
}

/// Which features the network reads (see `model-export`'s `nn::data`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FeaturePreset {
    /// Per joint: model torque, measured torque, position (3 per joint) -> the next-step
    /// torque.
    Paper,
    /// Per joint: model torque, measured residual (measured minus model torque), position
    /// (3 per joint) -> the residual one tick later, added to the model's torque of that
    /// tick: a network that knows nothing returns the model.
    PaperRelative,
    /// Per joint: model torque, position, velocity (3 per joint) -> residual.
    Feedforward,
    /// Per joint: `crate::features::DRIVE_COLUMNS` (11 per joint) -> residual.
    Drive,
    /// Other columns (no layout check beyond the sizes).
    Custom,
}

impl FeaturePreset {
    /// Every preset.
    pub const ALL: [FeaturePreset; 5] = [
        FeaturePreset::Paper,
        FeaturePreset::PaperRelative,
        FeaturePreset::Feedforward,
        FeaturePreset::Drive,
        FeaturePreset::Custom,
    ];

    /// Name in model files and metadata (`paper`, `paper_relative`, `feedforward`,
    /// `drive`, `custom`).
    pub const fn name(self) -> &'static str {
        match self {
            FeaturePreset::Paper => "paper",
            FeaturePreset::PaperRelative => "paper_relative",
            FeaturePreset::Feedforward => "feedforward",
            FeaturePreset::Drive => "drive",
            FeaturePreset::Custom => "custom",
        }
    }

    /// The preset of a name ([`Self::name`]).
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|p| p.name() == name)
    }

    /// Inputs per compensated joint (0 for `Custom`).
    pub const fn inputs_per_joint(self) -> usize {
        match self {
            FeaturePreset::Paper | FeaturePreset::PaperRelative | FeaturePreset::Feedforward => 3,
            FeaturePreset::Drive => crate::features::DRIVE_INPUTS_PER_JOINT,
            FeaturePreset::Custom => 0,
        }
    }

    /// The joint torque an output stands for, N*m: `PaperRelative`, `Feedforward` and
    /// `Drive` add the model torque (the network predicts the residual); `Paper` and
    /// `Custom` outputs are torques.
    pub fn torque_nm(self, output: f32, model_nm: f32) -> f32 {
        match self {
            FeaturePreset::PaperRelative | FeaturePreset::Feedforward | FeaturePreset::Drive => {
                model_nm + output
            }
            FeaturePreset::Paper | FeaturePreset::Custom => output,
        }
    }

    /// Whether `inputs` features and `outputs` outputs fit this preset for `joints` joints.
    pub const fn fits(self, joints: usize, inputs: usize, outputs: usize) -> bool {
        match self {
            FeaturePreset::Custom => true,
            _ => inputs == self.inputs_per_joint() * joints && outputs == joints,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn preset_names_round_trip_and_only_paper_outputs_torque() {
        for p in FeaturePreset::ALL {
            assert_eq!(FeaturePreset::from_name(p.name()), Some(p));
            let absolute = matches!(p, FeaturePreset::Paper | FeaturePreset::Custom);
            assert_eq!(p.torque_nm(1.0, 10.0), if absolute { 1.0 } else { 11.0 });
        }
        assert_eq!(FeaturePreset::from_name("Paper"), None);
    }
}
