//! Quantise a compensation network into the firmware's kernel layout
//! (`firmware::nn::kernels`, Q formats documented there) and write it, with the
//! normalisation, feature preset, joints, control rate and optionally the dynamics
//! model, as ONE Rust source file of fixed-size `static`/`const` arrays that the
//! firmware compiles in (`model-export export`).
//!
//! The host evaluation of an exported network runs the firmware's own shape-erased
//! kernels (`QuantView::step`, `F32View::step`) on the exporter's vectors, so the
//! predictions written into the file (`SELF_CHECK_*`) are what the target computes.
#![deny(unsafe_code)]
#![warn(missing_docs)]
mod accuracy;
pub mod envelope;
mod f32_layout;
mod placement;
mod quant;
mod render;

pub use accuracy::*;
pub use f32_layout::*;
pub use placement::*;
pub use quant::*;
pub use render::*;

use anyhow::{Context, Result, bail};
use compnet::model::LstmModel;
use firmware::dynamics::RigidBodyModel;
use firmware::model::self_check;
use firmware::nn::act;
use firmware::nn::format::{
    ACT_FRAC_BITS, FeaturePreset, I8Weights, I16Weights, INPUT_FRAC_BITS, InputActivation,
    WeightFormat,
};
use firmware::nn::kernels::{F32Dims, F32View, QuantDims, QuantView};
use robot::dynamics::firmware_model::FirmwareModel;
use sha2::{Digest, Sha256};
use std::fmt::Write as _;

/// Version of the generated file's layout and numerics: the firmware's.
pub const SCHEMA_VERSION: u32 = firmware::model::SCHEMA_VERSION;

/// Numeric precision of an exported network.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Precision {
    /// f32 weights and activations.
    F32,
    /// int16 weights, int16 activations.
    Int16,
    /// int8 weights, int16 activations.
    Int8,
}

impl Precision {
    /// All precisions, in report order.
    pub const ALL: [Precision; 3] = [Precision::F32, Precision::Int16, Precision::Int8];
    /// Name in reports and generated files.
    pub fn name(self) -> &'static str {
        match self {
            Precision::F32 => "f32",
            Precision::Int16 => "int16",
            Precision::Int8 => "int8",
        }
    }
}

/// Why a network cannot be exported.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// A weight or normalisation value is NaN or infinite.
    #[error("tensor `{tensor}` element {index} is {value}: weights must be finite")]
    NotFinite {
        /// Tensor name (interchange name).
        tensor: &'static str,
        /// Flat index.
        index: usize,
        /// The value.
        value: f32,
    },
    /// No power-of-two weight scale fits a layer (or gate) into the Q format.
    #[error(
        "layer `{layer}`: weights up to {max_abs:e} (bias up to {max_bias:e}) overflow the Q \
         format: no power-of-two scale 2^-P with P >= {p_min} keeps every weight within the \
         format and every accumulator below 2^31 (a smaller P would put the activation \
         index shift outside 1..=31); the weights are too large"
    )]
    ScaleOverflow {
        /// Layer name (`input`, `lstm gate i`, ...).
        layer: &'static str,
        /// Largest weight magnitude.
        max_abs: f64,
        /// Largest bias magnitude.
        max_bias: f64,
        /// Smallest exponent the index shift allows.
        p_min: i32,
    },
    /// A linear input layer's outputs have no int16 format the kernel can shift to.
    #[error(
        "layer `input` (linear): its outputs reach {bound:e} for inputs within the Q3.12 \
         range (+-8 after normalisation), and no int16 format of them has a requantisation \
         shift in 1..=31 that keeps the accumulator below 2^31; the weights are too large"
    )]
    LinearInputRange {
        /// Largest `|e|` the layer can give.
        bound: f64,
    },
    /// A standard deviation is not positive.
    #[error("tensor `{tensor}` element {index} is {value}: standard deviations must be > 0")]
    BadStd {
        /// Tensor name.
        tensor: &'static str,
        /// Index.
        index: usize,
        /// Value.
        value: f32,
    },
    /// The model does not fit the flash budget.
    #[error(
        "the exported network needs {bytes} bytes of flash, over the budget of {budget} bytes \
         ({source_file})"
    )]
    TooLarge {
        /// Bytes of weights.
        bytes: usize,
        /// Budget.
        budget: u64,
        /// Where the budget comes from.
        source_file: String,
    },
}

/// An exported network in one of the precisions.
#[derive(Clone, Debug)]
pub enum Exported {
    /// f32.
    F32(F32Net),
    /// int16 weights.
    Int16(QuantNet<I16Weights>),
    /// int8 weights.
    Int8(QuantNet<I8Weights>),
}

impl Exported {
    /// Quantises / arranges `m` for `p`.
    pub fn new(m: &LstmModel, p: Precision) -> Result<Self, ExportError> {
        Ok(match p {
            Precision::F32 => Exported::F32(F32Net::arrange(m)?),
            Precision::Int16 => Exported::Int16(QuantNet::quantise(m)?),
            Precision::Int8 => Exported::Int8(QuantNet::quantise(m)?),
        })
    }

    /// Streams the firmware kernel from the zero state.
    pub fn stream(&self, inputs: &[Vec<f32>]) -> Vec<Vec<f32>> {
        match self {
            Exported::F32(n) => n.stream(inputs),
            Exported::Int16(n) => n.stream(inputs),
            Exported::Int8(n) => n.stream(inputs),
        }
    }

    /// Activation after the network's input layer.
    pub fn input_activation(&self) -> InputActivation {
        match self {
            Exported::F32(n) => n.input_activation,
            Exported::Int16(n) => n.in_activation,
            Exported::Int8(n) => n.in_activation,
        }
    }

    /// Bytes of one block of the gate matrix and the number of blocks, when the network
    /// can place the first blocks apart from the rest (f32: `F32GateRows`), else `(0, 0)`.
    pub fn gate_blocks(&self) -> (usize, usize) {
        match self {
            Exported::F32(n) => {
                let z = 4 * n.dims.embed_blocks + n.dims.hidden;
                (z * 16, n.dims.hidden)
            }
            Exported::Int16(_) | Exported::Int8(_) => (0, 0),
        }
    }

    /// Bytes of the activation tables the network reads (`firmware::nn::act`, 32 KiB for
    /// the integer networks; 0 for f32, whose activations are computed).
    pub fn act_tables_bytes(&self) -> usize {
        match self {
            Exported::F32(_) => 0,
            Exported::Int16(_) | Exported::Int8(_) => act::ACT_TABLES_BYTES,
        }
    }

    /// Bytes of flash the network's arrays take.
    pub fn flash_bytes(&self) -> usize {
        match self {
            Exported::F32(n) => n.flash_bytes(),
            Exported::Int16(n) => n.flash_bytes(),
            Exported::Int8(n) => n.flash_bytes(),
        }
    }
}

/// FNV-1a over the bits of every output of every step (the self-check digest).
/// (`firmware::model::self_check::Digest`).
pub fn output_digest(outputs: &[Vec<f32>]) -> u64 {
    let mut d = self_check::Digest::default();
    for row in outputs {
        d.add(row);
    }
    d.0
}

/// What goes into the generated file besides the network.
#[derive(Clone, Debug)]
pub struct ExportMeta {
    /// Feature preset (`paper`, `feedforward`, `custom`).
    pub preset: String,
    /// Indices of the compensated joints (0-based).
    pub joints: Vec<usize>,
    /// Control rate [Hz].
    pub control_rate_hz: u32,
    /// Steps of golden input for the self-check (`firmware::model::self_check::input`).
    pub self_check_steps: usize,
    /// Where the model's arrays live on the target, and why.
    pub placement: PlacementChoice,
    /// Drive profile of each compensated joint, in `joints` order (the robot
    /// description's, `JointProfile::BOARD` where it gives none).
    pub profiles: Vec<firmware::control::JointProfile>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use firmware::nn::reference::LstmDims;

    /// The paper int16 network's sizes (68 968 B), and the board's model budget.
    const PAPER_INT16: ModelBytes = ModelBytes {
        network: 68_968,
        dynamics: 808,
        linear_stage: 324,
        act_tables: act::ACT_TABLES_BYTES,
        gate_block: 0,
        gate_blocks: 0,
    };
    const BUDGET: Option<ModelBudget> = Some(ModelBudget {
        sram_bytes: 73_728,
        ccm_bytes: 0,
    });

    fn tables(
        want: WeightsIn,
        bytes: ModelBytes,
        budget: Option<ModelBudget>,
    ) -> Option<Placement> {
        choose_placement(want, bytes, budget)
            .expect("placement")
            .act_tables
    }

    #[test]
    fn the_tables_go_to_sram_only_when_they_fit_beside_the_arrays() {
        // 68 968 + 808 + 324 + 32 768 > 73 728: the tables stay in flash.
        assert_eq!(
            tables(WeightsIn::Auto, PAPER_INT16, BUDGET),
            Some(Placement::Flash)
        );
        // The per-joint network (4 728 B): everything fits.
        let joint = ModelBytes {
            network: 4_728,
            dynamics: 0,
            linear_stage: 108,
            ..PAPER_INT16
        };
        let p = choose_placement(WeightsIn::Auto, joint, BUDGET).expect("placement");
        assert_eq!(
            (p.network, p.linear_stage, p.act_tables),
            (Placement::Sram, Placement::Sram, Some(Placement::Sram))
        );
        assert!(
            p.describe()
                .contains("activation tables 32768 bytes in SRAM")
        );
        // Exactly at the budget fits; one byte over does not.
        let exact = ModelBytes {
            network: 73_728 - 32_768,
            dynamics: 0,
            linear_stage: 0,
            ..PAPER_INT16
        };
        assert_eq!(
            tables(WeightsIn::Auto, exact, BUDGET),
            Some(Placement::Sram)
        );
        let over = ModelBytes {
            network: exact.network + 1,
            ..exact
        };
        assert_eq!(
            tables(WeightsIn::Auto, over, BUDGET),
            Some(Placement::Flash)
        );
        // A network too big for SRAM leaves the room to the tables.
        let f32_sized = ModelBytes {
            network: 135_800,
            ..joint
        };
        let p = choose_placement(WeightsIn::Auto, f32_sized, BUDGET).expect("placement");
        assert_eq!(
            (p.network, p.act_tables),
            (Placement::Flash, Some(Placement::Sram))
        );
    }

    #[test]
    fn an_f32_network_too_big_for_sram_puts_its_first_gate_blocks_there() {
        // The paper f32 network: 135 800 B, 64 gate blocks of 128 columns (2 048 B).
        let paper_f32 = ModelBytes {
            network: 135_800,
            dynamics: 808,
            linear_stage: 324,
            act_tables: 0,
            gate_block: 2_048,
            gate_blocks: 64,
        };
        let p = choose_placement(WeightsIn::Auto, paper_f32, BUDGET).expect("placement");
        // (73 728 - 808 - 324) / 2 048 = 35 blocks.
        assert_eq!(
            (p.network, p.dynamics, p.linear_stage, p.gate_blocks_in_sram),
            (Placement::Flash, Placement::Sram, Placement::Sram, 35)
        );
        assert_eq!(p.gate_blocks_in_ccm, 0);
        assert!(
            p.describe()
                .contains("(its gate matrix's first 35 of 64 blocks, 71680 bytes, in SRAM)"),
            "{}",
            p.describe()
        );
        // With CCM SRAM beside the code: the next blocks go there (24 576 / 2 048 = 12;
        // up to 26 623 B still 12: whole blocks).
        for ccm_bytes in [24_576, 25_000, 26_623] {
            let budget = Some(ModelBudget {
                sram_bytes: 73_728,
                ccm_bytes,
            });
            let p = choose_placement(WeightsIn::Auto, paper_f32, budget).expect("placement");
            assert_eq!((p.gate_blocks_in_sram, p.gate_blocks_in_ccm), (35, 12));
            assert!(
                p.describe()
                    .contains("71680 bytes, in SRAM, the next 12, 24576 bytes, in CCM SRAM)"),
                "{}",
                p.describe()
            );
        }
        // Never more blocks than the matrix has.
        let huge = Some(ModelBudget {
            sram_bytes: 73_728,
            ccm_bytes: 1 << 20,
        });
        let p = choose_placement(WeightsIn::Auto, paper_f32, huge).expect("placement");
        assert_eq!((p.gate_blocks_in_sram, p.gate_blocks_in_ccm), (35, 29));
        for (want, budget) in [(WeightsIn::Flash, BUDGET), (WeightsIn::Auto, None)] {
            let p = choose_placement(want, paper_f32, budget).expect("placement");
            assert_eq!((p.gate_blocks_in_sram, p.gate_blocks_in_ccm), (0, 0));
        }
        // A network that fits keeps its gate matrix whole (with the network).
        let small = ModelBytes {
            network: 3_192,
            ..paper_f32
        };
        let p = choose_placement(WeightsIn::Auto, small, BUDGET).expect("placement");
        assert_eq!((p.network, p.gate_blocks_in_sram), (Placement::Sram, 0));
    }

    #[test]
    fn the_ccm_budget_is_the_ccmram_region_less_the_code_reserve() {
        let layout = "MEMORY\n{\n  RAM : ORIGIN = 0x20000000, LENGTH = 96K\n  \
                      CCMRAM : ORIGIN = 0x10000000, LENGTH = 32K /* CCMRAM: LENGTH = 1 */\n}\n";
        assert_eq!(layout_region_bytes(layout, "CCMRAM"), Ok(Some(32 * 1024)));
        assert_eq!(layout_region_bytes(layout, "FLASH"), Ok(None));
        assert!(
            layout_region_bytes("CCMRAM : ORIGIN = 0, LENGTH = x", "CCMRAM")
                .is_err_and(|e| e.contains("line 1") && e.contains("CCMRAM"))
        );
        let mut b = SramBudget {
            layout_ram_bytes: 96 * 1024,
            ram_limit_bytes: 98_304,
            stack_reserve_bytes: 16_384,
            firmware_ram_bytes: 8_192,
            layout_ccm_bytes: 32 * 1024,
            ccm_code_reserve_bytes: Some(8_192),
        };
        assert_eq!(
            b.model_bytes(),
            ModelBudget {
                sram_bytes: 73_728,
                ccm_bytes: 24_576
            }
        );
        // Without the reserve in the budget file, nothing goes to CCM SRAM.
        b.ccm_code_reserve_bytes = None;
        assert_eq!(b.model_bytes().ccm_bytes, 0);
        // The board's own budget file and memory layout.
        let file =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../host-tests/budgets.toml");
        let board = sram_budget(&file).expect("budget file");
        assert_eq!(board.layout_ccm_bytes, 32 * 1024);
        assert!(board.model_bytes().ccm_bytes > 0);
    }

    #[test]
    fn the_generated_f32_network_splits_its_gate_matrix_between_three_statics() {
        let m = LstmModel::init(
            LstmDims {
                input: 3,
                embed: 4,
                hidden: 8,
                output: 1,
            },
            5,
        );
        let net = F32Net::arrange(&m).expect("arranges");
        let sram = format!("{SRAM_SECTION_ATTRIBUTE}\n");
        let ccm = format!("{CCM_SECTION_ATTRIBUTE}\n");
        let mut s = String::new();
        write_f32(&mut s, "", &sram, [3, 2], &net);
        assert!(s.contains(&format!(
            "{sram}pub static GATES_HEAD: [[[f32; 4]; 12]; 3] = "
        )));
        assert!(s.contains(&format!(
            "{ccm}pub static GATES_MIDDLE: [[[f32; 4]; 12]; 2] = "
        )));
        assert!(s.contains("\npub static GATES_TAIL: [[[f32; 4]; 12]; 3] = "));
        assert!(!s.contains(&format!("{sram}pub static GATES_TAIL")));
        assert!(s.contains(
            "w_gates: F32GateRows { head: &GATES_HEAD, middle: &GATES_MIDDLE, tail: &GATES_TAIL },"
        ));
        // Nothing in SRAM or CCM SRAM: no attribute for the empty parts.
        let mut s = String::new();
        write_f32(&mut s, "", "", [0, 0], &net);
        assert!(s.contains("pub static GATES_HEAD: [[[f32; 4]; 12]; 0] = [];"));
        assert!(s.contains("pub static GATES_MIDDLE: [[[f32; 4]; 12]; 0] = [];"));
        assert!(!s.contains("link_section"));
        assert_eq!(Exported::F32(net).gate_blocks(), (12 * 16, 8));
    }

    #[test]
    fn forced_and_unbudgeted_choices_place_the_tables_with_the_arrays() {
        let joint = ModelBytes {
            network: 4_728,
            dynamics: 0,
            linear_stage: 108,
            ..PAPER_INT16
        };
        assert_eq!(
            tables(WeightsIn::Flash, joint, BUDGET),
            Some(Placement::Flash)
        );
        assert_eq!(tables(WeightsIn::Auto, joint, None), Some(Placement::Flash));
        assert_eq!(tables(WeightsIn::Sram, joint, None), Some(Placement::Sram));
        assert_eq!(
            tables(WeightsIn::Sram, joint, BUDGET),
            Some(Placement::Sram)
        );
        // `sram` keeps the arrays in SRAM and the tables where they fit.
        assert_eq!(
            tables(WeightsIn::Sram, PAPER_INT16, BUDGET),
            Some(Placement::Flash)
        );
        // An f32 network reads no tables.
        let f32_net = ModelBytes {
            act_tables: 0,
            ..joint
        };
        let p = choose_placement(WeightsIn::Auto, f32_net, BUDGET).expect("placement");
        assert_eq!(p.act_tables, None);
        assert!(p.describe().contains("no activation tables (f32)"));
    }

    #[test]
    fn the_generated_format_names_the_chosen_tables() {
        let m = LstmModel::init(
            LstmDims {
                input: 3,
                embed: 4,
                hidden: 4,
                output: 1,
            },
            5,
        );
        let net = QuantNet::<I16Weights>::quantise(&m).expect("quantises");
        for (p, name) in [
            (Placement::Sram, "&firmware::nn::act::ACT_TABLES_SRAM;"),
            (Placement::Flash, "&firmware::nn::act::ACT_TABLES_FLASH;"),
        ] {
            let mut s = String::new();
            write_quant(&mut s, "", p, &net, "I16Weights", quads_i16);
            let line = s
                .lines()
                .find(|l| l.contains("const ACT_TABLES"))
                .expect("the format names its tables");
            assert!(line.ends_with(name), "{line}");
        }
        assert_eq!(Exported::Int16(net).act_tables_bytes(), 32_768);
    }
}
